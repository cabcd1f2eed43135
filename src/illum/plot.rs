//! PNG plots: the visible fraction of the Sun and the Earth over time, and the horizon profile
//! with the Sun's and the Earth's sky tracks (rectangular az × el, and a polar variant).
//!
//! Rendering uses `plotters`' bitmap backend into an RGB buffer, encoded as PNG with `image`, then
//! written atomically ([`crate::output::write_bytes_atomic`]). Text uses the DejaVu Sans font
//! embedded by the `dejavu` crate (Bitstream Vera licence, permissive) through `ab_glyph`, so no
//! system font library (freetype/fontconfig) is needed.

use std::path::Path;
use std::sync::OnceLock;

use hifitime::Epoch;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::IllumError;
use super::disc::HorizonProfile;

/// Default plot size in pixels (width, height).
pub const DEFAULT_SIZE_PX: (u32, u32) = (1200, 600);

/// Colour of the Sun's curves and track.
const SUN_COLOR: RGBColor = RGBColor(230, 130, 0);
/// Colour of the Earth's curves and track.
const EARTH_COLOR: RGBColor = RGBColor(30, 90, 200);
/// Fill colour of the terrain below the horizon.
const TERRAIN_COLOR: RGBColor = RGBColor(170, 170, 170);
/// Most track points drawn per body (longer tracks are thinned by a uniform stride).
const MAX_TRACK_POINTS: usize = 40_000;

/// Registers the embedded font once (the ab_glyph backend has no font until one is registered).
fn ensure_font() -> Result<(), IllumError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
            .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(IllumError::Plot {
            what: "font",
            message: "the embedded DejaVu Sans font failed to load".to_string(),
        })
    }
}

fn plot_err<E: std::fmt::Display>(what: &'static str) -> impl Fn(E) -> IllumError {
    move |e| IllumError::Plot {
        what,
        message: e.to_string(),
    }
}

/// Draws with `draw` on a white canvas of `size_px` and returns the PNG bytes.
fn render_png(
    what: &'static str,
    size_px: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), IllumError>,
) -> Result<Vec<u8>, IllumError> {
    ensure_font()?;
    let (w, h) = size_px;
    if w < 200 || h < 150 {
        return Err(IllumError::Plot {
            what,
            message: format!("plot size {w}x{h} px is too small (min 200x150)"),
        });
    }
    let mut rgb = vec![0_u8; (w as usize) * (h as usize) * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err(what))?;
        draw(&root)?;
        root.present().map_err(plot_err(what))?;
    }
    let img = image::RgbImage::from_raw(w, h, rgb).ok_or_else(|| IllumError::Plot {
        what,
        message: "pixel buffer has the wrong size".to_string(),
    })?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(plot_err(what))?;
    Ok(png)
}

/// The rectangular chart of the fraction and horizon plots (caption, margins and label areas
/// shared) over the axis ranges `x` and `y`.
fn rect_chart<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    title: &str,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    (what, y_label_px): (&'static str, u32),
) -> Result<
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    IllumError,
> {
    ChartBuilder::on(root)
        .caption(title, ("sans-serif", 24))
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(y_label_px)
        .build_cartesian_2d(x, y)
        .map_err(plot_err(what))
}

/// A visibility time series to plot: uniform grid from `start_utc` every `step_s` seconds.
#[derive(Debug, Clone, Copy)]
pub struct FractionSeries<'a> {
    /// Epoch of the first sample.
    pub start_utc: Epoch,
    /// Step between samples, seconds.
    pub step_s: f64,
    /// Visible fraction of the Sun per sample.
    pub sun_fraction: &'a [f64],
    /// Visible fraction of the Earth per sample, if it is to be drawn.
    pub earth_fraction: Option<&'a [f64]>,
}

/// Time axis unit chosen from the span: hours up to 3 days, days up to 2 years, else years.
fn time_unit(span_s: f64) -> (f64, &'static str) {
    if span_s <= 3.0 * 86_400.0 {
        (3600.0, "h")
    } else if span_s <= 2.0 * 365.25 * 86_400.0 {
        (86_400.0, "days")
    } else {
        (365.25 * 86_400.0, "years")
    }
}

/// Series longer than this are drawn as monthly aggregates (hourly lines over months are a solid
/// wall of colour), days.
pub const AGGREGATE_AFTER_DAYS: f64 = 62.0;

/// Calendar ticks of a time axis in `unit_s` units from `start` over `0..x_max`: whole hours
/// (every 3, 6, 12 or 24 h) for spans of hours, midnights (every 1, 2, 5, 7 or 14 days) for
/// spans up to two months, else the first of a month (every 1, 2, 3, 6, 12, 24 or 60 months;
/// `YYYY` labels from a year on), at most 10 ticks. Positions and labels (UTC).
fn calendar_ticks(start: Epoch, x_max: f64, unit_s: f64) -> Vec<(f64, String)> {
    let span_s = x_max * unit_s;
    // A tick in the last 3 % of the axis would have its centred label cut at the right edge.
    let end = start + hifitime::Duration::from_seconds(0.97 * span_s);
    let x_of = |e: Epoch| (e - start).to_seconds() / unit_s;
    let (y0, m0, d0, h0, _, _, _) = start.to_gregorian_utc();
    let mut ticks = Vec::new();
    if span_s <= 3.0 * 86_400.0 {
        let step_h = [3_i64, 6, 12, 24]
            .into_iter()
            .find(|h| span_s / (*h as f64 * 3600.0) <= 10.0)
            .unwrap_or(24);
        let mut e = Epoch::from_gregorian_utc(y0, m0, d0, h0, 0, 0, 0);
        while e <= end {
            let (_, mo, d, h, mi, _, _) = e.to_gregorian_utc();
            if e >= start && i64::from(h) % step_h == 0 {
                ticks.push((x_of(e), format!("{mo:02}-{d:02} {h:02}:{mi:02}")));
            }
            e += hifitime::Duration::from_seconds(3600.0);
        }
    } else if span_s <= 62.0 * 86_400.0 {
        let step_d = [1_i64, 2, 5, 7, 14]
            .into_iter()
            .find(|d| span_s / (*d as f64 * 86_400.0) <= 10.0)
            .unwrap_or(14);
        let mut e = Epoch::from_gregorian_utc_at_midnight(y0, m0, d0);
        let mut k = 0_i64;
        while e <= end {
            if e >= start && k % step_d == 0 {
                let (y, mo, d, _, _, _, _) = e.to_gregorian_utc();
                ticks.push((x_of(e), format!("{y}-{mo:02}-{d:02}")));
            }
            e += hifitime::Duration::from_seconds(86_400.0);
            k += 1;
        }
    } else {
        let months = span_s / (30.44 * 86_400.0);
        let step_m = [1_i64, 2, 3, 6, 12, 24, 60]
            .into_iter()
            .find(|m| months / *m as f64 <= 10.0)
            .unwrap_or(60);
        let (mut y, mut mo) = (y0, m0);
        loop {
            let e = Epoch::from_gregorian_utc_at_midnight(y, mo, 1);
            if e > end {
                break;
            }
            let index = i64::from(y) * 12 + i64::from(mo) - 1;
            if e >= start && index.rem_euclid(step_m) == 0 {
                let label = if step_m >= 12 {
                    format!("{y}")
                } else {
                    format!("{y}-{mo:02}")
                };
                ticks.push((x_of(e), label));
            }
            (y, mo) = if mo == 12 { (y + 1, 1) } else { (y, mo + 1) };
        }
    }
    ticks
}

/// One calendar month (UTC) of a series.
#[derive(Debug, Clone, PartialEq)]
pub struct MonthStats {
    /// Year and month (1–12).
    pub year_month: (i32, u8),
    /// Mean visible fraction of the Sun over the month's samples, % (time- and disc-weighted).
    pub sun_pct: f64,
    /// Mean visible fraction of the Earth, % (`NaN` without an Earth series).
    pub earth_pct: f64,
    /// Longest run of samples with the Sun entirely hidden within or into the month, hours: a
    /// run that began in an earlier month counts from its start.
    pub longest_dark_h: f64,
}

/// Monthly aggregates of a series (calendar months, UTC): what the plot of a long series shows.
pub fn monthly_stats(series: &FractionSeries<'_>) -> Vec<MonthStats> {
    let mut out: Vec<MonthStats> = Vec::new();
    let (mut sun_sum, mut earth_sum, mut n) = (0.0, 0.0, 0usize);
    let (mut run, mut longest) = (0usize, 0usize);
    let mut current: Option<(i32, u8)> = None;
    let step_h = series.step_s / 3600.0;
    let mut close = |ym: (i32, u8), sun: f64, earth: f64, n: usize, longest: usize| {
        out.push(MonthStats {
            year_month: ym,
            sun_pct: 100.0 * sun / n.max(1) as f64,
            earth_pct: if series.earth_fraction.is_some() {
                100.0 * earth / n.max(1) as f64
            } else {
                f64::NAN
            },
            longest_dark_h: longest as f64 * step_h,
        });
    };
    for (k, &sun) in series.sun_fraction.iter().enumerate() {
        let e = series.start_utc + hifitime::Duration::from_seconds(k as f64 * series.step_s);
        let (y, mo, ..) = e.to_gregorian_utc();
        if current.is_some_and(|c| c != (y, mo)) {
            close(current.unwrap_or((y, mo)), sun_sum, earth_sum, n, longest);
            (sun_sum, earth_sum, n, longest) = (0.0, 0.0, 0, 0);
        }
        current = Some((y, mo));
        sun_sum += sun;
        earth_sum += series.earth_fraction.map_or(0.0, |e| e[k]);
        n += 1;
        if sun <= 0.0 {
            run += 1;
            longest = longest.max(run);
        } else {
            run = 0;
        }
    }
    if let Some(ym) = current {
        close(ym, sun_sum, earth_sum, n, longest);
    }
    out
}

/// Renders the visible fraction of the Sun (and the Earth) over time as PNG bytes: the samples
/// against dates for series up to [`AGGREGATE_AFTER_DAYS`], monthly bars ([`monthly_stats`]: mean
/// visible %, longest darkness) beyond.
fn render_fraction_plot_png(
    title: &str,
    series: &FractionSeries<'_>,
    size_px: (u32, u32),
) -> Result<Vec<u8>, IllumError> {
    const WHAT: &str = "visible-fraction plot";
    let n = series.sun_fraction.len();
    if n == 0 {
        return Err(IllumError::EmptySeries {
            site: title.to_string(),
        });
    }
    let span_s = n as f64 * series.step_s;
    if span_s > AGGREGATE_AFTER_DAYS * 86_400.0 {
        return render_monthly_png(title, &monthly_stats(series), size_px);
    }
    let (unit_s, _) = time_unit(span_s);
    let x_max = span_s / unit_s;
    let x_of = |k: usize| k as f64 * series.step_s / unit_s;
    let start = series.start_utc;
    render_png(WHAT, size_px, |root| {
        let mut chart = rect_chart(root, title, 0.0..x_max, -0.02..1.2, (WHAT, 60))?;
        chart
            .configure_mesh()
            .x_desc("date (UTC)")
            .x_labels(0)
            .y_desc("visible fraction of the disc")
            .y_labels(13)
            .light_line_style(BLACK.mix(0.04))
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .draw()
            .map_err(plot_err(WHAT))?;
        draw_ticks(root, &chart, &calendar_ticks(start, x_max, unit_s), &[])
            .map_err(plot_err(WHAT))?;
        if let Some(earth) = series.earth_fraction {
            chart
                .draw_series(LineSeries::new(
                    earth.iter().enumerate().map(|(k, &f)| (x_of(k), f)),
                    EARTH_COLOR.stroke_width(1),
                ))
                .map_err(plot_err(WHAT))?
                .label("Earth")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], EARTH_COLOR));
        }
        chart
            .draw_series(LineSeries::new(
                series
                    .sun_fraction
                    .iter()
                    .enumerate()
                    .map(|(k, &f)| (x_of(k), f)),
                SUN_COLOR.stroke_width(2),
            ))
            .map_err(plot_err(WHAT))?
            .label("Sun")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], SUN_COLOR));
        draw_legend(&mut chart, 15, SeriesLabelPosition::UpperRight, WHAT)?;
        Ok(())
    })
}

/// One row of a [`write_windows_plot`]: a label, a flag per sample and a colour (RGB).
#[derive(Debug, Clone, Copy)]
pub struct WindowRow<'a> {
    /// The row's label, e.g. `"DTE"`.
    pub label: &'a str,
    /// The condition per sample (same time grid as the plot's).
    pub on: &'a [bool],
    /// Bar colour, RGB.
    pub rgb: (u8, u8, u8),
}

/// A timeline of windows: each row's runs of `true` samples as bars (a sample covers one step
/// from its epoch), rows top to bottom in the order given. Used for the link to Earth beside
/// sunlight (`dte_windows.png`).
pub fn write_windows_plot(
    path: &Path,
    title: &str,
    start_utc: Epoch,
    step_s: f64,
    rows: &[WindowRow<'_>],
    size_px: (u32, u32),
) -> Result<(), IllumError> {
    const WHAT: &str = "windows plot";
    let n = rows.first().map_or(0, |r| r.on.len());
    if n == 0 || rows.iter().any(|r| r.on.len() != n) {
        return Err(IllumError::EmptySeries {
            site: title.to_string(),
        });
    }
    let span_s = n as f64 * step_s;
    let (unit_s, _) = time_unit(span_s);
    let x_of = |k: usize| k as f64 * step_s / unit_s;
    let m = rows.len() as f64;
    // Room for the longest row label (≈ 8 px a character at 15 px).
    let label_px = rows
        .iter()
        .map(|r| 8 * r.label.chars().count() as u32 + 16)
        .max()
        .unwrap_or(0)
        .max(60);
    let png = render_png(WHAT, size_px, |root| {
        let mut chart = rect_chart(root, title, 0.0..span_s / unit_s, 0.0..m, (WHAT, label_px))?;
        chart
            .configure_mesh()
            .x_desc("date (UTC)")
            .x_labels(0)
            .y_labels(2 * rows.len() + 1)
            .y_label_formatter(&|y| {
                // Ticks every half row: a row's label at its middle (rows from the top).
                let i = (m - y - 0.5).round();
                if ((m - y - 0.5) - i).abs() < 1e-6 && i >= 0.0 {
                    rows.get(i as usize)
                        .map_or(String::new(), |r| r.label.to_string())
                } else {
                    String::new()
                }
            })
            .disable_y_mesh()
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .draw()
            .map_err(plot_err(WHAT))?;
        draw_ticks(
            root,
            &chart,
            &calendar_ticks(start_utc, span_s / unit_s, unit_s),
            &[],
        )
        .map_err(plot_err(WHAT))?;
        for (i, row) in rows.iter().enumerate() {
            let y0 = m - i as f64 - 0.85;
            let y1 = m - i as f64 - 0.15;
            let color = RGBColor(row.rgb.0, row.rgb.1, row.rgb.2).filled();
            let bars = runs(row.on)
                .into_iter()
                .map(|(a, b)| Rectangle::new([(x_of(a), y0), (x_of(b), y1)], color));
            chart.draw_series(bars).map_err(plot_err(WHAT))?;
        }
        Ok(())
    })?;
    crate::output::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// Runs of `true` in `on` as half-open sample ranges.
fn runs(on: &[bool]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < on.len() {
        if on[k] {
            let a = k;
            while k < on.len() && on[k] {
                k += 1;
            }
            out.push((a, k));
        } else {
            k += 1;
        }
    }
    out
}

/// A panel's power (top) and, with a battery, its charge (bottom) over time, the nights (the Sun
/// entirely hidden) shaded: `power.png`.
#[allow(
    clippy::too_many_arguments,
    reason = "a plot of one series and its shading, all plain values"
)]
pub fn write_power_plot(
    path: &Path,
    title: &str,
    start_utc: Epoch,
    step_s: f64,
    power_w: &[f64],
    battery_wh: Option<&[f64]>,
    night: &[bool],
    size_px: (u32, u32),
) -> Result<(), IllumError> {
    const WHAT: &str = "power plot";
    let n = power_w.len();
    if n == 0 || night.len() != n || battery_wh.is_some_and(|b| b.len() != n) {
        return Err(IllumError::EmptySeries {
            site: title.to_string(),
        });
    }
    let span_s = n as f64 * step_s;
    let (unit_s, _) = time_unit(span_s);
    let x_of = |k: usize| k as f64 * step_s / unit_s;
    let x_max = span_s / unit_s;
    let nights = runs(night);
    let shade = BLACK.mix(0.12).filled();
    let max_of = |v: &[f64]| {
        v.iter()
            .copied()
            .filter(|x| x.is_finite())
            .fold(0.0_f64, f64::max)
    };
    let png = render_png(WHAT, size_px, |root| {
        let root = root
            .titled(title, ("sans-serif", 24))
            .map_err(plot_err(WHAT))?;
        let areas: Vec<_> = match battery_wh {
            Some(_) => {
                let (a, b) = root.split_vertically(root.dim_in_pixel().1 / 2);
                vec![a, b]
            }
            None => vec![root],
        };
        let series: Vec<(&[f64], &str, RGBColor)> =
            std::iter::once((power_w, "power, W", SUN_COLOR))
                .chain(battery_wh.map(|b| (b, "battery charge, Wh", EARTH_COLOR)))
                .collect();
        for (area, (values, label, color)) in areas.iter().zip(series) {
            let y_max = (max_of(values) * 1.05).max(1.0);
            let mut chart = ChartBuilder::on(area)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d(0.0..x_max, 0.0..y_max)
                .map_err(plot_err(WHAT))?;
            chart
                .configure_mesh()
                .x_labels(0)
                .y_desc(label)
                .light_line_style(BLACK.mix(0.04))
                .label_style(("sans-serif", 14))
                .axis_desc_style(("sans-serif", 16))
                .draw()
                .map_err(plot_err(WHAT))?;
            draw_ticks(area, &chart, &calendar_ticks(start_utc, x_max, unit_s), &[])
                .map_err(plot_err(WHAT))?;
            chart
                .draw_series(
                    nights
                        .iter()
                        .map(|&(a, b)| Rectangle::new([(x_of(a), 0.0), (x_of(b), y_max)], shade)),
                )
                .map_err(plot_err(WHAT))?;
            chart
                .draw_series(LineSeries::new(
                    values.iter().enumerate().map(|(k, &v)| (x_of(k), v)),
                    color.stroke_width(1),
                ))
                .map_err(plot_err(WHAT))?;
        }
        Ok(())
    })?;
    crate::output::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// Tick marks, labels and light grid lines at chosen values of a chart's x and y axes (plotters'
/// own labels are off: its choice of values cannot be made to fall on calendar months or to
/// stop at 100 %). `area` is the drawing area the chart was built on.
fn draw_ticks<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    chart: &ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    x_ticks: &[(f64, String)],
    y_ticks: &[(f64, String)],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (x_range, y_range) = (chart.x_range(), chart.y_range());
    let base = area.get_base_pixel();
    let plot = chart.plotting_area();
    let font = ("sans-serif", 14).into_font();
    for (x, text) in x_ticks {
        plot.draw(&PathElement::new(
            vec![(*x, y_range.start), (*x, y_range.end)],
            BLACK.mix(0.12),
        ))?;
        let (px, py) = chart.backend_coord(&(*x, y_range.start));
        let (px, py) = (px - base.0, py - base.1);
        area.draw(&PathElement::new(vec![(px, py), (px, py + 5)], BLACK))?;
        area.draw(&Text::new(
            text.clone(),
            (px, py + 8),
            TextStyle::from(font.clone()).pos(Pos::new(HPos::Center, VPos::Top)),
        ))?;
    }
    for (y, text) in y_ticks {
        plot.draw(&PathElement::new(
            vec![(x_range.start, *y), (x_range.end, *y)],
            BLACK.mix(0.12),
        ))?;
        let (px, py) = chart.backend_coord(&(x_range.start, *y));
        let (px, py) = (px - base.0, py - base.1);
        area.draw(&PathElement::new(vec![(px - 5, py), (px, py)], BLACK))?;
        area.draw(&Text::new(
            text.clone(),
            (px - 8, py),
            TextStyle::from(font.clone()).pos(Pos::new(HPos::Right, VPos::Center)),
        ))?;
    }
    Ok(())
}

/// Monthly bars: mean visible % of the Sun and the Earth (top), longest darkness (bottom).
fn render_monthly_png(
    title: &str,
    months: &[MonthStats],
    size_px: (u32, u32),
) -> Result<Vec<u8>, IllumError> {
    const WHAT: &str = "monthly visibility plot";
    let m = months.len() as f64;
    let label = |x: f64| {
        let i = x.floor().max(0.0) as usize;
        months
            .get(i)
            .map(|s| format!("{}-{:02}", s.year_month.0, s.year_month.1))
            .unwrap_or_default()
    };
    // Month labels at a regular step (1, 2, 3, 6 months, or whole years), on calendar
    // boundaries (January, April, …), at most about 12 of them.
    let step = [1usize, 2, 3, 6, 12, 24, 60, 120]
        .into_iter()
        .find(|k| months.len() / k <= 12)
        .unwrap_or(240);
    let month_ticks: Vec<(f64, String)> = months
        .iter()
        .enumerate()
        .filter(|(_, s)| {
            let (y, mo) = (i64::from(s.year_month.0), i64::from(s.year_month.1));
            (y * 12 + (mo - 1)).rem_euclid(step as i64) == 0
        })
        .map(|(i, _)| (i as f64, label(i as f64)))
        .collect();
    let has_earth = months.iter().any(|s| !s.earth_pct.is_nan());
    render_png(WHAT, size_px, |root| {
        let root = root
            .titled(title, ("sans-serif", 24))
            .map_err(plot_err(WHAT))?;
        let (top, bottom) = root.split_vertically(root.dim_in_pixel().1 * 55 / 100);
        let mut chart = ChartBuilder::on(&top)
            .margin(12)
            .x_label_area_size(30)
            .y_label_area_size(60)
            // Head room above 100 % for the legend, so that it covers no bar; ticks (and
            // labels) only at 0, 20, …, 100.
            .build_cartesian_2d(0.0..m, 0.0..135.0)
            .map_err(plot_err(WHAT))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(0)
            .y_labels(0)
            .y_desc("mean visible % of the month")
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(plot_err(WHAT))?;
        let pct_ticks: Vec<(f64, String)> = (0..=5)
            .map(|k| (20.0 * k as f64, format!("{}", 20 * k)))
            .collect();
        draw_ticks(&top, &chart, &month_ticks, &pct_ticks).map_err(plot_err(WHAT))?;
        let width = if has_earth { 0.42 } else { 0.84 };
        // The Sun's bars (body 0), then the Earth's beside them.
        let bars = [
            (0.08, SUN_COLOR, "Sun (disc-weighted)"),
            (0.5, EARTH_COLOR, "Earth"),
        ];
        let n_bars = 1 + usize::from(has_earth);
        for (body, (x_off, colour, name)) in bars.into_iter().enumerate().take(n_bars) {
            chart
                .draw_series(months.iter().enumerate().map(|(i, s)| {
                    let x0 = i as f64 + x_off;
                    let pct = [s.sun_pct, s.earth_pct][body];
                    Rectangle::new([(x0, 0.0), (x0 + width, pct)], colour.filled())
                }))
                .map_err(plot_err(WHAT))?
                .label(name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 15, y + 5)], colour.filled())
                });
        }
        draw_legend(&mut chart, 14, SeriesLabelPosition::UpperRight, WHAT)?;
        let dark_max = months
            .iter()
            .map(|s| s.longest_dark_h)
            .fold(0.0_f64, f64::max)
            .max(1.0)
            * 1.1;
        let mut chart = ChartBuilder::on(&bottom)
            .margin(12)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..m, 0.0..dark_max)
            .map_err(plot_err(WHAT))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(0)
            .y_labels(0)
            .x_desc("month (UTC)")
            .y_desc("longest darkness (h)")
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(plot_err(WHAT))?;
        let (values, decimals) = nice_ticks(0.0, dark_max / 1.1, 5);
        let dark_ticks: Vec<(f64, String)> = values
            .into_iter()
            .map(|v| (v, format!("{v:.decimals$}")))
            .collect();
        draw_ticks(&bottom, &chart, &month_ticks, &dark_ticks).map_err(plot_err(WHAT))?;
        chart
            .draw_series(months.iter().enumerate().map(|(i, s)| {
                Rectangle::new(
                    [(i as f64 + 0.08, 0.0), (i as f64 + 0.92, s.longest_dark_h)],
                    RGBColor(60, 60, 60).filled(),
                )
            }))
            .map_err(plot_err(WHAT))?;
        Ok(())
    })
}

/// Writes the fraction plot (`render_fraction_plot_png`) to `path` atomically.
pub fn write_fraction_plot(
    path: &Path,
    title: &str,
    series: &FractionSeries<'_>,
    size_px: (u32, u32),
) -> Result<(), IllumError> {
    let png = render_fraction_plot_png(title, series, size_px)?;
    crate::output::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// Sky tracks of the Sun and the Earth over a period, as (azimuth, elevation) pairs in degrees.
#[derive(Debug, Clone, Copy, Default)]
pub struct SkyTracks<'a> {
    /// The Sun's centre, (az_deg, el_deg) per sample.
    pub sun_az_el_deg: &'a [(f64, f64)],
    /// The Earth's centre, (az_deg, el_deg) per sample.
    pub earth_az_el_deg: &'a [(f64, f64)],
}

/// Every `stride`-th point so that at most [`MAX_TRACK_POINTS`] remain.
fn thinned(track: &[(f64, f64)]) -> impl Iterator<Item = (f64, f64)> + '_ {
    let stride = track.len().div_ceil(MAX_TRACK_POINTS).max(1);
    track
        .iter()
        .step_by(stride)
        .map(|&(az, el)| (az.rem_euclid(360.0), el))
}

/// Elevation range (deg) covering the horizon and both tracks, padded.
fn el_range_deg(horizon: &HorizonProfile<'_>, tracks: &SkyTracks<'_>) -> (f64, f64) {
    let all = horizon.el_deg().iter().copied().chain(
        tracks
            .sun_az_el_deg
            .iter()
            .chain(tracks.earth_az_el_deg)
            .map(|p| p.1)
            .filter(|e| e.is_finite()),
    );
    let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), e| {
        (lo.min(e), hi.max(e))
    });
    let pad = (0.05 * (hi - lo)).max(0.2);
    (lo - pad, hi + pad)
}

/// Horizon samples as (az, el) points closing the circle at 360°.
fn horizon_points(horizon: &HorizonProfile<'_>) -> Vec<(f64, f64)> {
    let step = horizon.az_step_deg();
    let el = horizon.el_deg();
    let mut pts: Vec<(f64, f64)> = el
        .iter()
        .enumerate()
        .map(|(i, &e)| (i as f64 * step, e))
        .collect();
    pts.push((360.0, el[0]));
    pts
}

/// The legend box of a chart (white, framed) at `position`.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    font_px: u32,
    position: SeriesLabelPosition,
    what: &'static str,
) -> Result<(), IllumError> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", font_px))
        .position(position)
        .draw()
        .map_err(plot_err(what))
}

/// Draws the non-empty Sun and Earth tracks as dots with their legend entries; `to_point` maps
/// a (thinned) (az, el) sample to the chart's coordinates, or drops it (`None`).
fn draw_tracks<'a, DB: DrawingBackend + 'a, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'a, DB, CT>,
    tracks: &SkyTracks<'_>,
    to_point: impl Fn((f64, f64)) -> Option<(f64, f64)>,
    what: &'static str,
) -> Result<(), IllumError> {
    for (track, color, label) in [
        (tracks.sun_az_el_deg, SUN_COLOR, "Sun centre track"),
        (tracks.earth_az_el_deg, EARTH_COLOR, "Earth centre track"),
    ] {
        if track.is_empty() {
            continue;
        }
        chart
            .draw_series(
                thinned(track)
                    .filter_map(&to_point)
                    .map(|p| Circle::new(p, 1, color.filled())),
            )
            .map_err(plot_err(what))?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
    }
    Ok(())
}

/// Renders the horizon profile (terrain filled) with the Sun's and the Earth's tracks on a
/// rectangular azimuth (0–360°) × elevation plot, as PNG bytes.
fn render_horizon_plot_png(
    title: &str,
    horizon: &HorizonProfile<'_>,
    tracks: &SkyTracks<'_>,
    size_px: (u32, u32),
) -> Result<Vec<u8>, IllumError> {
    const WHAT: &str = "horizon plot";
    let (el_lo, el_hi) = el_range_deg(horizon, tracks);
    render_png(WHAT, size_px, |root| {
        let mut chart = rect_chart(root, title, 0.0..360.0, el_lo..el_hi, (WHAT, 60))?;
        chart
            .configure_mesh()
            .x_desc("azimuth (deg, clockwise from north)")
            .y_desc("elevation (deg)")
            .x_labels(13)
            .x_label_formatter(&|az| format!("{az:.0}"))
            .light_line_style(BLACK.mix(0.04))
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .draw()
            .map_err(plot_err(WHAT))?;
        // Tracks first: the terrain covers them where they pass below it, and the horizon line
        // stays on top.
        draw_tracks(&mut chart, tracks, Some, WHAT)?;
        let pts = horizon_points(horizon);
        chart
            .draw_series(AreaSeries::new(
                pts.iter().copied(),
                el_lo,
                TERRAIN_COLOR.mix(0.75),
            ))
            .map_err(plot_err(WHAT))?;
        chart
            .draw_series(LineSeries::new(pts, BLACK.stroke_width(2)))
            .map_err(plot_err(WHAT))?
            .label("horizon (terrain below)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
        draw_legend(&mut chart, 15, SeriesLabelPosition::UpperRight, WHAT)?;
        Ok(())
    })
}

/// Renders the polar variant: azimuth clockwise from north (up), the radius linear in elevation
/// with the highest elevation of the plot at the centre and the lowest on the rim (so a horizon a
/// few degrees high stays readable, unlike a zenith-centred plot), as PNG bytes.
fn render_horizon_polar_png(
    title: &str,
    horizon: &HorizonProfile<'_>,
    tracks: &SkyTracks<'_>,
    size_px: u32,
) -> Result<Vec<u8>, IllumError> {
    const WHAT: &str = "polar horizon plot";
    let (el_lo, el_hi) = el_range_deg(horizon, tracks);
    let to_xy = |az_deg: f64, el_deg: f64| {
        let rho = ((el_hi - el_deg) / (el_hi - el_lo)).clamp(0.0, 1.0);
        let az = az_deg.to_radians();
        (rho * az.sin(), rho * az.cos())
    };
    render_png(WHAT, (size_px, size_px), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 22))
            .margin(20)
            .build_cartesian_2d(-1.2..1.2, -1.2..1.2)
            .map_err(plot_err(WHAT))?;
        // Tracks first: the terrain ring covers them where they pass below the horizon, and
        // the horizon line is drawn last, on top.
        draw_tracks(
            &mut chart,
            tracks,
            |(az, el)| (el >= el_lo).then(|| to_xy(az, el)),
            WHAT,
        )?;
        // Terrain: the ring between the horizon curve and the rim, closed through a seam at 0°.
        let mut ring: Vec<(f64, f64)> = horizon_points(horizon)
            .into_iter()
            .map(|(az, el)| to_xy(az, el))
            .collect();
        ring.extend((0..=360).rev().map(|a| to_xy(f64::from(a), el_lo)));
        chart
            .draw_series(std::iter::once(Polygon::new(ring, TERRAIN_COLOR.mix(0.75))))
            .map_err(plot_err(WHAT))?;
        // Elevation rings with labels, and azimuth spokes every 30°.
        let (ticks, decimals) = nice_ticks(el_lo, el_hi, 8);
        for &el in &ticks {
            let circle: Vec<(f64, f64)> = (0..=360).map(|a| to_xy(f64::from(a), el)).collect();
            chart
                .draw_series(std::iter::once(PathElement::new(circle, BLACK.mix(0.3))))
                .map_err(plot_err(WHAT))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("{el:.decimals$}°"),
                    to_xy(45.0, el),
                    ("sans-serif", 13).into_font().color(&BLACK),
                )))
                .map_err(plot_err(WHAT))?;
        }
        for a in (0..360).step_by(30) {
            let az = f64::from(a);
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![to_xy(az, el_hi), to_xy(az, el_lo)],
                    BLACK.mix(0.3),
                )))
                .map_err(plot_err(WHAT))?;
            let label = match a {
                0 => "N".to_string(),
                90 => "E".to_string(),
                180 => "S".to_string(),
                270 => "W".to_string(),
                _ => format!("{a}°"),
            };
            let (x, y) = to_xy(az, el_lo);
            chart
                .draw_series(std::iter::once(Text::new(
                    label,
                    (1.08 * x - 0.04, 1.08 * y + 0.03),
                    ("sans-serif", 15).into_font().color(&BLACK),
                )))
                .map_err(plot_err(WHAT))?;
        }
        let horizon_xy: Vec<(f64, f64)> = horizon_points(horizon)
            .into_iter()
            .map(|(az, el)| to_xy(az, el))
            .collect();
        chart
            .draw_series(std::iter::once(PathElement::new(
                horizon_xy,
                BLACK.stroke_width(2),
            )))
            .map_err(plot_err(WHAT))?
            .label("horizon (terrain outside)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
        draw_legend(&mut chart, 14, SeriesLabelPosition::UpperLeft, WHAT)?;
        root.draw(&Text::new(
            format!("radius: elevation, {el_hi:.1}° at centre to {el_lo:.1}° at rim"),
            (10, i32::try_from(size_px).unwrap_or(i32::MAX) - 22),
            ("sans-serif", 14).into_font().color(&BLACK),
        ))
        .map_err(plot_err(WHAT))?;
        Ok(())
    })
}

/// About `count` round tick values (1, 2 or 5 × 10^k steps) inside `[lo, hi]`, and the number
/// of decimals that prints them exactly.
fn nice_ticks(lo: f64, hi: f64, count: usize) -> (Vec<f64>, usize) {
    let raw = (hi - lo) / count.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let mut ticks = Vec::new();
    let mut i = (lo / step).ceil();
    while i * step <= hi {
        ticks.push(i * step + 0.0); // + 0.0 turns -0.0 into 0.0
        i += 1.0;
    }
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    (ticks, decimals)
}

/// Writes the rectangular horizon plot (`render_horizon_plot_png`) to `path` atomically.
pub fn write_horizon_plot(
    path: &Path,
    title: &str,
    horizon: &HorizonProfile<'_>,
    tracks: &SkyTracks<'_>,
    size_px: (u32, u32),
) -> Result<(), IllumError> {
    let png = render_horizon_plot_png(title, horizon, tracks, size_px)?;
    crate::output::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// Writes the polar horizon plot (`render_horizon_polar_png`) to `path` atomically.
pub fn write_horizon_polar_plot(
    path: &Path,
    title: &str,
    horizon: &HorizonProfile<'_>,
    tracks: &SkyTracks<'_>,
    size_px: u32,
) -> Result<(), IllumError> {
    let png = render_horizon_polar_png(title, horizon, tracks, size_px)?;
    crate::output::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// How a map preview colours its values.
#[derive(Debug, Clone)]
pub enum MapLegend {
    /// A continuous value from `min` to `max` (viridis colour bar) labelled with `unit`.
    Continuous {
        /// Value at the bottom of the colour bar.
        min: f64,
        /// Value at the top of the colour bar.
        max: f64,
        /// Label of the colour bar, with its unit.
        unit: String,
    },
    /// Categories: (value, colour, label).
    Categories(Vec<(f32, RGBColor, String)>),
}

/// The viridis colour map (5 stops, linear in between), `t` in 0..=1.
fn viridis(t: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = x - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |p: f64, q: f64| (p + (q - p) * f).round().clamp(0.0, 255.0) as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Where a raster lies on the Moon: its grid and map projection (for the graticule, the scale
/// bar and the north arrow of [`write_map_preview`]).
#[derive(Debug, Clone)]
pub struct MapPlace {
    /// The raster's grid.
    pub grid: crate::terrain::GridGeometry,
    /// Its projection.
    pub projection: crate::terrain::Projection,
    /// Sites to mark on it: name, latitude and east longitude, degrees.
    pub marks: Vec<(String, f64, f64)>,
}

/// The graticule, scale bar and north arrow of a map preview, in preview pixels.
struct Overlay {
    /// Per preview pixel (row-major, `w × h`): on a parallel or a meridian.
    line: Vec<bool>,
    /// Labels: text and preview pixel (x, y) where it goes.
    labels: Vec<(String, i32, i32)>,
    /// Sites inside the preview: name and preview pixel (x, y).
    marks: Vec<(String, i32, i32)>,
    /// Degrees between parallels and between meridians.
    steps_deg: (f64, f64),
    /// Scale bar: length in preview pixels and its label.
    scale_bar: (f64, String),
    /// True north at the preview's centre: unit vector in preview pixels (x right, y down), or
    /// `None` at the pole itself.
    north: Option<(f64, f64)>,
}

/// Smallest step of `steps` that cuts `span` into at most `max_lines` pieces.
fn grid_step(span: f64, steps: &[f64], max_lines: f64) -> f64 {
    steps
        .iter()
        .copied()
        .find(|s| span / s <= max_lines)
        .unwrap_or(steps[steps.len() - 1])
}

/// Great-circle distance between two points of the 1737.4 km sphere, metres.
fn sphere_distance_m(a: (f64, f64), b: (f64, f64)) -> f64 {
    let (la, lo_a) = (a.0.to_radians(), a.1.to_radians());
    let (lb, lo_b) = (b.0.to_radians(), b.1.to_radians());
    let h =
        ((lb - la) / 2.0).sin().powi(2) + la.cos() * lb.cos() * ((lo_b - lo_a) / 2.0).sin().powi(2);
    2.0 * crate::MOON_RADIUS_M * h.sqrt().min(1.0).asin()
}

impl Overlay {
    /// The overlay of a `w × h` preview of `place`, one preview pixel = `scale` raster cells.
    fn new(place: &MapPlace, w: usize, h: usize, scale: f64) -> Overlay {
        let g = &place.grid;
        // Preview pixel corner (i, j) (i along x, j along y) -> raster fractional (row, col) of
        // the cell-centre convention.
        let lat_lon = |i: f64, j: f64| {
            let (x, y) = g.xy_from_row_col(j * scale - 0.5, i * scale - 0.5);
            place.projection.lat_lon_from_xy(x, y)
        };
        // Lat/lon at the centres of the preview pixels, plus one extra column and row.
        let (wc, hc) = (w + 1, h + 1);
        let mut ll = Vec::with_capacity(wc * hc);
        for j in 0..hc {
            for i in 0..wc {
                ll.push(lat_lon(i as f64 + 0.5, j as f64 + 0.5));
            }
        }
        let (mut lat_min, mut lat_max) = (f64::INFINITY, f64::NEG_INFINITY);
        for &(lat, _) in &ll {
            lat_min = lat_min.min(lat);
            lat_max = lat_max.max(lat);
        }
        // The pole in preview pixels (where the projection has it).
        let pole_lat = if lat_max + lat_min < 0.0 { -90.0 } else { 90.0 };
        let (px_pole, py_pole) = {
            let (x, y) = place.projection.xy_from_lat_lon(pole_lat, 0.0);
            let (row, col) = g.row_col_from_xy(x, y);
            ((col + 0.5) / scale, (row + 0.5) / scale)
        };
        let pole_inside =
            px_pole >= 0.0 && py_pole >= 0.0 && px_pole <= w as f64 && py_pole <= h as f64;
        let lat_step = grid_step(
            lat_max - lat_min,
            &[
                0.01, 0.02, 0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 15.0, 30.0,
            ],
            5.0,
        );
        let lon_step = if pole_inside {
            30.0
        } else {
            // Longitude span through the unwrapped differences to the centre pixel.
            let lon_c = ll[(hc / 2) * wc + wc / 2].1;
            let (mut lo, mut hi) = (0.0_f64, 0.0_f64);
            for &(_, lon) in &ll {
                let d = (lon - lon_c + 540.0).rem_euclid(360.0) - 180.0;
                lo = lo.min(d);
                hi = hi.max(d);
            }
            grid_step(
                hi - lo,
                &[
                    0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 15.0, 30.0, 45.0, 90.0,
                ],
                6.0,
            )
        };
        let lat_bin = |lat: f64| (lat / lat_step).floor() as i64;
        let lon_bin = |lon: f64| (lon / lon_step).floor() as i64;
        let mut line = vec![false; w * h];
        // Where each line is labelled: parallels at their rightmost pixel, meridians at their
        // pixel farthest from the pole.
        let mut lat_at: std::collections::BTreeMap<i64, (i32, i32)> = Default::default();
        let mut lon_at: std::collections::BTreeMap<i64, (i32, i32, f64)> = Default::default();
        // Meridians crowd at the pole: none drawn within this many pixels of it.
        let pole_clear = 0.06 * w.min(h) as f64;
        for j in 0..h {
            for i in 0..w {
                let here = ll[j * wc + i];
                let (right, below) = (ll[j * wc + i + 1], ll[(j + 1) * wc + i]);
                let b = lat_bin(here.0);
                for n in [right, below] {
                    let bn = lat_bin(n.0);
                    if bn != b {
                        line[j * w + i] = true;
                        let key = b.max(bn);
                        let e = lat_at.entry(key).or_insert((i as i32, j as i32));
                        if i as i32 > e.0 {
                            *e = (i as i32, j as i32);
                        }
                    }
                }
                let far = (i as f64 + 0.5 - px_pole).hypot(j as f64 + 0.5 - py_pole);
                if far < pole_clear {
                    continue;
                }
                let b = lon_bin(here.1);
                for n in [right, below] {
                    let bn = lon_bin(n.1);
                    // Neighbours across the ±180° seam differ by one turn, not one line.
                    let turn = (360.0 / lon_step).round() as i64;
                    let d = (bn - b).rem_euclid(turn);
                    if d != 0 {
                        line[j * w + i] = true;
                        let key = if d == 1 { bn } else { b }.rem_euclid(turn);
                        let e = lon_at.entry(key).or_insert((i as i32, j as i32, far));
                        if far > e.2 {
                            *e = (i as i32, j as i32, far);
                        }
                    }
                }
            }
        }
        let decimals = |step: f64| {
            if step >= 1.0 {
                0
            } else if step >= 0.1 {
                1
            } else {
                2
            }
        };
        let mut labels = Vec::new();
        for (k, (i, j)) in lat_at {
            let v = k as f64 * lat_step;
            labels.push((format!("{v:.*}°", decimals(lat_step)), i - 46, j - 14));
        }
        for (k, (i, j, _)) in lon_at {
            let mut v = k as f64 * lon_step;
            if v > 180.0 {
                v -= 360.0;
            }
            let text = if v == 0.0 || v == 180.0 {
                format!("{:.*}°", decimals(lon_step), v.abs())
            } else if v < 0.0 {
                format!("{:.*}°W", decimals(lon_step), -v)
            } else {
                format!("{:.*}°E", decimals(lon_step), v)
            };
            labels.push((text, i + 3, j + 2));
        }
        // Scale at the preview's centre: the sphere distance of one preview pixel along x.
        let (ci, cj) = (w as f64 / 2.0, h as f64 / 2.0);
        let m_per_px = sphere_distance_m(lat_lon(ci - 0.5, cj), lat_lon(ci + 0.5, cj));
        let target_m = m_per_px * w as f64 / 5.0;
        let magnitude = 10f64.powf(target_m.log10().floor());
        let bar_m = [1.0, 2.0, 5.0]
            .iter()
            .map(|f| f * magnitude)
            .rfind(|v| *v <= target_m)
            .unwrap_or(magnitude);
        let bar_label = if bar_m >= 1000.0 {
            format!("{} km", bar_m / 1000.0)
        } else {
            format!("{bar_m} m")
        };
        // True north at the centre: towards increasing latitude.
        let (lat_c, lon_c) = lat_lon(ci, cj);
        let north = if lat_c.abs() > 89.999 {
            None
        } else {
            let (x0, y0) = place.projection.xy_from_lat_lon(lat_c, lon_c);
            let (x1, y1) = place.projection.xy_from_lat_lon(lat_c + 0.001, lon_c);
            let (dx, dy) = ((x1 - x0) / g.px_x_m, -(y1 - y0) / g.px_y_m);
            let n = dx.hypot(dy);
            Some((dx / n, dy / n))
        };
        let marks = place
            .marks
            .iter()
            .filter_map(|(name, lat, lon)| {
                let (x, y) = place.projection.xy_from_lat_lon(*lat, *lon);
                let (row, col) = g.row_col_from_xy(x, y);
                let (i, j) = ((col + 0.5) / scale, (row + 0.5) / scale);
                (i >= 0.0 && j >= 0.0 && i < w as f64 && j < h as f64)
                    .then(|| (name.clone(), i as i32, j as i32))
            })
            .collect();
        Overlay {
            line,
            labels,
            marks,
            steps_deg: (lat_step, lon_step),
            scale_bar: (bar_m / m_per_px, bar_label),
            north,
        }
    }
}

/// Renders a raster (row-major, `NaN` = nodata, drawn grey) as a PNG preview with a title and a
/// colour bar or a legend. Large rasters are subsampled to at most 800 px on a side. With `place`,
/// a graticule (parallels and meridians, labelled), a scale bar (true at the centre) and the true
/// north at the centre are drawn; without it, rows are drawn top to bottom and nothing is said of
/// north.
fn render_map_png(
    title: &str,
    values: &[f32],
    rows: usize,
    cols: usize,
    legend: &MapLegend,
    place: Option<&MapPlace>,
) -> Result<Vec<u8>, IllumError> {
    const WHAT: &str = "map preview";
    if rows == 0 || cols == 0 || values.len() != rows * cols {
        return Err(IllumError::Plot {
            what: WHAT,
            message: format!("{} values for a {rows} x {cols} raster", values.len()),
        });
    }
    // Grid cells per drawn pixel: large grids are thinned to at most 800 px a side, small ones
    // drawn with several pixels per cell, about 640 px a side.
    let n = rows.max(cols) as f64;
    let scale = if n < 640.0 {
        n / 640.0
    } else {
        (n / 800.0).max(1.0)
    };
    let (w_map, h_map) = (
        ((cols as f64 / scale).round() as u32).max(1),
        ((rows as f64 / scale).round() as u32).max(1),
    );
    let title_lines = title.splitn(4, " — ").count() as i32;
    let (left, top) = (20_i32, 50_i32 + 17 * (title_lines - 2).max(0));
    // Wide enough for the title's lines (≈ 0.5 em per character) and the colour bar's labels.
    let title_w = title
        .splitn(4, " — ")
        .zip([16.0, 13.0, 12.0, 12.0])
        .map(|(l, size)| (l.chars().count() as f64 * 0.5 * size) as u32)
        .max()
        .unwrap_or(0)
        + 2 * left as u32;
    let size_px = (
        (w_map + 300).max(500).max(title_w),
        (h_map + top as u32 + 84).max(330),
    );
    let overlay = place.map(|p| Overlay::new(p, w_map as usize, h_map as usize, scale));
    let colour_of = |v: f32| -> RGBColor {
        if v.is_nan() {
            return RGBColor(200, 200, 200);
        }
        match legend {
            MapLegend::Continuous { min, max, .. } => {
                viridis((f64::from(v) - min) / (max - min).max(f64::MIN_POSITIVE))
            }
            MapLegend::Categories(cats) => cats
                .iter()
                .find(|(c, _, _)| *c == v)
                .map(|(_, col, _)| *col)
                .unwrap_or(RGBColor(255, 0, 255)),
        }
    };
    render_png(WHAT, size_px, |root| {
        // The title may carry up to three more lines, each after " — ".
        let mut lines = title.splitn(4, " — ");
        for (size, y) in [(16, 6), (13, 27), (12, 45), (12, 61)] {
            let Some(line) = lines.next() else { break };
            root.draw(&Text::new(
                line.to_string(),
                (left, y),
                ("sans-serif", size).into_font(),
            ))
            .map_err(plot_err(WHAT))?;
        }
        for py in 0..h_map {
            let row = ((f64::from(py) + 0.5) * scale) as usize;
            for px in 0..w_map {
                let col = ((f64::from(px) + 0.5) * scale) as usize;
                let v = values[row.min(rows - 1) * cols + col.min(cols - 1)];
                let mut c = colour_of(v);
                if let Some(o) = &overlay
                    && o.line[py as usize * w_map as usize + px as usize]
                {
                    // Graticule: half-way to white.
                    let mix = |a: u8| ((u16::from(a) + 255) / 2) as u8;
                    c = RGBColor(mix(c.0), mix(c.1), mix(c.2));
                }
                root.draw_pixel((left + px as i32, top + py as i32), &c)
                    .map_err(plot_err(WHAT))?;
            }
        }
        if let Some(o) = &overlay {
            // Labels that would overlap one already drawn are left out (corners crowd).
            let mut drawn: Vec<(i32, i32, i32, i32)> = Vec::new();
            for (text, i, j) in &o.labels {
                let width = 7 * text.chars().count() as i32;
                let (x, y) = (
                    (left + i).clamp(left, left + w_map as i32 - width),
                    (top + j).clamp(top, top + h_map as i32 - 14),
                );
                let bx = (x - 2, y - 1, x + width, y + 13);
                if drawn
                    .iter()
                    .any(|d| bx.0 < d.2 && d.0 < bx.2 && bx.1 < d.3 && d.1 < bx.3)
                {
                    continue;
                }
                drawn.push(bx);
                // A dark box behind the label, so that it reads on bright data.
                root.draw(&Rectangle::new(
                    [(x - 2, y - 1), (x + width, y + 13)],
                    RGBAColor(0, 0, 0, 0.45).filled(),
                ))
                .map_err(plot_err(WHAT))?;
                root.draw(&Text::new(
                    text.clone(),
                    (x, y),
                    ("sans-serif", 12).into_font().color(&WHITE),
                ))
                .map_err(plot_err(WHAT))?;
            }
            // Sites: a ring and the name, where the map holds them.
            for (name, i, j) in &o.marks {
                let (x, y) = (left + i, top + j);
                root.draw(&Circle::new((x, y), 5, WHITE.stroke_width(3)))
                    .map_err(plot_err(WHAT))?;
                root.draw(&Circle::new((x, y), 5, RGBColor(200, 0, 0).stroke_width(2)))
                    .map_err(plot_err(WHAT))?;
                let width = 7 * name.chars().count() as i32;
                let tx = (x + 8).min(left + w_map as i32 - width).max(left);
                let ty = (y - 7).clamp(top, top + h_map as i32 - 14);
                root.draw(&Rectangle::new(
                    [(tx - 2, ty - 1), (tx + width, ty + 13)],
                    RGBAColor(255, 255, 255, 0.7).filled(),
                ))
                .map_err(plot_err(WHAT))?;
                root.draw(&Text::new(
                    name.clone(),
                    (tx, ty),
                    ("sans-serif", 12).into_font(),
                ))
                .map_err(plot_err(WHAT))?;
            }
            // Scale bar under the map, left.
            let y = top + h_map as i32 + 36;
            let len = o.scale_bar.0.round() as i32;
            root.draw(&Rectangle::new(
                [(left, y), (left + len, y + 5)],
                BLACK.filled(),
            ))
            .map_err(plot_err(WHAT))?;
            root.draw(&Text::new(
                format!("{} (at the centre)", o.scale_bar.1),
                (left + len + 8, y - 4),
                ("sans-serif", 13).into_font(),
            ))
            .map_err(plot_err(WHAT))?;
            // True north at the centre, right of the scale bar's label.
            let (ax, ay) = (left + len + 200, y + 2);
            match o.north {
                Some((dx, dy)) => {
                    let tip = (ax + (dx * 22.0) as i32, ay + (dy * 22.0) as i32);
                    let tail = (ax - (dx * 8.0) as i32, ay - (dy * 8.0) as i32);
                    root.draw(&PathElement::new(vec![tail, tip], BLACK.stroke_width(2)))
                        .map_err(plot_err(WHAT))?;
                    root.draw(&Circle::new(tip, 3, BLACK.filled()))
                        .map_err(plot_err(WHAT))?;
                    root.draw(&Text::new(
                        "N (true north at the centre)",
                        (ax + 28, y - 4),
                        ("sans-serif", 13).into_font(),
                    ))
                    .map_err(plot_err(WHAT))?;
                }
                None => {
                    root.draw(&Text::new(
                        "pole at the centre: north points away from it",
                        (ax, y - 4),
                        ("sans-serif", 13).into_font(),
                    ))
                    .map_err(plot_err(WHAT))?;
                }
            }
        }
        let x0 = left + w_map as i32 + 30;
        match legend {
            MapLegend::Continuous { min, max, unit } => {
                let bar_h = (h_map as i32).min(400);
                for k in 0..bar_h {
                    let t = 1.0 - f64::from(k) / f64::from(bar_h - 1).max(1.0);
                    root.draw(&Rectangle::new(
                        [(x0, top + k), (x0 + 24, top + k + 1)],
                        viridis(t).filled(),
                    ))
                    .map_err(plot_err(WHAT))?;
                }
                // Round ticks: 1, 2, 2.5 or 5 times a power of ten, about five of them.
                let span = (max - min).max(f64::MIN_POSITIVE);
                let raw = span / 5.0;
                let mag = 10f64.powf(raw.log10().floor());
                let step = [1.0, 2.0, 2.5, 5.0, 10.0]
                    .iter()
                    .map(|f| f * mag)
                    .find(|s| span / s <= 6.0)
                    .unwrap_or(10.0 * mag);
                // 2.5 × 10^k needs one decimal more than 10^k (0.25, 2.5; not 25 or 250).
                let quarter = f64::from(u8::from((step / mag - 2.5).abs() < 1e-9));
                let decimals = (-step.log10().floor() + quarter).max(0.0) as usize;
                let mut v = (min / step).ceil() * step;
                while v <= max + 1e-9 * span {
                    let t = (v - min) / span;
                    let y = top + ((1.0 - t) * f64::from(bar_h - 1)) as i32;
                    root.draw(&Rectangle::new(
                        [(x0 + 24, y), (x0 + 28, y + 1)],
                        BLACK.filled(),
                    ))
                    .map_err(plot_err(WHAT))?;
                    root.draw(&Text::new(
                        format!("{v:.decimals$}"),
                        (x0 + 30, y - 7),
                        ("sans-serif", 14).into_font(),
                    ))
                    .map_err(plot_err(WHAT))?;
                    v += step;
                }
                root.draw(&Text::new(
                    unit.clone(),
                    (x0, top + bar_h + 10),
                    ("sans-serif", 14).into_font(),
                ))
                .map_err(plot_err(WHAT))?;
            }
            MapLegend::Categories(cats) => {
                for (k, (_, colour, label)) in cats.iter().enumerate() {
                    let y = top + 26 * k as i32;
                    root.draw(&Rectangle::new(
                        [(x0, y), (x0 + 18, y + 18)],
                        colour.filled(),
                    ))
                    .map_err(plot_err(WHAT))?;
                    root.draw(&Text::new(
                        label.clone(),
                        (x0 + 26, y + 2),
                        ("sans-serif", 14).into_font(),
                    ))
                    .map_err(plot_err(WHAT))?;
                }
            }
        }
        let note = match &overlay {
            Some(o) => format!(
                "grey = no data; parallels every {}°, meridians every {}°",
                o.steps_deg.0, o.steps_deg.1
            ),
            None => "grid rows top to bottom (no georeferencing); grey = no data".to_string(),
        };
        root.draw(&Text::new(
            note,
            (left, top + h_map as i32 + 58),
            ("sans-serif", 13).into_font(),
        ))
        .map_err(plot_err(WHAT))?;
        Ok(())
    })
}

/// Writes the raster preview (`render_map_png`) to `path` atomically.
pub fn write_map_preview(
    path: &Path,
    title: &str,
    values: &[f32],
    rows: usize,
    cols: usize,
    legend: &MapLegend,
    place: Option<&MapPlace>,
) -> Result<(), IllumError> {
    let png = render_map_png(title, values, rows, cols, legend, place)?;
    crate::output::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// One panel of a [`write_height_plot`]: its y-axis label and one line per site, `(site,
/// [(height_m, value)])` (NaN values are left out).
pub type HeightPanel<'a> = (&'a str, Vec<(&'a str, Vec<(f64, f64)>)>);

/// Figures against the mast height, one panel per figure stacked top to bottom, one line (with
/// markers) per site: `mast.png`.
pub fn write_height_plot(
    path: &Path,
    title: &str,
    panels: &[HeightPanel<'_>],
    size_px: (u32, u32),
) -> Result<(), IllumError> {
    const WHAT: &str = "mast height plot";
    const COLOURS: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(23, 190, 207),
    ];
    let finite = |v: &[(f64, f64)]| {
        v.iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect::<Vec<_>>()
    };
    let all: Vec<(f64, f64)> = panels
        .iter()
        .flat_map(|p| p.1.iter().flat_map(|l| finite(&l.1)))
        .collect();
    if panels.is_empty() || all.is_empty() {
        return Err(IllumError::EmptySeries {
            site: title.to_string(),
        });
    }
    let h_max = all.iter().map(|p| p.0).fold(0.0_f64, f64::max) * 1.05;
    let png = render_png(WHAT, size_px, |root| {
        let root = root
            .titled(title, ("sans-serif", 22))
            .map_err(plot_err(WHAT))?;
        let areas = root.split_evenly((panels.len(), 1));
        for (area, (label, lines)) in areas.iter().zip(panels) {
            let pts: Vec<(f64, f64)> = lines.iter().flat_map(|l| finite(&l.1)).collect();
            let (lo, hi) = pts
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                    (a.min(p.1), b.max(p.1))
                });
            let pad = ((hi - lo) * 0.08).max(1e-3 * hi.abs().max(1.0));
            // The legend where the lines are not: low on the right when they end high.
            let ends: Vec<f64> = lines
                .iter()
                .filter_map(|l| finite(&l.1).last().map(|p| p.1))
                .collect();
            let end_mean = ends.iter().sum::<f64>() / ends.len().max(1) as f64;
            let legend_at = if end_mean > 0.5 * (lo + hi) {
                SeriesLabelPosition::LowerRight
            } else {
                SeriesLabelPosition::UpperRight
            };
            let y = if lo.is_finite() {
                (lo - pad)..(hi + pad)
            } else {
                0.0..1.0
            };
            let mut chart = ChartBuilder::on(area)
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(80)
                .build_cartesian_2d(0.0..h_max.max(1.0), y)
                .map_err(plot_err(WHAT))?;
            chart
                .configure_mesh()
                .x_desc("mast height above ground, m")
                .y_desc(*label)
                .light_line_style(BLACK.mix(0.05))
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 15))
                .draw()
                .map_err(plot_err(WHAT))?;
            for (i, (site, values)) in lines.iter().enumerate() {
                let c = COLOURS[i % COLOURS.len()];
                let v = finite(values);
                chart
                    .draw_series(LineSeries::new(v.iter().copied(), c.stroke_width(2)))
                    .map_err(plot_err(WHAT))?
                    .label(*site)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
                chart
                    .draw_series(v.iter().map(|&p| Circle::new(p, 3, c.filled())))
                    .map_err(plot_err(WHAT))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 13))
                .position(legend_at)
                .draw()
                .map_err(plot_err(WHAT))?;
        }
        Ok(())
    })?;
    crate::output::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// Smallest frame that gets burnt-in annotations, pixels (a smaller one keeps its picture whole).
pub const ANNOTATE_MIN_PX: (u32, u32) = (240, 120);

/// Burns the annotations of a rendered frame into its RGB8 pixels (`width` x `height`): `lines`
/// in white on a half-transparent black box in the bottom-left corner, and `az_ticks` (column,
/// label) as tick marks with labels along the top edge. Frames smaller than
/// [`ANNOTATE_MIN_PX`] are left as they are. Returns the box (x0, y0, x1, y1) drawn, if any.
pub fn annotate_frame(
    rgb: &mut [u8],
    (width, height): (u32, u32),
    lines: &[String],
    az_ticks: &[(u32, String)],
) -> Result<Option<(u32, u32, u32, u32)>, IllumError> {
    const WHAT: &str = "frame annotation";
    if width < ANNOTATE_MIN_PX.0 || height < ANNOTATE_MIN_PX.1 {
        return Ok(None);
    }
    ensure_font()?;
    let size = (height / 36).clamp(11, 22);
    let pad = size / 2;
    let root = BitMapBackend::with_buffer(rgb, (width, height)).into_drawing_area();
    let style = TextStyle::from(("sans-serif", size).into_font()).color(&WHITE);
    let width_of = |t: &str| root.estimate_text_size(t, &style).map_or(0, |(w, _)| w);
    // Lines wider than the frame are wrapped at spaces.
    let mut wrapped: Vec<String> = Vec::new();
    for line in lines {
        let mut current = String::new();
        for word in line.split(' ') {
            let candidate = if current.is_empty() {
                word.to_string()
            } else {
                format!("{current} {word}")
            };
            if !current.is_empty() && width_of(&candidate) + 2 * pad > width {
                wrapped.push(std::mem::replace(&mut current, word.to_string()));
            } else {
                current = candidate;
            }
        }
        wrapped.push(current);
    }
    let lines = &wrapped;
    let text_w = lines.iter().map(|l| width_of(l)).max().unwrap_or(0);
    let line_h = size + size / 4;
    let box_w = (text_w + 2 * pad).min(width);
    let box_h = (line_h * lines.len() as u32 + 2 * pad).min(height);
    let (x0, y0) = (0, height - box_h);
    root.draw(&Rectangle::new(
        [(x0 as i32, y0 as i32), (box_w as i32, height as i32)],
        BLACK.mix(0.55).filled(),
    ))
    .map_err(plot_err(WHAT))?;
    for (k, line) in lines.iter().enumerate() {
        let y = y0 + pad + line_h * k as u32;
        root.draw(&Text::new(
            line.clone(),
            (pad as i32, y as i32),
            style.clone(),
        ))
        .map_err(plot_err(WHAT))?;
    }
    let tick_h = (size * 2 / 3) as i32;
    for (col, label) in az_ticks {
        let x = *col as i32;
        root.draw(&PathElement::new(
            vec![(x, 0), (x, tick_h)],
            WHITE.stroke_width(2),
        ))
        .map_err(plot_err(WHAT))?;
        let label_style = style.pos(Pos::new(HPos::Center, VPos::Top));
        root.draw(&Text::new(label.clone(), (x, tick_h + 2), label_style))
            .map_err(plot_err(WHAT))?;
    }
    root.present().map_err(plot_err(WHAT))?;
    Ok(Some((x0, y0, box_w, height)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Days from 1970-01-01 to a civil date (H. Hinnant's algorithm, proleptic Gregorian):
    /// the calendar the ticks are checked against, independent of hifitime.
    fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
        let y = if m <= 2 { y - 1 } else { y };
        let era = y.div_euclid(400);
        let yoe = y - era * 400;
        let mp = (m + 9) % 12;
        let doy = (153 * mp + 2) / 5 + d - 1;
        let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
        era * 146_097 + doe - 719_468
    }

    #[test]
    fn calendar_ticks_fall_on_calendar_dates() {
        let day = 86_400.0;
        // 20 years from 2017-01-01 in years: every second 1 January, labelled by the year.
        let start = Epoch::from_gregorian_utc_at_midnight(2017, 1, 1);
        let year_s = 365.25 * day;
        let span = (days_from_civil(2037, 1, 1) - days_from_civil(2017, 1, 1)) as f64 * day;
        let ticks = calendar_ticks(start, span / year_s, year_s);
        let want: Vec<i64> = (2018..=2036).step_by(2).collect();
        assert_eq!(ticks.len(), want.len(), "{ticks:?}");
        for ((x, label), y) in ticks.iter().zip(&want) {
            assert_eq!(label, &y.to_string());
            let days = (days_from_civil(*y, 1, 1) - days_from_civil(2017, 1, 1)) as f64;
            assert!((x * year_s / day - days).abs() < 1e-6, "{label}: {x}");
        }
        // One year from 2027-03-10 in days: the first of every second month, from 2027-05 (the
        // 2028-03-01 tick, in the last 3 % of the axis, would have its label cut).
        let start = Epoch::from_gregorian_utc_at_midnight(2027, 3, 10);
        let ticks = calendar_ticks(start, 365.0, day);
        let labels: Vec<&str> = ticks.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(
            labels,
            ["2027-05", "2027-07", "2027-09", "2027-11", "2028-01"]
        );
        for ((x, _), (y, m)) in
            ticks
                .iter()
                .zip([(2027, 5), (2027, 7), (2027, 9), (2027, 11), (2028, 1)])
        {
            let days = (days_from_civil(y, m, 1) - days_from_civil(2027, 3, 10)) as f64;
            assert!((x - days).abs() < 1e-9);
        }
        // Two days from 06:30 in hours: every 6 h on the hour.
        let start = Epoch::from_gregorian_utc(2027, 3, 10, 6, 30, 0, 0);
        let ticks = calendar_ticks(start, 48.0, 3600.0);
        assert_eq!(ticks[0], (5.5, "03-10 12:00".to_string()));
        assert_eq!(
            ticks.len(),
            7,
            "the 8th, at 47.5 h of 48, is in the last 3 %"
        );
        assert!(
            ticks
                .windows(2)
                .all(|w| (w[1].0 - w[0].0 - 6.0).abs() < 1e-9)
        );
    }

    #[test]
    fn nice_ticks_are_round() {
        // Span 5.5 / 5 = 1.1 → step 2.
        let (t, d) = nice_ticks(-1.3, 4.2, 5);
        assert_eq!(d, 0);
        let labels: Vec<String> = t.iter().map(|v| format!("{v:.d$}")).collect();
        assert_eq!(labels, ["0", "2", "4"]);
        // Span 0.9 / 8 = 0.1125 → step 0.2, one decimal.
        let (t, d) = nice_ticks(0.05, 0.95, 8);
        let labels: Vec<String> = t.iter().map(|v| format!("{v:.d$}")).collect();
        assert_eq!(labels, ["0.2", "0.4", "0.6", "0.8"]);
    }

    /// A polar stereographic place: `n × n` cells of `px_m` centred on map point (`xc`, `yc`).
    fn polar_place(n: usize, px_m: f64, xc: f64, yc: f64) -> MapPlace {
        let half = n as f64 * px_m / 2.0;
        MapPlace {
            marks: Vec::new(),
            grid: crate::terrain::GridGeometry {
                rows: n,
                cols: n,
                x_left_m: xc - half,
                y_top_m: yc + half,
                px_x_m: px_m,
                px_y_m: px_m,
            },
            projection: crate::terrain::Projection::LOLA_SOUTH_POLAR,
        }
    }

    /// Every graticule pixel lies within one pixel of a parallel or a meridian, by an inverse
    /// polar stereographic written here (`lat = −90° + 2 atan(ρ / 2R)`, `lon = atan2(x, y)`), and
    /// every parallel crossing the map is drawn.
    #[test]
    fn graticule_lines_lie_on_parallels_and_meridians() {
        let r = crate::MOON_RADIUS_M;
        let place = polar_place(400, 100.0, 0.0, 0.0);
        let o = Overlay::new(&place, 400, 400, 1.0);
        let (lat_step, lon_step) = o.steps_deg;
        assert_eq!((lat_step, lon_step), (0.2, 30.0));
        let mut parallels = std::collections::BTreeSet::new();
        let mut n_line = 0;
        for j in 0..400 {
            for i in 0..400 {
                if !o.line[j * 400 + i] {
                    continue;
                }
                n_line += 1;
                let (x, y) = (
                    -20_000.0 + (i as f64 + 0.5) * 100.0,
                    20_000.0 - (j as f64 + 0.5) * 100.0,
                );
                let rho = x.hypot(y);
                let lat = -90.0 + 2.0 * (rho / (2.0 * r)).atan().to_degrees();
                let lon = x.atan2(y).to_degrees();
                // Metres per degree of latitude along the map (scale ≈ 1 this near the pole).
                let m_per_deg = r * std::f64::consts::PI / 180.0;
                let near_lat = (lat / lat_step).round() * lat_step;
                let d_par_px = (lat - near_lat).abs() * m_per_deg / 100.0;
                let near_lon = (lon / lon_step).round() * lon_step;
                let d_mer_px = (lon - near_lon).abs().to_radians() * rho / 100.0;
                assert!(
                    d_par_px.min(d_mer_px) <= 1.0,
                    "pixel ({i}, {j}) at {lat:.4}°, {lon:.2}° is {d_par_px:.2} px from a parallel and {d_mer_px:.2} px from a meridian"
                );
                if d_par_px <= 1.0 {
                    parallels.insert((near_lat * 10.0).round() as i64);
                }
            }
        }
        // The map reaches −90 + 2 atan(20 km √2 / 2R) ≈ −89.07°: parallels −89.2 … −89.8.
        assert_eq!(
            parallels.into_iter().collect::<Vec<_>>(),
            [-898, -896, -894, -892]
        );
        assert!(n_line > 2000, "{n_line} line pixels");
        assert!(o.north.is_none(), "the pole is at the centre");
    }

    /// Off the pole: true north points away from the pole (the map direction of the centre from
    /// the pole), and the scale bar's length in pixels times the sphere distance of one pixel
    /// (100 m over the projection's scale factor `2 / (1 + sin |lat|)`) is its label, a 1, 2 or 5
    /// that fills a tenth to a fifth of the map.
    #[test]
    fn north_arrow_and_scale_bar_are_true_at_the_centre() {
        let r = crate::MOON_RADIUS_M;
        // Centre at lat −88°, lon 45° E.
        // ρ = 2R tan(45° + lat/2) on the south polar stereographic map.
        let rho = 2.0 * r * 1.0_f64.to_radians().tan();
        let (xc, yc) = (
            rho * 45f64.to_radians().sin(),
            rho * 45f64.to_radians().cos(),
        );
        let o = Overlay::new(&polar_place(300, 100.0, xc, yc), 300, 300, 1.0);
        let (dx, dy) = o.north.expect("off the pole");
        let want = (xc / rho, -yc / rho);
        assert!(
            dx * want.0 + dy * want.1 > 0.99999,
            "({dx}, {dy}) vs {want:?}"
        );
        let k = 2.0 / (1.0 + 88f64.to_radians().sin());
        let m_per_px = 100.0 / k;
        let (bar_px, label) = &o.scale_bar;
        let bar_m = bar_px * m_per_px;
        let lead = bar_m / 10f64.powf(bar_m.log10().floor());
        assert!(
            [1.0, 2.0, 5.0].iter().any(|v| (lead - v).abs() < 1e-6),
            "{bar_m} m"
        );
        assert!(*bar_px >= 30.0 && *bar_px <= 60.0, "{bar_px} px");
        assert_eq!(*label, format!("{} km", (bar_m / 1000.0).round()));
    }

    #[test]
    fn time_units() {
        assert_eq!(time_unit(48.0 * 3600.0).1, "h");
        assert_eq!(time_unit(30.0 * 86_400.0).1, "days");
        assert_eq!(time_unit(18.6 * 365.25 * 86_400.0).1, "years");
    }
}

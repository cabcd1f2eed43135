//! Writing the statistics of an epoch range: one GeoTIFF on the DEM's grid and one PNG preview per quantity.

use std::path::Path;

use super::{MapGrid, RangeStats, RasterInfo, write_on};
use crate::illum::plot::{MapLegend, MapPlace, write_map_preview};
use crate::shadow::MASK_NODATA;
use crate::terrain::Dem;

/// One continuous output: file stem, description, values on the DEM grid, full scale, unit.
type Continuous = (&'static str, String, Vec<f32>, f64, String);

/// The description (GeoTIFF `content`) of the PSR mask.
pub const PSR_DESCRIPTION: &str =
    "permanently shadowed over the span: 1 never lit, 0 lit at least once, 255 no data";

/// The span of an epoch range as `penumbra map` records it: `first .. last, N epochs`.
pub fn span_text(epochs: &[hifitime::Epoch]) -> String {
    match (epochs.first(), epochs.last()) {
        (Some(a), Some(b)) => format!(
            "{} .. {}, {} epochs",
            crate::ephem::time::format_iso(*a),
            crate::ephem::time::format_iso(*b),
            epochs.len()
        ),
        _ => "no epochs".to_string(),
    }
}

/// The metadata items of every statistics GeoTIFF: the span ([`span_text`], or a scenario's), the
/// number of epochs and the step.
pub fn range_metadata(span: &str, s: &RangeStats) -> Vec<(String, String)> {
    vec![
        ("span_utc".to_string(), span.to_string()),
        ("epochs".to_string(), s.epochs.to_string()),
        ("step_h".to_string(), format!("{}", s.step_h)),
    ]
}

/// The GeoTIFF unit of a statistic, from its file stem's suffix (`_pct`, `_h`, `_w_m2`, `_wh`,
/// `_w`).
pub fn geotiff_unit(stem: &str) -> &'static str {
    if stem.ends_with("_pct") {
        "%"
    } else if stem.ends_with("_h") {
        "h"
    } else if stem.ends_with("_w_m2") {
        "W m-2"
    } else if stem.ends_with("_wh") {
        "W h"
    } else if stem.ends_with("_w") {
        "W"
    } else {
        ""
    }
}

/// One statistic of an epoch range as a raster on the DEM's grid.
#[derive(Debug, Clone)]
pub struct RangeRaster {
    /// File stem (`sun_illumination_pct`, …).
    pub name: &'static str,
    /// What the values are, with their unit (the GeoTIFF's `content`).
    pub description: String,
    /// Row-major values on the DEM's grid (NaN = nodata).
    pub values: Vec<f32>,
    /// Full scale of the preview's colour bar.
    pub full_scale: f64,
    /// Unit of the preview's colour bar.
    pub unit: String,
}

/// The rasters of the statistics on the grid of `dem` (statistics per model cell,
/// `!s.on_dem_grid`, are resampled through `model`) and the PSR mask (1 never lit, 0 lit at least
/// once, 255 nodata): what [`write_range`] writes, for callers that want the arrays.
pub fn range_rasters(
    dem: &Dem,
    model: Option<&MapGrid>,
    s: &RangeStats,
) -> anyhow::Result<(Vec<RangeRaster>, Vec<u8>)> {
    let model = match (s.on_dem_grid, model) {
        (true, _) => None,
        (false, Some(m)) => Some(m),
        (false, None) => anyhow::bail!("model-cell statistics need their model grid to be written"),
    };
    let n_epochs = s.epochs.max(1) as f64;
    let pct = |count: &[u32]| -> Vec<f32> {
        count
            .iter()
            .map(|&c| (100.0 * f64::from(c) / n_epochs) as f32)
            .collect()
    };
    let hours = |count: &[u32]| -> Vec<f32> {
        count
            .iter()
            .map(|&k| (f64::from(k) * s.step_h) as f32)
            .collect()
    };
    // Nodata of the arrays' own grid: the DEM's pixels or the model cells (see `on_dem_grid`).
    let nodata: Vec<bool> = match model {
        None => dem.heights_m.iter().map(|z| z.is_nan()).collect(),
        Some(m) => m.hf.z_m.iter().map(|z| z.is_nan()).collect(),
    };
    let mask_nodata = |v: Vec<f32>| -> Vec<f32> {
        v.into_iter()
            .zip(&nodata)
            .map(|(x, &nd)| if nd { f32::NAN } else { x })
            .collect()
    };
    let to_dem = |v: Vec<f32>| -> Vec<f32> {
        match model {
            None => v,
            Some(m) => m.to_output_f32(&v),
        }
    };
    let span_h = n_epochs * s.step_h;
    let limb = s.extra.as_ref().map_or("uniform disc".to_string(), |e| {
        format!("{} limb darkening", e.limb_law)
    });
    let mut outputs: Vec<Continuous> = vec![
        (
            "sun_illumination_pct",
            format!("average Sun illumination (time-mean visible fraction of the disc, {limb}), %"),
            s.sun_fraction_sum
                .iter()
                .map(|&x| (100.0 * x / n_epochs) as f32)
                .collect(),
            100.0,
            "% of time (disc-weighted)".into(),
        ),
        (
            "sun_visible_pct",
            "Sun visible (any part of the disc), % of time".into(),
            pct(&s.sun_visible_count),
            100.0,
            "% of time".into(),
        ),
        (
            "longest_dark_h",
            "longest continuous darkness (Sun entirely hidden), hours".into(),
            hours(&s.longest_dark_epochs),
            span_h,
            "hours".into(),
        ),
        (
            "earth_visible_pct",
            "Earth visible (any part of the disc), % of time".into(),
            pct(&s.earth_visible_count),
            100.0,
            "% of time".into(),
        ),
        match &s.sun_and_earth_count {
            Some(count) => (
                "sun_and_earth_pct",
                "Sun and Earth both (partly) visible, % of time".into(),
                pct(count),
                100.0,
                "% of time".into(),
            ),
            None => (
                "sun_and_earth_pct",
                "Sun and Earth both visible, % of time: not computed by the GPU sweep (all NaN)"
                    .into(),
                vec![f32::NAN; nodata.len()],
                100.0,
                "% of time".into(),
            ),
        },
    ];
    if let Some(e) = &s.extra {
        let peak = |v: &[f32]| {
            f64::from(
                v.iter()
                    .filter(|x| x.is_finite())
                    .fold(1.0_f32, |a, &b| a.max(b)),
            )
        };
        outputs.extend([
            (
                "sun_full_pct",
                "Sun fully visible (the whole disc), % of time".into(),
                pct(&e.sun_full_count),
                100.0,
                "% of time".into(),
            ),
            (
                "longest_earth_hidden_h",
                "longest continuous run with the Earth entirely hidden, hours".into(),
                hours(&e.longest_earth_hidden_epochs),
                span_h,
                "hours".into(),
            ),
            (
                "irradiance_horizontal_w_m2",
                format!(
                    "time-mean solar irradiance on a level surface (no terrain reflection, \
                     {limb}), W/m2"
                ),
                e.irradiance_horizontal_mean_w_m2.clone(),
                peak(&e.irradiance_horizontal_mean_w_m2),
                "W/m²".into(),
            ),
            (
                "irradiance_tracking_w_m2",
                format!(
                    "time-mean solar irradiance on a vertical panel turned to the Sun's azimuth \
                     (no terrain reflection, {limb}), W/m2"
                ),
                e.irradiance_tracking_mean_w_m2.clone(),
                peak(&e.irradiance_tracking_mean_w_m2),
                "W/m²".into(),
            ),
        ]);
        if let Some(p) = &e.power {
            let top = |v: &[f32]| {
                f64::from(
                    v.iter()
                        .filter(|x| x.is_finite())
                        .fold(1.0_f32, |a, &b| a.max(b)),
                )
            };
            outputs.extend([
                (
                    "mean_power_w",
                    format!("time-mean power of the panel ({}), W", p.described),
                    p.mean_power_w.clone(),
                    top(&p.mean_power_w),
                    "W".into(),
                ),
                (
                    "required_battery_wh",
                    format!(
                        "smallest battery that, starting full, carries the load through every \
                         epoch ({}), Wh",
                        p.described
                    ),
                    p.required_battery_wh.clone(),
                    top(&p.required_battery_wh),
                    "Wh".into(),
                ),
            ]);
        }
        if let Some(d) = &e.dte {
            outputs.extend([
                (
                    "dte_pct",
                    format!(
                        "direct-to-Earth (any part of the Earth above the terrain horizon and a \
                         station above its mask; {}), % of time",
                        d.stations
                    ),
                    pct(&d.dte_count),
                    100.0,
                    "% of time".into(),
                ),
                (
                    "longest_dte_blackout_h",
                    format!(
                        "longest continuous run without direct-to-Earth ({}), hours",
                        d.stations
                    ),
                    hours(&d.longest_dte_blackout_epochs),
                    span_h,
                    "hours".into(),
                ),
            ]);
        }
    }

    let rasters: Vec<RangeRaster> = outputs
        .into_iter()
        .map(
            |(name, description, values, full_scale, unit)| RangeRaster {
                name,
                description,
                values: to_dem(mask_nodata(values)),
                full_scale,
                unit,
            },
        )
        .collect();
    let psr: Vec<u8> = s
        .sun_visible_count
        .iter()
        .zip(&nodata)
        .map(|(&c, &nd)| if nd { MASK_NODATA } else { u8::from(c == 0) })
        .collect();
    let psr_out = match model {
        None => psr,
        Some(m) => m.to_output_u8(&psr),
    };
    Ok((rasters, psr_out))
}

/// Writes the statistics of an epoch range as GeoTIFFs and PNG previews into `out_dir` on the grid of
/// `dem` (the finest layer); returns the file names. Statistics per model cell
/// (`!s.on_dem_grid`, the GPU per-epoch DP) are resampled through `model`, which they need.
/// Every file says how it was made (`made`: tags of the GeoTIFFs, subtitles of the PNGs);
/// the previews mark `marks` (name, latitude, east longitude in degrees).
pub fn write_range(
    dem: &Dem,
    model: Option<&MapGrid>,
    s: &RangeStats,
    out_dir: &Path,
    made: &crate::output::MadeWith,
    marks: &[(String, f64, f64)],
) -> anyhow::Result<Vec<String>> {
    let (rasters, psr_out) = range_rasters(dem, model, s)?;
    let mut files = Vec::new();
    let mut items = range_metadata(&made.span_utc, s);
    items.extend(made.items());
    let subtitle = format!("{} — {}", made.subtitle(), made.sources());
    let (rows, cols) = (dem.grid.rows, dem.grid.cols);
    let place = MapPlace {
        grid: dem.grid,
        projection: dem.projection,
        marks: marks.to_vec(),
    };
    for r in rasters {
        let out = r.values;
        // Colour bar up to the data's maximum, rounded up to a tenth of the full scale.
        let data_max = out
            .iter()
            .filter(|v| v.is_finite())
            .fold(0.0_f32, |a, &b| a.max(b));
        let tenth = r.full_scale / 10.0;
        let max = ((f64::from(data_max) / tenth).ceil() * tenth).clamp(tenth, r.full_scale);
        let tif = format!("{}.tif", r.name);
        let info = RasterInfo {
            description: &r.description,
            unit: geotiff_unit(r.name),
            items: items.clone(),
        };
        write_on(dem, &out_dir.join(&tif), &out, &info)?;
        let png = format!("{}.png", r.name);
        write_map_preview(
            &out_dir.join(&png),
            &format!("{} — {subtitle}", r.description),
            &out,
            rows,
            cols,
            &MapLegend::Continuous {
                min: 0.0,
                max,
                unit: r.unit,
            },
            Some(&place),
        )?;
        files.extend([tif, png]);
    }
    write_on(
        dem,
        &out_dir.join("psr_mask.tif"),
        &psr_out,
        &RasterInfo {
            description: PSR_DESCRIPTION,
            unit: "",
            items,
        },
    )?;
    let psr_f: Vec<f32> = psr_out
        .iter()
        .map(|&v| {
            if v == MASK_NODATA {
                f32::NAN
            } else {
                f32::from(v)
            }
        })
        .collect();
    write_map_preview(
        &out_dir.join("psr_mask.png"),
        &format!("Never lit (PSR over the span) — {subtitle}"),
        &psr_f,
        rows,
        cols,
        &MapLegend::Categories(vec![
            (
                1.0,
                plotters::style::RGBColor(20, 20, 60),
                "never lit".into(),
            ),
            (
                0.0,
                plotters::style::RGBColor(250, 220, 90),
                "lit at least once".into(),
            ),
        ]),
        Some(&place),
    )?;
    files.extend(["psr_mask.tif".to_string(), "psr_mask.png".to_string()]);
    Ok(files)
}

//! The mast-height trade: a site's figures at each height of a list (`penumbra mast`: `mast.csv`,
//! `mast.png`, one series folder per height), and per pixel of a map the smallest height of a list
//! at which the Sun is visible a given % of the time (`penumbra mast-map`: `min_height_m.tif`).
//!
//! Heights change the horizons (a raised observer sees over nearer terrain), so every height is
//! computed again from the terrain: a site's horizons per height (milliseconds), a map's
//! whole-grid line sweep per height (the bulk of the cost). What is shared across heights: the
//! terrain, the kernels and the ephemeris table. Until the sweep gives every height in one pass,
//! an H-height map costs H maps.

use std::path::PathBuf;

use anyhow::Context as _;
use serde::Serialize;

use super::series::SeriesRequest;
use super::{DemFiles, Inputs, KernelSource, TerrainSource};
use crate::compute::MapSettings;
use crate::compute::range::{RangeHooks, RangeInputs};
use crate::model::{EpochRange, MapEngineKind, ObserverHeight, RasterInfo, Site};

/// The heights of a trade: at least one, strictly increasing, at most [`MAX_HEIGHTS`].
pub fn check_heights(heights: &[ObserverHeight]) -> anyhow::Result<()> {
    if heights.is_empty() || heights.len() > MAX_HEIGHTS {
        anyhow::bail!(
            "--heights: give 1 to {MAX_HEIGHTS} heights, metres (e.g. 2,5,10,20,50), not {}",
            heights.len()
        );
    }
    if let Some(w) = heights.windows(2).find(|w| w[1].m() <= w[0].m()) {
        anyhow::bail!(
            "--heights: list them in increasing order ({} m then {} m)",
            w[0].m(),
            w[1].m()
        );
    }
    Ok(())
}

/// The most heights one trade takes.
pub const MAX_HEIGHTS: usize = 32;

/// One row of `mast.csv`: a site at one height.
#[derive(Debug, Clone, Serialize)]
pub struct MastRow {
    /// The site.
    pub site: String,
    /// Height of the observer (the panel's centre, the antenna) above the ground, m.
    pub height_m: f64,
    /// % of time with any part of the Sun visible.
    pub sun_visible_pct: f64,
    /// Mean visible fraction of the Sun's flux, %.
    pub sun_illumination_pct: f64,
    /// Longest run with the Sun entirely hidden, hours.
    pub longest_dark_h: f64,
    /// % of time with direct-to-Earth (with stations).
    pub dte_pct: Option<f64>,
    /// Mean power of the panel, W (with a panel).
    pub mean_power_w: Option<f64>,
    /// The smallest battery that survives the period, Wh (with a panel).
    pub required_battery_wh: Option<f64>,
}

/// The header of `mast.csv`.
pub const MAST_CSV_HEADER: &str = "site,height_m,sun_visible_pct,sun_illumination_pct,longest_dark_h,dte_pct,mean_power_w,required_battery_wh";

/// Runs `penumbra mast`: the series of `req` at each of `heights` (the sites' own heights are
/// replaced), each into `out_dir/h{H}m/` (statistics only: no CSV, no plots), then `mast.csv`,
/// `mast.json` and (with plots) `mast.png` in `out_dir`.
pub fn run_sites(req: &SeriesRequest, heights: &[ObserverHeight]) -> anyhow::Result<Vec<MastRow>> {
    let t0 = std::time::Instant::now();
    check_heights(heights)?;
    if req.sites.is_empty() {
        anyhow::bail!("no site given (use --site NAME,LAT,LON or --sites FILE)");
    }
    crate::model::check_distinct_sites(&req.sites)?;
    let epochs = req.epochs.epochs();
    let step_s = req.epochs.step_s();
    let inputs = Inputs::load(&req.terrain, &req.kernels, &epochs, DemFiles::Record)?;
    let kernels = inputs.kernels.as_ref().expect("a series has epochs");
    let _lock = crate::output::cleanup::RunLock::begin(&req.out_dir, "run.json")
        .map_err(anyhow::Error::msg)?;
    let mut config = req.config.clone();
    config.write_csv = false;
    config.plots = false;
    let mut rows = Vec::new();
    let mut files = Vec::new();
    let mut backend = String::new();
    for h in heights {
        let sites: Vec<Site> = req
            .sites
            .iter()
            .map(|s| Site::new(s.name(), s.lat_deg(), s.lon_deg(), *h))
            .collect::<Result<_, _>>()?;
        let folder = format!("h{}m", h.m());
        let run = super::series::run_series(
            kernels,
            &inputs.stack,
            &sites,
            &epochs,
            step_s,
            &config,
            &req.out_dir.join(&folder),
        )?;
        files.extend(run.files.iter().map(|f| format!("{folder}/{f}")));
        backend = run.backend.clone();
        for o in &run.outcomes {
            rows.push(row(o, h.m(), step_s));
        }
    }
    // Rows by site, then height.
    let order: Vec<&str> = req.sites.iter().map(Site::name).collect();
    rows.sort_by(|a, b| {
        let (ia, ib) = (
            order.iter().position(|n| *n == a.site),
            order.iter().position(|n| *n == b.site),
        );
        ia.cmp(&ib).then(a.height_m.total_cmp(&b.height_m))
    });
    files.extend(write_site_files(&req.out_dir, &rows, req.config.plots)?);
    let mut prov = inputs.provenance;
    prov.outputs = files;
    prov.series_engine = Some(req.config.engine.name().into());
    prov.series_backend = Some(backend);
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&req.out_dir.join("run.json"))?;
    crate::note!(
        "penumbra: {} site(s) x {} height(s) x {} epochs -> {} ({:.1} s)",
        req.sites.len(),
        heights.len(),
        epochs.len(),
        req.out_dir.display(),
        prov.wall_time_s
    );
    Ok(rows)
}

/// A site's row at `height_m` from its series.
fn row(o: &super::series::SiteOutcome, height_m: f64, step_s: f64) -> MastRow {
    let n = o.sun_fraction.len().max(1) as f64;
    let lit = o.sun_fraction.iter().filter(|&&f| f > 0.0).count() as f64;
    let dark = crate::illum::stats::longest_run(o.sun_fraction.len(), |k| o.sun_fraction[k] <= 0.0)
        .map_or(0, |r| r.len);
    MastRow {
        site: o.site.name().to_string(),
        height_m,
        sun_visible_pct: 100.0 * lit / n,
        sun_illumination_pct: 100.0 * o.sun_fraction.iter().sum::<f64>() / n,
        longest_dark_h: dark as f64 * step_s / 3600.0,
        dte_pct: (!o.dte.is_empty())
            .then(|| 100.0 * o.dte.iter().filter(|&&d| d).count() as f64 / n),
        mean_power_w: o.power.as_ref().map(|p| p.mean_power_w),
        required_battery_wh: o.power.as_ref().map(|p| p.required_battery_wh),
    }
}

/// Writes `mast.csv`, `mast.json` and (with `plot`) `mast.png`; returns their names.
fn write_site_files(
    out_dir: &std::path::Path,
    rows: &[MastRow],
    plot: bool,
) -> anyhow::Result<Vec<String>> {
    let opt = |v: Option<f64>, digits: usize| v.map_or(String::new(), |x| format!("{x:.digits$}"));
    crate::output::write_atomic(&out_dir.join("mast.csv"), |w| -> anyhow::Result<()> {
        writeln!(w, "{MAST_CSV_HEADER}")?;
        for r in rows {
            let name = crate::products::series::csv_field(&r.site);
            writeln!(
                w,
                "{name},{},{:.4},{:.4},{:.3},{},{},{}",
                r.height_m,
                r.sun_visible_pct,
                r.sun_illumination_pct,
                r.longest_dark_h,
                opt(r.dte_pct, 4),
                opt(r.mean_power_w, 4),
                opt(r.required_battery_wh, 3)
            )?;
        }
        Ok(())
    })?;
    crate::output::write_atomic(&out_dir.join("mast.json"), |w| -> anyhow::Result<()> {
        serde_json::to_writer_pretty(&mut *w, &serde_json::json!({ "rows": rows }))?;
        writeln!(w)?;
        Ok(())
    })?;
    let mut files = vec!["mast.csv".to_string(), "mast.json".to_string()];
    if plot {
        let mut sites: Vec<&str> = Vec::new();
        for r in rows {
            if !sites.contains(&r.site.as_str()) {
                sites.push(&r.site);
            }
        }
        let line = |f: &dyn Fn(&MastRow) -> Option<f64>| -> Vec<(&str, Vec<(f64, f64)>)> {
            sites
                .iter()
                .map(|s| {
                    let v = rows
                        .iter()
                        .filter(|r| r.site == *s)
                        .map(|r| (r.height_m, f(r).unwrap_or(f64::NAN)))
                        .collect();
                    (*s, v)
                })
                .collect()
        };
        let mut panels: Vec<crate::illum::plot::HeightPanel<'_>> =
            vec![("Sun visible, % of time", line(&|r| Some(r.sun_visible_pct)))];
        if rows.iter().any(|r| r.dte_pct.is_some()) {
            panels.push(("direct-to-Earth, % of time", line(&|r| r.dte_pct)));
        }
        if rows.iter().any(|r| r.required_battery_wh.is_some()) {
            panels.push(("required battery, Wh", line(&|r| r.required_battery_wh)));
        }
        let height = 60 + 300 * panels.len() as u32;
        crate::illum::plot::write_height_plot(
            &out_dir.join("mast.png"),
            "Mast height trade",
            &panels,
            (1100, height),
        )?;
        files.push("mast.png".into());
    }
    Ok(files)
}

/// What `penumbra mast-map` computes.
#[derive(Debug, Clone)]
pub struct MastMapRequest {
    /// The terrain (every layer).
    pub terrain: TerrainSource,
    /// The kernels.
    pub kernels: KernelSource,
    /// Aberration correction.
    pub abcorr: crate::ephem::AbCorr,
    /// The epochs.
    pub epochs: EpochRange,
    /// The heights, increasing.
    pub heights: Vec<ObserverHeight>,
    /// The % of time with the Sun (partly) visible a height must reach.
    pub target_lit_pct: f64,
    /// How each height's map is computed (the horizons engine; its observer height is set per
    /// height).
    pub settings: MapSettings,
    /// Output folder.
    pub out_dir: PathBuf,
}

/// One height of a mast map: how many pixels reach the target there first, and its cost.
#[derive(Debug, Clone, Serialize)]
pub struct HeightCost {
    /// Height above the ground, m.
    pub height_m: f64,
    /// Pixels whose smallest height reaching the target is this one.
    pub first_reached_px: usize,
    /// Mean % of time with the Sun visible over the pixels with data.
    pub mean_sun_visible_pct: f64,
    /// Wall time of this height's map (sweep and statistics), s.
    pub wall_s: f64,
}

/// Runs `penumbra mast-map`: one horizons-engine map per height, then `min_height_m.tif` (NaN
/// where no height of the list reaches the target or without data), its preview and
/// `heights.csv` (per height: pixels reached first, mean lit %, seconds).
pub fn run_map(req: &MastMapRequest) -> anyhow::Result<Vec<HeightCost>> {
    let t0 = std::time::Instant::now();
    check_heights(&req.heights)?;
    if !(req.target_lit_pct.is_finite() && (0.0..=100.0).contains(&req.target_lit_pct)) {
        anyhow::bail!(
            "--target-lit-pct {}: give a % of time from 0 to 100",
            req.target_lit_pct
        );
    }
    if req
        .settings
        .engine
        .is_some_and(|e| e != MapEngineKind::Horizons)
    {
        anyhow::bail!("mast maps come from the horizons engine (whole-grid horizons per height)");
    }
    let epochs = req.epochs.epochs();
    let inputs = Inputs::load(&req.terrain, &req.kernels, &epochs, DemFiles::Record)?;
    let kernels = inputs.kernels.as_ref().expect("a range has epochs");
    let fine = &inputs.stack.layers[0];
    let n_px = fine.heights_m.len();
    let _lock = crate::output::cleanup::RunLock::begin(&req.out_dir, "run.json")
        .map_err(anyhow::Error::msg)?;
    let mut min_height = vec![f32::NAN; n_px];
    let mut costs = Vec::new();
    let mut backend = String::new();
    for h in &req.heights {
        let t = std::time::Instant::now();
        let mut settings = req.settings.clone();
        settings.observer_height = *h;
        settings.engine = Some(MapEngineKind::Horizons);
        let range = RangeInputs {
            stack: &inputs.stack,
            kernels,
            epochs: &req.epochs,
            abcorr: req.abcorr,
        };
        let hooks = RangeHooks {
            report: &mut |_, _| true,
            store: &mut crate::horizon::statistics::NoStore,
        };
        crate::note!("penumbra: mast map at {} m above the ground", h.m());
        let result = crate::compute::range::range_statistics(range, &settings, hooks)
            .with_context(|| format!("the map at {} m", h.m()))?;
        backend = result.note;
        let s = &result.stats;
        let n = s.epochs.max(1) as f64;
        let (mut first, mut sum, mut count) = (0, 0.0, 0usize);
        for (px, &c) in s.sun_visible_count.iter().enumerate() {
            if fine.heights_m[px].is_nan() {
                continue;
            }
            let pct = 100.0 * f64::from(c) / n;
            sum += pct;
            count += 1;
            if min_height[px].is_nan() && pct >= req.target_lit_pct - 1e-9 {
                min_height[px] = h.m() as f32;
                first += 1;
            }
        }
        costs.push(HeightCost {
            height_m: h.m(),
            first_reached_px: first,
            mean_sun_visible_pct: sum / count.max(1) as f64,
            wall_s: t.elapsed().as_secs_f64(),
        });
    }
    let span = crate::model::span_text(&epochs);
    let heights_text = req
        .heights
        .iter()
        .map(|h| h.m().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let description = format!(
        "smallest height above the ground (of {heights_text} m) at which any part of the Sun is \
         visible >= {} % of the time, m (NaN: none of them)",
        req.target_lit_pct
    );
    let mut items = vec![
        ("span_utc".to_string(), span.clone()),
        ("epochs".to_string(), epochs.len().to_string()),
        ("heights_m".to_string(), heights_text.clone()),
        ("target_lit_pct".to_string(), req.target_lit_pct.to_string()),
    ];
    // How it was made (engine, limb darkening, layers and kernels with sha256); the heights are
    // the list above, not one observer height.
    let made = crate::output::MadeWith::new(
        &inputs.provenance,
        f64::NAN,
        MapEngineKind::Horizons.name(),
        req.settings.limb.name(),
        &span,
    );
    items.extend(
        made.items()
            .into_iter()
            .filter(|(k, _)| k != "observer_height_m"),
    );
    let top = req.heights.last().map_or(1.0, |h| h.m());
    crate::model::write_on(
        fine,
        &req.out_dir.join("min_height_m.tif"),
        &min_height,
        &RasterInfo {
            description: &description,
            unit: "m",
            items,
        },
    )?;
    crate::illum::plot::write_map_preview(
        &req.out_dir.join("min_height_m.png"),
        &format!(
            "minimum mast height for >= {} % lit, m (NaN: above {top} m)",
            req.target_lit_pct
        ),
        &min_height,
        fine.grid.rows,
        fine.grid.cols,
        &crate::illum::plot::MapLegend::Continuous {
            min: 0.0,
            max: top,
            unit: "m".into(),
        },
        Some(&crate::illum::plot::MapPlace {
            marks: Vec::new(),
            grid: fine.grid,
            projection: fine.projection,
        }),
    )?;
    crate::output::write_atomic(
        &req.out_dir.join("heights.csv"),
        |w| -> anyhow::Result<()> {
            writeln!(w, "height_m,first_reached_px,mean_sun_visible_pct,wall_s")?;
            for c in &costs {
                writeln!(
                    w,
                    "{},{},{:.4},{:.2}",
                    c.height_m, c.first_reached_px, c.mean_sun_visible_pct, c.wall_s
                )?;
            }
            Ok(())
        },
    )?;
    let mut prov = inputs.provenance;
    prov.outputs = vec![
        "min_height_m.tif".into(),
        "min_height_m.png".into(),
        "heights.csv".into(),
    ];
    prov.backend = format!("{backend}; one map per height ({heights_text} m)");
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&req.out_dir.join("run.json"))?;
    crate::note!(
        "penumbra: minimum heights over {} height(s) -> {} ({:.1} s)",
        req.heights.len(),
        req.out_dir.display(),
        prov.wall_time_s
    );
    Ok(costs)
}

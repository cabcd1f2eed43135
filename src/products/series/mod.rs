//! `penumbra series` and a scenario's `[series]`: per-site illumination time series, statistics
//! and plots. The request ([`SeriesRequest`], its settings [`SeriesConfig`]) is built by the
//! command line, a scenario and the Python module; [`run_series`] computes and writes a run, the
//! horizons and the smap-dp engine through [`crate::compute`].

mod config;
pub mod gis;
pub mod neighbourhood;
mod pipeline;

use std::path::PathBuf;

use super::{KernelSource, TerrainSource};
use crate::model::{Epochs, Site};

pub use config::{SeriesConfig, SeriesEngine};
pub use pipeline::{
    BATTERY_CSV_COLUMN, LINK_CSV_COLUMNS, LONG_TABLE, LONG_TABLE_SITE_COLUMNS, LinkContext,
    LinkScratch, POWER_CSV_COLUMNS, PowerTrack, RELAY_CSV_COLUMNS, SERIES_CSV_HEADER, SeriesRow,
    SeriesRun, SiteFractions, SiteOutcome, csv_field, extra_csv_columns, link_record, row_values,
    run_series, site_fractions, site_location,
};

/// What `penumbra series` computes.
#[derive(Debug, Clone)]
pub struct SeriesRequest {
    /// The terrain.
    pub terrain: TerrainSource,
    /// The sites (at least one; names unique).
    pub sites: Vec<Site>,
    /// The epochs.
    pub epochs: Epochs,
    /// Engine, backend, disc method, limb darkening, horizon settings, outputs.
    pub config: SeriesConfig,
    /// The kernels.
    pub kernels: KernelSource,
    /// Output folder (created if needed): one sub-folder per site, plus stats.json and run.json.
    pub out_dir: PathBuf,
}

/// Runs `penumbra series` and writes its `run.json`.
pub fn run(req: &SeriesRequest) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    let (_, prov, _lock) = execute(req)?;
    finish(req, prov, t0)
}

/// The series of `req` (files and all) and its provenance, without `run.json` (for products
/// built on a series, e.g. `penumbra windows`, which add their files first), and the output
/// folder's lock, to hold until `run.json` is written.
pub fn execute(
    req: &SeriesRequest,
) -> anyhow::Result<(
    SeriesRun,
    crate::output::Provenance,
    crate::output::cleanup::RunLock,
)> {
    if req.sites.is_empty() {
        anyhow::bail!(
            "no site given (use --site NAME,LAT,LON, --sites FILE or --lat-deg/--lon-deg)"
        );
    }
    crate::model::check_distinct_sites(&req.sites)?;
    let epochs = req.epochs.epochs();
    let step_s = req.epochs.step_s();
    let inputs = super::Inputs::load(&req.terrain, &req.kernels, &epochs, super::DemFiles::Record)?;
    let kernels = inputs.kernels.as_ref().expect("a series has epochs");
    let lock = crate::output::cleanup::RunLock::begin(&req.out_dir, "run.json")
        .map_err(anyhow::Error::msg)?;
    let run = run_series(
        kernels,
        &inputs.stack,
        &req.sites,
        &epochs,
        step_s,
        &req.config,
        &req.out_dir,
    )?;
    let mut prov = inputs.provenance;
    prov.outputs = run.files.clone();
    prov.series_engine = Some(req.config.engine.name().into());
    prov.series_backend = Some(run.backend.clone());
    prov.ground_stations = run.stations.clone();
    Ok((run, prov, lock))
}

/// Writes `run.json` of a series-based run and says what was done.
pub fn finish(
    req: &SeriesRequest,
    mut prov: crate::output::Provenance,
    t0: std::time::Instant,
) -> anyhow::Result<()> {
    let epochs = req.epochs.epochs();
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&req.out_dir.join("run.json"))?;
    crate::note!(
        "penumbra: {} site(s) x {} epochs -> {} ({:.1} s)",
        req.sites.len(),
        epochs.len(),
        req.out_dir.display(),
        prov.wall_time_s
    );
    Ok(())
}

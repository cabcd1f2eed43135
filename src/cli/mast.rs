//! `penumbra mast` (a site's figures against the mast height) and `penumbra mast-map` (the
//! smallest height reaching a lit % per pixel).

use std::path::PathBuf;

use clap::Args;
use penumbra::model::ObserverHeight;

use super::series::SeriesArgs;
use super::{EpochArgs, KernelArgs, TerrainArgs};

/// The default heights of a trade, metres.
const DEFAULT_HEIGHTS_M: &str = "2,5,10,15,20,30,40,50";

/// Arguments of `penumbra mast`: a series (every `penumbra series` option; its --observer-height-m
/// is replaced by each height) and the heights.
#[derive(Debug, Clone, Args)]
pub struct MastArgs {
    /// The series computed at each height.
    #[command(flatten)]
    pub series: SeriesArgs,
    /// Mast heights above the ground, metres, increasing (comma-separated).
    #[arg(long, value_name = "M,M,…", value_delimiter = ',', default_value = DEFAULT_HEIGHTS_M, allow_hyphen_values = true)]
    pub heights: Vec<ObserverHeight>,
}

/// Runs `penumbra mast`.
pub fn run(args: &MastArgs) -> anyhow::Result<()> {
    let req = super::series::request(&args.series)?;
    penumbra::products::mast::run_sites(&req, &args.heights)?;
    Ok(())
}

/// Arguments of `penumbra mast-map`.
#[derive(Debug, Clone, Args)]
pub struct MastMapArgs {
    /// Terrain: DEM layers or the synthetic DEM.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// The epoch range (--start, --stop, --step).
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// Mast heights above the ground, metres, increasing (comma-separated).
    #[arg(long, value_name = "M,M,…", value_delimiter = ',', default_value = DEFAULT_HEIGHTS_M, allow_hyphen_values = true)]
    pub heights: Vec<ObserverHeight>,
    /// The % of time with any part of the Sun visible that a height must reach.
    #[arg(
        long,
        value_name = "PCT",
        default_value_t = 90.0,
        allow_hyphen_values = true
    )]
    pub target_lit_pct: f64,
    /// Requested azimuths of each height's line sweep.
    #[arg(long, default_value_t = penumbra::horizon::sweep::DEFAULT_SWEEP_AZIMUTHS as u32, value_parser = clap::value_parser!(u32).range(4..=100_000))]
    pub azimuths: u32,
    /// Largest step component of a sweep direction.
    #[arg(long, default_value_t = penumbra::horizon::sweep::DEFAULT_MAX_STEP, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub max_step: u32,
    /// Where each height's map runs (the line sweep and the statistics' epoch loop).
    #[arg(long, value_enum, default_value_t = super::BackendArg::Auto)]
    pub backend: super::BackendArg,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
    /// Output folder: min_height_m.tif (+ .png), heights.csv, run.json.
    #[arg(long, value_name = "DIR")]
    pub out_dir: PathBuf,
}

/// Runs `penumbra mast-map`.
pub fn run_map(args: &MastMapArgs) -> anyhow::Result<()> {
    let Some(penumbra::model::Epochs::Range(epochs)) = args.epochs.spec()? else {
        anyhow::bail!("a mast map needs an epoch range: --start, --stop and --step");
    };
    let settings = penumbra::compute::MapSettings {
        engine: Some(penumbra::model::MapEngineKind::Horizons),
        backend: args.backend.into(),
        horizons: penumbra::compute::range::HorizonsFrom::Sweep {
            azimuths: args.azimuths as usize,
            max_step: args.max_step,
        },
        ..Default::default()
    };
    penumbra::products::mast::run_map(&penumbra::products::mast::MastMapRequest {
        terrain: args.terrain.source(),
        kernels: args.kernels.source(),
        abcorr: super::abcorr(&args.abcorr)?,
        epochs,
        heights: args.heights.clone(),
        target_lit_pct: args.target_lit_pct,
        settings,
        out_dir: args.out_dir.clone(),
    })?;
    Ok(())
}

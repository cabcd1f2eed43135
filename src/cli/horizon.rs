//! `penumbra horizon`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use penumbra::horizon::HorizonParams;
use penumbra::products::horizon::HorizonRequest;

use super::BackendArg;

/// Arguments of `penumbra horizon`.
#[derive(Debug, Clone, Args)]
pub struct HorizonArgs {
    /// DEM GeoTIFF layer; repeat for several layers (the finest with data is used at each point).
    #[arg(long = "dem", value_name = "FILE", required = true)]
    pub dem: Vec<PathBuf>,
    /// Where: latitude and longitude.
    #[command(flatten)]
    pub at: super::LatLonArgs,
    /// Observer height above the terrain surface (radial), metres (0 … 100000).
    #[arg(long, value_name = "M", default_value_t = penumbra::model::ObserverHeight::DEFAULT, allow_negative_numbers = true)]
    pub observer_height_m: penumbra::model::ObserverHeight,
    /// Azimuth step, degrees (must divide 360).
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    pub az_step_deg: f64,
    /// Scan method: `exact` (every cell crossed) or `fast` (conservative skipping, <= 0.002 deg).
    #[arg(long, value_enum, default_value_t = HorizonMethodArg::Fast)]
    pub method: HorizonMethodArg,
    /// Output format.
    #[arg(long, value_enum, default_value_t = HorizonFormat::Csv)]
    pub format: HorizonFormat,
    /// Output file (written atomically); stdout when absent.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Compute backend: `auto` (default; for one site the CPU scan of `--method`), `cpu`, or
    /// `gpu` (the GPU horizon scan, sampled like `--method exact`; `--method` is then ignored).
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
}

/// Horizon scan method on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HorizonMethodArg {
    /// Conservative block-maximum skipping.
    Fast,
    /// The reference scan.
    Exact,
}

/// Output format of `penumbra horizon`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HorizonFormat {
    /// `az_deg,horizon_el_deg,distance_m` rows.
    Csv,
    /// One JSON object with the site and the arrays.
    Json,
}

impl From<HorizonMethodArg> for penumbra::horizon::HorizonMethod {
    fn from(m: HorizonMethodArg) -> Self {
        match m {
            HorizonMethodArg::Fast => penumbra::horizon::HorizonMethod::Fast,
            HorizonMethodArg::Exact => penumbra::horizon::HorizonMethod::Exact,
        }
    }
}

/// Runs `penumbra horizon`.
pub fn run(args: &HorizonArgs) -> anyhow::Result<()> {
    penumbra::products::horizon::run(&HorizonRequest {
        dems: args.dem.clone(),
        lat_deg: args.at.lat_deg,
        lon_deg: args.at.lon_deg,
        params: HorizonParams {
            observer_height_m: args.observer_height_m.m(),
            az_step_deg: args.az_step_deg,
            method: args.method.into(),
            ..HorizonParams::default()
        },
        format: match args.format {
            HorizonFormat::Csv => penumbra::products::horizon::HorizonFormat::Csv,
            HorizonFormat::Json => penumbra::products::horizon::HorizonFormat::Json,
        },
        out: args.out.clone(),
        backend: args.backend.into(),
    })
}

//! `penumbra ephem`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use penumbra::products::ephem::{EphemRequest, TableFormat};

use super::{EpochArgs, KernelArgs};

/// Output formats for tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Comma-separated values with a header row.
    Csv,
    /// A JSON document.
    Json,
}

impl From<Format> for TableFormat {
    fn from(f: Format) -> Self {
        match f {
            Format::Csv => TableFormat::Csv,
            Format::Json => TableFormat::Json,
        }
    }
}

/// Arguments of `penumbra ephem`.
#[derive(Debug, Clone, Args)]
pub struct EphemArgs {
    /// Where: latitude and longitude.
    #[command(flatten)]
    pub at: super::LatLonArgs,
    /// Site height above the 1737.4 km reference sphere, metres (not above the ground: the
    /// ephemerides need no DEM; `--height-m` is an old alias).
    #[arg(
        long = "height-above-sphere-m",
        alias = "height-m",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub height_m: f64,
    /// Epoch(s).
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// Aberration correction: lt+s (light time + stellar aberration) or none (geometric).
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Csv)]
    pub format: Format,
    /// Output file (default: standard output). Written atomically.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// Runs `penumbra ephem`.
pub fn run(args: &EphemArgs) -> anyhow::Result<()> {
    let abcorr = super::abcorr(&args.abcorr)?;
    let site = penumbra::ephem::Site::new(args.at.lat_deg, args.at.lon_deg, args.height_m)?;
    penumbra::products::ephem::run(&EphemRequest {
        site,
        epochs: args.epochs.required()?,
        abcorr,
        kernels: args.kernels.source(),
        format: args.format.into(),
        out: args.out.clone(),
    })
}

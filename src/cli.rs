//! Command-line interface (clap derive). Every argument documents its unit.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// penumbra: sunlight and earthlight at the lunar poles.
#[derive(Debug, Parser)]
#[command(name = "penumbra", version, about, long_about = None)]
pub struct Cli {
    /// The subcommand to run.
    #[command(subcommand)]
    pub command: Command,
}

/// penumbra's subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print the SPICE kernels that are loaded: files, bodies, frames and time coverage.
    Kernels,
    /// Compute the terrain horizon profile (elevation and distance per azimuth) of one site.
    Horizon(HorizonArgs),
}

/// Arguments of `penumbra horizon`.
#[derive(Debug, Clone, Args)]
pub struct HorizonArgs {
    /// DEM GeoTIFF layer; repeat for several layers (the finest with data is used at each point).
    #[arg(long = "dem", value_name = "FILE", required = true)]
    pub dem: Vec<PathBuf>,
    /// Site planetocentric latitude, degrees.
    #[arg(long, allow_negative_numbers = true)]
    pub lat_deg: f64,
    /// Site east longitude, degrees.
    #[arg(long, allow_negative_numbers = true)]
    pub lon_deg: f64,
    /// Observer height above the terrain surface (radial), metres.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub observer_height_m: f64,
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

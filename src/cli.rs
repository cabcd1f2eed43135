//! Command-line interface (clap derive). Every argument documents its unit.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};

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
    /// Inspect or generate DEMs (GeoTIFF).
    Dem {
        /// The DEM action.
        #[command(subcommand)]
        command: DemCommand,
    },
}

/// `penumbra dem ...` actions.
#[derive(Debug, Subcommand)]
pub enum DemCommand {
    /// Print a DEM's size, pixel size, CRS, bounds (x/y in m, lat/lon in deg), height range and
    /// nodata count.
    Info {
        /// The DEM file (GeoTIFF).
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value_t = InfoFormat::Text)]
        format: InfoFormat,
        /// Also print the bilinear height (m) at a point `LAT,LON` (planetocentric latitude and
        /// east longitude, deg); repeatable. A point outside the DEM is an error.
        #[arg(long = "at", value_name = "LAT,LON", allow_hyphen_values = true)]
        at: Vec<String>,
    },
    /// Write the deterministic synthetic south-polar DEM (craters, a ridge, a massif, fractal
    /// roughness) as a float32 GeoTIFF.
    Synth {
        /// Grid size, pixels (square).
        #[arg(long, default_value_t = 400)]
        size: usize,
        /// Pixel size, metres.
        #[arg(long = "px-m", default_value_t = 100.0)]
        px_m: f64,
        /// Seed of the pseudo-random generator.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output GeoTIFF path.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Output format of `dem info`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InfoFormat {
    /// `key: value` lines.
    Text,
    /// One JSON object.
    Json,
}

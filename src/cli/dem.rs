//! `penumbra dem info|synth`.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::{Subcommand, ValueEnum};

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

/// Runs `penumbra dem …`.
pub fn run(command: DemCommand) -> anyhow::Result<()> {
    match command {
        DemCommand::Info { file, format, at } => {
            let points = at
                .iter()
                .map(|spec| {
                    spec.split_once(',')
                        .and_then(|(a, b)| {
                            Some((a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?))
                        })
                        .with_context(|| format!("--at {spec:?}: expected LAT,LON in degrees"))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            let format = match format {
                InfoFormat::Text => penumbra::products::dem::InfoFormat::Text,
                InfoFormat::Json => penumbra::products::dem::InfoFormat::Json,
            };
            print!("{}", penumbra::products::dem::info(&file, format, &points)?);
            Ok(())
        }
        DemCommand::Synth {
            size,
            px_m,
            seed,
            out,
        } => penumbra::products::dem::synth(
            &penumbra::terrain::synth::SynthParams {
                size_px: size,
                px_m,
                seed,
            },
            &out,
        ),
    }
}

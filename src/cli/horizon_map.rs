//! `penumbra horizon-map build|info`.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use penumbra::products::horizon_map::{HorizonMapBuildRequest, HorizonSweepRequest};

use super::{BackendArg, TerrainArgs};

/// Actions of `penumbra horizon-map`.
#[derive(Debug, Clone, Subcommand)]
pub enum HorizonMapCommand {
    /// Build a Fourier-compressed horizon map (16 f16 complex coefficients per cell) and write
    /// it as a multi-page TIFF.
    Build(HorizonMapBuildArgs),
    /// Exact whole-grid horizons by the line sweep (every layer, on the finest layer's grid):
    /// a GeoTIFF with one int16 band (centi-degrees) per direction.
    Sweep(HorizonSweepArgs),
    /// Describe a horizon-map TIFF: geometry, parameters, mean coefficient amplitudes.
    Info {
        /// The horizon-map TIFF.
        file: PathBuf,
    },
}

/// Arguments of `penumbra horizon-map build`.
#[derive(Debug, Clone, Args)]
pub struct HorizonMapBuildArgs {
    /// The terrain.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// Observer height above the ground (radial), metres (0 … 100000).
    #[arg(long, value_name = "M", default_value_t = penumbra::model::ObserverHeight::DEFAULT, allow_negative_numbers = true)]
    pub observer_height_m: penumbra::model::ObserverHeight,
    /// Number of sampled azimuths before the DFT (at least 32).
    #[arg(long, default_value_t = penumbra::shadow::fourier::DEFAULT_AZIMUTHS)]
    pub azimuths: usize,
    /// Longest horizon ray, cells (default: the grid's rows + columns, i.e. the whole grid).
    #[arg(long)]
    pub max_distance_cells: Option<usize>,
    /// Output TIFF.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Compute backend of the build: `gpu` (shaders/fourier_build.wgsl, f32; the map agrees with
    /// the CPU build within the bounds of docs/gpu.md), `cpu` (the rayon engine, f64) or `auto`
    /// (the GPU when a hardware adapter exists, else the CPU with one warning line).
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
}

/// Arguments of `penumbra horizon-map sweep`.
#[derive(Debug, Clone, Args)]
pub struct HorizonSweepArgs {
    /// The terrain.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// Observer height above the ground (radial), metres (0 … 100000).
    #[arg(long, value_name = "M", default_value_t = penumbra::model::ObserverHeight::DEFAULT, allow_negative_numbers = true)]
    pub observer_height_m: penumbra::model::ObserverHeight,
    /// Requested azimuths, uniform in grid azimuth; each is served by the nearest line direction
    /// (band descriptions give the exact grid azimuths).
    #[arg(long, default_value_t = penumbra::horizon::sweep::DEFAULT_SWEEP_AZIMUTHS)]
    pub azimuths: usize,
    /// Largest step component (cells) of a line direction: more directions near the grid axes,
    /// more work (about |dcol| + |dnorth| samples per pixel and direction).
    #[arg(long, default_value_t = penumbra::horizon::sweep::DEFAULT_MAX_STEP)]
    pub max_step: u32,
    /// Output GeoTIFF of horizon elevations (BigTIFF, one int16 band per direction, centi-degrees).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Also write the distance to the horizon point (one float16 band per direction, km).
    #[arg(long, value_name = "FILE")]
    pub distance_out: Option<PathBuf>,
    /// Compute backend: `cpu` (the rayon sweep, f64, exact 3-D elevations; the default until
    /// the GPU path is timed on a hardware GPU), `gpu` (lines built on the CPU, hulls and
    /// tangents in shaders/line_sweep.wgsl, f32; within 0.01 deg of the CPU sweep, docs/gpu.md)
    /// or `auto` (the GPU when a hardware adapter exists, else the CPU with one warning line).
    #[arg(long, value_enum, default_value_t = BackendArg::Cpu)]
    pub backend: BackendArg,
}

/// Runs `penumbra horizon-map …`.
pub fn run(command: HorizonMapCommand) -> anyhow::Result<()> {
    match command {
        HorizonMapCommand::Build(args) => {
            penumbra::products::horizon_map::build(&HorizonMapBuildRequest {
                terrain: args.terrain.source(),
                observer_height: args.observer_height_m,
                azimuths: args.azimuths,
                max_distance_cells: args.max_distance_cells,
                out: args.out.clone(),
                backend: args.backend.into(),
            })
        }
        HorizonMapCommand::Sweep(args) => {
            penumbra::products::horizon_map::sweep(&HorizonSweepRequest {
                terrain: args.terrain.source(),
                observer_height: args.observer_height_m,
                azimuths: args.azimuths,
                max_step: args.max_step,
                out: args.out,
                distance_out: args.distance_out,
                backend: args.backend.into(),
            })
        }
        HorizonMapCommand::Info { file } => {
            print!("{}", penumbra::products::horizon_map::info(&file)?);
            Ok(())
        }
    }
}

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
    /// Sun and Earth azimuth, elevation, range and angular radius seen from a site.
    Ephem(EphemArgs),
    /// List the SPICE kernels that are loaded: files, bodies, frames and time coverage.
    Kernels(KernelArgs),
    /// Run a scenario file (scenarios/*.toml).
    Run(RunArgs),
    /// List the GPU adapters wgpu finds (honours WGPU_BACKEND): name, backend, device type,
    /// driver and the compute limits that bound penumbra's kernels.
    GpuInfo(GpuInfoArgs),
}

/// Output formats for tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Comma-separated values with a header row.
    Csv,
    /// A JSON document.
    Json,
}

/// Where the SPICE kernels come from.
#[derive(Debug, Clone, Args)]
pub struct KernelArgs {
    /// Folder of SPICE kernels (.bsp, .bpc, .tf, .tls). Default: $PENUMBRA_KERNELS, ./kernels,
    /// then the kernels/ folder of the source tree.
    #[arg(long, value_name = "DIR")]
    pub kernels: Option<PathBuf>,
}

/// An epoch or a range of epochs (UTC).
#[derive(Debug, Clone, Args)]
pub struct EpochArgs {
    /// A single epoch, UTC (e.g. 2024-01-03T00:00:00).
    #[arg(long, value_name = "UTC", conflicts_with_all = ["start", "stop", "step"])]
    pub utc: Option<String>,
    /// First epoch of a range, UTC.
    #[arg(long, value_name = "UTC", requires_all = ["stop", "step"])]
    pub start: Option<String>,
    /// Last epoch of a range, UTC (inclusive when it falls on the step grid).
    #[arg(long, value_name = "UTC", requires_all = ["start", "step"])]
    pub stop: Option<String>,
    /// Step of the range: a number and a unit s, m, h or d (e.g. 10m, 1h, 6h, 1d).
    #[arg(long, value_name = "STEP", requires_all = ["start", "stop"])]
    pub step: Option<String>,
}

/// Arguments of `penumbra ephem`.
#[derive(Debug, Clone, Args)]
pub struct EphemArgs {
    /// Site planetocentric latitude, degrees (-90..90).
    #[arg(long, allow_hyphen_values = true)]
    pub lat_deg: f64,
    /// Site east longitude, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub lon_deg: f64,
    /// Site height above the 1737.4 km reference sphere, metres.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
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

/// Arguments of `penumbra run`.
#[derive(Debug, Clone, Args)]
pub struct RunArgs {
    /// The scenario file (TOML).
    pub scenario: PathBuf,
    /// Override the scenario's output folder.
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    /// Kernels (overrides the scenario's `kernels`).
    #[command(flatten)]
    pub kernels: KernelArgs,
}

/// Arguments of `penumbra gpu-info`.
#[derive(Debug, Clone, Args)]
pub struct GpuInfoArgs {
    /// Also resolve this backend choice (as `--backend` of the compute commands does) and print
    /// the result: `auto` falls back to the CPU with one warning, `gpu` fails without an adapter.
    #[arg(long, value_enum, value_name = "BACKEND")]
    pub backend: Option<crate::gpu::Backend>,
}

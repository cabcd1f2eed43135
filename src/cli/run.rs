//! `penumbra run`.

use std::path::PathBuf;

use clap::Args;
use penumbra::scenario::RunRequest;

use super::KernelArgs;

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

/// Runs `penumbra run`.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    penumbra::scenario::run_file(&RunRequest {
        scenario: args.scenario.clone(),
        out_dir: args.out_dir.clone(),
        kernels: args.kernels.kernels.clone(),
    })
}

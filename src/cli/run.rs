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
    /// Carry on an unfinished (killed) run in the output folder: its finished parts (stages,
    /// blocks of map rows, rendered frames) are kept and the outputs are the same bytes as an
    /// uninterrupted run's. Refused if that run had other inputs or parameters.
    #[arg(long)]
    pub resume: bool,
}

/// Runs `penumbra run`.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    penumbra::scenario::run_file(&RunRequest {
        scenario: args.scenario.clone(),
        out_dir: args.out_dir.clone(),
        kernels: args.kernels.kernels.clone(),
        resume: args.resume,
    })
}

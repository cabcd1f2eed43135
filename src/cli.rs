//! Command-line interface (clap derive). Every argument documents its unit.

use clap::{Parser, Subcommand};

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
}

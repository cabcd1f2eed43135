//! Runs a parsed command line: the glue between [`crate::cli`] and the library.

use crate::cli::{Cli, Command};

/// Runs one invocation of the tool.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Kernels => Ok(()),
        Command::Horizon(args) => {
            let stack = load_stack(&args.dem)?;
            crate::horizon::cli_run(&args, &stack)
        }
    }
}

/// Loads DEM layers into a terrain stack.
// TODO(lead): replace with terrain::load_dem (this uses the horizon module's stub reader).
fn load_stack(paths: &[std::path::PathBuf]) -> anyhow::Result<crate::terrain::TerrainStack> {
    crate::horizon::tiff_stub::load_stack(paths)
}

/// Formats an error chain on one line (`outer: inner: root cause`), as `main` prints it.
pub fn one_line(err: &anyhow::Error) -> String {
    format!("{err:#}").replace('\n', " ")
}

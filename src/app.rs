//! Runs a parsed command line: the glue between [`crate::cli`] and the library.

use crate::cli::{Cli, Command};

/// Runs one invocation of the tool.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Kernels => Ok(()),
    }
}

/// Formats an error chain on one line (`outer: inner: root cause`), as `main` prints it.
pub fn one_line(err: &anyhow::Error) -> String {
    format!("{err:#}").replace('\n', " ")
}

//! The `penumbra` command-line tool: a thin shell over the library.
//!
//! Parses the command line ([`cli`], the only place that knows clap), runs the subcommand and maps
//! errors to exit code 2 with one line on stderr (ripgrep `main.rs` pattern).

use std::process::ExitCode;

use clap::Parser as _;

mod cli;

fn main() -> ExitCode {
    let args = match cli::Cli::try_parse() {
        Ok(args) => args,
        Err(err) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr.
            let is_error = err.use_stderr();
            err.print().ok();
            return if is_error {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("penumbra: error: {}", penumbra::products::one_line(&err));
            ExitCode::from(2)
        }
    }
}

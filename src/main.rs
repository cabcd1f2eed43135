//! The `penumbra` command-line tool: a thin shell over the library.
//!
//! Parses the command line ([`cli`], the only place that knows clap), runs the subcommand and maps
//! errors to exit code 2 with one line on stderr (ripgrep `main.rs` pattern).

use std::process::ExitCode;

use clap::Parser as _;

mod cli;

/// On SIGINT/SIGTERM: remove the temporary files and locks of the run, say so on one line, exit
/// 130/143 (128 + signal). Finished outputs stay (each was renamed into place whole).
fn handle_signals() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            let removed = penumbra::output::cleanup::remove_registered();
            let name = if sig == SIGINT { "SIGINT" } else { "SIGTERM" };
            eprintln!(
                "penumbra: interrupted by {name}; {removed} temporary file(s) removed, finished outputs kept"
            );
            std::process::exit(128 + sig);
        }
    });
}

/// Without `XDG_RUNTIME_DIR` (cron, Docker, Slurm) every GPU probe made Mesa's Vulkan WSI print
/// "error: XDG_RUNTIME_DIR is invalid or not set" 2–4 times on a successful run. Pointing it at
/// the temporary folder silences that (no display is ever opened).
#[expect(
    unsafe_code,
    reason = "std::env::set_var is unsafe since edition 2024; no other thread exists yet"
)]
fn quiet_headless_vulkan() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none_or(|v| v.is_empty()) {
        // SAFETY: called first thing in `main`, before any other thread exists.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
}

fn main() -> ExitCode {
    quiet_headless_vulkan();
    handle_signals();
    let args = match cli::Cli::try_parse() {
        Ok(args) => args,
        Err(err) => {
            // clap prints help/version to stdout (exit 0).
            if !err.use_stderr() {
                err.print().ok();
                return ExitCode::SUCCESS;
            }
            if err.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                err.print().ok();
                return ExitCode::from(2);
            }
            // Usage errors on one line, like every other error: the message up to "Usage:".
            let text = err.render().to_string();
            let first = text
                .lines()
                .take_while(|l| !l.starts_with("Usage:"))
                .filter(|l| !l.starts_with("For more information"))
                .map(str::trim)
                .filter(|l| !l.is_empty())
                .collect::<Vec<_>>()
                .join(" ");
            let first = first.trim_start_matches("error: ");
            eprintln!("penumbra: error: {first} (see --help)");
            return ExitCode::from(2);
        }
    };
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            // `penumbra ephem … | head`: the reader left; not an error (ripgrep does the same).
            let broken_pipe = err.chain().any(|e| {
                e.downcast_ref::<std::io::Error>()
                    .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            });
            if broken_pipe {
                return ExitCode::SUCCESS;
            }
            eprintln!("penumbra: error: {}", penumbra::products::one_line(&err));
            ExitCode::from(2)
        }
    }
}

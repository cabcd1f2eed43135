//! Test helpers: paths to fixtures and shared data, running the binary.

#![allow(dead_code, reason = "not every test module uses every helper")]

use std::path::{Path, PathBuf};
use std::process::Output;

/// The crate root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A committed fixture under `tests/fixtures/`.
pub fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures").join(name)
}

/// The shipped kernel folder.
pub fn kernels_dir() -> PathBuf {
    root().join("kernels")
}

/// A file of the shared LOLA data, or `None` (with a printed reason) when it is absent.
pub fn shared_lola(name: &str) -> Option<PathBuf> {
    let p = root()
        .join("../shared/data/lola-south-pole-moondao")
        .join(name);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!("skipping: shared LOLA data {} is absent", p.display());
        None
    }
}

/// Runs the penumbra binary with `args` in `cwd`.
pub fn penumbra(cwd: &Path, args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .current_dir(cwd)
        .env_remove("PENUMBRA_KERNELS")
        .output()
        .expect("the penumbra binary runs")
}

/// Asserts that a run failed cleanly: exit code 2 (not a panic's 101), exactly one line on stderr
/// starting with `penumbra: error:` that contains `needle`.
pub fn assert_clean_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "exit code; stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert!(
        lines.len() == 1 || lines[0].starts_with("error:"),
        "expected one error line, got: {stderr}"
    );
    assert!(
        stderr.to_lowercase().contains(&needle.to_lowercase()),
        "stderr should mention '{needle}': {stderr}"
    );
}

/// Files left in a folder (to check that nothing half-written remains).
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

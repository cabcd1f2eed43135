//! Guards at the edge of the file system: inputs that are regular files (a FIFO or a device would
//! block or never end), sizes declared by files checked against a memory budget before anything
//! is allocated, outputs that replace only regular files and never share a path.

use std::fs::File;
use std::path::{Component, Path, PathBuf};

/// Environment variable that sets the memory budget, GiB (default: 80 % of the memory available).
pub const MEMORY_BUDGET_ENV: &str = "PENUMBRA_MEMORY_BUDGET_GB";

/// Opens an input file, refusing anything but a regular file (or a symlink to one): a FIFO with no
/// writer would block forever, `/dev/zero` would never end.
pub fn open_regular(path: &Path) -> std::io::Result<File> {
    check_regular(path)?;
    File::open(path)
}

/// Errors unless `path` is a regular file (following symlinks).
pub fn check_regular(path: &Path) -> std::io::Result<std::fs::Metadata> {
    let meta = std::fs::metadata(path)?;
    if meta.is_dir() {
        return Err(std::io::Error::other("is a folder, not a file"));
    }
    if !meta.is_file() {
        return Err(std::io::Error::other(
            "not a regular file (a FIFO, socket or device); penumbra reads only regular files",
        ));
    }
    Ok(meta)
}

/// Reads a whole text input of at most `max_bytes` (a scenario, a meta-kernel, a label).
pub fn read_small_text(path: &Path, max_bytes: u64) -> std::io::Result<String> {
    let meta = check_regular(path)?;
    if meta.len() > max_bytes {
        return Err(std::io::Error::other(format!(
            "{} bytes is too large (at most {max_bytes} B for this kind of file)",
            meta.len()
        )));
    }
    let bytes = std::fs::read(path)?;
    String::from_utf8(bytes).map_err(|_| std::io::Error::other("not UTF-8 text"))
}

/// The memory penumbra may allocate for one input, bytes: `PENUMBRA_MEMORY_BUDGET_GB`, else 80 %
/// of `MemAvailable` (Linux), else 8 GiB.
fn memory_budget_bytes() -> u64 {
    if let Some(gb) = std::env::var(MEMORY_BUDGET_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|gb| gb.is_finite() && *gb > 0.0)
    {
        return (gb * (1u64 << 30) as f64) as u64;
    }
    // Read once per process: the budget is a bound, not a live figure, and readers check it on
    // every input (the fuzz targets call them millions of times).
    static AVAILABLE_KIB: std::sync::OnceLock<Option<u64>> = std::sync::OnceLock::new();
    let available_kib = *AVAILABLE_KIB.get_or_init(|| {
        std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|text| {
                text.lines()
                    .find(|l| l.starts_with("MemAvailable:"))
                    .and_then(|l| l.split_whitespace().nth(1))
                    .and_then(|v| v.parse::<u64>().ok())
            })
    });
    match available_kib {
        Some(kib) => kib * 1024 / 10 * 8,
        None => 8 << 30,
    }
}

/// Errors when `bytes` (what an input declares it needs) exceed the memory budget.
pub fn check_budget(what: &str, bytes: u128) -> Result<(), String> {
    let budget = memory_budget_bytes();
    if bytes > u128::from(budget) {
        return Err(format!(
            "{what} needs {:.1} GiB, more than the memory budget of {:.1} GiB \
             (80 % of available memory; set {MEMORY_BUDGET_ENV} to change it)",
            bytes as f64 / (1u64 << 30) as f64,
            budget as f64 / (1u64 << 30) as f64
        ));
    }
    Ok(())
}

/// Lexically normalised absolute form of `path` (no file-system access beyond the working
/// directory): `a/./b/../c` → `<cwd>/a/c`. Symlinks of existing parents are resolved.
pub fn normalised(path: &Path) -> PathBuf {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("/"))
            .join(path)
    };
    let mut out = PathBuf::new();
    for c in absolute.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    // Resolve the existing parent (a symlinked folder names the same files).
    if let (Some(parent), Some(name)) = (out.parent(), out.file_name())
        && let Ok(real) = parent.canonicalize()
    {
        return real.join(name);
    }
    out
}

/// Checks that an output may be written at `path`: the path is not a folder, a FIFO or a device
/// (penumbra replaces only regular files; a symlink is followed to its target), and its folder
/// exists. `-` (standard output) is accepted where `stdout_ok`.
pub fn check_output_target(flag: &str, path: &Path, stdout_ok: bool) -> Result<(), String> {
    if path.as_os_str() == "-" {
        return if stdout_ok {
            Ok(())
        } else {
            Err(format!(
                "{flag} -: this output cannot go to standard output; give a file name"
            ))
        };
    }
    if path.as_os_str().is_empty() {
        return Err(format!("{flag}: the output path is empty"));
    }
    match target_problem(path) {
        Some(why) => Err(format!("{flag} {}: {why}", path.display())),
        None => Ok(()),
    }
}

/// Why a file cannot be written at `path` (a folder, a device, no such folder), if it cannot.
pub fn target_problem(path: &Path) -> Option<String> {
    if let Ok(meta) = std::fs::metadata(path) {
        if meta.is_dir() {
            return Some("is a folder".into());
        }
        if !meta.is_file() {
            return Some(
                "not a regular file (a device, FIFO or socket); penumbra replaces only regular files"
                    .into(),
            );
        }
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        return Some(format!("the folder {} does not exist", parent.display()));
    }
    None
}

/// Errors when two outputs of one command name the same file (after normalisation and symlinks
/// of existing folders).
pub fn check_distinct_outputs(outputs: &[(&str, &Path)]) -> Result<(), String> {
    for (i, (flag_a, a)) in outputs.iter().enumerate() {
        for (flag_b, b) in &outputs[i + 1..] {
            let same = if a.as_os_str() == "-" || b.as_os_str() == "-" {
                a.as_os_str() == b.as_os_str()
            } else {
                normalised(&resolve_symlink(a)) == normalised(&resolve_symlink(b))
            };
            if same {
                return Err(format!(
                    "{flag_a} and {flag_b} name the same file {}: give each output its own path",
                    a.display()
                ));
            }
        }
    }
    Ok(())
}

/// The target of `path` if it is a symlink (followed to the end), else `path`.
pub fn resolve_symlink(path: &Path) -> PathBuf {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => path.canonicalize().unwrap_or_else(|_| {
            // A dangling link: write where it points.
            std::fs::read_link(path)
                .map(|t| match path.parent() {
                    Some(p) if t.is_relative() => p.join(t),
                    _ => t,
                })
                .unwrap_or_else(|_| path.to_path_buf())
        }),
        _ => path.to_path_buf(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_files_only() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.txt");
        std::fs::write(&f, "x").unwrap();
        assert!(open_regular(&f).is_ok());
        assert!(open_regular(dir.path()).is_err());
        assert!(open_regular(Path::new("/dev/zero")).is_err());
        assert!(read_small_text(&f, 0).is_err());
        assert_eq!(read_small_text(&f, 1).unwrap(), "x");
    }

    #[test]
    fn outputs_must_differ_and_be_regular() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.tif");
        let a2 = dir.path().join("sub/../a.tif");
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let b = dir.path().join("b.tif");
        assert!(check_distinct_outputs(&[("--x", &a), ("--y", &b)]).is_ok());
        let err = check_distinct_outputs(&[("--x", &a), ("--y", &a2)]).unwrap_err();
        assert!(err.contains("--x and --y"), "{err}");
        #[cfg(unix)]
        {
            let link = dir.path().join("link.tif");
            std::os::unix::fs::symlink(&a, &link).unwrap();
            assert!(check_distinct_outputs(&[("--x", &a), ("--y", &link)]).is_err());
        }
        assert!(check_output_target("--x", &a, false).is_ok());
        assert!(check_output_target("--x", dir.path(), false).is_err());
        assert!(check_output_target("--x", Path::new("/dev/null"), false).is_err());
        assert!(check_output_target("--x", &dir.path().join("no/a.tif"), false).is_err());
        assert!(check_output_target("--x", Path::new("-"), false).is_err());
        assert!(check_output_target("--x", Path::new("-"), true).is_ok());
    }
}

//! The shipped kernel set (`kernels/`, 4.2 MB) built into the binary, so that an installed
//! penumbra (`cargo install`, a wheel, a container) runs anywhere without the source tree.
//!
//! `anise` and the meta-kernel reader work on files, so the set is written once into a cache
//! folder named after its content (`$XDG_CACHE_HOME/penumbra/kernels-<sha256 prefix>`, else
//! `~/.cache/…`, else the temp folder) and loaded from there. Files are written under temporary
//! names and renamed, so concurrent first runs (a Slurm array) never see half a file; a file of
//! the wrong size (an interrupted copy by something else) is written again.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The files of the shipped set, by name.
pub const EMBEDDED_KERNELS: &[(&str, &[u8])] = &[
    (
        "de440_moon_2000_2025.bsp",
        include_bytes!("../../kernels/de440_moon_2000_2025.bsp"),
    ),
    (
        "de440_moon_2025_2050.bsp",
        include_bytes!("../../kernels/de440_moon_2025_2050.bsp"),
    ),
    (
        "moon_pa_de421_2000_2050.bpc",
        include_bytes!("../../kernels/moon_pa_de421_2000_2050.bpc"),
    ),
    (
        "moon_080317.tf",
        include_bytes!("../../kernels/moon_080317.tf"),
    ),
    (
        "moon_assoc_me.tf",
        include_bytes!("../../kernels/moon_assoc_me.tf"),
    ),
    ("naif0012.tls", include_bytes!("../../kernels/naif0012.tls")),
];

/// The first 16 hex digits of the sha256 of every embedded file (names and contents).
pub fn embedded_set_id() -> &'static str {
    static ID: OnceLock<String> = OnceLock::new();
    ID.get_or_init(|| {
        use sha2::Digest as _;
        let mut h = sha2::Sha256::new();
        for (name, bytes) in EMBEDDED_KERNELS {
            h.update(name.as_bytes());
            h.update((bytes.len() as u64).to_le_bytes());
            h.update(bytes);
        }
        format!("{:x}", h.finalize())[..16].to_string()
    })
}

/// Where the embedded set is (or would be) written: the user's cache folder, else the temp folder.
fn cache_roots() -> Vec<PathBuf> {
    let mut roots = Vec::new();
    if let Some(x) = std::env::var_os("XDG_CACHE_HOME").filter(|x| !x.is_empty()) {
        roots.push(PathBuf::from(x).join("penumbra"));
    } else if let Some(home) = std::env::var_os("HOME").filter(|x| !x.is_empty()) {
        roots.push(PathBuf::from(home).join(".cache").join("penumbra"));
    }
    roots.push(std::env::temp_dir().join("penumbra"));
    roots
}

/// Writes the set into `dir` (the files missing or of the wrong size), atomically per file.
fn write_set(dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    for (name, bytes) in EMBEDDED_KERNELS {
        let path = dir.join(name);
        if std::fs::metadata(&path).is_ok_and(|m| m.is_file() && m.len() == bytes.len() as u64) {
            continue;
        }
        let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
        std::fs::write(&tmp, bytes)?;
        std::fs::rename(&tmp, &path).inspect_err(|_| {
            let _ = std::fs::remove_file(&tmp);
        })?;
    }
    Ok(())
}

/// The folder holding the embedded set, written on first use (see the module docs).
pub fn embedded_kernel_dir() -> Result<PathBuf, String> {
    static DIR: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    DIR.get_or_init(|| {
        let name = format!("kernels-{}", embedded_set_id());
        let mut why = Vec::new();
        for root in cache_roots() {
            let dir = root.join(&name);
            match write_set(&dir) {
                Ok(()) => return Ok(dir),
                Err(e) => why.push(format!("{}: {e}", dir.display())),
            }
        }
        Err(format!(
            "could not write the built-in kernel set ({}); give a kernel folder with --kernels or \
             $PENUMBRA_KERNELS",
            why.join("; ")
        ))
    })
    .clone()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_set_is_the_shipped_folder() {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("kernels");
        let mut names: Vec<String> = std::fs::read_dir(&shipped)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .filter(|n| n != "README.md")
            .collect();
        names.sort();
        let mut embedded: Vec<String> = EMBEDDED_KERNELS
            .iter()
            .map(|(n, _)| n.to_string())
            .collect();
        embedded.sort();
        assert_eq!(names, embedded, "kernels/ and EMBEDDED_KERNELS differ");
        let dir = embedded_kernel_dir().unwrap();
        for (name, bytes) in EMBEDDED_KERNELS {
            assert_eq!(&std::fs::read(dir.join(name)).unwrap(), bytes, "{name}");
            assert_eq!(&std::fs::read(shipped.join(name)).unwrap(), bytes, "{name}");
        }
    }
}

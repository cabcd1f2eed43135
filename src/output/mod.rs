//! Output writers: atomic file writes (temp file + rename), CSV/JSON helpers and provenance.
//!
//! Every file penumbra writes goes through [`write_atomic`], so an error or an interrupted run never
//! leaves a half-written output file behind.

use std::io::Write;
use std::path::Path;

pub mod checkpoint;

/// How much penumbra says on stderr: 0 errors and warnings only (`--quiet`), 1 also what it did
/// (the default), 2 also details (`--verbose`).
static VERBOSITY: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(1);

/// Sets the verbosity (see [`verbosity`]).
pub fn set_verbosity(level: u8) {
    VERBOSITY.store(level, std::sync::atomic::Ordering::Relaxed);
}

/// 0 errors and warnings only, 1 also what was done (default), 2 also details.
pub fn verbosity() -> u8 {
    VERBOSITY.load(std::sync::atomic::Ordering::Relaxed)
}

/// An informational line on stderr (what was done), silenced by `--quiet`.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {
        if $crate::output::verbosity() >= 1 {
            eprintln!($($arg)*);
        }
    };
}

/// A detail line on stderr, shown with `--verbose` only.
#[macro_export]
macro_rules! detail {
    ($($arg:tt)*) => {
        if $crate::output::verbosity() >= 2 {
            eprintln!($($arg)*);
        }
    };
}
pub mod cleanup;
pub mod guard;

/// Errors of the output subsystem.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// Creating, writing or renaming the output file failed.
    #[error("writing {path}: {source}")]
    Io {
        /// The file that was being written.
        path: String,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Reading an input file (to hash it for provenance) failed.
    #[error("reading {path}: {source}")]
    Read {
        /// The file that was being read.
        path: String,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// Writes a file atomically: `fill` writes into a temporary file in the same folder, which is
/// renamed onto `path` only if `fill` succeeds. On error the temporary file is removed.
///
/// Only a regular file is replaced: a folder, FIFO or device at `path` is an error (as root, a
/// rename would turn `/dev/full` into a regular file). A symlink is followed: its target is
/// replaced and the link stays. `-` writes to standard output instead.
pub fn write_atomic<E>(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<OutputError>,
{
    let io_err = |source| OutputError::Io {
        path: path.display().to_string(),
        source,
    };
    if path.as_os_str() == "-" {
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        fill(&mut out)?;
        return out.flush().map_err(|e| io_err(e).into());
    }
    let mut tmp = temp_file_beside(path).map_err(io_err)?;
    {
        let mut buf = std::io::BufWriter::new(tmp.as_file_mut());
        fill(&mut buf)?;
        buf.flush().map_err(io_err)?;
    }
    persist_temp(tmp, path).map_err(io_err)?;
    Ok(())
}

/// A temporary file (`.penumbra-*.tmp`) in the folder of `path`, removed when dropped: where an
/// output is built before [`persist_temp`] renames it into place.
pub fn temp_file_beside(path: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let path = guard::resolve_symlink(path);
    if let Some(why) = guard::target_problem(&path) {
        return Err(std::io::Error::other(why));
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".penumbra-")
        .suffix(".tmp")
        .tempfile_in(dir)?;
    cleanup::register(tmp.path());
    Ok(tmp)
}

/// Renames a finished temporary file onto `path` with the usual 0644 permissions (temporary
/// files are created private, 0600).
pub fn persist_temp(tmp: tempfile::NamedTempFile, path: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))?;
    }
    let path = guard::resolve_symlink(path);
    if let Ok(meta) = std::fs::metadata(&path)
        && !meta.is_file()
    {
        return Err(std::io::Error::other(
            "not a regular file; penumbra replaces only regular files",
        ));
    }
    let tmp_path = tmp.path().to_path_buf();
    let result = tmp.persist(&path).map_err(|e| e.error);
    cleanup::forget(&tmp_path);
    result?;
    Ok(())
}

/// Writes bytes atomically to `path`.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomic(path, |w| {
        w.write_all(bytes).map_err(|source| OutputError::Io {
            path: path.display().to_string(),
            source,
        })
    })
}

/// Decimals a statistic is written with, by the unit its JSON key ends in (`_pct` 2, `_h` 3,
/// `_fraction` 4, `_deg` 6, `_m` 3, `_km` 4, `_s` 3, `_w`/`_wh`/`_w_m2` 2); `None` for other keys.
fn decimals_for_key(key: &str) -> Option<i32> {
    const RULES: [(&str, i32); 10] = [
        ("_pct", 2),
        ("_fraction", 4),
        ("_deg", 6),
        ("_km", 4),
        ("_w_m2", 2),
        ("_wh", 2),
        ("_w", 2),
        ("_m", 3),
        ("_h", 3),
        ("_s", 3),
    ];
    RULES
        .iter()
        .find(|(suffix, _)| key.ends_with(suffix))
        .map(|&(_, d)| d)
}

/// Rounds every number of a JSON document to the precision its key's unit deserves
/// (`decimals_for_key`; members of an object without a unit of their own, such as a
/// statistic's `min`/`max`, take their parent's), so that `stats.json` says 67.81, not
/// 67.80821917808219. Integers and keys without a unit are left alone.
pub fn round_json_numbers(value: &mut serde_json::Value) {
    fn walk(v: &mut serde_json::Value, decimals: Option<i32>) {
        match v {
            serde_json::Value::Object(map) => {
                for (k, child) in map.iter_mut() {
                    walk(child, decimals_for_key(k).or(decimals));
                }
            }
            serde_json::Value::Array(items) => {
                for child in items {
                    walk(child, decimals);
                }
            }
            serde_json::Value::Number(n) => {
                if let (Some(d), Some(x)) = (decimals, n.as_f64())
                    && !n.is_i64()
                    && !n.is_u64()
                {
                    let scale = 10f64.powi(d);
                    let r = (x * scale).round() / scale;
                    if let Some(m) = serde_json::Number::from_f64(if r == 0.0 { 0.0 } else { r }) {
                        *n = m;
                    }
                }
            }
            _ => {}
        }
    }
    walk(value, None);
}

/// Lowercase hex sha256 of a file's contents.
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    use sha2::Digest as _;
    let mut hasher = sha2::Sha256::new();
    // A FIFO or `/dev/zero` would block or never end.
    let mut f = guard::open_regular(path)?;
    std::io::copy(&mut f, &mut hasher)?;
    Ok(format!("{:x}", hasher.finalize()))
}

/// The `schema` of the `run.json` records this penumbra writes: bumped when a field changes
/// meaning or goes away (new fields keep the number).
pub const RUN_SCHEMA: &str = "penumbra-run/1";

/// Provenance of a run, written as `run.json` next to its outputs: what made the files, from what.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Provenance {
    /// The record's schema and version ([`RUN_SCHEMA`]).
    pub schema: &'static str,
    /// penumbra's version.
    pub penumbra_version: &'static str,
    /// The git commit the binary was built from, or `unknown`.
    pub git_commit: &'static str,
    /// The command line.
    pub command_line: Vec<String>,
    /// The scenario file, when the run came from one.
    pub scenario_file: Option<String>,
    /// The scenario as parsed, when the run came from one.
    pub scenario: Option<serde_json::Value>,
    /// Kernel files with sizes and sha256.
    pub kernels: Vec<crate::ephem::kernels::KernelFile>,
    /// DEM layers used (paths, or a description of the synthetic DEM).
    pub dem_layers: Vec<String>,
    /// The DEM files read, with sizes and sha256 (none for the synthetic DEM).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub dem_files: Vec<InputFile>,
    /// First epoch, UTC.
    pub epoch_start_utc: String,
    /// Last epoch, UTC.
    pub epoch_stop_utc: String,
    /// Number of epochs.
    pub epoch_count: usize,
    /// Compute backend.
    pub backend: String,
    /// Engine of a per-site series (`horizon` or `smap-dp`), when the run made one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub series_engine: Option<String>,
    /// Backend of the per-site series' terrain part (`cpu: …` / `gpu: … on <adapter>`), when
    /// a series ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub series_backend: Option<String>,
    /// The ground stations of the link to Earth (name, geodetic position, mask, source), when
    /// the run has any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ground_stations: Option<serde_json::Value>,
    /// Files written, relative to the output folder.
    pub outputs: Vec<String>,
    /// Map products: lit cells (or cell-epochs of a sweep) whose ray toward the Sun leaves the
    /// outermost DEM layer below the reference sphere or meets it further on, where the real
    /// Moon would block it (the DEM is too small for those cells: add a far-field layer), when
    /// counted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map_rays_blocked_beyond_dem: Option<BelowSphereExits>,
    /// How the maps were made (observer height, engine, limb darkening, span, layers, kernels),
    /// as their GeoTIFF tags and PNG subtitles say it (map products only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map_made_with: Option<MadeWith>,
    /// Wall time of the run, seconds.
    pub wall_time_s: f64,
}

/// How a map was made, so that a copied GeoTIFF or PNG still says it: the observer's height,
/// the engine, the limb darkening, the epochs, the DEM layers and the kernels (each with the
/// start of its sha256). Written into every statistics GeoTIFF's tags, every preview's subtitle
/// and the map's `run.json` (`map_made_with`).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MadeWith {
    /// Observer height above the ground, metres.
    pub observer_height_m: f64,
    /// The engine that computed the maps (`horizons`, `combined`, …).
    pub engine: String,
    /// The Sun's limb darkening in the mean fraction.
    pub limb_darkening: String,
    /// The epochs: `first .. last, N epochs`.
    pub span_utc: String,
    /// Each DEM layer: its file name and `sha256:` + 12 hex digits, or the synthetic DEM's
    /// description.
    pub layers: Vec<String>,
    /// Each kernel: its file name and `sha256:` + 12 hex digits.
    pub kernels: Vec<String>,
}

impl MadeWith {
    /// From a run's provenance (layers, kernels) and the map's own settings.
    pub fn new(
        prov: &Provenance,
        observer_height_m: f64,
        engine: &str,
        limb_darkening: &str,
        span_utc: &str,
    ) -> Self {
        let file_name = |p: &str| {
            Path::new(p)
                .file_name()
                .map_or_else(|| p.to_string(), |n| n.to_string_lossy().into_owned())
        };
        let short = |sha: &str| sha.chars().take(12).collect::<String>();
        let layers = if prov.dem_files.is_empty() {
            prov.dem_layers.clone()
        } else {
            prov.dem_files
                .iter()
                .map(|f| format!("{} (sha256:{})", file_name(&f.path), short(&f.sha256)))
                .collect()
        };
        let kernels = prov
            .kernels
            .iter()
            .map(|k| {
                format!(
                    "{} (sha256:{})",
                    file_name(&k.path.display().to_string()),
                    short(&k.sha256)
                )
            })
            .collect();
        MadeWith {
            observer_height_m,
            engine: engine.to_string(),
            limb_darkening: limb_darkening.to_string(),
            span_utc: span_utc.to_string(),
            layers,
            kernels,
        }
    }

    /// The GeoTIFF metadata items.
    pub fn items(&self) -> Vec<(String, String)> {
        vec![
            (
                "observer_height_m".into(),
                format!("{}", self.observer_height_m),
            ),
            ("engine".into(), self.engine.clone()),
            ("limb_darkening".into(), self.limb_darkening.clone()),
            ("dem_layers".into(), self.layers.join("; ")),
            ("kernels".into(), self.kernels.join("; ")),
        ]
    }

    /// The preview's second line: epochs, height, engine, limb darkening.
    pub fn subtitle(&self) -> String {
        format!(
            "{}; observer {} m above ground; {} engine; {} limb darkening",
            self.span_utc, self.observer_height_m, self.engine, self.limb_darkening
        )
    }

    /// The preview's third and fourth lines (split at ` — `): layers and kernels, by file name.
    pub fn sources(&self) -> String {
        let names = |v: &[String]| {
            v.iter()
                .map(|s| s.split(" (sha256").next().unwrap_or(s).to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "DEM: {} — kernels: {}",
            names(&self.layers),
            names(&self.kernels)
        )
    }
}

/// An input file of a run (a DEM layer), identified like the kernels: path, size, sha256.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct InputFile {
    /// Path as given.
    pub path: String,
    /// Size in bytes.
    pub size_bytes: u64,
    /// Lowercase hex sha256 of the contents.
    pub sha256: String,
}

impl InputFile {
    /// Reads `path` and hashes it.
    pub fn of(path: &Path) -> Result<Self, OutputError> {
        let io = |source| OutputError::Read {
            path: path.display().to_string(),
            source,
        };
        Ok(InputFile {
            path: path.display().to_string(),
            size_bytes: std::fs::metadata(path).map_err(io)?.len(),
            sha256: sha256_file(path).map_err(io)?,
        })
    }
}

/// How many map results rest on a ray that left the DEM below the reference sphere.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BelowSphereExits {
    /// Output cells with at least one such lit result.
    pub cells: u64,
    /// Lit (cell, epoch) results resting on such a ray (one epoch for a one-light map).
    pub cell_epochs: u64,
    /// Output cells with data.
    pub cells_total: u64,
}

impl BelowSphereExits {
    /// Prints the one-line warning on stderr when any cell rests on such a ray.
    pub fn warn(&self) {
        if self.cells > 0 {
            eprintln!(
                "penumbra: warning: {} of {} map cells ({} cell-epochs) are lit by rays that leave \
                 the DEM toward the reference sphere, where the real Moon would block them; \
                 add a far-field layer (--dem) that covers their horizon",
                self.cells, self.cells_total, self.cell_epochs
            );
        }
    }
}

impl Provenance {
    /// A provenance record with the tool's identity and command line filled in.
    pub fn new() -> Self {
        Provenance {
            schema: RUN_SCHEMA,
            penumbra_version: env!("CARGO_PKG_VERSION"),
            git_commit: env!("PENUMBRA_GIT_COMMIT"),
            command_line: std::env::args().collect(),
            scenario_file: None,
            scenario: None,
            kernels: Vec::new(),
            dem_layers: Vec::new(),
            dem_files: Vec::new(),
            epoch_start_utc: String::new(),
            epoch_stop_utc: String::new(),
            epoch_count: 0,
            backend: "cpu".into(),
            series_engine: None,
            series_backend: None,
            ground_stations: None,
            outputs: Vec::new(),
            map_rays_blocked_beyond_dem: None,
            map_made_with: None,
            wall_time_s: 0.0,
        }
    }

    /// Records the epoch range (first, last, count; UTC).
    pub fn set_epochs(&mut self, epochs: &[hifitime::Epoch]) {
        use crate::ephem::time::format_iso;
        if let (Some(first), Some(last)) = (epochs.first(), epochs.last()) {
            self.epoch_start_utc = format_iso(*first);
            self.epoch_stop_utc = format_iso(*last);
        }
        self.epoch_count = epochs.len();
    }

    /// Writes the record as pretty JSON to `path`, atomically.
    pub fn write(&self, path: &Path) -> Result<(), OutputError> {
        let mut bytes = serde_json::to_vec_pretty(self).map_err(|e| OutputError::Io {
            path: path.display().to_string(),
            source: std::io::Error::other(e),
        })?;
        bytes.push(b'\n');
        write_bytes_atomic(path, &bytes)
    }
}

impl Default for Provenance {
    fn default() -> Self {
        Self::new()
    }
}

/// A progress bar of `len` steps with `template` (indicatif syntax; drawn on stderr when it is a
/// terminal).
pub fn progress_bar(len: usize, template: &str) -> indicatif::ProgressBar {
    let progress = indicatif::ProgressBar::new(len as u64);
    if verbosity() == 0 {
        progress.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    progress.set_style(
        indicatif::ProgressStyle::with_template(template)
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    progress
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_whole_files_and_leaves_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_bytes_atomic(&path, b"first").unwrap();
        write_bytes_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        // A failing writer leaves the old file untouched and no temporary file behind.
        let err = write_atomic(&path, |w| {
            w.write_all(b"half").ok();
            Err(OutputError::Io {
                path: "x".into(),
                source: std::io::Error::other("boom"),
            })
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(
                mode, 0o644,
                "outputs are world-readable like any written file"
            );
        }
    }
}

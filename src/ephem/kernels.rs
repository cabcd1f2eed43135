//! The SPICE kernel set: finding it, loading it into an `anise` [`Almanac`], and describing it.
//!
//! A kernel folder holds SPK (`.bsp`) ephemerides, binary PCK (`.bpc`) Moon orientation, text frame
//! kernels (`.tf`, converted by `anise` into Euler parameters at load time) and a leap-seconds kernel
//! (`.tls`; penumbra uses hifitime's built-in table, which equals `naif0012.tls`, and checks that
//! the folder's file agrees with it).
//!
//! A SPICE meta-kernel (`.tm`) may stand in for the folder: its `KERNELS_TO_LOAD` files are
//! loaded in order (see [`super::metakernel`]).
//!
//! Where the folder comes from, first match wins: `--kernels DIR` (or a scenario's `kernels`),
//! the `PENUMBRA_KERNELS` environment variable, then the shipped set built into the binary
//! ([`super::embedded`]). `penumbra kernels` prints which one was used.

use std::path::{Path, PathBuf};

use anise::prelude::{Almanac, BPC, Epoch, Frame, SPK};

use super::EphemError;

/// NAIF id of the solar-system barycentre.
pub const SSB_ID: i32 = 0;
/// NAIF id of the Sun.
pub const SUN_ID: i32 = 10;
/// NAIF id of the Earth-Moon barycentre.
pub const EMB_ID: i32 = 3;
/// NAIF id of the Earth.
pub const EARTH_ID: i32 = 399;
/// NAIF id of the Moon.
pub const MOON_ID: i32 = 301;
/// NAIF id of the J2000 inertial frame.
pub const J2000_ID: i32 = 1;
/// Frame id of `MOON_PA_DE421`, the frame of the DE421 Moon orientation BPC.
pub const MOON_PA_DE421_ID: i32 = 31006;
/// Frame id of `MOON_ME_DE421` (`moon_080317.tf`): the `MOON_ME` of the DE421 set.
pub const MOON_ME_DE421_ID: i32 = 31007;
/// Frame id of `MOON_PA_DE440`, the frame of the DE440 Moon orientation BPC
/// (`moon_pa_de440_200625.bpc`).
pub const MOON_PA_DE440_ID: i32 = 31008;
/// Frame id of `MOON_ME_DE440_ME421` (`moon_de440_220930.tf`): the `MOON_ME` of the DE440 set.
pub const MOON_ME_DE440_ID: i32 = 31009;

/// The Moon-centred J2000 frame.
pub const MOON_J2000: Frame = Frame::new(MOON_ID, J2000_ID);

/// A lunar mean-Earth/polar-axis frame pair: the principal-axes frame held by a binary PCK and the
/// mean-Earth frame a text frame kernel defines relative to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct LunarFrames {
    /// NAIF name of the principal-axes frame (`MOON_PA_DE440`).
    pub pa_name: &'static str,
    /// Its frame id (the BPC's frame class id).
    pub pa_id: i32,
    /// NAIF name of the mean-Earth frame (`MOON_ME_DE440_ME421`).
    pub me_name: &'static str,
    /// Its frame id (a TK frame of the frame kernel).
    pub me_id: i32,
}

impl LunarFrames {
    /// The Moon-centred `MOON_ME` frame of this pair.
    pub fn moon_me(&self) -> Frame {
        Frame::new(MOON_ID, self.me_id)
    }
}

/// The lunar frame pairs penumbra knows, most recent first: when a set holds both, `MOON_ME` is
/// the DE440 one. (SPICE's generic aliases `MOON_PA`/`MOON_ME` are 31000/31001 in the DE421 kernel
/// and 31010/31011 in the DE440 one; penumbra names the realisation it uses instead.)
pub const LUNAR_FRAMES: [LunarFrames; 2] = [
    LunarFrames {
        pa_name: "MOON_PA_DE440",
        pa_id: MOON_PA_DE440_ID,
        me_name: "MOON_ME_DE440_ME421",
        me_id: MOON_ME_DE440_ID,
    },
    LunarFrames {
        pa_name: "MOON_PA_DE421",
        pa_id: MOON_PA_DE421_ID,
        me_name: "MOON_ME_DE421",
        me_id: MOON_ME_DE421_ID,
    },
];

/// Seconds before the first usable epoch that the ephemeris must cover: light-time correction
/// looks the Sun up about 500 s earlier, plus margin.
pub const LIGHT_TIME_MARGIN_S: f64 = 600.0;

/// One file of the kernel set.
#[derive(Debug, Clone, serde::Serialize)]
pub struct KernelFile {
    /// Path as loaded.
    pub path: PathBuf,
    /// Kind: `spk`, `bpc`, `fk` or `lsk`.
    pub kind: &'static str,
    /// Size in bytes.
    pub size_bytes: u64,
    /// Lowercase hex sha256 of the contents.
    pub sha256: String,
}

/// A loaded kernel set.
pub struct Kernels {
    /// The anise almanac holding the SPKs, BPCs and frame parameters.
    pub almanac: Almanac,
    /// The folder the kernels came from (a meta-kernel's folder for a meta-kernel).
    pub dir: PathBuf,
    /// The meta-kernel that listed the files, if the set came from one.
    pub meta_kernel: Option<PathBuf>,
    /// The files that were loaded.
    pub files: Vec<KernelFile>,
    /// Files of the set that penumbra does not use (text PCKs, DSKs, name-only frame kernels...).
    pub skipped: Vec<SkippedKernel>,
    /// First and last epoch at which the Sun, the Earth, the Moon and the `MOON_ME` frame are all
    /// available (light-time margin included).
    pub coverage: (Epoch, Epoch),
    /// The lunar frames in use: `MOON_ME` is `frames.moon_me()`.
    pub frames: LunarFrames,
}

impl Kernels {
    /// The Moon-centred `MOON_ME` frame of this set.
    pub fn moon_me(&self) -> Frame {
        self.frames.moon_me()
    }
}

/// Where the default kernels are: the `PENUMBRA_KERNELS` folder (or meta-kernel), else the set
/// built into penumbra ([`super::embedded`]). A `./kernels` folder in the working directory is
/// not looked at: give it with `--kernels kernels`.
pub fn default_kernel_dir() -> PathBuf {
    default_kernel_source().0
}

/// The default kernels and where they come from, in words (for `penumbra kernels`).
pub fn default_kernel_source() -> (PathBuf, String) {
    if let Some(dir) = std::env::var_os("PENUMBRA_KERNELS").filter(|d| !d.is_empty()) {
        let dir = PathBuf::from(dir);
        let what = format!("$PENUMBRA_KERNELS = {}", dir.display());
        return (dir, what);
    }
    match super::embedded::embedded_kernel_dir() {
        Ok(dir) => {
            let what = format!(
                "the set built into penumbra {} (id {}, written to {})",
                env!("CARGO_PKG_VERSION"),
                super::embedded::embedded_set_id(),
                dir.display()
            );
            (dir, what)
        }
        Err(why) => {
            // The source tree's copy, if this binary was built here; else loading says it is absent.
            eprintln!("penumbra: warning: {why}");
            let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/kernels"));
            let what = format!("the source tree's kernels/ ({})", dir.display());
            (dir, what)
        }
    }
}

fn load_failed(path: &Path, why: impl std::fmt::Display) -> EphemError {
    EphemError::Kernel {
        path: path.display().to_string(),
        why: why.to_string().replace('\n', " "),
    }
}

/// Runs an anise parser, turning a panic on a corrupt file into an error.
fn guarded<T>(path: &Path, f: impl FnOnce() -> Result<T, String>) -> Result<T, EphemError> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(why)) => Err(load_failed(path, why)),
        Err(_) => Err(load_failed(path, "the file is corrupt (the parser failed)")),
    }
}

impl Kernels {
    /// Loads a kernel set: every kernel in a folder, or the files a SPICE meta-kernel (`.tm`, see
    /// [`super::metakernel`]) lists, in its order. Checks that the set covers the Sun, the Earth,
    /// the Moon and `MOON_ME`.
    pub fn load(source: &Path) -> Result<Self, EphemError> {
        let meta = std::fs::metadata(source).map_err(|e| EphemError::KernelDir {
            path: source.display().to_string(),
            why: e.to_string(),
        })?;
        if meta.is_file() {
            return Self::load_meta_kernel(source, meta.len());
        }
        if !meta.is_dir() {
            return Err(EphemError::KernelDir {
                path: source.display().to_string(),
                why: "neither a folder nor a meta-kernel file".into(),
            });
        }
        let dir = source;
        let entries = std::fs::read_dir(dir).map_err(|e| EphemError::KernelDir {
            path: dir.display().to_string(),
            why: e.to_string(),
        })?;
        let mut paths: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file())
            .collect();
        paths.sort();
        let (almanac, files, skipped, fk_ids) = load_files(&paths, false)?;
        if files.is_empty() {
            return Err(EphemError::KernelDir {
                path: dir.display().to_string(),
                why: "no kernel files (.bsp, .bpc, .tf, .tls) found".into(),
            });
        }
        let (frames, coverage) = coverage(&almanac, &fk_ids, dir)?;
        Ok(Kernels {
            almanac,
            dir: dir.to_path_buf(),
            meta_kernel: None,
            files,
            skipped,
            coverage,
            frames,
        })
    }

    fn load_meta_kernel(path: &Path, size_bytes: u64) -> Result<Self, EphemError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        if matches!(ext.as_str(), "bsp" | "bpc" | "tf" | "tls" | "tpc" | "bds") {
            return Err(load_failed(
                path,
                "is one kernel, not a set: pass its folder or a meta-kernel (.tm) listing the set",
            ));
        }
        if size_bytes > super::metakernel::MAX_META_KERNEL_BYTES {
            return Err(load_failed(
                path,
                format!(
                    "{size_bytes} bytes is too large for a meta-kernel (at most {} B); pass a kernel folder instead",
                    super::metakernel::MAX_META_KERNEL_BYTES
                ),
            ));
        }
        let bytes = std::fs::read(path).map_err(|e| load_failed(path, e))?;
        let text = String::from_utf8(bytes).map_err(|_| {
            load_failed(
                path,
                "not a text file (a meta-kernel is text; pass a kernel folder or a .tm file)",
            )
        })?;
        let names =
            super::metakernel::kernels_to_load(&text).map_err(|why| load_failed(path, why))?;
        let mut paths = Vec::with_capacity(names.len());
        for name in names {
            let resolved = super::metakernel::resolve(&name, path);
            if !resolved.is_file() {
                return Err(load_failed(
                    path,
                    format!(
                        "lists '{name}', which is not a file (relative names are tried against the working directory, then the meta-kernel's folder)"
                    ),
                ));
            }
            paths.push(resolved);
        }
        let (almanac, files, skipped, fk_ids) = load_files(&paths, true)?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let (frames, coverage) = coverage(&almanac, &fk_ids, path)?;
        Ok(Kernels {
            almanac,
            dir,
            meta_kernel: Some(path.to_path_buf()),
            files,
            skipped,
            coverage,
            frames,
        })
    }

    /// Where the set came from, for reports: the meta-kernel or the folder.
    pub fn source(&self) -> &Path {
        self.meta_kernel.as_deref().unwrap_or(&self.dir)
    }
    /// Errors unless `epoch` lies within the kernels' coverage.
    pub fn check_epoch(&self, epoch: Epoch) -> Result<(), EphemError> {
        if epoch < self.coverage.0 || epoch > self.coverage.1 {
            return Err(EphemError::OutsideCoverage {
                epoch: super::time::format_utc(epoch),
                start: super::time::format_utc(self.coverage.0),
                stop: super::time::format_utc(self.coverage.1),
            });
        }
        Ok(())
    }
}

/// A file of the set that was not loaded, and why.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SkippedKernel {
    /// The file.
    pub path: PathBuf,
    /// Why penumbra does not use it.
    pub why: String,
}

/// Loads `paths` in order into one almanac. Files with other extensions are ignored in a folder
/// and reported as skipped when a meta-kernel lists them (`listed`).
/// The loaded almanac, the files, the skipped files and the frame ids the frame kernels define.
type Loaded = (Almanac, Vec<KernelFile>, Vec<SkippedKernel>, Vec<i32>);

fn load_files(paths: &[PathBuf], listed: bool) -> Result<Loaded, EphemError> {
    let mut skipped = Vec::new();
    let mut almanac = Almanac::default();
    let mut files = Vec::new();
    // Every frame kernel's text, in load order: they are converted together, so that a frame
    // may be defined relative to one in another kernel, and a later definition of an id wins
    // (as in SPICE's kernel pool).
    let mut fk_text: Vec<u8> = Vec::new();
    let mut fk_paths: Vec<PathBuf> = Vec::new();
    for path in paths {
        let path = path.clone();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let kind = match ext.as_str() {
            "bsp" => "spk",
            "bpc" => "bpc",
            "tf" => "fk",
            "tls" => "lsk",
            _ if listed => {
                skipped.push(SkippedKernel {
                    path: path.clone(),
                    why: "penumbra reads only .bsp, .bpc, .tf and .tls kernels".into(),
                });
                continue;
            }
            _ => continue,
        };
        let bytes = std::fs::read(&path).map_err(|e| load_failed(&path, e))?;
        match kind {
            "spk" => {
                let spk = guarded(&path, || SPK::parse(&bytes[..]).map_err(|e| e.to_string()))?;
                almanac = almanac.with_spk(spk);
            }
            "bpc" => {
                let bpc = guarded(&path, || BPC::parse(&bytes[..]).map_err(|e| e.to_string()))?;
                almanac = almanac.with_bpc(bpc);
            }
            "fk" => {
                let text = String::from_utf8_lossy(&bytes);
                // moon_assoc_*.tf only associate names with frames: nothing to convert.
                if !text.contains("TKFRAME_") {
                    skipped.push(SkippedKernel {
                        path: path.clone(),
                        why: "a frame kernel without TKFRAME definitions (name associations only)"
                            .into(),
                    });
                    continue;
                }
                // Each kernel starts in a comment block, whatever mode the previous one ended in.
                fk_text.extend_from_slice(b"\n\\begintext\n");
                fk_text.extend_from_slice(&bytes);
                fk_paths.push(path.clone());
            }
            _ => check_leap_seconds(&path, &bytes)?,
        }
        files.push(KernelFile {
            size_bytes: bytes.len() as u64,
            sha256: sha256_hex(&bytes),
            path,
            kind,
        });
    }
    let mut fk_ids = Vec::new();
    if let Some(last) = fk_paths.last() {
        let label = if fk_paths.len() == 1 {
            last.clone()
        } else {
            let names: Vec<String> = fk_paths.iter().map(|p| p.display().to_string()).collect();
            PathBuf::from(names.join(" + "))
        };
        let ep = frame_parameters(&label, &fk_text)?;
        fk_ids = ep.lut.by_id.keys().copied().collect();
        almanac = almanac.with_euler_parameters_as(ep, Some("frame kernels".into()));
    }
    Ok((almanac, files, skipped, fk_ids))
}

/// Converts the text of one or more frame kernels (`label` names them in errors) into `anise`
/// Euler parameters; a panic of the parser on a corrupt file is an error.
pub fn frame_parameters(
    label: &Path,
    text: &[u8],
) -> Result<anise::structure::EulerParameterDataSet, EphemError> {
    use anise::naif::kpl::{fk::FKItem, parser};
    guarded(label, || {
        let items =
            parser::parse_bytes::<_, FKItem>(&mut &text[..], false).map_err(|e| e.to_string())?;
        parser::convert_fk_items(items).map_err(|e| e.to_string())
    })
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest as _;
    format!("{:x}", sha2::Sha256::digest(bytes))
}

/// The lunar frames of the set ([`LUNAR_FRAMES`]: the first whose principal-axes frame a BPC
/// holds and whose mean-Earth frame the frame kernels define), and the intersection of the SPK
/// domains of the bodies penumbra needs and of that BPC's domain, shrunk by the light-time margin
/// at the start.
fn coverage(
    almanac: &Almanac,
    fk_ids: &[i32],
    dir: &Path,
) -> Result<(LunarFrames, (Epoch, Epoch)), EphemError> {
    let missing = |what: String| EphemError::KernelDir {
        path: dir.display().to_string(),
        why: what,
    };
    let mut start = Epoch::from_tdb_seconds(f64::MIN / 4.0);
    let mut stop = Epoch::from_tdb_seconds(f64::MAX / 4.0);
    for (id, name) in [
        (SUN_ID, "the Sun (10)"),
        (EMB_ID, "the Earth-Moon barycentre (3)"),
        (EARTH_ID, "the Earth (399)"),
        (MOON_ID, "the Moon (301)"),
    ] {
        let (s, e) = almanac
            .spk_domain(id)
            .map_err(|_| missing(format!("no SPK holds {name}")))?;
        start = start.max(s);
        stop = stop.min(e);
    }
    let in_bpc: Vec<&LunarFrames> = LUNAR_FRAMES
        .iter()
        .filter(|f| almanac.bpc_domain(f.pa_id).is_ok())
        .collect();
    let Some(frames) = in_bpc.iter().find(|f| fk_ids.contains(&f.me_id)).copied() else {
        return Err(missing(match in_bpc.first() {
            None => "no binary PCK holds the Moon orientation (MOON_PA_DE440 31008 or MOON_PA_DE421 31006)".into(),
            Some(f) => format!(
                "the binary PCK holds {} ({}) but no frame kernel defines {} ({}): add {}",
                f.pa_name,
                f.pa_id,
                f.me_name,
                f.me_id,
                if f.pa_id == MOON_PA_DE440_ID { "moon_de440_220930.tf" } else { "moon_080317.tf" }
            ),
        }));
    };
    let (s, e) = almanac
        .bpc_domain(frames.pa_id)
        .map_err(|e| missing(e.to_string()))?;
    start = start.max(s);
    stop = stop.min(e);
    // MOON_ME must resolve through the frame kernels' chain.
    almanac
        .rotate(
            MOON_J2000,
            frames.moon_me(),
            start + hifitime::Unit::Day * 1,
        )
        .map_err(|e| {
            missing(format!(
                "{} ({}) does not resolve: {e}",
                frames.me_name, frames.me_id
            ))
        })?;
    start += hifitime::Unit::Second * LIGHT_TIME_MARGIN_S;
    if stop <= start {
        return Err(missing("the kernels' time spans do not overlap".into()));
    }
    Ok((*frames, (start, stop)))
}

/// Checks a leap-seconds kernel against hifitime's built-in table: the number of `DELTA_AT`
/// entries and the last offset must match (naif0012: 28 entries, last 37 s on 2017-01-01).
pub fn check_leap_seconds(path: &Path, bytes: &[u8]) -> Result<(), EphemError> {
    let text = String::from_utf8_lossy(bytes);
    let Some(start) = text.find("DELTET/DELTA_AT") else {
        return Err(load_failed(
            path,
            "not a leap-seconds kernel (no DELTET/DELTA_AT)",
        ));
    };
    let body = &text[start..];
    let body = &body[..body.find(')').unwrap_or(body.len())];
    let offsets: Vec<f64> = body
        .split(|c: char| c.is_whitespace() || c == ',' || c == '(')
        .filter_map(|t| t.parse::<f64>().ok())
        .collect();
    let builtin_last_s = 37.0;
    match offsets.last() {
        Some(&last) if (last - builtin_last_s).abs() < 1e-9 => Ok(()),
        Some(&last) => Err(load_failed(
            path,
            format!(
                "its last leap-second offset is {last} s but penumbra's table ends at {builtin_last_s} s (naif0012)"
            ),
        )),
        None => Err(load_failed(path, "no DELTA_AT values could be read")),
    }
}

//! Mutation fuzzing of every file reader, in a test binary of its own (`cargo test --release
//! --test fuzz`): GeoTIFF DEMs (float32 strips, int16 Deflate tiles, uint16 LZW strips), PDS3
//! (attached and detached labels) and PDS4 DEMs, Fourier horizon-map TIFFs, horizon-sweep
//! BigTIFFs, scenario TOML, site CSV and GeoJSON, SPICE text kernels (leap seconds, frames,
//! meta-kernels), the binary SPK and PCK kernels (anise's DAF readers behind penumbra's loader,
//! then a Sun/Earth query), shard partials (`shard.json`, `shard.pnbstat`, the latter also behind
//! a manifest rewritten with its hash) and the resume journal.
//!
//! Harness: proptest generates mutations of the seeds (`tests/fixtures/fuzz/`, the shipped
//! kernels, and seeds made at run time by penumbra itself: a shard partial, a journal): bit flips,
//! byte sets, 16/32/64-bit little- and big-endian overwrites with boundary values (0, 1, 2³¹−1,
//! 2³²−1, the file length, ...), truncations, insertions and duplicated spans; for the large
//! binary kernels every second mutation lands in the first 16 KiB (DAF header and summaries).
//! **Every seed must be accepted unmutated** (a reader that refused everything would otherwise
//! pass); then each input goes through the reader inside `catch_unwind`. A reader may refuse an
//! input but must not panic, abort or hang (the process would die or time out). A failing input
//! is saved to `target/tmp/fuzz-failures/<target>-<n>.bin`. The panic hook is silent only on a
//! thread while it runs a reader, and only in this process.
//!
//! This is blind fuzzing, run in CI. The coverage-guided run (cargo-fuzz/libFuzzer over the same
//! readers) is `tools/fuzz-coverage.sh`; see docs/VALIDATION.md.
//!
//! Length: `PENUMBRA_FUZZ_SECONDS` per target (default 8 s) and at most `PENUMBRA_FUZZ_CASES`
//! inputs (default unbounded).

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::strategy::ValueTree as _;
use proptest::test_runner::{Config, TestRunner};

/// The repository's root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A file of `tests/fixtures/`.
fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures").join(name)
}

/// The shipped kernel folder.
fn kernels_dir() -> PathBuf {
    root().join("kernels")
}

/// One mutation of a seed file.
#[derive(Debug, Clone)]
enum Mutation {
    FlipBit(usize, u8),
    SetByte(usize, u8),
    Word(usize, u64, u8, bool),
    Truncate(usize),
    Insert(usize, Vec<u8>),
    Duplicate(usize, usize, usize),
}

impl Mutation {
    /// Moves the mutation's offset into the first `bytes` of the input.
    fn confine(&mut self, bytes: usize) {
        match self {
            Mutation::FlipBit(o, _)
            | Mutation::SetByte(o, _)
            | Mutation::Word(o, ..)
            | Mutation::Insert(o, _)
            | Mutation::Duplicate(_, o, _) => *o %= bytes,
            Mutation::Truncate(_) => {}
        }
    }
}

const INTERESTING: [u64; 12] = [
    0,
    1,
    2,
    7,
    255,
    65_535,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    0x1_0000_0000,
    u64::MAX,
    16_384,
];

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 0u8..8).prop_map(|(o, b)| Mutation::FlipBit(o, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(o, v)| Mutation::SetByte(o, v)),
        (
            any::<usize>(),
            prop_oneof![prop::sample::select(&INTERESTING[..]), any::<u64>()],
            prop::sample::select(&[2u8, 4, 8][..]),
            any::<bool>()
        )
            .prop_map(|(o, v, w, be)| Mutation::Word(o, v, w, be)),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(o, b)| Mutation::Insert(o, b)),
        (any::<usize>(), any::<usize>(), 1usize..256)
            .prop_map(|(a, b, n)| Mutation::Duplicate(a, b, n)),
    ]
}

fn apply(seed: &[u8], mutations: &[Mutation]) -> Vec<u8> {
    let mut b = seed.to_vec();
    for m in mutations {
        if b.is_empty() {
            break;
        }
        let at = |o: usize, len: usize| o % len;
        match m {
            Mutation::FlipBit(o, bit) => {
                let i = at(*o, b.len());
                b[i] ^= 1 << bit;
            }
            Mutation::SetByte(o, v) => {
                let i = at(*o, b.len());
                b[i] = *v;
            }
            Mutation::Word(o, v, width, be) => {
                let w = usize::from(*width);
                if b.len() >= w {
                    let i = at(*o, b.len() - w + 1);
                    let v = if *v == 16_384 { b.len() as u64 } else { *v };
                    let bytes = if *be {
                        v.to_be_bytes()
                    } else {
                        v.to_le_bytes()
                    };
                    let src = if *be { &bytes[8 - w..] } else { &bytes[..w] };
                    b[i..i + w].copy_from_slice(src);
                }
            }
            Mutation::Truncate(o) => b.truncate(at(*o, b.len())),
            Mutation::Insert(o, bytes) => {
                let i = at(*o, b.len() + 1);
                b.splice(i..i, bytes.iter().copied());
            }
            Mutation::Duplicate(a, d, n) => {
                let s = at(*a, b.len());
                let n = (*n).min(b.len() - s);
                let span = b[s..s + n].to_vec();
                let i = at(*d, b.len() + 1);
                b.splice(i..i, span);
            }
        }
    }
    b
}

thread_local! {
    /// Set while this thread runs a reader on an input: its panics are expected findings, reported
    /// with the saved input, so the panic hook keeps quiet about them.
    static IN_READER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Installs, once for this process, a panic hook that is silent inside a reader and the default
/// hook everywhere else (a failing assertion of the harness still prints its message). This
/// binary holds the fuzz targets only, so no other test shares the hook.
fn quiet_inside_readers() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !IN_READER.with(std::cell::Cell::get) {
                default(info);
            }
        }));
    });
}

/// Runs `reader` on one input: `Ok(accepted)`, or `Err` when it panicked.
fn run_reader(reader: &impl Fn(&[u8]) -> bool, input: &[u8]) -> Result<bool, ()> {
    IN_READER.with(|f| f.set(true));
    let r = std::panic::catch_unwind(AssertUnwindSafe(|| reader(input)));
    IN_READER.with(|f| f.set(false));
    r.map_err(|_| ())
}

/// How a target mutates its seeds.
#[derive(Debug, Clone, Copy)]
struct Plan {
    /// Where present, every second mutation lands in the first `hot_bytes` of the file (the
    /// header and directory of a large binary seed, where a mutation changes structure rather
    /// than one coefficient).
    hot_bytes: Option<usize>,
}

const PLAIN: Plan = Plan { hot_bytes: None };

/// Runs `reader` on mutations of `seeds` for the configured time; returns the number of inputs.
///
/// `reader` returns whether it accepted the input. Every unmutated seed must be accepted first:
/// a reader that refused everything would otherwise pass any number of mutated inputs.
fn fuzz(target: &str, seeds: &[Vec<u8>], plan: Plan, reader: impl Fn(&[u8]) -> bool) -> usize {
    let seconds: f64 = std::env::var("PENUMBRA_FUZZ_SECONDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(8.0);
    let max_cases: usize = std::env::var("PENUMBRA_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(usize::MAX);
    quiet_inside_readers();
    for (i, seed) in seeds.iter().enumerate() {
        match run_reader(&reader, seed) {
            Ok(true) => {}
            Ok(false) => panic!(
                "{target}: seed {i} ({} bytes) is refused before any mutation: the target \
                 would test nothing",
                seed.len()
            ),
            Err(()) => panic!("{target}: seed {i} makes the reader panic before any mutation"),
        }
    }
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let strategy = (0..seeds.len(), prop::collection::vec(mutation(), 1..6));
    let mut runner = TestRunner::new(Config::default());
    let (mut n, mut accepted) = (0usize, 0usize);
    let mut failures = Vec::new();
    while Instant::now() < deadline && n < max_cases {
        let (seed, mut mutations) = strategy.new_tree(&mut runner).unwrap().current();
        if let Some(hot) = plan.hot_bytes {
            for m in mutations.iter_mut().step_by(2) {
                m.confine(hot);
            }
        }
        let input = apply(&seeds[seed], &mutations);
        n += 1;
        match run_reader(&reader, &input) {
            Ok(ok) => accepted += usize::from(ok),
            Err(()) => {
                failures.push(input);
                if failures.len() >= 5 {
                    break;
                }
            }
        }
    }
    if !failures.is_empty() {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-failures");
        std::fs::create_dir_all(&dir).unwrap();
        for (i, f) in failures.iter().enumerate() {
            std::fs::write(dir.join(format!("{target}-{i}.bin")), f).unwrap();
        }
        panic!(
            "{target}: {} of {n} inputs made the reader panic; saved in {}",
            failures.len(),
            dir.display()
        );
    }
    println!(
        "{target}: {} seeds accepted; {n} mutated inputs ({accepted} still accepted), no panic",
        seeds.len()
    );
    n
}

fn seed(path: PathBuf) -> Vec<u8> {
    std::fs::read(&path).unwrap_or_else(|e| panic!("seed {}: {e}", path.display()))
}

/// A folder for the readers that take a path, reused for every input of a target.
fn scratch_dir() -> tempfile::TempDir {
    // In memory where the system has a tmpfs: a disk file system's journal makes the write of
    // each input cost more than the reader itself.
    let shm = Path::new("/dev/shm");
    if shm.is_dir()
        && let Ok(dir) = tempfile::tempdir_in(shm)
    {
        return dir;
    }
    tempfile::tempdir().unwrap()
}

/// Writes `bytes` to `dir/name` (replacing the previous input).
fn scratch(dir: &Path, bytes: &[u8], name: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn fuzz_geotiff_dem_reader() {
    let seeds = [
        "dem_f32.tif",
        "dem_i16_deflate_tiled.tif",
        "dem_u16_lzw.tif",
    ]
    .map(|s| seed(fixture(&format!("fuzz/{s}"))));
    fuzz("geotiff", &seeds, PLAIN, |bytes| {
        penumbra::terrain::geotiff::read_geotiff_from(std::io::Cursor::new(bytes), "fuzz")
            .is_ok_and(|(dem, _)| dem.check().is_ok())
    });
}

#[test]
fn fuzz_horizon_map_reader() {
    let seeds = [seed(fixture("fuzz/horizon_map.tif"))];
    fuzz("horizon-map", &seeds, PLAIN, |bytes| {
        // The same reader `read_tiff` runs on a file, here on memory.
        penumbra::shadow::fourier::HorizonMap::read_tiff_from(
            std::io::Cursor::new(bytes),
            bytes.len() as u64,
            "fuzz",
        )
        .is_ok()
    });
}

#[test]
fn fuzz_horizon_sweep_reader() {
    use penumbra::horizon::statistics::HorizonRows as _;
    let seeds = [seed(fixture("fuzz/sweep.tif"))];
    let dir = scratch_dir();
    fuzz("horizon-sweep", &seeds, PLAIN, |bytes| {
        let path = scratch(dir.path(), bytes, "s.tif");
        let Ok(mut file) = penumbra::horizon::statistics::HorizonFile::open(&path) else {
            return false;
        };
        let rows = file.grid().rows;
        let mut out = Vec::new();
        file.read_rows(0..rows, &mut out).is_ok()
    });
}

#[test]
fn fuzz_scenario_reader() {
    let seeds = [
        seed(fixture("fuzz/scenario.toml")),
        seed(root().join("scenarios/south-pole-demo.toml")),
    ];
    // `Scenario::load` reads the file and hands its text to `from_toml`, with the whole-scenario
    // preflight (paths it names are looked up beside the scenario: the repository's root, so
    // that the demo's kernel folder exists).
    let path = root().join("fuzz-input.toml");
    fuzz("scenario", &seeds, PLAIN, |bytes| {
        std::str::from_utf8(bytes)
            .is_ok_and(|text| penumbra::scenario::Scenario::from_toml(text, &path).is_ok())
    });
}

#[test]
fn fuzz_kernel_texts() {
    let seeds = [
        seed(fixture("fuzz/set.tm")),
        seed(kernels_dir().join("naif0012.tls")),
        seed(kernels_dir().join("moon_080317.tf")),
        seed(fixture("kernels-de440-frames/moon_de440_frames.tf")),
    ];
    fuzz("kernel-texts", &seeds, PLAIN, |bytes| {
        // The meta-kernel parser, the leap-seconds check and the frame-kernel conversion
        // (anise's text kernel parser) on any text, in memory. A seed is one of the three kinds,
        // so it counts as accepted when one of the readers takes it.
        let name = std::path::Path::new("fuzz");
        let text = String::from_utf8_lossy(bytes);
        let meta = penumbra::ephem::metakernel::kernels_to_load(&text)
            .is_ok_and(|files| !files.is_empty());
        let lsk = penumbra::ephem::kernels::check_leap_seconds(name, bytes).is_ok();
        let fk = penumbra::ephem::kernels::frame_parameters(name, bytes)
            .is_ok_and(|frames| !frames.is_empty());
        meta || lsk || fk
    });
}

/// Fuzzes the shipped kernel `name` as it stands in a full kernel folder (the other kernels
/// fixed): penumbra's loader, then a Sun/Earth query ([`load_and_query`]).
fn fuzz_kernel_in_a_folder(target: &str, name: &str, plan: Plan) {
    let dir = kernel_set_without(name);
    fuzz(target, &[seed(kernels_dir().join(name))], plan, |bytes| {
        scratch(dir.path(), bytes, name);
        load_and_query(dir.path())
    });
}

/// Every second mutation of a binary kernel lands in its DAF header and summaries.
const BINARY_KERNEL: Plan = Plan {
    hot_bytes: Some(16 << 10),
};

#[test]
fn fuzz_leap_seconds_kernel_in_a_folder() {
    fuzz_kernel_in_a_folder("lsk", "naif0012.tls", PLAIN);
}

#[test]
fn fuzz_frame_kernel_in_a_folder() {
    // anise's text kernel parser reads a path: the folder scan runs it on the input.
    fuzz_kernel_in_a_folder("fk", "moon_080317.tf", PLAIN);
}

#[test]
fn fuzz_meta_kernel_file() {
    // A meta-kernel naming the shipped set through a path symbol, in the form SPICE's
    // `furnsh` takes: string continuation, `+=`, and other variables.
    let k = kernels_dir();
    let set = format!(
        "KPL/MK\n\\begindata\nPATH_VALUES  = ( '{}' )\nPATH_SYMBOLS = ( 'K' )\n\
         KERNELS_TO_LOAD = ( '$K/de440_moon+'\n                    '_2000_2025.bsp'\n\
         '$K/naif0012.tls', '$K/moon_080317.tf' )\nKERNELS_TO_LOAD += '$K/moon_pa_de421_2000_2050.bpc'\n\
         OTHER = ( 1, 2.5D0, 'a''b' )\n\\begintext\nnotes\n",
        k.display()
    );
    let dir = scratch_dir();
    fuzz("meta-kernel", &[set.into_bytes()], PLAIN, |bytes| {
        let tm = scratch(dir.path(), bytes, "set.tm");
        load_and_query(&tm)
    });
}

/// A folder holding the shipped kernels, all but `mutated`, which each input replaces.
fn kernel_set_without(mutated: &str) -> tempfile::TempDir {
    let dir = scratch_dir();
    for entry in std::fs::read_dir(kernels_dir()).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        let wanted = name.ends_with(".bpc")
            || name.ends_with(".tf")
            || name.ends_with(".tls")
            || name == "de440_moon_2000_2025.bsp";
        if wanted && name != mutated {
            std::fs::copy(&path, dir.path().join(&name)).unwrap();
        }
    }
    dir
}

/// Loads the kernel folder and asks for the Sun and the Earth seen from a polar site at an
/// epoch the shipped ephemeris covers: the binary readers (anise's DAF, SPK and BPC parsers,
/// behind penumbra's loader) and the evaluation of what they read.
fn load_and_query(folder: &Path) -> bool {
    use penumbra::ephem::{AbCorr, Kernels};
    let Ok(kernels) = Kernels::load(folder) else {
        return false;
    };
    let epoch = penumbra::ephem::time::parse_utc("2024-06-01T00:00:00").unwrap();
    let site = penumbra::ephem::Site::new(-89.5, 120.0, 2.0).unwrap();
    penumbra::ephem::sun_earth_series(&kernels, &[site], &[epoch], AbCorr::default())
        .is_ok_and(|s| s[0][0].sun.el_deg.is_finite() && s[0][0].earth.el_deg.is_finite())
}

#[test]
fn fuzz_spk_reader() {
    fuzz_kernel_in_a_folder("spk", "de440_moon_2000_2025.bsp", BINARY_KERNEL);
}

#[test]
fn fuzz_binary_pck_reader() {
    fuzz_kernel_in_a_folder("bpc", "moon_pa_de421_2000_2050.bpc", BINARY_KERNEL);
}

#[test]
fn fuzz_pds3_reader() {
    let seeds = [
        seed(fixture("fuzz/pds3_attached.img")),
        seed(fixture("fuzz/pds3_detached.lbl")),
    ];
    // The input as an image with an attached label, and as a detached label beside a fixed
    // image; a seed is one of the two.
    let dir = scratch_dir();
    std::fs::copy(
        fixture("fuzz/pds3_detached.img"),
        dir.path().join("PDS3_DETACHED.IMG"),
    )
    .unwrap();
    fuzz("pds3", &seeds, PLAIN, |bytes| {
        let mut any = false;
        for name in ["a.img", "pds3_detached.lbl"] {
            let path = scratch(dir.path(), bytes, name);
            any |= penumbra::terrain::pds3::read_pds3(&path).is_ok_and(|dem| dem.check().is_ok());
        }
        any
    });
}

#[test]
fn fuzz_pds4_reader() {
    let seeds = [seed(fixture("fuzz/pds4_seed.xml"))];
    // The input as an XML label beside the fixed image it names.
    let dir = scratch_dir();
    std::fs::copy(
        fixture("fuzz/pds4_seed.img"),
        dir.path().join("pds4_seed.img"),
    )
    .unwrap();
    fuzz("pds4", &seeds, PLAIN, |bytes| {
        let path = scratch(dir.path(), bytes, "a.xml");
        penumbra::terrain::pds4::read_pds4(&path).is_ok_and(|dem| dem.check().is_ok())
    });
}

#[test]
fn fuzz_sites_files() {
    let seeds = [
        seed(fixture("fuzz/sites.csv")),
        seed(fixture("fuzz/sites.geojson")),
    ];
    // Each input under both names: the extension picks the CSV or the GeoJSON reader.
    let dir = scratch_dir();
    fuzz("sites", &seeds, PLAIN, |bytes| {
        let mut any = false;
        for name in ["s.csv", "s.geojson"] {
            let path = scratch(dir.path(), bytes, name);
            any |= penumbra::model::read_sites_file(&path, Default::default()).is_ok();
        }
        any
    });
}

/// The partial of shard 0 of 1 of a small map job (the fuzz DEM, two days at 12 h), made by
/// the binary: `(shard.json, shard.pnbstat)`.
fn shard_seeds() -> (Vec<u8>, Vec<u8>) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("part");
    let k = kernels_dir();
    let dem = fixture("fuzz/dem_f32.tif");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(["map", "--dem"])
        .arg(&dem)
        .args([
            "--start",
            "2025-01-01",
            "--stop",
            "2025-01-03",
            "--step",
            "12h",
            "--azimuths",
            "16",
            "--shard",
            "0/1",
            "--quiet",
            "--kernels",
        ])
        .arg(&k)
        .arg("--out-dir")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "making the shard seed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let read = |name: &str| std::fs::read(out.join(name)).unwrap();
    (read("shard.json"), read("shard.pnbstat"))
}

/// `penumbra merge` of the one shard in `dir` into a new folder under `out` (merge refuses to
/// overwrite a finished one; `n` numbers them), removed afterwards: whether it succeeded.
fn merge_one(dir: &Path, out: &Path, n: &std::cell::Cell<usize>) -> bool {
    n.set(n.get() + 1);
    let dest = out.join(format!("m{}", n.get()));
    let ok = penumbra::products::map::shard::merge(&dest, &[dir.to_path_buf()]).is_ok();
    let _ = std::fs::remove_dir_all(&dest);
    ok
}

#[test]
fn fuzz_shard_partials() {
    let (manifest, data) = shard_seeds();
    // The input as the manifest beside the seed's data file, and as the data file beside the
    // seed's manifest; `penumbra merge` reads both (sizes and sha256 are checked, so a mutated
    // data file is refused by its hash unless the mutation left it unchanged).
    let (json_dir, data_dir, out) = (scratch_dir(), scratch_dir(), scratch_dir());
    std::fs::write(json_dir.path().join("shard.pnbstat"), &data).unwrap();
    std::fs::write(data_dir.path().join("shard.json"), &manifest).unwrap();
    let n = std::cell::Cell::new(0);
    fuzz(
        "shard-manifest",
        std::slice::from_ref(&manifest),
        PLAIN,
        |bytes| {
            scratch(json_dir.path(), bytes, "shard.json");
            merge_one(json_dir.path(), out.path(), &n)
        },
    );
    fuzz("shard-data", &[data], PLAIN, |bytes| {
        scratch(data_dir.path(), bytes, "shard.pnbstat");
        merge_one(data_dir.path(), out.path(), &n)
    });
}

/// The hash check of a shard's data file hides what `merge` does with wrong bytes: here the
/// manifest is rewritten to carry each mutated data file's size and sha256, so the mutated
/// bytes reach the decoder of the per-pixel sums.
#[test]
fn fuzz_shard_data_behind_a_matching_hash() {
    use sha2::Digest as _;
    let (manifest, data) = shard_seeds();
    let manifest: serde_json::Value = serde_json::from_slice(&manifest).unwrap();
    let (dir, out) = (scratch_dir(), scratch_dir());
    let n = std::cell::Cell::new(0);
    fuzz("shard-data-rehashed", &[data], PLAIN, |bytes| {
        let mut m = manifest.clone();
        m["data_bytes"] = serde_json::json!(bytes.len());
        m["data_sha256"] = serde_json::json!(format!("{:x}", sha2::Sha256::digest(bytes)));
        scratch(dir.path(), &serde_json::to_vec(&m).unwrap(), "shard.json");
        scratch(dir.path(), bytes, "shard.pnbstat");
        merge_one(dir.path(), out.path(), &n)
    });
}

#[test]
fn fuzz_resume_journal() {
    use penumbra::output::checkpoint::{CHECKPOINT_DIR, Checkpoint};
    // A journal with a finished part (one output file) and a blob, written by the checkpoint
    // code itself.
    let made = tempfile::tempdir().unwrap();
    std::fs::write(made.path().join("a.txt"), b"part a").unwrap();
    {
        let (mut c, _) = Checkpoint::open(made.path(), "fp", false).unwrap();
        c.mark_done("part a", &["a.txt".to_string()], "cpu")
            .unwrap();
        c.store_blob("rows 0-8", &[1, 2, 3]).unwrap();
    }
    let journal = made.path().join(CHECKPOINT_DIR).join("journal.json");
    let seeds = [seed(journal)];
    let dir = scratch_dir();
    std::fs::write(dir.path().join("a.txt"), b"part a").unwrap();
    let blob_dir = dir.path().join(CHECKPOINT_DIR);
    std::fs::create_dir_all(&blob_dir).unwrap();
    let blob = std::fs::read_dir(made.path().join(CHECKPOINT_DIR))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "bin"))
        .unwrap();
    fuzz("resume-journal", &seeds, PLAIN, |bytes| {
        // `--resume` over a folder whose journal is the input.
        std::fs::create_dir_all(&blob_dir).unwrap();
        std::fs::copy(&blob, blob_dir.join(blob.file_name().unwrap())).unwrap();
        scratch(&blob_dir, bytes, "journal.json");
        let Ok((c, _)) = Checkpoint::open(dir.path(), "fp", true) else {
            return false;
        };
        let _ = c.part("part a");
        let _ = c.load_blob("rows 0-8");
        c.is_done("part a") && c.load_blob("rows 0-8").is_some()
    });
}

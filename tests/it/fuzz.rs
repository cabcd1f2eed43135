//! Mutation fuzzing of every file reader (issue 17): GeoTIFF DEMs (float32 strips, int16 Deflate
//! tiles, uint16 LZW strips), Fourier horizon-map TIFFs, horizon-sweep BigTIFFs, scenario TOML,
//! SPICE meta-kernels, and the kernel-folder scan (text kernels).
//!
//! Harness: proptest (stable toolchain) generates mutations of the seed corpus in
//! `tests/fixtures/fuzz/` (and `kernels/naif0012.tls`, `kernels/moon_080317.tf`): bit flips, byte
//! sets, 16/32/64-bit little- and big-endian overwrites with boundary values (0, 1, 2³¹−1, 2³²−1,
//! the file length, ...), truncations, insertions and duplicated spans. Each input goes through the
//! reader inside `catch_unwind`; a reader may refuse it but must not panic, abort or hang (the
//! test process would die or time out). A failing input is saved to
//! `target/fuzz-failures/<target>-<n>.bin` for reproduction.
//!
//! Length: `PENUMBRA_FUZZ_SECONDS` per target (default 8 s in CI) and at most
//! `PENUMBRA_FUZZ_CASES` inputs (default unbounded); the long recorded run is in
//! docs/VALIDATION.md.

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::strategy::ValueTree as _;
use proptest::test_runner::{Config, TestRunner};

use crate::util::{fixture, kernels_dir};

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

/// Runs `reader` on mutations of `seeds` for the configured time; returns the number of inputs.
fn fuzz(target: &str, seeds: &[Vec<u8>], reader: impl Fn(&[u8])) -> usize {
    let seconds: f64 = std::env::var("PENUMBRA_FUZZ_SECONDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(8.0);
    let max_cases: usize = std::env::var("PENUMBRA_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(usize::MAX);
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let strategy = (0..seeds.len(), prop::collection::vec(mutation(), 1..6));
    let mut runner = TestRunner::new(Config::default());
    // Quiet panics: a caught panic is reported below, with the input saved.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut n = 0usize;
    let mut failures = Vec::new();
    // Every seed as it stands first.
    for seed in seeds {
        if std::panic::catch_unwind(AssertUnwindSafe(|| reader(seed))).is_err() {
            failures.push(seed.clone());
        }
    }
    while Instant::now() < deadline && n < max_cases {
        let (seed, mutations) = strategy.new_tree(&mut runner).unwrap().current();
        let input = apply(&seeds[seed], &mutations);
        n += 1;
        if std::panic::catch_unwind(AssertUnwindSafe(|| reader(&input))).is_err() {
            failures.push(input);
            if failures.len() >= 5 {
                break;
            }
        }
    }
    std::panic::set_hook(hook);
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
    println!("{target}: {n} mutated inputs, no panic");
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
        "sweep.tif",
    ]
    .map(|s| seed(fixture(&format!("fuzz/{s}"))));
    fuzz("geotiff", &seeds, |bytes| {
        if let Ok((dem, _)) =
            penumbra::terrain::geotiff::read_geotiff_from(std::io::Cursor::new(bytes), "fuzz")
        {
            let _ = dem.check();
        }
    });
}

#[test]
fn fuzz_horizon_map_reader() {
    let seeds = [seed(fixture("fuzz/horizon_map.tif"))];
    fuzz("horizon-map", &seeds, |bytes| {
        // The same reader `read_tiff` runs on a file, here on memory.
        let _ = penumbra::shadow::fourier::HorizonMap::read_tiff_from(
            std::io::Cursor::new(bytes),
            bytes.len() as u64,
            "fuzz",
        );
    });
}

#[test]
fn fuzz_horizon_sweep_reader() {
    use penumbra::horizon::statistics::HorizonRows as _;
    let seeds = [seed(fixture("fuzz/sweep.tif"))];
    let dir = scratch_dir();
    fuzz("horizon-sweep", &seeds, |bytes| {
        let path = scratch(dir.path(), bytes, "s.tif");
        if let Ok(mut file) = penumbra::horizon::statistics::HorizonFile::open(&path) {
            let rows = file.grid().rows;
            let mut out = Vec::new();
            let _ = file.read_rows(0..rows, &mut out);
        }
    });
}

#[test]
fn fuzz_scenario_reader() {
    let seeds = [
        seed(fixture("fuzz/scenario.toml")),
        seed(kernels_dir().join("../scenarios/south-pole-demo.toml")),
    ];
    // `Scenario::load` reads the file and hands its text to `from_toml`, with the whole-scenario
    // preflight (paths it names are looked up in this folder).
    let dir = scratch_dir();
    let path = dir.path().join("s.toml");
    fuzz("scenario", &seeds, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = penumbra::scenario::Scenario::from_toml(text, &path);
        }
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
    fuzz("kernel-texts", &seeds, |bytes| {
        // The meta-kernel parser, the leap-seconds check and the frame-kernel conversion
        // (anise's text kernel parser) on any text, in memory.
        let name = std::path::Path::new("fuzz");
        let _ = penumbra::ephem::metakernel::kernels_to_load(&String::from_utf8_lossy(bytes));
        let _ = penumbra::ephem::kernels::check_leap_seconds(name, bytes);
        let _ = penumbra::ephem::kernels::frame_parameters(name, bytes);
    });
}

#[test]
fn fuzz_kernel_folder() {
    let seeds = [
        seed(fixture("fuzz/set.tm")),
        seed(kernels_dir().join("naif0012.tls")),
        seed(kernels_dir().join("moon_080317.tf")),
    ];
    let (folder, meta) = (scratch_dir(), scratch_dir());
    fuzz("kernel-folder", &seeds, |bytes| {
        // The folder scan with the input as a leap-seconds and a frame kernel (anise's text
        // kernel parser reads a path), and the input as a meta-kernel file.
        scratch(folder.path(), bytes, "a.tls");
        scratch(folder.path(), bytes, "b.tf");
        let _ = penumbra::ephem::Kernels::load(folder.path());
        let tm = scratch(meta.path(), bytes, "set.tm");
        let _ = penumbra::ephem::Kernels::load(&tm);
    });
}

#[test]
fn fuzz_pds3_reader() {
    let seeds = [
        seed(fixture("fuzz/pds3_attached.img")),
        seed(fixture("fuzz/pds3_detached.lbl")),
    ];
    // The input as an image with an attached label, and as a detached label beside a fixed image.
    let dir = scratch_dir();
    std::fs::copy(
        fixture("fuzz/pds3_detached.img"),
        dir.path().join("PDS3_DETACHED.IMG"),
    )
    .unwrap();
    fuzz("pds3", &seeds, |bytes| {
        for name in ["a.img", "pds3_detached.lbl"] {
            let path = scratch(dir.path(), bytes, name);
            if let Ok(dem) = penumbra::terrain::pds3::read_pds3(&path) {
                let _ = dem.check();
            }
        }
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
    fuzz("pds4", &seeds, |bytes| {
        let path = scratch(dir.path(), bytes, "a.xml");
        if let Ok(dem) = penumbra::terrain::pds4::read_pds4(&path) {
            let _ = dem.check();
        }
    });
}

//! Test helpers: paths to fixtures and shared data, running the binary. Every test runs penumbra
//! through [`penumbra_command`] (or [`penumbra`], [`penumbra_ok`], [`penumbra_wgpu`] over it) and
//! finds files through [`root`], [`fixture`], [`kernels_dir`] and [`shared_lola`].

#![allow(dead_code, reason = "not every test module uses every helper")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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

/// The folder of the team's shared data: `$PENUMBRA_SHARED`, else `../shared` beside the clone.
pub fn shared_dir() -> PathBuf {
    std::env::var_os("PENUMBRA_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("../shared"))
}

/// A file of the shared LOLA data. When it is absent the test fails naming the file, unless
/// `PENUMBRA_SKIP` lists `lola`: then `None`, and the skip is recorded ([`missing`]).
pub fn shared_lola(name: &str) -> Option<PathBuf> {
    let p = shared_dir().join("data/lola-south-pole-moondao").join(name);
    if p.is_file() {
        Some(p)
    } else {
        missing(
            "lola",
            &format!("the shared LOLA grid {}", p.display()),
            "set PENUMBRA_SHARED to the folder that holds data/lola-south-pole-moondao/",
        );
        None
    }
}

/// Where skipped tests are listed, one `test<TAB>need<TAB>reason` line each (`.ci/run` prints
/// the count and the lines in its summary).
pub fn skip_log() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("penumbra-skipped.tsv")
}

/// The prerequisites a test may name in `missing`, and what `PENUMBRA_SKIP` accepts.
pub const NEEDS: [&str; 4] = ["gpu", "gdal", "lola", "tools"];

/// A prerequisite of the running test is missing. No hollow pass: the test fails naming `what`
/// and how to provide it, unless `PENUMBRA_SKIP` (comma-separated, e.g. `gpu,gdal`) lists
/// `need`; then the skip is written to [`skip_log`] and on stderr, and the caller returns.
pub fn missing(need: &str, what: &str, provide: &str) {
    assert!(NEEDS.contains(&need), "unknown need {need}");
    let skip = std::env::var("PENUMBRA_SKIP").unwrap_or_default();
    let allowed = skip.split(',').any(|k| k.trim() == need);
    assert!(
        allowed,
        "missing {what}: {provide} (or PENUMBRA_SKIP={need} to count the tests that need it as skipped)"
    );
    record_skip(need, what);
}

/// Writes a skipped test to [`skip_log`] (a test that could not run here for a reason that is
/// not a missing prerequisite, e.g. an adapter whose limits leave nothing to show, records
/// itself too: it is counted, not passed).
pub fn record_skip(need: &str, why: &str) {
    use std::io::Write as _;
    let test = std::thread::current()
        .name()
        .unwrap_or("unnamed test")
        .to_string();
    eprintln!("SKIPPED {test}: {why}");
    let log = skip_log();
    let _ = std::fs::create_dir_all(log.parent().unwrap());
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&log)
        .expect("open the skip log");
    writeln!(f, "{test}\t{need}\t{}", why.replace(['\t', '\n'], " ")).expect("write the skip log");
}

/// Whether the command-line tool `tool` runs (`tool --version`); when it does not, [`missing`]
/// (need `gdal` for GDAL's tools, `tools` for others) with the Debian package that provides it.
pub fn tool(name: &str, package: &str) -> bool {
    let found = Command::new(name).arg("--version").output().is_ok();
    if !found {
        let need = if package.contains("gdal") {
            "gdal"
        } else {
            "tools"
        };
        missing(
            need,
            &format!("the command `{name}`"),
            &format!("apt-get install {package}"),
        );
    }
    found
}

/// The penumbra binary cargo built for these tests.
pub fn penumbra_exe() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_penumbra"))
}

/// A command that runs `exe` (the penumbra binary or a copy of it) without `$PENUMBRA_KERNELS`, so
/// that the environment of whoever runs the tests picks no kernels; the caller adds the
/// arguments, the folder, the environment and how to wait for it.
pub fn command_of(exe: &Path) -> Command {
    let mut cmd = Command::new(exe);
    cmd.env_remove("PENUMBRA_KERNELS");
    cmd
}

/// [`command_of`] the built penumbra binary: the one way the tests start it.
pub fn penumbra_command() -> Command {
    command_of(penumbra_exe())
}

/// Runs the penumbra binary with `args` in `cwd`.
///
/// A run that outlives [`RUN_LIMIT_S`] is killed and the test fails naming its arguments: a hang
/// (a FIFO read, a loop) fails one test instead of stalling the whole suite until CI's limit.
pub fn penumbra(cwd: &Path, args: &[&str]) -> Output {
    penumbra_command()
        .args(args)
        .current_dir(cwd)
        .output_within()
        .expect("the penumbra binary runs")
}

/// Runs penumbra with `args` in `cwd` as the GPU tests do: `XDG_RUNTIME_DIR=/tmp` (lavapipe without
/// a session) and `WGPU_BACKEND` set to `wgpu_backend`, inherited when `None` (`metal` on Linux
/// enables no usable backend: the no-adapter paths).
pub fn penumbra_wgpu(cwd: &Path, wgpu_backend: Option<&str>, args: &[&str]) -> Output {
    let mut cmd = penumbra_command();
    cmd.args(args)
        .current_dir(cwd)
        .env("XDG_RUNTIME_DIR", "/tmp");
    if let Some(b) = wgpu_backend {
        cmd.env("WGPU_BACKEND", b);
    }
    cmd.output_within().expect("the penumbra binary runs")
}

/// The longest one penumbra command in a test may run, seconds (the slowest takes ≈ 3 min on CI).
pub const RUN_LIMIT_S: u64 = 900;

/// `Command::output` with a time limit ([`RUN_LIMIT_S`]): a command still running then is killed
/// and the test panics naming it, so that a hang fails one test instead of stalling the suite.
pub trait OutputWithin {
    /// Runs the command to its end, collecting stdout and stderr (stdin is null).
    fn output_within(&mut self) -> std::io::Result<Output>;
}

impl OutputWithin for std::process::Command {
    fn output_within(&mut self) -> std::io::Result<Output> {
        use std::io::Read as _;
        use std::process::Stdio;
        let mut child = self
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()?;
        let drain = |mut r: Box<dyn std::io::Read + Send>| {
            std::thread::spawn(move || {
                let mut buf = Vec::new();
                let _ = r.read_to_end(&mut buf);
                buf
            })
        };
        let out = drain(Box::new(child.stdout.take().expect("piped stdout")));
        let err = drain(Box::new(child.stderr.take().expect("piped stderr")));
        let t0 = std::time::Instant::now();
        let status = loop {
            if let Some(status) = child.try_wait()? {
                break status;
            }
            if t0.elapsed().as_secs() >= RUN_LIMIT_S {
                let _ = child.kill();
                let _ = child.wait();
                panic!("{self:?} still ran after {RUN_LIMIT_S} s: killed (a hang?)");
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        };
        Ok(Output {
            status,
            stdout: out.join().expect("stdout reader"),
            stderr: err.join().expect("stderr reader"),
        })
    }
}

/// Runs the penumbra binary with `args` in `cwd` and asserts that it succeeded (stderr shown
/// otherwise).
pub fn penumbra_ok(cwd: &Path, args: &[&str]) -> Output {
    let out = penumbra(cwd, args);
    assert!(
        out.status.success(),
        "penumbra {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Reads a GeoTIFF written by a run into `dir`.
pub fn read_tif(dir: &Path, name: &str) -> penumbra::terrain::Dem {
    penumbra::terrain::read_geotiff(&dir.join(name))
        .unwrap_or_else(|e| panic!("reading {name}: {e}"))
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

/// `n`² cells of 20 m: five Gaussian hills (60..400 m, σ 150..600 m), the Moon's curvature drop
/// z -= (x² + y²) / 2R, and a 3 × 3 hole near the centre: the GPU parity fixture of
/// `gpu/mod.rs` and `gpu/dp.rs`.
pub fn hills(n: usize) -> penumbra::terrain::HeightField {
    let mut hf = penumbra::terrain::HeightField::flat(n, n, 20.0);
    let half_m = n as f64 * 10.0;
    let hills = [
        (0.2, 0.3, 400.0, 600.0),
        (-0.5, -0.1, 250.0, 300.0),
        (0.6, -0.6, 300.0, 400.0),
        (-0.3, 0.7, 60.0, 150.0),
        (0.0, -0.4, 150.0, 250.0),
    ];
    for row in 0..n {
        for col in 0..n {
            let (x, y) = hf.xy_from_row_col(row as f64, col as f64);
            let mut z = -(x * x + y * y) / (2.0 * penumbra::MOON_RADIUS_M);
            for &(cx, cy, h, s) in &hills {
                let (dx, dy) = (x - cx * half_m, y - cy * half_m);
                z += h * (-(dx * dx + dy * dy) / (2.0 * s * s)).exp();
            }
            hf.z_m[row * n + col] = z as f32;
        }
    }
    for row in n / 2..n / 2 + 3 {
        for col in n / 3..n / 3 + 3 {
            hf.z_m[row * n + col] = f32::NAN;
        }
    }
    hf
}

/// The value of a PNG tEXt chunk, read back with the `png` decoder.
pub fn png_text(bytes: &[u8], keyword: &str) -> Option<String> {
    let reader = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .ok()?;
    reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .find(|t| t.keyword == keyword)
        .map(|t| t.text.clone())
}

/// Writes `toml` as `s.toml` in `dir`, runs `penumbra run s.toml` there, asserts success and
/// returns the output folder of the scenario (`dir/res`, as [`render_scenario`] sets it).
pub fn run_scenario_ok(dir: &Path, toml: &str) -> PathBuf {
    std::fs::write(dir.join("s.toml"), toml).unwrap();
    penumbra_ok(dir, &["run", "s.toml"]);
    dir.join("res")
}

/// A small render scenario: the seeded 300² synthetic DEM at 100 m, one site, hourly epochs from
/// 2027-01-20T00:00 to `stop_utc`, the shipped kernels, then `tables` (`[[render.views]]` or
/// `[[render.paths]]`).
pub fn render_scenario(name: &str, stop_utc: &str, tables: &str) -> String {
    format!(
        r#"name = "{name}"
output_dir = "res"
kernels = "{}"
[time]
start = "2027-01-20"
stop = "{stop_utc}"
step = "1h"
[terrain]
synthetic = {{ size_px = 300, px_m = 100.0, seed = 1 }}
[[sites]]
name = "a"
lat_deg = -89.6
lon_deg = 0.0
{tables}"#,
        kernels_dir().display()
    )
}

/// The GPU context shared by every GPU test of the binary. Without an adapter the test fails
/// naming the adapter error, unless `PENUMBRA_SKIP` lists `gpu` ([`missing`]): then `None`.
#[cfg(feature = "gpu")]
pub fn gpu() -> Option<&'static penumbra::gpu::GpuContext> {
    static CTX: std::sync::OnceLock<Result<penumbra::gpu::GpuContext, String>> =
        std::sync::OnceLock::new();
    let ctx = CTX.get_or_init(|| {
        let ctx = penumbra::gpu::GpuContext::new().map_err(|e| e.to_string());
        if let Ok(ctx) = &ctx {
            eprintln!(
                "GPU tests run on adapter: {} ({})",
                ctx.adapter_name(),
                ctx.adapter_kind()
            );
        }
        ctx
    });
    match ctx {
        Ok(ctx) => Some(ctx),
        Err(e) => {
            missing(
                "gpu",
                &format!("a GPU adapter ({e})"),
                "apt-get install mesa-vulkan-drivers libvulkan1 and run with WGPU_BACKEND=vulkan (lavapipe)",
            );
            None
        }
    }
}

/// Sun direction in model space for an azimuth (from north, clockwise) and elevation.
pub fn sun_dir(az_deg: f64, el_deg: f64) -> nalgebra::Vector3<f64> {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    nalgebra::Vector3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin())
}

/// Sun and Earth discs for `epochs` epochs: the Sun circles the sky at 0.5..5° elevation, the
/// Earth stays low in the north-west (1..3°), radii 0.2666° and 0.95°.
pub fn sweep_lights(epochs: usize) -> Vec<[f32; 4]> {
    use penumbra::twins::disc_light_to_f32;
    (0..epochs)
        .flat_map(|k| {
            let phase = k as f64 / epochs as f64;
            let sun_el = 2.75 + 2.25 * (4.0 * std::f64::consts::TAU * phase).sin();
            let earth_el = 2.0 + (std::f64::consts::TAU * phase).sin();
            [
                disc_light_to_f32(
                    &sun_dir(360.0 * phase, sun_el),
                    penumbra::shadow::SUN_ANGULAR_RADIUS_RAD,
                ),
                disc_light_to_f32(&sun_dir(300.0, earth_el), 0.95_f64.to_radians()),
            ]
        })
        .collect()
}

/// The files of `dir` whose extension is `ext`, sorted.
pub fn files_with_extension(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    paths.sort();
    paths
}

/// `src` (the WGSL of `name`) parsed and validated by naga with every validation flag and
/// capability; a failure panics with naga's message and the span it points at.
pub fn naga_validate(name: &str, src: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: WGSL parse error:\n{}", e.emit_to_string(src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: naga validation error:\n{}", e.emit_to_string(src)));
    module
}

/// The sizes naga's layouter gives the named structs of `shader` (composed as the pipelines
/// see it, validated first), for the tests that check a shader's structs against their Rust
/// mirrors.
pub fn wgsl_struct_sizes(
    shader: &penumbra::gpu::shaders::Shader,
) -> std::collections::HashMap<String, usize> {
    let module = naga_validate(shader.name, shader.source);
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    module
        .types
        .iter()
        .filter_map(|(h, t)| Some((t.name.clone()?, layouter[h].size as usize)))
        .collect()
}

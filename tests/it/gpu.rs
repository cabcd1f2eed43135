//! GPU backend: naga validation of every shader (never skipped) and GPU-vs-CPU-twin parity on
//! synthetic height fields (vello `compare_gpu_cpu.rs`). The GPU tests skip with a printed reason
//! when no adapter exists; `PENUMBRA_REQUIRE_GPU=1` turns the skip into a failure. In CI they
//! run on lavapipe (`WGPU_BACKEND=vulkan`).

use crate::util::OutputWithin as _;
use std::path::Path;

use penumbra::terrain::HeightField;
use penumbra::twins::{self, LIT, MarchGrid, RowBand, SHADOW};

use crate::util::sun_dir;

/// The shader source as a pipeline sees it: the `// requires: X` files first, then the file.
fn composed_source(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let mut src = String::new();
    for line in text.lines() {
        if let Some(dep) = line.strip_prefix("// requires: ") {
            let dep_path = path.parent().unwrap().join(dep.trim());
            src.push_str(&std::fs::read_to_string(&dep_path).unwrap());
        }
    }
    src.push_str(&text);
    src
}

fn validate(name: &str, src: &str) -> naga::Module {
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

/// Every `shaders/*.wgsl` (with its `// requires:` helpers) and every `shaders/shared/*.wgsl`
/// parses and validates, and each kernel file has exactly one entry point named like the file.
#[test]
fn naga_validates_every_shader() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut kernels = 0;
    for sub in [dir.clone(), dir.join("shared")] {
        let mut paths: Vec<_> = std::fs::read_dir(&sub)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
            .collect();
        paths.sort();
        for path in paths {
            let name = path.file_stem().unwrap().to_string_lossy().into_owned();
            let src = composed_source(&path);
            if sub != dir && src.starts_with("// fragment:") {
                continue; // validated within the kernels that require it
            }
            let module = validate(&name, &src);
            if sub == dir {
                kernels += 1;
                let entries: Vec<_> = module
                    .entry_points
                    .iter()
                    .map(|e| e.name.as_str())
                    .collect();
                assert_eq!(
                    entries,
                    [name.as_str()],
                    "{name}: one entry point named like the file"
                );
            }
        }
    }
    assert!(kernels >= 3, "found only {kernels} kernel shaders");
}

/// Analytic oracle for the twin (no GPU): a flat plane with a wall of height H along a column;
/// with the Sun due east at elevation e, cells west of the wall are dark exactly up to the
/// distance (H − h) / tan(e) from it (h = observer height), and every cell east of it is lit.
#[test]
fn twin_wall_shadow_length_matches_geometry() {
    let n = 64;
    let px_m = 10.0;
    let wall_col = 48;
    let (wall_m, observer_m) = (30.0, 2.0);
    let mut hf = HeightField::flat(n, n, px_m);
    for row in 0..n {
        hf.z_m[row * n + wall_col] = wall_m as f32;
    }
    let el_deg = 10.0_f64;
    let grid = MarchGrid::from_height_field(&hf, observer_m).unwrap();
    let light = twins::light_to_f32(&sun_dir(90.0, el_deg));
    let map = twins::shadow_march(&grid, &[light], 0, RowBand::whole(&grid));
    let row = n / 2;
    // The wall is a tent of the bilinear surface between its neighbours: the ray from col c
    // meets the lattice line at wall_col after (wall_col - c) cells and must pass above H.
    let shadow_cells = (wall_m - observer_m) / (px_m * el_deg.to_radians().tan());
    for col in 0..wall_col {
        let dist_cells = (wall_col - col) as f64;
        let expected = if dist_cells < shadow_cells {
            SHADOW
        } else {
            LIT
        };
        // Cells within 1e-3 cell of the analytic edge are ties; none here (edge at 15.88 cells).
        assert_eq!(
            map[row * n + col],
            expected,
            "col {col}: distance {dist_cells} cells, edge {shadow_cells:.3}"
        );
    }
    for col in wall_col + 1..n {
        assert_eq!(map[row * n + col], LIT, "col {col} east of the wall");
    }
}

#[cfg(feature = "gpu")]
mod on_gpu {
    use penumbra::gpu::shadow_march::{GpuMarchGrid, shadow_march_gpu, shadow_march_soft_gpu};
    use penumbra::gpu::sweep_accumulate::{SweepOptions, sweep_stats_gpu};
    use penumbra::twins::NODATA;

    use super::*;
    use crate::util::hills;

    /// Elevations of the parity fixtures (the brief: grazing, low, moderate) with azimuths that
    /// are not aligned with the grid axes.
    const SUNS_DEG: [(f64, f64); 3] = [(0.5, 37.0), (1.5, 151.0), (5.0, 262.0)];
    /// Largest share of cells allowed to differ between the GPU and the twin in a hard map: f32
    /// ties at grazing rays (the GPU may contract a*b+c into an FMA and round differently).
    const MAX_HARD_DIFF_FRACTION: f64 = 1e-3;

    use crate::util::gpu;

    fn hard_counts(map: &[u32]) -> (usize, usize, usize) {
        let count = |v| map.iter().filter(|&&s| s == v).count();
        (count(LIT), count(SHADOW), count(NODATA))
    }

    #[test]
    fn shadow_march_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let n = 256;
        let grid = MarchGrid::from_height_field(&hills(n), 2.0).unwrap();
        let gpu_grid = GpuMarchGrid::upload(ctx, &grid).unwrap();
        for (el_deg, az_deg) in SUNS_DEG {
            let light = twins::light_to_f32(&sun_dir(az_deg, el_deg));
            let cpu = twins::shadow_march(&grid, &[light], 0, RowBand::whole(&grid));
            // 40 rows per band: 7 bands, the last one short, so tiling is exercised too.
            let gpu_map = shadow_march_gpu(ctx, &gpu_grid, light, 40 * n as u64 * 4).unwrap();
            assert_eq!(gpu_map.len(), cpu.len());
            let differ = cpu.iter().zip(&gpu_map).filter(|(a, b)| a != b).count();
            let fraction = differ as f64 / cpu.len() as f64;
            let (lit, dark, nodata) = hard_counts(&cpu);
            eprintln!(
                "shadow_march {n}² el {el_deg}° az {az_deg}°: {differ} cells differ ({:.4} %), twin lit {lit} dark {dark} nodata {nodata}",
                100.0 * fraction
            );
            assert_eq!(nodata, 9, "the 3 × 3 hole");
            assert_eq!(hard_counts(&gpu_map).2, 9, "GPU nodata");
            assert!(
                dark > cpu.len() / 50 && lit > cpu.len() / 50,
                "fixture must have both lit and dark cells"
            );
            assert!(
                fraction <= MAX_HARD_DIFF_FRACTION,
                "{differ} cells differ at el {el_deg}°"
            );
        }
    }

    #[test]
    fn shadow_march_band_tiling_is_seamless() {
        let Some(ctx) = gpu() else { return };
        let n = 128;
        let grid = MarchGrid::from_height_field(&hills(n), 2.0).unwrap();
        let gpu_grid = GpuMarchGrid::upload(ctx, &grid).unwrap();
        let light = twins::light_to_f32(&sun_dir(151.0, 1.5));
        let whole = shadow_march_gpu(ctx, &gpu_grid, light, u64::MAX / 2).unwrap();
        // 1-row and 13-row bands must give bit-identical maps (same kernel, same cells).
        for band_rows in [1_u64, 13] {
            let banded = shadow_march_gpu(ctx, &gpu_grid, light, band_rows * n as u64 * 4).unwrap();
            assert_eq!(banded, whole, "bands of {band_rows} rows");
        }
    }

    #[test]
    fn shadow_march_soft_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let n = 256;
        let samples = 32;
        // The Sun's mean angular radius seen from the Moon: 0.2666°.
        let radius_rad = 0.2666_f64.to_radians();
        let grid = MarchGrid::from_height_field(&hills(n), 2.0).unwrap();
        let gpu_grid = GpuMarchGrid::upload(ctx, &grid).unwrap();
        for (el_deg, az_deg) in SUNS_DEG {
            let dirs = twins::sun_disc_directions(&sun_dir(az_deg, el_deg), radius_rad, samples);
            let cpu = twins::shadow_march_soft(&grid, &dirs, RowBand::whole(&grid));
            let gpu_map = shadow_march_soft_gpu(ctx, &gpu_grid, &dirs, 50 * n as u64 * 4).unwrap();
            let deltas: Vec<f64> = cpu
                .iter()
                .zip(&gpu_map)
                .map(|(a, b)| f64::from((a - b).abs()))
                .collect();
            let max = deltas.iter().copied().fold(0.0, f64::max);
            let mean = deltas.iter().sum::<f64>() / deltas.len() as f64;
            let partial = cpu.iter().filter(|&&f| f > 0.0 && f < 1.0).count();
            eprintln!(
                "shadow_march_soft {n}² N={samples} el {el_deg}°: max |Δ| {max:.4}, mean |Δ| {mean:.2e}, penumbra cells {partial}"
            );
            assert!(partial > 0, "the fixture must have penumbra cells");
            // One sample flipping by an f32 tie changes a fraction by 1/N; allow two per cell,
            // and on average far below one flip per 1000 cells.
            assert!(max <= 2.0 / samples as f64 + 1e-6, "max |Δ| {max}");
            assert!(mean <= 1e-3 / samples as f64, "mean |Δ| {mean}");
        }
    }

    #[test]
    fn sweep_stats_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let n = 128;
        let grid = MarchGrid::from_height_field(&hills(n), 2.0).unwrap();
        let gpu_grid = GpuMarchGrid::upload(ctx, &grid).unwrap();
        // 60 epochs: the Sun circles the sky once at an elevation oscillating in 0.5..5°.
        let lights: Vec<[f32; 4]> = (0..60)
            .map(|k| {
                let phase = k as f64 / 60.0;
                let el_deg = 2.75 + 2.25 * (4.0 * std::f64::consts::TAU * phase).sin();
                twins::light_to_f32(&sun_dir(360.0 * phase, el_deg))
            })
            .collect();
        let cpu = twins::sweep_stats(&grid, &lights, RowBand::whole(&grid));
        // 7 epochs per submit and 20-row bands (7 bands): batches and bands both end unevenly.
        let options = SweepOptions {
            epochs_per_submit: 7,
            band_bytes: 20 * n as u64 * 4,
        };
        let gpu_stats = sweep_stats_gpu(ctx, &gpu_grid, &lights, options).unwrap();
        assert_eq!(gpu_stats.len(), cpu.len());
        let equal = cpu.iter().zip(&gpu_stats).filter(|(a, b)| a == b).count();
        let fraction = equal as f64 / cpu.len() as f64;
        let never_lit = cpu.iter().filter(|s| s.ever_lit == 0).count();
        let longest = cpu.iter().map(|s| s.longest_dark_run_epochs).max().unwrap();
        eprintln!(
            "sweep {n}² × {} epochs: {equal}/{} cells with equal stats ({:.3} %), twin never lit {never_lit}, longest dark run {longest}",
            lights.len(),
            cpu.len(),
            100.0 * fraction
        );
        assert!(longest > 1 && longest < 60, "fixture must have dark runs");
        assert!(
            fraction >= 0.999,
            "only {:.3} % of cells equal",
            100.0 * fraction
        );
        // The twin's statistics are consistent with its own per-epoch maps.
        let lit_total: usize = (0..lights.len())
            .map(|e| {
                let map = twins::shadow_march(&grid, &lights, e as u32, RowBand::whole(&grid));
                map.iter().filter(|&&s| s == LIT).count()
            })
            .sum();
        assert_eq!(
            lit_total,
            cpu.iter().map(|s| s.lit_epochs as usize).sum::<usize>()
        );
    }
}

/// Runs `penumbra` with `WGPU_BACKEND` set to `wgpu_backend` (or inherited when `None`).
fn penumbra_with_backend(wgpu_backend: Option<&str>, args: &[&str]) -> std::process::Output {
    let dir = tempfile::tempdir().unwrap();
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"));
    cmd.args(args)
        .current_dir(dir.path())
        .env("XDG_RUNTIME_DIR", "/tmp");
    if let Some(b) = wgpu_backend {
        cmd.env("WGPU_BACKEND", b);
    }
    cmd.output_within().unwrap()
}

/// `gpu-info` lists the adapters (or says there is none) and exits 0.
#[test]
fn gpu_info_lists_adapters() {
    let out = penumbra_with_backend(None, &["gpu-info"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    eprintln!("{stdout}");
    assert_eq!(
        out.status.code(),
        Some(0),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    if cfg!(feature = "gpu") {
        assert!(
            stdout.contains("max_storage_buffer_binding_size")
                || stdout.contains("no GPU adapter found"),
            "{stdout}"
        );
    }
}

/// `--backend gpu` without any adapter (WGPU_BACKEND=metal on Linux enables no usable backend)
/// is one clean error line, exit 2, never a panic.
#[test]
fn backend_gpu_without_adapter_is_a_clean_error() {
    let out = penumbra_with_backend(Some("metal"), &["gpu-info", "--backend", "gpu"]);
    let needle = if cfg!(feature = "gpu") {
        "no GPU adapter found"
    } else {
        "without the `gpu` cargo feature"
    };
    crate::util::assert_clean_error(&out, needle);
}

/// `--backend auto` without any adapter falls back to the CPU with exactly one warning line.
#[test]
fn backend_auto_without_adapter_warns_once_and_uses_cpu() {
    let out = penumbra_with_backend(Some("metal"), &["gpu-info", "--backend", "auto"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "exactly one warning line: {stderr}");
    assert!(
        lines[0].starts_with("penumbra: warning: --backend auto:"),
        "{stderr}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("backend auto: cpu"));
}

/// `penumbra map` over a short epoch range on the synthetic DEM with `--backend B`, run in `cwd`.
fn map_range(cwd: &Path, wgpu_backend: Option<&str>, backend: &str) -> std::process::Output {
    let k = crate::util::kernels_dir();
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"));
    cmd.args([
        "map",
        "--synthetic",
        "--start",
        "2027-02-01",
        "--stop",
        "2027-02-03",
        "--step",
        "12h",
        "--out-dir",
        backend,
        "--kernels",
        k.to_str().unwrap(),
        "--backend",
        backend,
        // The GPU's method on both backends (the CPU default starts at the DEM's own pixels).
        "--observers",
        "cells",
    ])
    .current_dir(cwd)
    .env("XDG_RUNTIME_DIR", "/tmp")
    .env_remove("PENUMBRA_KERNELS");
    if let Some(b) = wgpu_backend {
        cmd.env("WGPU_BACKEND", b);
    }
    cmd.output_within().unwrap()
}

/// Minimum agreement of the PSR masks of `map --backend gpu` (soft GPU sweep: DP max-mipmap visible
/// fractions of the discs in f32, `src/gpu/dp.rs`) and `--backend cpu` (the f64 engines) over the
/// same epochs. Both count a pixel lit when any part of the Sun's disc shows, so they differ only
/// at f32 grazing ties: measured on lavapipe (5 epochs, 2027-02-01..03 step 12h, synthetic DEM,
/// 160,000 pixels) 99.990% agreement, 16 pixels GPU-PSR/CPU-lit, 0 the other way (after the CPU
/// DP sample fix; the earlier hard-shadow GPU sweep agreed on 96.5%).
#[cfg(feature = "gpu")]
const MIN_PSR_AGREEMENT: f64 = 0.999;

/// `map --backend gpu` and `--backend cpu` over the same range both succeed and their
/// `psr_mask.tif` agree on ≥ 99.9% of valid pixels (see [`MIN_PSR_AGREEMENT`]), with identical
/// nodata, and each direction of disagreement stays below 0.1% of the pixels.
#[cfg(feature = "gpu")]
#[test]
fn map_backend_gpu_matches_cpu_psr_mask() {
    if let Err(e) = penumbra::gpu::GpuContext::new() {
        let required = std::env::var("PENUMBRA_REQUIRE_GPU").is_ok_and(|v| v == "1");
        assert!(!required, "PENUMBRA_REQUIRE_GPU=1 but no GPU context: {e}");
        eprintln!("skipping GPU test: {e}");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for backend in ["cpu", "gpu"] {
        let out = map_range(dir.path(), None, backend);
        assert!(
            out.status.success(),
            "--backend {backend}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let run_json = std::fs::read_to_string(dir.path().join("gpu/run.json")).unwrap();
    assert!(
        run_json.contains("DP max-mipmap soft shadows"),
        "{run_json}"
    );
    let read = |b: &str| {
        penumbra::terrain::read_geotiff(&dir.path().join(b).join("psr_mask.tif"))
            .unwrap()
            .heights_m
    };
    let (cpu, gpu) = (read("cpu"), read("gpu"));
    assert_eq!(cpu.len(), gpu.len());
    let nodata = |v: f32| v.is_nan() || v == 255.0;
    let (mut valid, mut agree, mut gpu_psr_cpu_lit, mut gpu_lit_cpu_psr, mut psr_cpu) =
        (0_usize, 0_usize, 0_usize, 0_usize, 0_usize);
    for (&c, &g) in cpu.iter().zip(&gpu) {
        assert_eq!(nodata(c), nodata(g), "nodata masks differ");
        if nodata(c) {
            continue;
        }
        valid += 1;
        psr_cpu += usize::from(c == 1.0);
        match (c == 1.0, g == 1.0) {
            (a, b) if a == b => agree += 1,
            (false, true) => gpu_psr_cpu_lit += 1,
            _ => gpu_lit_cpu_psr += 1,
        }
    }
    let agreement = agree as f64 / valid as f64;
    eprintln!(
        "psr_mask GPU vs CPU: {valid} valid pixels, {psr_cpu} PSR on the CPU, agreement {:.4}%, \
         GPU-PSR/CPU-lit {gpu_psr_cpu_lit}, GPU-lit/CPU-PSR {gpu_lit_cpu_psr}",
        100.0 * agreement
    );
    assert!(valid > 10_000, "{valid} valid pixels");
    assert!(
        psr_cpu > 0,
        "the fixture must have shadowed pixels to compare"
    );
    assert!(agreement >= MIN_PSR_AGREEMENT, "agreement {agreement}");
    assert!(
        gpu_psr_cpu_lit as f64 <= 1e-3 * valid as f64,
        "{gpu_psr_cpu_lit} pixels PSR on the GPU but lit on the CPU"
    );
    assert!(
        gpu_lit_cpu_psr as f64 <= 1e-3 * valid as f64,
        "{gpu_lit_cpu_psr} pixels lit on the GPU but PSR on the CPU"
    );
}

/// `map --backend gpu` with no adapter (WGPU_BACKEND=metal on Linux): one error line, exit 2,
/// and no output folder.
#[test]
fn map_backend_gpu_without_adapter_is_a_clean_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = map_range(dir.path(), Some("metal"), "gpu");
    let needle = if cfg!(feature = "gpu") {
        "no GPU adapter found"
    } else {
        "without the `gpu` cargo feature"
    };
    crate::util::assert_clean_error(&out, needle);
    assert!(!dir.path().join("gpu").exists());
}

/// `map --backend auto` with no adapter: exactly one warning line, then the CPU sweep succeeds
/// and run.json records the CPU backend.
#[test]
fn map_backend_auto_without_adapter_warns_once_and_uses_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let out = map_range(dir.path(), Some("metal"), "auto");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "stderr: {stderr}");
    // One backend warning; the only other warning a range map may print is the count of cells
    // lit by rays that leave the (40 km) DEM toward the sphere.
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("warning") && !l.contains("toward the reference sphere"))
        .collect();
    assert_eq!(warnings.len(), 1, "exactly one warning line: {stderr}");
    assert!(
        warnings[0].starts_with("penumbra: warning: --backend auto:"),
        "{stderr}"
    );
    let run_json = std::fs::read_to_string(dir.path().join("auto/run.json")).unwrap();
    assert!(run_json.contains("\"backend\": \"cpu"), "{run_json}");
    assert!(dir.path().join("auto/psr_mask.tif").is_file());
}

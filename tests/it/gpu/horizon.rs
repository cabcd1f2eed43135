//! Per-site horizons on the GPU (`shaders/horizon_scan.wgsl`, `penumbra::gpu::horizon`) and its
//! CPU twin (`penumbra::twins::horizon_scan`): naga layout of the shader's structs (never skipped),
//! the twin against the analytic dip and against the f64 exact scan (no GPU needed), and on an
//! adapter (lavapipe in CI: `WGPU_BACKEND=vulkan`) the GPU against the twin and against the
//! exact scan on the synthetic DEM and on the real LOLA grids (skipped with a reason when absent).
//! No adapter: a failure naming the adapter error, unless `PENUMBRA_SKIP=gpu` (a counted skip).

use std::path::Path;

use penumbra::MOON_RADIUS_M;
use penumbra::horizon::{Horizon, HorizonEngine, HorizonMethod, HorizonParams};
use penumbra::terrain::synth::{SynthParams, south_polar_dem};
use penumbra::terrain::{Dem, GridGeometry, Projection, TerrainStack};
use penumbra::twins::horizon_scan::{self, ScanParams, SiteParams};

/// Sorted |a - b| over the azimuths of several horizon pairs: (max, p99, mean).
fn diff_stats(a: &[Horizon], b: &[Horizon]) -> (f64, f64, f64) {
    let mut d: Vec<f64> = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| {
            x.elevation_deg
                .iter()
                .zip(&y.elevation_deg)
                .map(|(p, q)| (p - q).abs())
        })
        .collect();
    assert!(d.iter().all(|v| v.is_finite()));
    d.sort_by(f64::total_cmp);
    let q = |f: f64| d[((d.len() - 1) as f64 * f).round() as usize];
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    (q(1.0), q(0.99), mean)
}

fn exact(step_deg: f64) -> HorizonParams {
    HorizonParams {
        observer_height_m: 2.0,
        az_step_deg: step_deg,
        method: HorizonMethod::Exact,
        ..HorizonParams::default()
    }
}

fn synthetic_stack() -> TerrainStack {
    TerrainStack::new(vec![south_polar_dem(&SynthParams::default()).unwrap()])
}

/// Sites on the synthetic 40 km DEM: the pole, and points 3-9 km from it.
const SYNTH_SITES: [(f64, f64); 4] = [(-90.0, 0.0), (-89.9, 45.0), (-89.8, 200.0), (-89.7, 300.0)];

/// The shader's structs have the sizes of their Rust mirrors (naga's layouter); never skipped.
#[test]
fn horizon_scan_struct_layout_matches_rust() {
    let sizes = crate::util::wgsl_struct_sizes(&penumbra::gpu::shaders::HORIZON_SCAN);
    let size = |name: &str| sizes[name];
    assert_eq!(size("ScanParams"), size_of::<ScanParams>());
    assert_eq!(size("Site"), size_of::<SiteParams>());
    assert_eq!(size("Layer"), size_of::<horizon_scan::LayerParams>());
}

/// Oracle: geometry. A flat sphere (all heights 0) of 50 m cells reaching 10 km around the pole,
/// 2 m observer: the horizon is the dip `-acos(R / (R + h))` (tangent point 2.64 km away) at
/// every azimuth, for the twin as for the f64 scan.
#[test]
fn twin_flat_sphere_gives_the_geometric_dip() {
    let n = 400;
    let px_m = 50.0;
    let dem = Dem {
        grid: GridGeometry {
            rows: n,
            cols: n,
            x_left_m: -(n as f64) * px_m / 2.0,
            y_top_m: n as f64 * px_m / 2.0,
            px_x_m: px_m,
            px_y_m: px_m,
        },
        projection: Projection::LOLA_SOUTH_POLAR,
        heights_m: vec![0.0; n * n],
        name: "flat".into(),
    };
    let stack = TerrainStack::new(vec![dem]);
    let h = 2.0;
    let dip_deg = -(MOON_RADIUS_M / (MOON_RADIUS_M + h)).acos().to_degrees();
    let hz =
        horizon_scan::horizons_twin(&stack, &[(-90.0, 0.0), (-89.99, 30.0)], &exact(5.0)).unwrap();
    let err = hz
        .iter()
        .flat_map(|z| z.elevation_deg.iter().map(|e| (e - dip_deg).abs()))
        .fold(0.0, f64::max);
    println!("twin flat sphere: dip {dip_deg:.6} deg, max |error| {err:.2e} deg");
    // f32: heights and the 2 m observer are exact, the dip is 0.0869 deg; 1e-4 deg is 5 mm of
    // height at the 2.64 km tangent point (measured 1.5e-6 deg).
    assert!(err < 1e-4, "{err}");
}

/// A flat finest layer inside a coarser 100 m plateau: the horizon is the plateau's edge just
/// past the finest layer (see `coarser_layer_is_seen_from_the_finer_layers_edge` in
/// tests/it/horizon/mod.rs, where the f64 exact scan meets the closed form to 4e-9 deg). The twin
/// samples the coarser layer at the finer layer's edge as the exact scan does.
#[test]
fn twin_sees_the_coarser_layer_from_the_finer_layers_edge() {
    use penumbra::terrain::synth::square_dem_at;
    let stack = TerrainStack::new(vec![
        square_dem_at(201, 50.0, (0.0, 0.0), "fine", |_, _| 0.0),
        square_dem_at(101, 1_000.0, (0.0, 0.0), "far", |_, _| 100.0),
    ]);
    let sites = [(-89.99, 30.0), (-89.9, 100.0)];
    let p = exact(1.0);
    let engine = HorizonEngine::new(&stack);
    let twin = horizon_scan::horizons_twin(&stack, &sites, &p).unwrap();
    let mut worst: f64 = 0.0;
    for (&(lat, lon), tw) in sites.iter().zip(&twin) {
        let cpu = engine.horizon(lat, lon, &p).unwrap();
        for (a, b) in tw.elevation_deg.iter().zip(&cpu.elevation_deg) {
            worst = worst.max((a - b).abs());
        }
    }
    println!("twin - exact scan, plateau past the finer layer: max {worst:.2e} deg");
    // Without the edge samples: 0.23 deg (measured).
    assert!(worst < 2e-3, "{worst}");
}

/// The twin (f32, what the GPU computes) against the f64 exact scan on the synthetic DEM.
#[test]
fn twin_matches_exact_scan_on_synthetic_dem() {
    let stack = synthetic_stack();
    let p = exact(1.0);
    let engine = HorizonEngine::new(&stack);
    let cpu: Vec<Horizon> = SYNTH_SITES
        .iter()
        .map(|&(lat, lon)| engine.horizon(lat, lon, &p).unwrap())
        .collect();
    let twin = horizon_scan::horizons_twin(&stack, &SYNTH_SITES, &p).unwrap();
    let (max, p99, mean) = diff_stats(&twin, &cpu);
    println!("twin vs exact, synthetic: max {max:.2e} p99 {p99:.2e} mean {mean:.2e} deg");
    // Measured 5.5e-4 / 3.1e-4 deg (f32 positions and heights); bounds ~3x that.
    assert!(max < 2e-3 && p99 < 1e-3, "max {max} p99 {p99}");
}

#[cfg(feature = "gpu")]
fn real_stack(names: &[&str]) -> Option<TerrainStack> {
    let paths: Option<Vec<std::path::PathBuf>> =
        names.iter().map(|n| crate::util::shared_lola(n)).collect();
    Some(TerrainStack::load(&paths?).unwrap())
}

#[cfg(feature = "gpu")]
const INNER: &str = "ldem75s_crop_240m_pm184km.tif";
#[cfg(feature = "gpu")]
const FAR: &str = "ldem75s_far_1787m_pm457km_feathered.tif";
#[cfg(feature = "gpu")]
const SITE01: &str = "site01_connecting_ridge_10m.tif";
#[cfg(feature = "gpu")]
/// Connecting Ridge (as tests/it/horizon/mod.rs) and a point on the Shackleton rim side.
const REAL_SITES: [(f64, f64); 2] = [(-89.45, 222.7), (-89.68, 200.0)];

#[cfg(feature = "gpu")]
mod on_gpu {
    use penumbra::gpu::horizon::{GpuHorizonScan, horizons_gpu};
    use penumbra::twins::horizon_scan::{ScanTerrain, azimuth_table, horizon_scan, site_setup};

    use super::*;

    use crate::util::gpu;

    /// GPU vs twin on the synthetic DEM, raw kernel outputs: the same f32 algorithm, so only GPU
    /// rounding (FMA contraction, division) differs.
    #[test]
    fn horizon_scan_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let stack = synthetic_stack();
        let terrain = ScanTerrain::new(&stack).unwrap();
        let engine = HorizonEngine::new(&stack);
        let sites: Vec<SiteParams> = SYNTH_SITES
            .iter()
            .map(|&(lat, lon)| site_setup(&engine, lat, lon, 2.0).unwrap().site)
            .collect();
        let az = azimuth_table(1.0).unwrap();
        let scan = GpuHorizonScan::new(ctx, &terrain).unwrap();
        let gpu = scan.scan(ctx, &sites, &az).unwrap();
        let twin = horizon_scan(&terrain, &sites, &az);
        assert_eq!(gpu.len(), twin.len());
        let max_deg = gpu
            .iter()
            .zip(&twin)
            .map(|(g, t)| (g[0].atan() - t[0].atan()).abs().to_degrees())
            .fold(0.0_f32, f32::max);
        let same = gpu.iter().zip(&twin).filter(|(g, t)| g == t).count();
        println!(
            "GPU vs twin, synthetic, {} outputs: {same} bit-identical, max |Δ el| {max_deg:.2e} deg",
            gpu.len()
        );
        assert!(max_deg < 1e-4, "{max_deg}");
    }

    /// GPU vs the f64 exact scan on the synthetic DEM.
    #[test]
    fn horizons_gpu_match_exact_scan_on_synthetic_dem() {
        let Some(ctx) = gpu() else { return };
        let stack = synthetic_stack();
        let p = exact(1.0);
        let engine = HorizonEngine::new(&stack);
        let cpu: Vec<Horizon> = SYNTH_SITES
            .iter()
            .map(|&(lat, lon)| engine.horizon(lat, lon, &p).unwrap())
            .collect();
        let sites: Vec<(f64, f64, f64)> = SYNTH_SITES.iter().map(|&(a, b)| (a, b, 2.0)).collect();
        let gpu = horizons_gpu(ctx, &stack, None, &sites, 1.0).unwrap();
        let (max, p99, mean) = diff_stats(&gpu, &cpu);
        println!("GPU vs exact, synthetic: max {max:.2e} p99 {p99:.2e} mean {mean:.2e} deg");
        // Measured on lavapipe 5.5e-4 / 3.1e-4 deg (as the twin); bounds ~3x that.
        assert!(max < 2e-3 && p99 < 1e-3, "max {max} p99 {p99}");
        assert_eq!(gpu[1].ground_layer, cpu[1].ground_layer);
        assert_eq!(gpu[1].ground_height_m, cpu[1].ground_height_m);
    }

    /// GPU vs the f64 exact scan on the real LOLA stacks (240 m + far field; 10 m + 240 m + far
    /// field), 1440 azimuths, 2 m observer.
    #[test]
    fn horizons_gpu_match_exact_scan_on_real_lola_grids() {
        let Some(ctx) = gpu() else { return };
        for names in [&[INNER, FAR][..], &[SITE01, INNER, FAR][..]] {
            let Some(stack) = real_stack(names) else {
                return;
            };
            // The 10 m layer is 16 km wide: only the Connecting Ridge is on it.
            let sites: &[(f64, f64)] = if names.len() == 3 {
                &REAL_SITES[..1]
            } else {
                &REAL_SITES
            };
            let p = exact(0.25);
            let engine = HorizonEngine::new(&stack);
            let cpu: Vec<Horizon> = sites
                .iter()
                .map(|&(lat, lon)| engine.horizon(lat, lon, &p).unwrap())
                .collect();
            let s3: Vec<(f64, f64, f64)> = sites.iter().map(|&(a, b)| (a, b, 2.0)).collect();
            let gpu = horizons_gpu(ctx, &stack, None, &s3, 0.25).unwrap();
            let (max, p99, mean) = diff_stats(&gpu, &cpu);
            println!("GPU vs exact, {names:?}: max {max:.2e} p99 {p99:.2e} mean {mean:.2e} deg");
            // Measured on lavapipe: 240 m + far 1.4e-3 / 8.3e-4 deg, 10 m + 240 m + far
            // 4.9e-4 / 3.1e-4 deg (f32 map positions and heights). Bounds ~3x the worst.
            assert!(max < 5e-3 && p99 < 2.5e-3, "max {max} p99 {p99}");
        }
    }
}

// ---- The command line: `--backend` on `horizon` and `series`. ----

/// A 100 x 100 synthetic DEM (100 m) written by `penumbra dem synth` into `dir/dem.tif`.
fn synth_dem(dir: &Path) {
    let o = crate::util::penumbra_wgpu(
        dir,
        None,
        &["dem", "synth", "--size", "100", "--out", "dem.tif"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

const HORIZON_ARGS: [&str; 9] = [
    "horizon",
    "--dem",
    "dem.tif",
    "--lat-deg",
    "-89.9",
    "--lon-deg",
    "30",
    "--az-step-deg",
    "2",
];

/// Without an adapter (`WGPU_BACKEND=metal` on Linux): `--backend auto` (the default) takes the
/// CPU scan for one site without probing, so it says nothing and writes what `--backend cpu`
/// writes; `--backend gpu` is a one-line error, exit 2, and writes nothing.
#[test]
fn horizon_backend_without_adapter() {
    let dir = tempfile::tempdir().unwrap();
    synth_dem(dir.path());
    let run = |backend: &str, out: &str| {
        let mut args = HORIZON_ARGS.to_vec();
        args.extend(["--backend", backend, "--out", out]);
        crate::util::penumbra_wgpu(dir.path(), Some("metal"), &args)
    };
    let cpu = run("cpu", "cpu.csv");
    assert!(
        cpu.status.success(),
        "{}",
        String::from_utf8_lossy(&cpu.stderr)
    );
    let auto = run("auto", "auto.csv");
    assert!(
        auto.status.success(),
        "{}",
        String::from_utf8_lossy(&auto.stderr)
    );
    let err = String::from_utf8_lossy(&auto.stderr);
    assert!(err.trim().is_empty(), "{err}");
    let read = |f: &str| std::fs::read_to_string(dir.path().join(f)).unwrap();
    assert_eq!(read("auto.csv"), read("cpu.csv"));
    let gpu = run("gpu", "gpu.csv");
    assert_eq!(gpu.status.code(), Some(2));
    let err = String::from_utf8_lossy(&gpu.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("no GPU adapter found"), "{err}");
    assert!(!dir.path().join("gpu.csv").exists());
}

/// Per-epoch fractions of column `col` of a site's series.csv.
#[cfg(feature = "gpu")]
fn csv_column(path: &Path, col: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let i = header.iter().position(|h| *h == col).unwrap();
    lines
        .map(|l| l.split(',').nth(i).unwrap().parse().unwrap())
        .collect()
}

/// On an adapter: `penumbra horizon --backend gpu` agrees with `--method exact` on the CPU, and
/// `penumbra series --backend gpu` agrees with the CPU series (exact horizons) epoch by epoch.
#[cfg(feature = "gpu")]
#[test]
fn horizon_and_series_backend_gpu_match_cpu() {
    if on_gpu_context_missing() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    synth_dem(dir.path());
    let run = |extra: &[&str], out: &str| {
        let mut args = HORIZON_ARGS.to_vec();
        args.extend(extra);
        args.extend(["--out", out]);
        let o = crate::util::penumbra_wgpu(dir.path(), None, &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&["--method", "exact"], "cpu.csv");
    run(&["--backend", "gpu"], "gpu.csv");
    let cpu = csv_column(&dir.path().join("cpu.csv"), "horizon_el_deg");
    let gpu = csv_column(&dir.path().join("gpu.csv"), "horizon_el_deg");
    assert_eq!(cpu.len(), 180);
    let max = cpu
        .iter()
        .zip(&gpu)
        .map(|(c, g)| (c - g).abs())
        .fold(0.0, f64::max);
    println!("penumbra horizon --backend gpu vs cpu exact: max |Δ| {max:.2e} deg");
    assert!(max < 2e-3, "{max}");

    let k = crate::util::kernels_dir();
    let series = |backend: &str, out: &str| {
        let o = crate::util::penumbra_wgpu(
            dir.path(),
            None,
            &[
                "series",
                "--dem",
                "dem.tif",
                "--site",
                "a,-89.9,30",
                "--site",
                "b,-89.87,200,10",
                "--start",
                "2027-01-01",
                "--stop",
                "2027-01-29",
                "--step",
                "3h",
                "--az-step-deg",
                "0.5",
                "--horizon-method",
                "exact",
                "--no-plots",
                "--kernels",
                k.to_str().unwrap(),
                "--backend",
                backend,
                "--out-dir",
                out,
            ],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    series("cpu", "cpu");
    series("gpu", "gpu");
    let mut max = 0.0_f64;
    let mut n = 0;
    for site in ["a", "b"] {
        for col in ["sun_visible_fraction", "earth_visible_fraction"] {
            let c = csv_column(&dir.path().join(format!("cpu/{site}/series.csv")), col);
            let g = csv_column(&dir.path().join(format!("gpu/{site}/series.csv")), col);
            assert_eq!(c.len(), g.len());
            n += c.iter().filter(|f| **f > 0.0 && **f < 1.0).count();
            max = c
                .iter()
                .zip(&g)
                .map(|(a, b)| (a - b).abs())
                .fold(max, f64::max);
        }
    }
    println!("series --backend gpu vs cpu: max |Δ fraction| {max:.2e} ({n} partial-disc epochs)");
    // Measured on lavapipe 9.1e-5. Bound: a horizon error of 5e-4 deg (3x the p99 above) moves
    // a 0.27 deg Sun disc's visible fraction by at most ~5e-4 / 0.27 * 1.27 ~ 2.4e-3 (chord through
    // the centre, d(fraction)/d(apothem / radius) = 4 / pi / 2 * 2).
    assert!(max < 2.5e-3, "{max}");
}

/// The scenario key `backend` of `[series]` parses (cpu/gpu/auto, default auto) and rejects
/// anything else with a message naming the choices.
#[test]
fn series_config_backend_key() {
    use penumbra::gpu::Backend;
    use penumbra::products::series::SeriesConfig;
    let parse = |t: &str| toml::from_str::<SeriesConfig>(t);
    assert_eq!(parse("").unwrap().backend, Backend::Auto);
    assert_eq!(parse("backend = \"cpu\"").unwrap().backend, Backend::Cpu);
    assert_eq!(parse("backend = \"gpu\"").unwrap().backend, Backend::Gpu);
    assert_eq!(parse("backend = \"auto\"").unwrap().backend, Backend::Auto);
    let err = parse("backend = \"cuda\"").unwrap_err().to_string();
    assert!(
        err.contains("unknown backend 'cuda' (use cpu, gpu or auto)"),
        "{err}"
    );
}

/// Whether no GPU context exists (the rule of [`crate::util::gpu`]: a failure naming the
/// adapter error, or a recorded skip with `PENUMBRA_SKIP=gpu`).
#[cfg(feature = "gpu")]
fn on_gpu_context_missing() -> bool {
    crate::util::gpu().is_none()
}

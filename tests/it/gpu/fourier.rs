//! Fourier horizon maps on the GPU (`shaders/fourier_build.wgsl`, `shaders/fourier_eval.wgsl`):
//! the f32 CPU twin against the f64 CPU engine (`shadow::fourier`; always run), the GPU against the
//! twin and the engine, band/chunk seams, and the CLI (`horizon-map build --backend`, `map
//! --engine fourier --backend gpu`). GPU tests fail naming the adapter error when no adapter
//! exists, unless `PENUMBRA_SKIP=gpu` counts them as skipped. naga validation of both shaders is part of
//! `gpu::naga_validates_every_shader` (every shader of `penumbra::gpu::shaders`).

use penumbra::shadow::fourier::{self, HorizonMap, HorizonMapMeta, HorizonMapParams};
use penumbra::shadow::{MASK_NODATA, SUN_ANGULAR_RADIUS_RAD};
use penumbra::terrain::HeightField;
use penumbra::twins::MarchGrid;
use penumbra::twins::fourier::{self as fourier_twin, FourierEvalParams};

use crate::util::hills;

const OBSERVER_M: f64 = 2.0;
/// Grazing, low and moderate Suns, azimuths off the grid axes (as `gpu/mod.rs`).
const SUNS_DEG: [(f64, f64); 3] = [(0.5, 37.0), (1.5, 151.0), (5.0, 262.0)];

fn light(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    [az.sin() * el.cos(), az.cos() * el.cos(), el.sin()]
}

fn params(hf: &HeightField, n_az: usize) -> HorizonMapParams {
    HorizonMapParams {
        observer_height_m: OBSERVER_M,
        n_azimuths: n_az,
        max_distance_cells: hf.rows + hf.cols,
        n_coeffs: fourier::DEFAULT_COEFFS,
    }
}

fn cpu_map(hf: &HeightField, p: &HorizonMapParams) -> HorizonMap {
    HorizonMap::build_with(
        hf,
        p.observer_height_m,
        p.n_azimuths,
        p.max_distance_cells,
        p.n_coeffs,
    )
    .unwrap()
}

fn twin_map(hf: &HeightField, p: &HorizonMapParams) -> HorizonMap {
    let grid = MarchGrid::from_height_field(hf, p.observer_height_m).unwrap();
    let values =
        fourier_twin::build_coeffs_twin(&grid, p.n_azimuths, p.n_coeffs, p.max_distance_cells);
    fourier_twin::horizon_map_from_f32(HorizonMapMeta::for_height_field(hf, p), &values)
}

/// |Δ| statistics of two maps: (coefficients max, mean) in radians over valid cells; the
/// reconstructed horizon at the N sampled azimuths (max, mean) in degrees; cells where exactly
/// one map is a hole.
struct MapDelta {
    coeff_max_rad: f64,
    coeff_mean_rad: f64,
    horizon_max_deg: f64,
    horizon_mean_deg: f64,
    /// Horizon samples with |Δ| > 0.01°.
    horizon_over_001_deg: usize,
    hole_mismatch: usize,
}

fn map_delta(a: &HorizonMap, b: &HorizonMap) -> MapDelta {
    assert_eq!(a.meta, b.meta, "same metadata");
    assert_eq!(a.coeffs.len(), b.coeffs.len(), "same layout");
    let (rows, cols, n_az) = (a.meta.rows, a.meta.cols, a.meta.n_azimuths);
    let (mut c_max, mut c_sum, mut c_n) = (0.0_f64, 0.0_f64, 0usize);
    let (mut h_max, mut h_sum, mut h_n, mut h_over) = (0.0_f64, 0.0_f64, 0usize, 0usize);
    let mut hole_mismatch = 0;
    for row in 0..rows {
        for col in 0..cols {
            let (ca, cb) = (a.cell(row, col), b.cell(row, col));
            let (ha, hb) = (ca[0].is_nan(), cb[0].is_nan());
            if ha || hb {
                hole_mismatch += usize::from(ha != hb);
                continue;
            }
            for (x, y) in ca.iter().zip(cb) {
                let d = (x.to_f64() - y.to_f64()).abs();
                c_max = c_max.max(d);
                c_sum += d;
                c_n += 1;
            }
            for n in 0..n_az {
                let az = std::f64::consts::TAU * n as f64 / n_az as f64;
                let d = f64::from(a.elevation_rad(row, col, az) - b.elevation_rad(row, col, az))
                    .abs()
                    .to_degrees();
                h_max = h_max.max(d);
                h_over += usize::from(d > 0.01);
                h_sum += d;
                h_n += 1;
            }
        }
    }
    MapDelta {
        coeff_max_rad: c_max,
        coeff_mean_rad: c_sum / c_n.max(1) as f64,
        horizon_max_deg: h_max,
        horizon_mean_deg: h_sum / h_n.max(1) as f64,
        horizon_over_001_deg: h_over,
        hole_mismatch,
    }
}

fn report(label: &str, d: &MapDelta) {
    eprintln!(
        "{label}: coeff max |Δ| {:.2e} rad, mean {:.2e} rad; horizon max |Δ| {:.2e}°, mean {:.2e}°, \
         {} samples > 0.01°; hole mismatches {}",
        d.coeff_max_rad,
        d.coeff_mean_rad,
        d.horizon_max_deg,
        d.horizon_mean_deg,
        d.horizon_over_001_deg,
        d.hole_mismatch
    );
}

/// Asserts the |Δ| bounds: coefficients (radians) and reconstructed horizon (degrees).
fn assert_bounds(d: &MapDelta, coeff_max: f64, coeff_mean: f64, hor_max: f64, hor_mean: f64) {
    assert!(
        d.coeff_max_rad < coeff_max,
        "coeff max {:.2e}",
        d.coeff_max_rad
    );
    assert!(
        d.coeff_mean_rad < coeff_mean,
        "coeff mean {:.2e}",
        d.coeff_mean_rad
    );
    assert!(
        d.horizon_max_deg < hor_max,
        "horizon max {:.2e}",
        d.horizon_max_deg
    );
    assert!(
        d.horizon_mean_deg < hor_mean,
        "horizon mean {:.2e}",
        d.horizon_mean_deg
    );
}

/// Oracle: the f64 CPU engine. The f32 twin's map (same DDA, f32 heights relative to z_ref,
/// f32 azimuth directions, f32 DFT) on the 128² hills, 64 azimuths, whole-grid rays.
#[test]
fn fourier_twin_matches_cpu_engine() {
    let hf = hills(128);
    let p = params(&hf, 64);
    let cpu = cpu_map(&hf, &p);
    let twin = twin_map(&hf, &p);
    let d = map_delta(&cpu, &twin);
    report("twin vs CPU engine (128², 64 az)", &d);
    assert_eq!(d.hole_mismatch, 0);
    assert_bounds(&d, 5e-4, 1e-7, 0.03, 1e-4);
}

/// The evaluation twin against the f64 CPU engine on the same map: soft fractions and the hard
/// test (the twin evaluates eq. 3 in f32 by the rotation recurrence).
#[test]
fn fourier_eval_twin_matches_cpu_engine() {
    let hf = hills(96);
    let map = cpu_map(&hf, &params(&hf, 64));
    for (el, az) in SUNS_DEG {
        let l = light(az, el);
        let cpu = fourier::visible_fraction(&map, l, SUN_ANGULAR_RADIUS_RAD).unwrap();
        let fe = FourierEvalParams::new(&map.meta, l, SUN_ANGULAR_RADIUS_RAD).unwrap();
        let twin = fourier_twin::fourier_eval(&map, &fe);
        let (max, mean, mismatch) = fraction_delta(&cpu, &twin);
        eprintln!("eval twin vs CPU at el {el}°: fraction max |Δ| {max:.2e}, mean {mean:.2e}");
        assert_eq!(mismatch, 0);
        assert!(max < 1e-4 && mean < 1e-6, "max {max:.2e} mean {mean:.2e}");
        let cpu_mask = fourier::hard_mask(&map, l).unwrap();
        let fe0 = FourierEvalParams::new(&map.meta, l, 0.0).unwrap();
        let twin_mask = to_mask(&fourier_twin::fourier_eval(&map, &fe0));
        let differ = cpu_mask
            .iter()
            .zip(&twin_mask)
            .filter(|(a, b)| a != b)
            .count();
        eprintln!(
            "eval twin vs CPU at el {el}°: {differ} of {} mask cells differ",
            cpu_mask.len()
        );
        assert!(differ <= 2, "{differ} mask cells differ");
    }
}

/// Max and mean |a − b| over cells where both are data (NaN or < 0 is nodata), and the number of
/// cells where exactly one is nodata.
fn fraction_delta(a: &[f32], b: &[f32]) -> (f64, f64, usize) {
    let (mut max, mut sum, mut n, mut mismatch) = (0.0_f64, 0.0_f64, 0usize, 0usize);
    for (&x, &y) in a.iter().zip(b) {
        let (xn, yn) = (x.is_nan() || x < 0.0, y.is_nan() || y < 0.0);
        if xn || yn {
            mismatch += usize::from(xn != yn);
            continue;
        }
        let d = f64::from((x - y).abs());
        max = max.max(d);
        sum += d;
        n += 1;
    }
    (max, sum / n.max(1) as f64, mismatch)
}

fn to_mask(f: &[f32]) -> Vec<u8> {
    f.iter()
        .map(|&v| {
            if v < 0.0 {
                MASK_NODATA
            } else if v > 0.5 {
                1
            } else {
                0
            }
        })
        .collect()
}

#[cfg(feature = "gpu")]
mod on_gpu {
    use penumbra::gpu::DEFAULT_BAND_BYTES;
    use penumbra::gpu::fourier::{
        GpuBuildOptions, GpuHorizonMap, build_horizon_map_gpu, build_horizon_map_gpu_with,
    };

    use super::*;

    pub(super) use crate::util::gpu;

    /// GPU build vs the twin (oracle for the GPU's arithmetic) and vs the f64 CPU engine
    /// (oracle for the result), 128² hills, 64 azimuths, whole-grid rays.
    #[test]
    fn fourier_build_gpu_matches_twin_and_cpu() {
        let Some(ctx) = gpu() else { return };
        let hf = hills(128);
        let p = params(&hf, 64);
        let gpu_map = build_horizon_map_gpu(ctx, &hf, &p).unwrap();
        let twin = twin_map(&hf, &p);
        let d = map_delta(&twin, &gpu_map);
        report("GPU vs twin (128², 64 az)", &d);
        assert_eq!(d.hole_mismatch, 0);
        assert_bounds(&d, 5e-4, 1e-6, 0.03, 5e-4);
        let cpu = cpu_map(&hf, &p);
        let d = map_delta(&cpu, &gpu_map);
        report("GPU vs CPU engine (128², 64 az)", &d);
        assert_eq!(d.hole_mismatch, 0);
        assert_bounds(&d, 5e-4, 1e-6, 0.03, 5e-4);
    }

    /// Row bands and azimuth chunks do not change the result: 5-row bands × 7-azimuth dispatches
    /// are bit-identical to one band × one dispatch (partial sums round-trip exactly through f32
    /// storage).
    #[test]
    fn fourier_build_gpu_bands_and_chunks_are_seamless() {
        let Some(ctx) = gpu() else { return };
        let hf = hills(48);
        let p = params(&hf, 32);
        let one = build_horizon_map_gpu_with(
            ctx,
            &hf,
            &p,
            &GpuBuildOptions {
                band_bytes: DEFAULT_BAND_BYTES,
                azimuths_per_dispatch: 32,
            },
        )
        .unwrap();
        let per_cell_bytes = 2 * p.n_coeffs as u64 * 4;
        let split = build_horizon_map_gpu_with(
            ctx,
            &hf,
            &p,
            &GpuBuildOptions {
                band_bytes: 5 * 48 * per_cell_bytes,
                azimuths_per_dispatch: 7,
            },
        )
        .unwrap();
        let bits = |m: &HorizonMap| m.coeffs.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&one), bits(&split));
    }

    /// GPU evaluation vs the twin and the f64 CPU engine on one CPU-built map (128² hills): soft
    /// Sun fractions and hard masks at three Suns; also banded uploads equal one band.
    #[test]
    fn fourier_eval_gpu_matches_twin_and_cpu() {
        let Some(ctx) = gpu() else { return };
        let hf = hills(128);
        let map = cpu_map(&hf, &params(&hf, 64));
        let on_gpu = GpuHorizonMap::upload(ctx, &map, DEFAULT_BAND_BYTES).unwrap();
        let banded = GpuHorizonMap::upload(ctx, &map, 11 * 128 * 16 * 4).unwrap();
        for (el, az) in SUNS_DEG {
            let l = light(az, el);
            let g = on_gpu
                .visible_fraction(ctx, l, SUN_ANGULAR_RADIUS_RAD)
                .unwrap();
            let fe = FourierEvalParams::new(&map.meta, l, SUN_ANGULAR_RADIUS_RAD).unwrap();
            let twin = fourier_twin::fourier_eval(&map, &fe);
            let (max_t, mean_t, mm_t) = fraction_delta(&twin, &g);
            let cpu = fourier::visible_fraction(&map, l, SUN_ANGULAR_RADIUS_RAD).unwrap();
            let (max_c, mean_c, mm_c) = fraction_delta(&cpu, &g);
            let penumbra = cpu.iter().filter(|&&f| f > 0.0 && f < 1.0).count();
            eprintln!(
                "eval at el {el}°: GPU vs twin max |Δ| {max_t:.2e} mean {mean_t:.2e}; GPU vs CPU \
                 max |Δ| {max_c:.2e} mean {mean_c:.2e}; {penumbra} penumbra cells"
            );
            assert_eq!((mm_t, mm_c), (0, 0));
            assert!(
                max_t < 2e-4 && mean_t < 2e-6,
                "vs twin {max_t:.2e} {mean_t:.2e}"
            );
            assert!(
                max_c < 2e-4 && mean_c < 2e-6,
                "vs CPU {max_c:.2e} {mean_c:.2e}"
            );
            assert_eq!(
                banded
                    .visible_fraction(ctx, l, SUN_ANGULAR_RADIUS_RAD)
                    .unwrap(),
                g
            );
            let gm = on_gpu.hard_mask(ctx, l).unwrap();
            let cm = fourier::hard_mask(&map, l).unwrap();
            let differ = gm.iter().zip(&cm).filter(|(a, b)| a != b).count();
            let dark = cm.iter().filter(|&&m| m == 0).count();
            eprintln!(
                "hard mask at el {el}°: {differ} of {} cells differ ({dark} dark)",
                cm.len()
            );
            assert!(differ <= 3, "{differ} mask cells differ");
        }
    }
}

/// `horizon-map build --backend gpu` writes the same map as `--backend cpu` (synthetic DEM,
/// 404² model grid, 32 azimuths, whole-grid rays), within the bounds of the library test. (A
/// short integer `--max-distance-cells` is avoided on purpose: at the axis-aligned azimuths the
/// crossings fall at integer distances, and whether the one at exactly the limit is sampled is
/// decided by f32 vs f64 rounding; docs/gpu.md.)
#[cfg(feature = "gpu")]
#[test]
fn cli_horizon_map_build_gpu_matches_cpu() {
    if on_gpu::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for backend in ["cpu", "gpu"] {
        let out = crate::util::penumbra_wgpu(
            dir.path(),
            None,
            &[
                "horizon-map",
                "build",
                "--synthetic",
                "--azimuths",
                "32",
                "--backend",
                backend,
                "--out",
                &format!("{backend}.tif"),
            ],
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(stderr.contains(&format!("on {backend}")), "{stderr}");
    }
    let cpu = HorizonMap::read_tiff(&dir.path().join("cpu.tif")).unwrap();
    let gpu = HorizonMap::read_tiff(&dir.path().join("gpu.tif")).unwrap();
    let d = map_delta(&cpu, &gpu);
    report("CLI horizon-map build gpu vs cpu (404², 32 az)", &d);
    assert_eq!(d.hole_mismatch, 0);
    assert_bounds(&d, 2e-3, 2e-6, 0.2, 1e-3);
}

/// `map --engine fourier --backend gpu` (horizon map built and evaluated on the GPU) against
/// `--backend cpu` on the synthetic DEM, Sun at 5°: fraction and mask GeoTIFFs.
#[cfg(feature = "gpu")]
#[test]
fn cli_map_fourier_gpu_matches_cpu() {
    if on_gpu::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for backend in ["cpu", "gpu"] {
        let out = crate::util::penumbra_wgpu(
            dir.path(),
            None,
            &[
                "map",
                "--synthetic",
                "--engine",
                "fourier",
                "--sun-az-deg",
                "135",
                "--sun-el-deg",
                "5",
                "--backend",
                backend,
                "--out-fraction",
                &format!("f_{backend}.tif"),
                "--out-mask",
                &format!("m_{backend}.tif"),
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let read = |name: &str| penumbra::terrain::read_geotiff(&dir.path().join(name)).unwrap();
    let (fc, fg) = (read("f_cpu.tif"), read("f_gpu.tif"));
    let (max, mean, mismatch) = fraction_delta(&fc.heights_m, &fg.heights_m);
    let (mc, mg) = (read("m_cpu.tif"), read("m_gpu.tif"));
    let differ = mc
        .heights_m
        .iter()
        .zip(&mg.heights_m)
        .filter(|(a, b)| a != b)
        .count();
    eprintln!(
        "CLI map --engine fourier gpu vs cpu: fraction max |Δ| {max:.2e}, mean {mean:.2e}; \
         {differ} of {} mask pixels differ",
        mc.heights_m.len()
    );
    assert_eq!(mismatch, 0);
    assert!(
        max < 0.05 && mean < 2e-5,
        "fraction max {max:.2e} mean {mean:.2e}"
    );
    assert!(
        differ * 1000 <= mc.heights_m.len(),
        "{differ} mask pixels differ (bound 0.1%)"
    );
}

/// `horizon-map build --backend gpu` without any adapter (WGPU_BACKEND=metal on Linux) is one
/// clean error line, exit 2, no file; `--backend auto` falls back to the CPU with exactly one
/// warning line and writes the map.
#[test]
fn cli_horizon_map_build_backend_without_adapter() {
    let dir = tempfile::tempdir().unwrap();
    let args = |backend: &'static str, out: &'static str| {
        [
            "horizon-map",
            "build",
            "--synthetic",
            "--azimuths",
            "32",
            "--max-distance-cells",
            "4",
            "--backend",
            backend,
            "--out",
            out,
        ]
    };
    let gpu = crate::util::penumbra_wgpu(dir.path(), Some("metal"), &args("gpu", "g.tif"));
    let needle = if cfg!(feature = "gpu") {
        "no GPU adapter found"
    } else {
        "without the `gpu` cargo feature"
    };
    crate::util::assert_clean_error(&gpu, needle);
    assert!(!dir.path().join("g.tif").exists(), "nothing written");
    let auto = crate::util::penumbra_wgpu(dir.path(), Some("metal"), &args("auto", "a.tif"));
    let stderr = String::from_utf8_lossy(&auto.stderr);
    assert!(auto.status.success(), "{stderr}");
    assert!(!stderr.contains("warning"), "no warning: {stderr}");
    let said = stderr
        .lines()
        .filter(|l| l.starts_with("penumbra: --backend auto:"))
        .count();
    assert_eq!(said, 1, "exactly one line on the fallback: {stderr}");
    assert!(stderr.contains("on cpu"), "{stderr}");
    let map = HorizonMap::read_tiff(&dir.path().join("a.tif")).unwrap();
    assert_eq!(map.meta.n_azimuths, 32);
}

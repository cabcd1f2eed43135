//! GPU DP soft shadows (`shaders/dp_visible.wgsl`, `shaders/dp_sweep.wgsl`): the f32 CPU twin
//! against the f64 reference engines (`shadow::dp`, `shadow::brute`; always run), and the GPU
//! against the twin and the references (lavapipe in CI; no adapter is a failure naming the
//! adapter error, unless `PENUMBRA_SKIP=gpu` counts the test as skipped). naga validation of the DP shaders is
//! part of `gpu::naga_validates_every_shader` (every `shaders/*.wgsl`).

#[cfg(feature = "gpu")]
use crate::util::OutputWithin as _;
use penumbra::shadow::{Engine, SUN_ANGULAR_RADIUS_RAD, dp};
use penumbra::twins::{self, DpMip, MarchGrid, RowBand};

#[cfg(feature = "gpu")]
use crate::util::sweep_lights;
use crate::util::{hills, sun_dir};

/// Grazing, low and moderate Suns, azimuths off the grid axes (as `gpu/mod.rs`).
const SUNS_DEG: [(f64, f64); 3] = [(0.5, 37.0), (1.5, 151.0), (5.0, 262.0)];
const OBSERVER_M: f64 = 2.0;

/// Max and mean |a − b| over cells where both are data (`a` NaN / `b` < 0 is nodata) and the
/// number of cells where exactly one is nodata.
fn deltas(reference: &[f32], other: &[f32]) -> (f64, f64, usize) {
    let (mut max, mut sum, mut n, mut mismatch) = (0.0_f64, 0.0_f64, 0usize, 0usize);
    for (&a, &b) in reference.iter().zip(other) {
        let a_nodata = a.is_nan() || a < 0.0;
        let b_nodata = b.is_nan() || b < 0.0;
        if a_nodata || b_nodata {
            mismatch += usize::from(a_nodata != b_nodata);
            continue;
        }
        let d = f64::from((a - b).abs());
        max = max.max(d);
        sum += d;
        n += 1;
    }
    (max, sum / n.max(1) as f64, mismatch)
}

fn penumbra_cells(map: &[f32]) -> usize {
    map.iter().filter(|&&f| f > 0.0 && f < 1.0).count()
}

/// The twin's mipmap equals the f64 reference's MaxMipmap semantics: every level-0 texel is the
/// max of its four corners and every coarser texel the max of its 2 × 2 children (independent
/// recomputation), down to one texel holding the grid's maximum.
#[test]
fn dp_twin_mipmap_bounds_the_surface() {
    let hf = hills(37);
    let grid = MarchGrid::from_height_field(&hf, OBSERVER_M).unwrap();
    let mip = DpMip::build(&grid);
    let top = mip.levels.last().unwrap();
    assert_eq!((top[0], top[1]), (1, 1));
    assert_eq!(mip.texels[top[2] as usize], grid.z_max_m);
    let [r0, c0, _, _] = mip.levels[0];
    assert_eq!((r0, c0), (36, 36));
    for i in 0..36usize {
        for j in 0..36usize {
            let corners = [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
                .map(|(r, c)| grid.heights_m[r * 37 + c])
                .into_iter()
                .fold(f32::MIN, f32::max);
            assert_eq!(mip.texels[i * 36 + j], corners);
            // Level 3 texel covering it.
            let l3 = mip.levels[3];
            let v = mip.texels[(l3[2] + (i as u32 / 8) * l3[1] + j as u32 / 8) as usize];
            assert!(v >= corners);
        }
    }
}

/// Oracle: the f64 reference engines. The twin's visible fraction vs `dp::visible_fraction`
/// (same cost model, f64, interval search) and its radius-0 mask vs `Engine::Brute.hard_mask` (the
/// exhaustive march) on the 128² hills.
#[test]
fn dp_twin_matches_reference_engines() {
    let n = 128;
    let hf = hills(n);
    let grid = MarchGrid::from_height_field(&hf, OBSERVER_M).unwrap();
    let mip = DpMip::build(&grid);
    for (el_deg, az_deg) in SUNS_DEG {
        let dir = sun_dir(az_deg, el_deg);
        let reference = dp::visible_fraction(
            &hf,
            OBSERVER_M,
            dir.into(),
            SUN_ANGULAR_RADIUS_RAD,
            &dp::DpConfig::default(),
        )
        .unwrap();
        let light = twins::disc_light_to_f32(&dir, SUN_ANGULAR_RADIUS_RAD);
        let twin = twins::dp_visible(&grid, &mip, &[light], 0, RowBand::whole(&grid));
        let (max, mean, mismatch) = deltas(&reference, &twin);
        let partial = penumbra_cells(&reference);
        eprintln!(
            "dp twin vs dp::visible_fraction {n}² el {el_deg}°: max |Δ| {max:.2e} mean |Δ| {mean:.2e}, penumbra cells {partial}"
        );
        assert_eq!(mismatch, 0);
        assert!(partial > 50, "fixture needs penumbra cells");
        assert!(max <= TWIN_VS_DP_MAX && mean <= TWIN_VS_DP_MEAN);

        let brute = Engine::Brute
            .hard_mask(&hf, OBSERVER_M, dir.into())
            .unwrap();
        let hard = twins::disc_light_to_f32(&dir, 0.0);
        let twin_hard = twins::dp_visible(&grid, &mip, &[hard], 0, RowBand::whole(&grid));
        let differ = brute
            .iter()
            .zip(&twin_hard)
            .filter(|(b, t)| **b != 255 && f32::from(**b) != **t)
            .count();
        let dark = brute.iter().filter(|&&b| b == 0).count();
        eprintln!(
            "dp twin hard vs brute {n}² el {el_deg}°: {differ} cells differ, brute dark {dark}"
        );
        assert!(dark > n * n / 50);
        assert!(differ as f64 <= TWIN_VS_BRUTE_HARD_FRACTION * (n * n) as f64);
    }
}

/// Bounds measured on the hills fixtures (see docs/VALIDATION.md).
const TWIN_VS_DP_MAX: f64 = 1e-2;
const TWIN_VS_DP_MEAN: f64 = 5e-6;
const TWIN_VS_BRUTE_HARD_FRACTION: f64 = 1e-3;

#[cfg(feature = "gpu")]
pub(crate) mod on_gpu {
    use penumbra::gpu::dp::{DpSweepOptions, GpuDpGrid, dp_sweep_gpu, dp_visible_gpu};
    use penumbra::twins::DpCellStats;

    use super::*;

    use crate::util::gpu;

    /// GPU vs its f32 twin (same algorithm, same arithmetic) and vs `dp::visible_fraction` (f64)
    /// on the 256² hills, soft (Sun radius) and hard (radius 0), bands of 50 rows.
    #[test]
    fn dp_visible_gpu_matches_twin_and_reference() {
        let Some(ctx) = gpu() else { return };
        let n = 256;
        let hf = hills(n);
        let grid = MarchGrid::from_height_field(&hf, OBSERVER_M).unwrap();
        let mip = DpMip::build(&grid);
        let on_gpu = GpuDpGrid::upload(ctx, &grid, &mip).unwrap();
        for (el_deg, az_deg) in SUNS_DEG {
            let dir = sun_dir(az_deg, el_deg);
            let light = twins::disc_light_to_f32(&dir, SUN_ANGULAR_RADIUS_RAD);
            let twin = twins::dp_visible(&grid, &mip, &[light], 0, RowBand::whole(&grid));
            let gpu_map = dp_visible_gpu(ctx, &on_gpu, light, 50 * n as u64 * 4).unwrap();
            let (max, mean, mismatch) = deltas(&twin, &gpu_map);
            eprintln!(
                "dp_visible gpu vs twin {n}² el {el_deg}°: max |Δ| {max:.2e} mean |Δ| {mean:.2e}"
            );
            assert_eq!(mismatch, 0);
            assert!(max <= GPU_VS_TWIN_MAX && mean <= GPU_VS_TWIN_MEAN);
            let reference = dp::visible_fraction(
                &hf,
                OBSERVER_M,
                dir.into(),
                SUN_ANGULAR_RADIUS_RAD,
                &dp::DpConfig::default(),
            )
            .unwrap();
            let (max, mean, mismatch) = deltas(&reference, &gpu_map);
            eprintln!(
                "dp_visible gpu vs dp::visible_fraction {n}² el {el_deg}°: max |Δ| {max:.2e} mean |Δ| {mean:.2e}, penumbra {}",
                penumbra_cells(&reference)
            );
            assert_eq!(mismatch, 0);
            assert!(max <= TWIN_VS_DP_MAX && mean <= TWIN_VS_DP_MEAN);

            let hard = twins::disc_light_to_f32(&dir, 0.0);
            let gpu_hard = dp_visible_gpu(ctx, &on_gpu, hard, 50 * n as u64 * 4).unwrap();
            let brute = Engine::Brute
                .hard_mask(&hf, OBSERVER_M, dir.into())
                .unwrap();
            let differ = brute
                .iter()
                .zip(&gpu_hard)
                .filter(|(b, g)| **b != 255 && f32::from(**b) != **g)
                .count();
            eprintln!("dp_visible gpu hard vs brute {n}² el {el_deg}°: {differ} cells differ");
            assert!(differ as f64 <= TWIN_VS_BRUTE_HARD_FRACTION * (n * n) as f64);
        }
    }

    /// Of two sweeps' statistics: how many cells have all four counts equal, and the largest
    /// |Δ| of the Sun's fraction sum.
    pub(crate) fn stats_agreement(a: &[DpCellStats], b: &[DpCellStats]) -> (usize, f64) {
        let counts = |s: &DpCellStats| {
            (
                s.sun_visible_epochs,
                s.longest_dark_run_epochs,
                s.earth_visible_epochs,
                s.sun_and_earth_epochs,
            )
        };
        let equal = a
            .iter()
            .zip(b)
            .filter(|(x, y)| counts(x) == counts(y))
            .count();
        let max_sum = a
            .iter()
            .zip(b)
            .map(|(x, y)| f64::from((x.sun_fraction_sum - y.sun_fraction_sum).abs()))
            .fold(0.0, f64::max);
        (equal, max_sum)
    }

    /// Bounds measured on lavapipe (docs/VALIDATION.md).
    const GPU_VS_TWIN_MAX: f64 = 2e-4;
    const GPU_VS_TWIN_MEAN: f64 = 2e-6;

    /// Row bands of 1 and 13 rows give the same map as one band.
    #[test]
    fn dp_visible_gpu_bands_are_seamless() {
        let Some(ctx) = gpu() else { return };
        let n = 64;
        let grid = MarchGrid::from_height_field(&hills(n), OBSERVER_M).unwrap();
        let mip = DpMip::build(&grid);
        let on_gpu = GpuDpGrid::upload(ctx, &grid, &mip).unwrap();
        let light = twins::disc_light_to_f32(&sun_dir(151.0, 1.5), SUN_ANGULAR_RADIUS_RAD);
        let whole = dp_visible_gpu(ctx, &on_gpu, light, u64::MAX / 2).unwrap();
        for rows in [1_u64, 13] {
            let banded = dp_visible_gpu(ctx, &on_gpu, light, rows * n as u64 * 4).unwrap();
            assert_eq!(banded, whole, "bands of {rows} rows");
        }
    }

    /// The soft sweep: GPU vs twin (bit-level statistics except the f32 sum) on 64² × 40 epochs,
    /// 3 epochs per dispatch, 5 dispatches per submit, bands of 9 rows.
    #[test]
    fn dp_sweep_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let n = 64;
        let grid = MarchGrid::from_height_field(&hills(n), OBSERVER_M).unwrap();
        let mip = DpMip::build(&grid);
        let on_gpu = GpuDpGrid::upload(ctx, &grid, &mip).unwrap();
        let lights = sweep_lights(40);
        let twin = twins::dp_sweep(&grid, &mip, &lights, RowBand::whole(&grid));
        let options = DpSweepOptions {
            epochs_per_dispatch: 3,
            dispatches_per_submit: 5,
            band_bytes: 9 * n as u64 * 32,
        };
        let gpu_stats = dp_sweep_gpu(ctx, &on_gpu, &lights, options).unwrap();
        let (equal, max_sum) = stats_agreement(&twin, &gpu_stats);
        let longest = twin
            .iter()
            .map(|s| s.longest_dark_run_epochs)
            .max()
            .unwrap();
        eprintln!(
            "dp_sweep gpu vs twin {n}² × 40: {equal}/{} cells with equal counts, max |Δ sun_fraction_sum| {max_sum:.2e}, longest dark {longest}",
            twin.len()
        );
        assert!(longest > 1 && longest < 40, "fixture must have dark runs");
        assert!(equal as f64 >= 0.999 * twin.len() as f64);
        assert!(max_sum <= 40.0 * GPU_VS_TWIN_MAX);
    }
}

/// `penumbra map` over 2027-02-01..05 step 12h (9 epochs) on the synthetic DEM with
/// `--engine dp --backend B --observers O`, in `cwd/B-O`.
#[cfg(feature = "gpu")]
fn map_range_dp(cwd: &std::path::Path, backend: &str, observers: &str) -> std::process::Output {
    let k = crate::util::kernels_dir();
    let out_dir = format!("{backend}-{observers}");
    crate::util::penumbra_command()
        .args([
            "map",
            "--synthetic",
            "--start",
            "2027-02-01",
            "--stop",
            "2027-02-05",
            "--step",
            "12h",
            "--engine",
            "dp",
            "--out-dir",
            &out_dir,
            "--kernels",
            k.to_str().unwrap(),
            "--backend",
            backend,
            "--observers",
            observers,
        ])
        .current_dir(cwd)
        .env("XDG_RUNTIME_DIR", "/tmp")
        .env_remove("PENUMBRA_KERNELS")
        .output_within()
        .unwrap()
}

/// The soft GPU sweep against the CPU `map::sweep` (engine DP, f64) with the same definitions:
/// every statistic map of `--backend gpu` vs `--backend cpu` on the synthetic DEM, rays from the
/// model cells and (the default) from the DEM pixels, same nodata, max / mean |Δ| per map within
/// the bounds measured on lavapipe (docs/VALIDATION.md).
#[cfg(feature = "gpu")]
#[test]
fn map_sweep_gpu_soft_matches_cpu_sweep() {
    if crate::util::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut failures = 0;
    for observers in ["cells", "pixels"] {
        for backend in ["cpu", "gpu"] {
            let out = map_range_dp(dir.path(), backend, observers);
            assert!(
                out.status.success(),
                "--backend {backend} --observers {observers}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let run = std::fs::read_to_string(
                dir.path()
                    .join(format!("{backend}-{observers}"))
                    .join("run.json"),
            )
            .unwrap();
            let words = match observers {
                "cells" => penumbra::model::ObserverPlacement::Cells,
                _ => penumbra::model::ObserverPlacement::Pixels,
            }
            .describe();
            assert!(
                run.contains(words),
                "{backend} {observers}: run.json does not say \"{words}\""
            );
        }
        let read = |b: &str, name: &str| {
            penumbra::terrain::read_geotiff(
                &dir.path()
                    .join(format!("{b}-{observers}"))
                    .join(format!("{name}.tif")),
            )
            .unwrap()
            .heights_m
        };
        // (map, a difference that counts (in the map's unit), mean |Δ| bound). One epoch is 11.1 %
        // or 12 h. Measured on lavapipe since the CPU DP fix (shadow::dp, missed occluders next to
        // the nodata margin; test dp_twin_vs_cpu_dp_on_synthetic_dem, docs/VALIDATION.md):
        // sun_illumination_pct mean |Δ| 1.7e-4 % (0 pixels > 1 %), longest_dark_h 1.5e-4 h (2 pixels
        // > 0.5 h: f32 vs f64 fractions at the edge of 0), psr_mask, earth and sun-and-earth 0.
        // Before the fix: 3.3e-3 % (94 px), 3.8e-3 h (73 px), psr_mask 8 px.
        for (name, counts_m, mean_bound) in [
            ("sun_illumination_pct", 1.0, 2e-3),
            ("longest_dark_h", 0.5, 2e-3),
            ("psr_mask", 0.5, 1e-4),
            ("earth_visible_pct", 1.0, 2e-3),
            ("sun_and_earth_pct", 1.0, 2e-3),
        ] {
            let (cpu, gpu) = (read("cpu", name), read("gpu", name));
            assert_eq!(cpu.len(), gpu.len());
            let nodata = |v: f32| v.is_nan() || (name == "psr_mask" && v == 255.0);
            let (mut valid, mut differ, mut max, mut sum) = (0usize, 0usize, 0.0_f64, 0.0_f64);
            let mut worst = (0usize, 0.0_f32, 0.0_f32);
            for (k, (&c, &g)) in cpu.iter().zip(&gpu).enumerate() {
                assert_eq!(nodata(c), nodata(g), "{name}: nodata masks differ");
                if nodata(c) {
                    continue;
                }
                valid += 1;
                let d = f64::from((c - g).abs());
                differ += usize::from(d > counts_m);
                if d > max {
                    worst = (k, c, g);
                }
                max = max.max(d);
                sum += d;
            }
            let mean = sum / valid as f64;
            eprintln!(
                "map sweep gpu vs cpu (dp, observers {observers}) {name}: {valid} valid, max |Δ| {max:.3e}, mean |Δ| {mean:.3e}, {differ} pixels differ > {counts_m}, worst (index, cpu, gpu) {worst:?}"
            );
            failures += usize::from(mean > mean_bound || differ as f64 > 1e-4 * valid as f64);
            assert!(valid > 10_000);
        }
    }
    assert_eq!(failures, 0, "maps out of bounds (see stderr)");
}

/// Next to large holes (a nodata margin, as at the edge of a resampled DEM) the twin's radius-0
/// mask equals the brute-force reference (lattice-line crossings, `Engine::Brute.hard_mask`), and so
/// does the CPU DP engine's, cell for cell.
#[test]
fn dp_twin_hard_matches_brute_next_to_holes() {
    let n = 96;
    let mut hf = hills(n);
    for row in 0..n {
        for col in 0..(5 + row % 7) {
            hf.z_m[row * n + col] = f32::NAN;
        }
    }
    let grid = MarchGrid::from_height_field(&hf, OBSERVER_M).unwrap();
    let mip = DpMip::build(&grid);
    for (el_deg, az_deg) in [(0.5, 265.0), (1.5, 290.0), (1.0, 240.0)] {
        let dir = sun_dir(az_deg, el_deg);
        let brute = Engine::Brute
            .hard_mask(&hf, OBSERVER_M, dir.into())
            .unwrap();
        let cpu_dp = Engine::Dp.hard_mask(&hf, OBSERVER_M, dir.into()).unwrap();
        let hard = twins::disc_light_to_f32(&dir, 0.0);
        let twin = twins::dp_visible(&grid, &mip, &[hard], 0, RowBand::whole(&grid));
        let twin_vs_brute = brute
            .iter()
            .zip(&twin)
            .filter(|(b, t)| **b != 255 && f32::from(**b) != **t)
            .count();
        let dp_vs_brute = brute.iter().zip(&cpu_dp).filter(|(b, d)| b != d).count();
        let dark = brute.iter().filter(|&&b| b == 0).count();
        eprintln!(
            "holes el {el_deg}° az {az_deg}°: twin vs brute {twin_vs_brute}, cpu dp vs brute {dp_vs_brute}, brute dark {dark}"
        );
        assert!(dark > 100);
        assert!(twin_vs_brute as f64 <= TWIN_VS_BRUTE_HARD_FRACTION * (n * n) as f64);
        assert_eq!(dp_vs_brute, 0);
    }
}

/// The twin vs the CPU DP engine on the built-in synthetic DEM's model grid (404², 100 m, a
/// 2-cell nodata margin) for a 1° Sun from three western azimuths, where the CPU DP used to miss
/// occluders on the margin's first valid lines (9 / 0 / 33 of 163,216 cells off by > 0.01, brute
/// force on the twin's side in every one; fixed in `shadow::dp`, docs/shadow.md "Dropped line
/// samples next to holes"). Asserted: no cell differs by > 0.01 (measured max |Δ| 4.9e-4), and
/// the CPU DP hard masks at the disc's centre and at its lower and upper limbs equal brute
/// force's in every cell — the prism fraction is 1 exactly when the lower limb is lit and 0 when
/// the upper limb is hidden, so this checks both ends of the soft fraction against the oracle
/// (before the fix, at the lower limb / centre / upper limb: 9 / 4 / 3 cells wrong at 250°,
/// 16 / 16 / 17 at 290°, none at 270°; 11 s in debug builds, 3 × (3 brute + 3 DP masks)).
#[test]
fn dp_twin_vs_cpu_dp_on_synthetic_dem() {
    // The synthetic DEM alone (its far field is not what these DP checks are about).
    let stack = penumbra::terrain::TerrainStack::new(vec![
        penumbra::terrain::synth::south_polar_dem(&penumbra::terrain::synth::SynthParams::default())
            .unwrap(),
    ]);
    let grid = penumbra::model::MapGrid::new(&stack).unwrap();
    let hf = &grid.hf;
    let march = MarchGrid::from_height_field(hf, OBSERVER_M).unwrap();
    let mip = DpMip::build(&march);
    let mut mask_failures = 0;
    for az in [250.0, 270.0, 290.0] {
        let dir = sun_dir(az, 1.0);
        let reference = dp::visible_fraction(
            hf,
            OBSERVER_M,
            dir.into(),
            SUN_ANGULAR_RADIUS_RAD,
            &dp::DpConfig::default(),
        )
        .unwrap();
        let light = twins::disc_light_to_f32(&dir, SUN_ANGULAR_RADIUS_RAD);
        let twin = twins::dp_visible(&march, &mip, &[light], 0, RowBand::whole(&march));
        let (max, mean, one_sided) = deltas(&reference, &twin);
        let differ = reference
            .iter()
            .zip(&twin)
            .filter(|(a, b)| !a.is_nan() && (*a - *b).abs() > 0.01)
            .count();
        let mut limbs = Vec::new();
        for el_deg in [
            1.0 - SUN_ANGULAR_RADIUS_RAD.to_degrees(),
            1.0,
            1.0 + SUN_ANGULAR_RADIUS_RAD.to_degrees(),
        ] {
            let d = sun_dir(az, el_deg);
            let brute = Engine::Brute.hard_mask(hf, OBSERVER_M, d.into()).unwrap();
            let cpu = Engine::Dp.hard_mask(hf, OBSERVER_M, d.into()).unwrap();
            let wrong = brute.iter().zip(&cpu).filter(|(b, c)| b != c).count();
            let dark = brute.iter().filter(|&&b| b == 0).count();
            limbs.push((wrong, dark));
            mask_failures += wrong;
        }
        eprintln!(
            "synthetic az {az}: twin vs cpu dp max |Δ| {max:.2e}, mean {mean:.2e}, {differ} of {} cells > 0.01; cpu dp vs brute hard masks (lower limb, centre, upper limb): (wrong, brute dark) {limbs:?}",
            reference.len()
        );
        assert_eq!(one_sided, 0);
        assert_eq!(
            differ, 0,
            "cells where the twin and the CPU DP differ by > 0.01"
        );
        assert!(max < 5e-3 && mean < 2e-6);
        assert!(limbs.iter().all(|&(_, dark)| dark > 10_000));
    }
    assert_eq!(
        mask_failures, 0,
        "CPU DP hard masks differ from brute force"
    );
}

/// One-light maps: `penumbra map --synthetic --sun-az-deg 151 --sun-el-deg 1.5 --engine dp
/// --out-fraction/--out-mask` with `--backend gpu` vs `--backend cpu`, rays from the model cells
/// and (the default) from the DEM pixels: same nodata, fraction mean |Δ| ≤ 1e-3 and ≤ 0.1 % of
/// pixels off by > 0.01, masks differ on ≤ 0.1 % of pixels.
#[cfg(feature = "gpu")]
#[test]
fn map_one_light_gpu_matches_cpu() {
    if crate::util::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for observers in ["cells", "pixels"] {
        for backend in ["cpu", "gpu"] {
            let out = crate::util::penumbra_command()
                .args([
                    "map",
                    "--synthetic",
                    "--sun-az-deg",
                    "151",
                    "--sun-el-deg",
                    "1.5",
                    "--engine",
                    "dp",
                    "--out-fraction",
                    &format!("f_{backend}.tif"),
                    "--out-mask",
                    &format!("m_{backend}.tif"),
                    "--backend",
                    backend,
                    "--observers",
                    observers,
                ])
                .current_dir(dir.path())
                .env("XDG_RUNTIME_DIR", "/tmp")
                .output_within()
                .unwrap();
            assert!(
                out.status.success(),
                "{backend}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        let read = |f: &str| {
            penumbra::terrain::read_geotiff(&dir.path().join(f))
                .unwrap()
                .heights_m
        };
        let (fc, fg) = (read("f_cpu.tif"), read("f_gpu.tif"));
        let (mut n, mut sum, mut off) = (0usize, 0.0_f64, 0usize);
        for (&c, &g) in fc.iter().zip(&fg) {
            assert_eq!(c.is_nan(), g.is_nan());
            if c.is_nan() {
                continue;
            }
            n += 1;
            let d = f64::from((c - g).abs());
            sum += d;
            off += usize::from(d > 0.01);
        }
        let (mc, mg) = (read("m_cpu.tif"), read("m_gpu.tif"));
        let mask_differ = mc.iter().zip(&mg).filter(|(a, b)| a != b).count();
        eprintln!(
            "one-light gpu vs cpu (dp, observers {observers}): {n} px, fraction mean |Δ| {:.2e}, {off} px off > 0.01, masks differ {mask_differ}",
            sum / n as f64
        );
        assert!(n > 10_000);
        assert!(sum / n as f64 <= 1e-3);
        assert!(off as f64 <= 1e-3 * n as f64);
        assert!(mask_differ as f64 <= 1e-3 * mc.len() as f64);
    }
}

/// The built-in synthetic DEM's map grid, its DEM pixels' own observers and their point records
/// (the kernels' inputs of `dp_points.wgsl` / `dp_points_sweep.wgsl`, issue 13).
struct PixelCase {
    grid: penumbra::model::MapGrid,
    observers: Vec<Option<penumbra::shadow::Observer>>,
    march: MarchGrid,
    mip: DpMip,
    pixel_of_point: Vec<usize>,
    points: Vec<[f32; 4]>,
}

fn pixel_case() -> PixelCase {
    // The synthetic DEM alone (its far field is not what these DP checks are about).
    let stack = penumbra::terrain::TerrainStack::new(vec![
        penumbra::terrain::synth::south_polar_dem(&penumbra::terrain::synth::SynthParams::default())
            .unwrap(),
    ]);
    let grid = penumbra::model::MapGrid::new(&stack).unwrap();
    let observers = grid.pixel_observers(OBSERVER_M);
    let march = MarchGrid::from_height_field(&grid.hf, OBSERVER_M).unwrap();
    let mip = DpMip::build(&march);
    let (pixel_of_point, points) = twins::pixel_point_records(&march, &observers);
    PixelCase {
        grid,
        observers,
        march,
        mip,
        pixel_of_point,
        points,
    }
}

/// Oracle: the f64 CPU DP engine started from the same DEM pixels (`MapEngine::
/// visible_fraction_on_dem` with the pixels' observers, the CPU maps' default). The f32 twin of
/// `dp_points.wgsl` (records marching beyond the near field, which the DEM lattice's own march
/// covers, as the maps combine them) on the built-in synthetic DEM (404² pixels), a low Sun from
/// three azimuths and one below the map centre's horizontal (the rims see it): soft fractions
/// and hard masks.
#[test]
fn dp_points_twin_matches_the_cpu_dp_engine_from_the_pixels() {
    use penumbra::model::{MapEngine, MapEngineKind};
    let c = pixel_case();
    let engine = MapEngine::new(MapEngineKind::Direct(Engine::Dp), &c.grid, OBSERVER_M).unwrap();
    assert!(c.points.len() > 100_000);
    let (_, beyond) =
        twins::pixel_point_records_from(&c.march, &c.observers, penumbra::model::NEAR_FIELD_CELLS);
    for (az, el) in [(40.0, 1.0), (151.0, 1.5), (262.0, 0.5), (300.0, -0.3)] {
        let dir = sun_dir(az, el);
        for radius in [SUN_ANGULAR_RADIUS_RAD, 0.0] {
            let cpu = engine
                .visible_fraction_on_dem(
                    &c.grid,
                    Some(&c.observers),
                    OBSERVER_M,
                    dir.into(),
                    radius,
                )
                .unwrap();
            // As the maps run it: the twin beyond the near field, the near field on the DEM's
            // own lattice (the CPU's, shared), the smaller fraction.
            let light = twins::disc_light_to_f32(&dir, radius);
            let per_point = twins::dp_points(&c.march, &c.mip, &beyond, light);
            let mut beyond_px = vec![f32::NAN; cpu.len()];
            for (&p, &v) in c.pixel_of_point.iter().zip(&per_point) {
                beyond_px[p] = v;
            }
            let twin = c
                .grid
                .with_near_field(&beyond_px, &c.observers, dir.into(), radius)
                .unwrap();
            let (max, mean, one_sided) = deltas(&cpu, &twin);
            let differ = cpu
                .iter()
                .zip(&twin)
                .filter(|(a, b)| !a.is_nan() && (*a - *b).abs() > 0.01)
                .count();
            let lit = cpu.iter().filter(|&&f| f > 0.5).count();
            eprintln!(
                "dp_points twin vs cpu dp from pixels, az {az} el {el} radius {radius:.4}: max |Δ| {max:.2e}, mean {mean:.2e}, {differ} of {} px > 0.01, {lit} lit",
                c.points.len()
            );
            assert_eq!(one_sided, 0, "nodata differs");
            assert!(
                lit > 1000 && lit < c.points.len(),
                "a case with light and shadow"
            );
            // f32 vs f64 at grazing ties: at most 1e-4 of the pixels.
            assert!(differ as f64 <= 1e-4 * c.points.len() as f64);
            assert!(mean < 2e-5, "mean {mean}");
        }
    }
}

#[cfg(feature = "gpu")]
mod points_on_gpu {
    use super::on_gpu::stats_agreement;
    use super::*;
    use crate::util::gpu;
    use penumbra::gpu::dp::{DpSweepOptions, GpuDpGrid, dp_points_gpu, dp_points_sweep_gpu};

    /// `dp_points.wgsl` against its twin, in chunks of 7,777 points (several dispatches, a
    /// partial last one): soft and hard.
    #[test]
    fn dp_points_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let c = pixel_case();
        let on_gpu = GpuDpGrid::upload(ctx, &c.march, &c.mip).unwrap();
        for (az, el, radius) in [
            (151.0, 1.5, SUN_ANGULAR_RADIUS_RAD),
            (300.0, -0.3, SUN_ANGULAR_RADIUS_RAD),
            (262.0, 0.5, 0.0),
        ] {
            let light = twins::disc_light_to_f32(&sun_dir(az, el), radius);
            let gpu_values = dp_points_gpu(ctx, &on_gpu, &c.points, light, 4 * 7_777).unwrap();
            let twin = twins::dp_points(&c.march, &c.mip, &c.points, light);
            // No nodata among points (a fraction may round to -1e-7, which `deltas` would take
            // for nodata): every point compared.
            assert_eq!(gpu_values.len(), twin.len());
            let d: Vec<f64> = twin
                .iter()
                .zip(&gpu_values)
                .map(|(a, b)| f64::from((a - b).abs()))
                .collect();
            let (max, mean) = (
                d.iter().copied().fold(0.0, f64::max),
                d.iter().sum::<f64>() / d.len() as f64,
            );
            let identical = d.iter().filter(|&&x| x == 0.0).count();
            eprintln!(
                "dp_points gpu vs twin az {az} el {el} radius {radius:.4}: {identical}/{} identical, max |Δ| {max:.2e}, mean {mean:.2e}",
                twin.len()
            );
            assert!(max <= 2e-4 && mean <= 2e-6);
        }
        // Bad input is an error, not a wrong map.
        let mut off = c.points[..3].to_vec();
        off[1][0] = -1.0;
        let light = twins::disc_light_to_f32(&sun_dir(151.0, 1.5), 0.0);
        assert!(dp_points_gpu(ctx, &on_gpu, &off, light, 1 << 20).is_err());
    }

    /// `dp_points_sweep.wgsl` against its twin over 24 epochs, chunks of 5,000 points, 5 epochs
    /// per dispatch and 2 dispatches per submit.
    #[test]
    fn dp_points_sweep_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let c = pixel_case();
        let on_gpu = GpuDpGrid::upload(ctx, &c.march, &c.mip).unwrap();
        let lights = sweep_lights(24);
        let options = DpSweepOptions {
            epochs_per_dispatch: 5,
            dispatches_per_submit: 2,
            band_bytes: 32 * 5_000,
        };
        let gpu_stats = dp_points_sweep_gpu(ctx, &on_gpu, &c.points, &lights, options).unwrap();
        let twin = twins::dp_points_sweep(&c.march, &c.mip, &c.points, &lights);
        assert_eq!(gpu_stats.len(), twin.len());
        let (equal, max_sum) = stats_agreement(&twin, &gpu_stats);
        let longest = twin
            .iter()
            .map(|s| s.longest_dark_run_epochs)
            .max()
            .unwrap();
        eprintln!(
            "dp_points_sweep gpu vs twin × 24: {equal}/{} points with equal counts, max |Δ sun_fraction_sum| {max_sum:.2e}, longest dark {longest}",
            twin.len()
        );
        assert!(
            twin.iter()
                .any(|s| s.longest_dark_run_epochs > 1 && s.longest_dark_run_epochs < 24),
            "fixture must have dark runs that end"
        );
        assert!(equal as f64 >= 0.999 * twin.len() as f64);
        assert!(max_sum <= 24.0 * 2e-4);
    }
}

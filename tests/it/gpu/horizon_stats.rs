//! The horizons engine's epoch loop on a kernel (`shaders/horizon_stats.wgsl` and its f32 CPU
//! twin) against the CPU engine, and the GPU against the twin.

use penumbra::horizon::statistics::{
    CellKernel, EpochBodies, HorizonStatistics, InMemoryHorizons, StatisticsEngine,
    StatisticsParams,
};
use penumbra::illum::LimbDarkening;
use penumbra::terrain::TerrainStack;
use penumbra::twins::horizon_stats::TwinKernel;

use crate::util::kernels_dir;

/// A rough synthetic DEM (96² px of 150 m round the pole), its sweep (180 azimuths) and the
/// bodies every 7 h of 2027 (1,252 epochs: three batches of the kernel).
fn rough_terrain() -> (TerrainStack, InMemoryHorizons, Vec<EpochBodies>) {
    penumbra::horizon::statistics::testing::rough_terrain_2027(96, 11, 7.0, &kernels_dir())
}

fn params() -> StatisticsParams {
    StatisticsParams {
        limb: LimbDarkening::EDDINGTON,
        visible_min_fraction: 1e-9,
        full_min_fraction: 0.999,
    }
}

fn run(
    stack: &TerrainStack,
    horizons: &mut InMemoryHorizons,
    bodies: &[EpochBodies],
    kernel: Option<&mut dyn CellKernel>,
) -> HorizonStatistics {
    let engine = StatisticsEngine::new(stack, params()).unwrap();
    let rows = 0..stack.layers[0].grid.rows;
    engine
        .run_rows_on(
            horizons,
            bodies,
            &mut penumbra::horizon::statistics::NoStore,
            rows,
            kernel,
            |_| true,
        )
        .unwrap()
}

/// How two statistics differ: per count, the pixels that differ and the largest difference;
/// for the sums, the largest difference of the per-epoch mean.
#[derive(Debug, Default)]
pub(crate) struct Differences {
    pub counts: Vec<(&'static str, usize, u32)>,
    pub mean_fraction_max: f64,
    pub irradiance_h_max_w_m2: f64,
    pub irradiance_t_max_w_m2: f64,
}

pub(crate) fn differences(a: &HorizonStatistics, b: &HorizonStatistics) -> Differences {
    assert_eq!(a.nodata, b.nodata, "nodata");
    let n = a.epochs as f64;
    let count = |name, x: &[u32], y: &[u32]| {
        let (mut px, mut worst) = (0, 0);
        for (&p, &q) in x.iter().zip(y) {
            if p != q {
                px += 1;
                worst = worst.max(p.abs_diff(q));
            }
        }
        (name, px, worst)
    };
    let max_mean = |x: &[f64], y: &[f64]| {
        x.iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs() / n)
            .fold(0.0, f64::max)
    };
    Differences {
        counts: vec![
            count("sun visible", &a.sun_visible_count, &b.sun_visible_count),
            count("sun full", &a.sun_full_count, &b.sun_full_count),
            count(
                "earth visible",
                &a.earth_visible_count,
                &b.earth_visible_count,
            ),
            count(
                "sun and earth",
                &a.sun_and_earth_count,
                &b.sun_and_earth_count,
            ),
            count(
                "longest dark",
                &a.longest_dark_epochs,
                &b.longest_dark_epochs,
            ),
            count(
                "longest earth hidden",
                &a.longest_earth_hidden_epochs,
                &b.longest_earth_hidden_epochs,
            ),
        ],
        mean_fraction_max: max_mean(&a.sun_fraction_sum, &b.sun_fraction_sum),
        irradiance_h_max_w_m2: max_mean(
            &a.irradiance_horizontal_sum_w_m2,
            &b.irradiance_horizontal_sum_w_m2,
        ),
        irradiance_t_max_w_m2: max_mean(
            &a.irradiance_tracking_sum_w_m2,
            &b.irradiance_tracking_sum_w_m2,
        ),
    }
}

/// The kernel's algorithm (no sector tables, no per-cell bounds, f32 sums, the Earth's exact
/// strip integral in f32) against the CPU engine on rough terrain over a year (measured: 1
/// pixel of 9,216 one epoch apart in Earth visible, mean fraction 4.9e-8, irradiance 1e-4
/// W/m²): every count within two epochs at ≤ 0.1 % of the pixels (f32 ties at the thresholds),
/// the mean fraction within 1e-5, the irradiance within 0.01 W/m², the below-sphere tally
/// identical (the engine re-runs the kernel's candidate cells on the CPU).
#[test]
fn twin_kernel_matches_the_cpu_engine() {
    let (stack, mut horizons, bodies) = rough_terrain();
    let cpu = run(&stack, &mut horizons, &bodies, None);
    let mut twin = TwinKernel::default();
    let on_twin = run(&stack, &mut horizons, &bodies, Some(&mut twin));
    let d = differences(&cpu, &on_twin);
    let px = cpu.nodata.iter().filter(|&&nd| !nd).count();
    eprintln!(
        "twin vs CPU engine, {px} px x {} epochs: {d:?}",
        bodies.len()
    );
    assert!(px > 9000, "{px} pixels with data");
    for &(name, n, worst) in &d.counts {
        assert!(
            n <= px / 1000 && worst <= 2,
            "{name}: {n} px differ, by up to {worst} epochs"
        );
    }
    assert!(d.mean_fraction_max < 1e-5, "{d:?}");
    assert!(
        d.irradiance_h_max_w_m2 < 0.01 && d.irradiance_t_max_w_m2 < 0.01,
        "{d:?}"
    );
    assert_eq!(cpu.below_sphere, on_twin.below_sphere, "below-sphere tally");
    assert!(
        cpu.below_sphere.cells > 0,
        "the check needs cells lit from below the sphere's horizon (one layer, no far field)"
    );
    // Something to compare: lit, dark and partly lit pixels.
    let lit = cpu.sun_visible_count.iter().filter(|&&c| c > 0).count();
    assert!(lit > px / 4 && lit < px, "{lit} of {px} px ever lit");
}

/// The shader's structs have the sizes of their Rust mirrors (naga's layouter); never skipped.
#[test]
fn horizon_stats_struct_layout_matches_rust() {
    use penumbra::horizon::statistics::{KernelAcc, KernelCell, KernelEpoch};
    let sizes = crate::util::wgsl_struct_sizes(&penumbra::gpu::shaders::HORIZON_STATS);
    let params = size_of::<penumbra::twins::horizon_stats::HorizonStatsParams>();
    assert_eq!(sizes["Params"], params);
    assert_eq!(sizes["Cell"], size_of::<KernelCell>());
    assert_eq!(sizes["Epoch"], size_of::<KernelEpoch>());
    assert_eq!(sizes["Acc"], size_of::<KernelAcc>());
}

#[cfg(feature = "gpu")]
mod on_gpu {
    use penumbra::gpu::horizon_stats::GpuHorizonStats;

    use super::*;
    use crate::util::gpu;

    /// GPU vs twin and vs the CPU engine through the whole engine (the same f32 algorithm as
    /// the twin: only GPU rounding, FMA contraction and the built-ins' `asin`/`sqrt` differ).
    /// Measured on lavapipe vs the twin: 21 px of 9,216 differ in Earth-visible epochs (by ≤ 2),
    /// ≤ 13 px in the others (by 1), mean fraction 3.4e-6, irradiance 4.5e-3 W/m². Bounds: counts
    /// within two epochs at ≤ 0.5 % of the pixels, sums within 1e-5 of the mean fraction and
    /// 0.01 W/m², the below-sphere tally identical.
    #[test]
    fn horizon_stats_gpu_matches_twin() {
        let Some(ctx) = gpu() else { return };
        let (stack, mut horizons, bodies) = rough_terrain();
        let mut twin = TwinKernel::default();
        let on_twin = run(&stack, &mut horizons, &bodies, Some(&mut twin));
        let mut kernel = GpuHorizonStats::new(ctx).unwrap();
        let on_gpu = run(&stack, &mut horizons, &bodies, Some(&mut kernel));
        let cpu = run(&stack, &mut horizons, &bodies, None);
        let px = on_twin.nodata.iter().filter(|&&nd| !nd).count();
        for (what, reference) in [("twin", &on_twin), ("CPU engine", &cpu)] {
            let d = differences(reference, &on_gpu);
            eprintln!("GPU vs {what}, {px} px x {} epochs: {d:?}", bodies.len());
            for &(name, n, worst) in &d.counts {
                assert!(
                    n <= px / 200 && worst <= 2,
                    "{what}: {name}: {n} px differ, by up to {worst} epochs"
                );
            }
            assert!(d.mean_fraction_max < 1e-5, "{what}: {d:?}");
            assert!(
                d.irradiance_h_max_w_m2 < 0.01 && d.irradiance_t_max_w_m2 < 0.01,
                "{what}: {d:?}"
            );
            assert_eq!(reference.below_sphere, on_gpu.below_sphere, "{what}");
        }
    }
}

/// A month of a polar Sun on the CLI's 64² synthetic DEM without a far field (cells near the
/// edge see the Sun low over it, below their horizontal): the CPU engine and the twin kernel
/// agree epoch for epoch. Found by the GPU kernel: the CPU engine's "never sees the Sun" bound
/// took the azimuths round the mean direction of the month's Sun (which points near the nadir)
/// as a ±90° window and marked 5 such cells dark that see the Sun 1–7 epochs (the per-site
/// series at one of them: 7 epochs, fractions 0.15–0.72).
#[test]
fn a_month_over_the_dem_edge_agrees_with_the_twin() {
    use crate::util::penumbra_ok;
    use penumbra::horizon::statistics::HorizonFile;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    penumbra_ok(
        d,
        &[
            "dem", "synth", "--size", "64", "--px-m", "200", "--out", "a.tif",
        ],
    );
    penumbra_ok(
        d,
        &[
            "horizon-map",
            "sweep",
            "--dem",
            "a.tif",
            "--azimuths",
            "90",
            "--max-step",
            "6",
            "--out",
            "h.tif",
        ],
    );
    let stack = TerrainStack::load(&[d.join("a.tif")]).unwrap();
    let kernels = penumbra::ephem::Kernels::load(&kernels_dir()).unwrap();
    let epochs = penumbra::ephem::time::epoch_range(
        penumbra::ephem::time::parse_utc("2027-03-01").unwrap(),
        penumbra::ephem::time::parse_utc("2027-04-01").unwrap(),
        hifitime::Duration::from_hours(3.0),
    )
    .unwrap();
    let bodies =
        EpochBodies::over_dem(&stack.layers[0], &kernels, &epochs, Default::default()).unwrap();
    let engine = StatisticsEngine::new(&stack, params()).unwrap();
    let go = |k: Option<&mut dyn CellKernel>| {
        let mut f = HorizonFile::open(&d.join("h.tif")).unwrap();
        let mut store = penumbra::horizon::statistics::NoStore;
        engine
            .run_rows_on(&mut f, &bodies, &mut store, 0..64, k, |_| true)
            .unwrap()
    };
    let cpu = go(None);
    let on_twin = go(Some(&mut TwinKernel::default()));
    let diff = differences(&cpu, &on_twin);
    eprintln!(
        "twin vs CPU engine, 64² x {} epochs: {diff:?}",
        bodies.len()
    );
    for &(name, n, worst) in &diff.counts {
        assert!(
            n <= 2 && worst <= 1,
            "{name}: {n} px differ, by up to {worst} epochs"
        );
    }
    assert!(diff.mean_fraction_max < 1e-5, "{diff:?}");
    // Cells that see the Sun only from below their horizontal, a few epochs a month.
    let low = (0..cpu.nodata.len())
        .filter(|&i| cpu.sun_visible_count[i] > 0 && cpu.irradiance_horizontal_sum_w_m2[i] == 0.0)
        .count();
    assert!(low >= 5, "{low} cells lit only from below their horizontal");
}

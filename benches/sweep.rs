//! Whole-grid horizons (issue 15), side by side in one run on the same 128² synthetic DEM at
//! 100 m (south polar stereographic, 60 km from the pole), 64 requested azimuths:
//! - `line_sweep`: `HorizonSweep` (exact, every pixel on its line, max step 8: 64 directions);
//! - `fourier_build`: today's `horizon-map build` engine on the model-space grid of the same DEM
//!   (`HorizonMap::build`, 64 azimuths, whole-grid rays);
//! - `per_site_exact` / `per_site_fast`: `HorizonEngine::horizon_toward` for 64 azimuths at each
//!   of 256 cells (time per cell x cells = the whole-grid cost of the per-site scan).
//!
//! Throughput is in pixel-azimuths. Run: `cargo bench --bench sweep`.
//!
//! Group `batched_looks_simulated_device`: the GPU path's pipeline (`twins::line_sweep::
//! sweep_batched`: lines packed on the CPU, looks on the device) on the same DEM, with a
//! simulated device that answers each batch after a sleep (no CPU) of the time its packing took
//! alone, so that packing and device weigh the same: `pack_only` (an instant device) and
//! `pack_and_device`. Packing and device in turn take twice `pack_only`; a perfect overlap takes
//! `pack_only` itself.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use penumbra::horizon::{HorizonEngine, HorizonMethod, HorizonParams, HorizonSweep, SweepParams};
use penumbra::model::MapGrid;
use penumbra::shadow::fourier::HorizonMap;
use penumbra::terrain::{Dem, Projection, TerrainStack};

const N: usize = 128;
const AZ: usize = 64;

fn dem() -> Dem {
    penumbra::terrain::synth::square_dem_at(N, 100.0, (45_000.0, -40_000.0), "bench", |x, y| {
        400.0 * penumbra::terrain::synth::fbm(x / 2500.0, y / 2500.0, 5, 0.5, 7)
    })
}

/// The benches' sweep: a 2 m observer, [`AZ`] directions, steps of at most 8 px.
fn sweep_params() -> SweepParams {
    SweepParams {
        observer_height_m: 2.0,
        azimuths: AZ,
        max_step: 8,
    }
}

fn bench_sweep(c: &mut Criterion) {
    let stack = TerrainStack::new(vec![dem()]);
    let sweep = HorizonSweep::new(&stack, sweep_params()).unwrap();
    assert_eq!(sweep.directions().len(), AZ);
    let mut group = c.benchmark_group("whole_grid_horizons_128sq_64az");
    group.sample_size(10);
    group.throughput(Throughput::Elements((N * N * AZ) as u64));
    group.bench_function("line_sweep", |b| {
        b.iter(|| {
            let mut sum = 0.0f64;
            sweep
                .run(
                    |band| -> Result<(), ()> {
                        sum += f64::from(band.elevation_deg[N * N / 2]);
                        Ok(())
                    },
                    |_| {},
                )
                .unwrap();
            sum
        })
    });
    let grid = MapGrid::new(&stack).unwrap();
    group.bench_function("fourier_build", |b| {
        b.iter(|| HorizonMap::build(&grid.hf, 2.0, AZ, N * 2).unwrap())
    });
    let engine = HorizonEngine::new(&stack);
    let cells: Vec<(f64, f64)> = (0..256)
        .map(|i| {
            let (r, c) = ((i * 37) % N, (i * 91) % N);
            let (x, y) = stack.layers[0].grid.xy_from_row_col(r as f64, c as f64);
            Projection::LOLA_SOUTH_POLAR.lat_lon_from_xy(x, y)
        })
        .collect();
    // 256 cells stand for the whole grid: scale the throughput accordingly.
    group.throughput(Throughput::Elements((cells.len() * AZ) as u64));
    for (name, method) in [
        ("per_site_exact", HorizonMethod::Exact),
        ("per_site_fast", HorizonMethod::Fast),
    ] {
        let hp = HorizonParams {
            observer_height_m: 2.0,
            method,
            ..HorizonParams::default()
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for &(lat, lon) in &cells {
                    for k in 0..AZ {
                        let az = 360.0 * k as f64 / AZ as f64;
                        sum += engine.horizon_toward(lat, lon, az, &hp).unwrap().0;
                    }
                }
                sum
            })
        });
    }
    group.finish();
}

/// A simulated device: the looks of one batch.
type Device<'a> =
    dyn FnMut(&penumbra::twins::line_sweep::LineBatch) -> Result<Vec<[f32; 2]>, ()> + 'a;

fn bench_batched(c: &mut Criterion) {
    use penumbra::twins::line_sweep::{LineBatch, TWIN_BATCH_SAMPLES, sweep_batched};
    use std::time::{Duration, Instant};
    let stack = TerrainStack::new(vec![dem()]);
    let sweep = HorizonSweep::new(&stack, sweep_params()).unwrap();
    let instant = |b: &LineBatch| -> Result<Vec<[f32; 2]>, ()> {
        Ok(vec![[1.0, 1.0]; 2 * b.observers.len()])
    };
    let run = |device: &mut Device<'_>| {
        let mut sum = 0.0f64;
        sweep_batched(
            &sweep,
            TWIN_BATCH_SAMPLES,
            device,
            |band| {
                sum += f64::from(band.elevation_deg[N * N / 2]);
                Ok(())
            },
            |_| {},
        )
        .unwrap();
        sum
    };
    // The packing time per sample, measured alone (best of 3), sets the simulated device's.
    let (mut samples, mut best) = (0usize, Duration::MAX);
    for _ in 0..3 {
        samples = 0;
        let t0 = Instant::now();
        run(&mut |b| {
            samples += b.samples.len();
            instant(b)
        });
        best = best.min(t0.elapsed());
    }
    let per_sample = best.as_secs_f64() / samples as f64;
    let mut group = c.benchmark_group("batched_looks_simulated_device");
    group.sample_size(10);
    group.throughput(Throughput::Elements((N * N * AZ) as u64));
    group.bench_function("pack_only", |b| b.iter(|| run(&mut |batch| instant(batch))));
    group.bench_function("pack_and_device", |b| {
        b.iter(|| {
            run(&mut |batch| {
                std::thread::sleep(Duration::from_secs_f64(
                    per_sample * batch.samples.len() as f64,
                ));
                instant(batch)
            })
        })
    });
    group.finish();
}

criterion_group!(benches, bench_sweep, bench_batched);
criterion_main!(benches);

//! Map statistics over an epoch range (issue 15), side by side in one run on the same 128²
//! synthetic south-polar DEM at 100 m (the demo's generator), throughput in pixel-epochs:
//! - `horizons_engine`: `StatisticsEngine::run` over whole-grid horizons held in memory (the
//!   sweep itself is set-up: see `benches/sweep.rs`), 1 year every 6 h (1460 epochs);
//! - `per_epoch_combined` / `per_epoch_dp`: the per-epoch CPU map sweep (`map::sweep`, rays from
//!   the pixels' own surface points) over 8 of those epochs.
//!
//! Run: `cargo bench --bench statistics`.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use penumbra::horizon::statistics::{
    EpochBodies, InMemoryHorizons, StatisticsEngine, StatisticsParams,
};
use penumbra::horizon::{HorizonSweep, SweepParams};
use penumbra::illum::LimbDarkening;
use penumbra::model::{MapEngine, MapEngineKind, ObserverPlacement};
use penumbra::model::{MapGrid, epoch_lights};
use penumbra::terrain::TerrainStack;

const N: usize = 128;

fn bench_statistics(c: &mut Criterion) {
    let dem = penumbra::terrain::synth::south_polar_dem(&penumbra::terrain::synth::SynthParams {
        size_px: N,
        px_m: 100.0,
        seed: 1,
    })
    .unwrap();
    let stack = TerrainStack::new(vec![dem.clone()]);
    let sweep = HorizonSweep::new(
        &stack,
        SweepParams {
            observer_height_m: 2.0,
            azimuths: 720,
            max_step: 16,
        },
    )
    .unwrap();
    let mut horizons = InMemoryHorizons::sweep(&sweep, |_| true).unwrap();
    let kernels =
        penumbra::ephem::Kernels::load(&penumbra::ephem::kernels::default_kernel_dir()).unwrap();
    let epochs = penumbra::ephem::time::epoch_range(
        penumbra::ephem::time::parse_utc("2027-01-01").unwrap(),
        penumbra::ephem::time::parse_utc("2027-12-31T18:00").unwrap(),
        hifitime::Duration::from_hours(6.0),
    )
    .unwrap();
    let bodies =
        EpochBodies::over_dem(&dem, &kernels, &epochs, penumbra::ephem::AbCorr::LtS).unwrap();
    let engine = StatisticsEngine::new(
        &stack,
        StatisticsParams {
            limb: LimbDarkening::EDDINGTON,
            visible_min_fraction: 1e-6,
            full_min_fraction: 0.999,
        },
    )
    .unwrap();
    let mut group = c.benchmark_group("range_statistics_128sq");
    group.sample_size(10);
    group.throughput(Throughput::Elements((N * N * epochs.len()) as u64));
    group.bench_function("horizons_engine", |b| {
        b.iter(|| {
            engine
                .run(&mut horizons, &bodies, |_| true)
                .unwrap()
                .sun_visible_count[N * N / 2]
        })
    });

    let grid = MapGrid::new(&stack).unwrap();
    let lights = epoch_lights(&grid, &kernels, &epochs[..8], penumbra::ephem::AbCorr::LtS).unwrap();
    group.throughput(Throughput::Elements((N * N * lights.len()) as u64));
    for (name, kind) in [
        (
            "per_epoch_combined",
            MapEngineKind::Direct(penumbra::shadow::Engine::Combined),
        ),
        (
            "per_epoch_dp",
            MapEngineKind::Direct(penumbra::shadow::Engine::Dp),
        ),
    ] {
        let engine = MapEngine::new(kind, &grid, 2.0).unwrap();
        group.bench_function(name, |b| {
            b.iter(|| {
                penumbra::model::per_epoch_statistics(
                    &grid,
                    &engine,
                    2.0,
                    ObserverPlacement::Pixels,
                    &lights,
                    6.0,
                )
                .unwrap()
                .sun_visible_count[N * N / 2]
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_statistics);
criterion_main!(benches);

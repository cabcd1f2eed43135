//! Horizon of one site (Connecting Ridge, 89.45 S 222.7 E, 2 m, 1440 azimuths) over the shared
//! 240 m + far-field LOLA layers: fast and exact methods, and the engine preparation.

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use penumbra::horizon::{HorizonEngine, HorizonMethod, HorizonParams};

fn bench_horizon(c: &mut Criterion) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/lola-south-pole-moondao");
    let paths = [
        dir.join("ldem75s_crop_240m_pm184km.tif"),
        dir.join("ldem75s_far_1787m_pm457km_feathered.tif"),
    ];
    if !paths.iter().all(|p| p.exists()) {
        eprintln!("skipped: shared LOLA grids absent under {}", dir.display());
        return;
    }
    let stack = penumbra::terrain::TerrainStack::load(&paths).unwrap();
    let engine = HorizonEngine::new(&stack);
    let mut group = c.benchmark_group("horizon_240m_far_1440az");
    group.sample_size(10);
    for method in [HorizonMethod::Fast, HorizonMethod::Exact] {
        let p = HorizonParams {
            method,
            ..HorizonParams::default()
        };
        group.bench_function(format!("{method:?}").to_lowercase(), |b| {
            b.iter(|| engine.horizon(-89.45, 222.7, &p).unwrap())
        });
    }
    group.bench_function("fast_including_engine_prep", |b| {
        b.iter(|| {
            penumbra::horizon::horizon(&stack, -89.45, 222.7, &HorizonParams::default()).unwrap()
        })
    });
    group.finish();

    let site01 = dir.join("site01_connecting_ridge_10m.tif");
    if site01.exists() {
        let stack3 =
            penumbra::terrain::TerrainStack::load(&[site01, paths[0].clone(), paths[1].clone()])
                .unwrap();
        let engine3 = HorizonEngine::new(&stack3);
        let mut group = c.benchmark_group("horizon_site01_240m_far_1440az");
        group.sample_size(10);
        group.bench_function("fast", |b| {
            b.iter(|| {
                engine3
                    .horizon(-89.45, 222.7, &HorizonParams::default())
                    .unwrap()
            })
        });
        group.finish();
    }
}

criterion_group!(benches, bench_horizon);
criterion_main!(benches);

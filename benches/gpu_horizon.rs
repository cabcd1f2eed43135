//! Per-site horizons, CPU engines next to the GPU scan at the same size: 100
//! sites on the synthetic south-polar DEM (400² × 100 m), 2 m observer, azimuth step
//! `PENUMBRA_BENCH_AZ_STEP_DEG` (default 1°, i.e. 360 azimuths; 0.25 gives the CLI default 1440).
//! Throughput is site-azimuths. Variants: `cpu_exact` / `cpu_fast` (`HorizonEngine`, rayon over
//! azimuths), `cpu_twin` (the f32 twin of the kernel, rayon over site-azimuths) and `gpu`
//! (`GpuHorizonScan::scan`, terrain uploaded once, readback included).
//!
//! Run: `WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=/tmp cargo bench --bench gpu_horizon` (GPU part
//! skipped with a printed reason when no adapter exists).

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use penumbra::gpu::GpuContext;
use penumbra::gpu::horizon::GpuHorizonScan;
use penumbra::horizon::{HorizonEngine, HorizonMethod, HorizonParams};
use penumbra::terrain::TerrainStack;
use penumbra::terrain::synth::{SynthParams, south_polar_dem};
use penumbra::twins::horizon_scan::{
    ScanTerrain, SiteParams, azimuth_table, horizon_scan, site_setup,
};

const SITES: usize = 100;

/// 100 sites on a 10 × 10 lattice within 12 km of the pole.
fn sites() -> Vec<(f64, f64)> {
    (0..SITES)
        .map(|i| {
            let (r, c) = ((i / 10) as f64, (i % 10) as f64);
            (-89.6 - 0.035 * r, 36.0 * c)
        })
        .collect()
}

fn bench_site_horizons(c: &mut Criterion) {
    let az_step_deg: f64 = std::env::var("PENUMBRA_BENCH_AZ_STEP_DEG")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1.0);
    let stack = TerrainStack::new(vec![
        south_polar_dem(&SynthParams::default()).expect("synthetic DEM"),
    ]);
    let engine = HorizonEngine::new(&stack);
    let sites = sites();
    let azimuths = azimuth_table(az_step_deg).expect("azimuth step");
    let terrain = ScanTerrain::new(&stack).expect("stack fits the kernel");
    let recs: Vec<SiteParams> = sites
        .iter()
        .map(|&(lat, lon)| site_setup(&engine, lat, lon, 2.0).expect("site").site)
        .collect();
    let mut group = c.benchmark_group("site_horizons");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    group.throughput(Throughput::Elements((SITES * azimuths.len()) as u64));
    let id = format!("{SITES}x{}", azimuths.len());
    for (name, method) in [
        ("cpu_exact", HorizonMethod::Exact),
        ("cpu_fast", HorizonMethod::Fast),
    ] {
        let p = HorizonParams {
            observer_height_m: 2.0,
            az_step_deg,
            method,
            ..HorizonParams::default()
        };
        group.bench_function(BenchmarkId::new(name, &id), |b| {
            b.iter(|| {
                for &(lat, lon) in &sites {
                    engine.horizon(lat, lon, &p).expect("horizon");
                }
            })
        });
    }
    group.bench_function(BenchmarkId::new("cpu_twin", &id), |b| {
        b.iter(|| horizon_scan(&terrain, &recs, &azimuths))
    });
    match GpuContext::new() {
        Ok(ctx) => {
            eprintln!("GPU bench adapter: {}", ctx.adapter_name());
            let scan = GpuHorizonScan::new(&ctx, &terrain).expect("upload");
            group.bench_function(BenchmarkId::new("gpu", &id), |b| {
                b.iter(|| scan.scan(&ctx, &recs, &azimuths).expect("scan"))
            });
        }
        Err(e) => eprintln!("skipping the GPU half of the bench: {e}"),
    }
    group.finish();
}

criterion_group!(benches, bench_site_horizons);
criterion_main!(benches);

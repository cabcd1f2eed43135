//! Fourier-compressed horizon maps (paper 001): building the map of a 128² synthetic field
//! (64 azimuths, whole-grid rays, 16 f16 coefficients) and evaluating a hard mask and a soft Sun
//! fraction from it.
//!
//! Run: `cargo bench --bench fourier`.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use penumbra::MOON_RADIUS_M;
use penumbra::shadow::SUN_ANGULAR_RADIUS_RAD;
use penumbra::shadow::fourier::{self, HorizonMap};
use penumbra::terrain::HeightField;

fn field(n: usize) -> HeightField {
    let mut hf = HeightField::flat(n, n, 100.0);
    for r in 0..n {
        for c in 0..n {
            let (x, y) = hf.xy_from_row_col(r as f64, c as f64);
            let h = 400.0 * penumbra::terrain::synth::fbm(x / 2500.0, y / 2500.0, 5, 0.5, 7);
            hf.z_m[r * n + c] = (h - (x * x + y * y) / (2.0 * MOON_RADIUS_M)) as f32;
        }
    }
    hf
}

fn bench_fourier(c: &mut Criterion) {
    let hf = field(128);
    let mut group = c.benchmark_group("fourier_128sq");
    group.sample_size(10);
    group.throughput(Throughput::Elements((hf.rows * hf.cols) as u64));
    group.bench_function("build_64az", |b| {
        b.iter(|| HorizonMap::build(&hf, 2.0, 64, 256).unwrap())
    });
    let map = HorizonMap::build(&hf, 2.0, 64, 256).unwrap();
    let light = [0.5, 0.8, 0.05];
    group.bench_function("hard_mask", |b| {
        b.iter(|| fourier::hard_mask(&map, light).unwrap())
    });
    group.bench_function("visible_fraction_sun", |b| {
        b.iter(|| fourier::visible_fraction(&map, light, SUN_ANGULAR_RADIUS_RAD).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench_fourier);
criterion_main!(benches);

//! Ephemeris throughput: Sun + Earth for one site over 18.6 years at 1 h steps (≈163,000 epochs),
//! and the same epochs for 100 sites (the Moon-centred geometry is shared across sites).
//!
//! Run: `cargo bench --bench ephem`.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use penumbra::ephem::{self, AbCorr, Kernels, Site};

fn bench_ephem(c: &mut Criterion) {
    let dir = ephem::kernels::default_kernel_dir();
    let kernels = match Kernels::load(&dir) {
        Ok(k) => k,
        Err(e) => {
            eprintln!("skipping ephem bench: {e}");
            return;
        }
    };
    let start = ephem::time::parse_utc("2024-01-01T00:00:00").unwrap();
    let stop = ephem::time::parse_utc("2042-08-07T00:00:00").unwrap();
    let epochs =
        ephem::time::epoch_range(start, stop, ephem::time::parse_step("1h").unwrap()).unwrap();
    let one_site = [Site::new(-89.45, -137.3, 1957.0).unwrap()];
    let hundred_sites: Vec<Site> = (0..100)
        .map(|i| Site::new(-89.0 - 0.009 * f64::from(i), f64::from(i) * 3.6, 1500.0).unwrap())
        .collect();

    let mut group = c.benchmark_group("ephem_18.6y_hourly");
    group.sample_size(10);
    group.throughput(Throughput::Elements(epochs.len() as u64));
    group.bench_function("sun_earth_1_site_lt+s", |b| {
        b.iter(|| ephem::sun_earth_series(&kernels, &one_site, &epochs, AbCorr::LtS).unwrap())
    });
    group.bench_function("sun_earth_100_sites_lt+s", |b| {
        b.iter(|| ephem::sun_earth_series(&kernels, &hundred_sites, &epochs, AbCorr::LtS).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench_ephem);
criterion_main!(benches);

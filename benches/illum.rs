//! Disc visibility throughput: one `visible_fraction` call per element, for the exact strip
//! integral, the circular segment and the middle value, for the Sun (r = 0.267°) and the Earth
//! (r = 0.95°), uniform and limb-darkened, on a rough 1440-sample horizon with the discs placed
//! across the horizon (the partially visible case, the expensive one).

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use penumbra::illum::disc::{Disc, DiscMethod, HorizonProfile, LimbDarkening, visible_fraction};

/// A rough synthetic horizon: base 1°, sum of sines with amplitude 0.6°/k at k = 1..=720.
fn rough_horizon() -> Vec<f64> {
    let n = 1440;
    (0..n)
        .map(|i| {
            let az = (i as f64) * std::f64::consts::TAU / n as f64;
            1.0 + (1..=720)
                .map(|k| {
                    let k = k as f64;
                    0.6 / k * (k * az + 2.399 * k * k).sin()
                })
                .sum::<f64>()
        })
        .collect()
}

fn bench_disc(c: &mut Criterion) {
    let el = rough_horizon();
    let h = HorizonProfile::new(&el).unwrap();
    const CALLS: usize = 10_000;
    let mut group = c.benchmark_group("illum_disc_fraction");
    group.throughput(Throughput::Elements(CALLS as u64));
    for (body, r) in [("sun", 0.267), ("earth", 0.95)] {
        let discs: Vec<Disc> = (0..CALLS)
            .map(|i| {
                let az = (i as f64 * 0.0361) % 360.0;
                let off = ((i * 7919) % 1000) as f64 / 500.0 - 1.0;
                Disc {
                    az_deg: az,
                    el_deg: h.el_at_az_deg(az) + off * r,
                    radius_deg: r,
                }
            })
            .collect();
        for (name, method, limb) in [
            ("exact", DiscMethod::Exact, LimbDarkening::UNIFORM),
            (
                "exact_eddington",
                DiscMethod::Exact,
                LimbDarkening::EDDINGTON,
            ),
            ("segment", DiscMethod::Segment, LimbDarkening::UNIFORM),
            (
                "middle_value",
                DiscMethod::MiddleValue,
                LimbDarkening::UNIFORM,
            ),
        ] {
            group.bench_with_input(BenchmarkId::new(name, body), &discs, |b, discs| {
                b.iter(|| {
                    discs
                        .iter()
                        .map(|d| visible_fraction(&h, d, method, &limb))
                        .sum::<f64>()
                })
            });
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(2))
        .warm_up_time(std::time::Duration::from_millis(500));
    targets = bench_disc
}
criterion_main!(benches);

//! Shadow-engine benchmarks (criterion, throughput in cells): SMap vs brute force for a hard
//! map, DP vs uniform ray stepping for a soft (visible-fraction) map, on a synthetic grid, the
//! shared 1536² 240 m LOLA grid (skipped if absent) and a sweep of sizes.
//!
//! `cargo bench --bench shadow` (figures in docs/shadow.md).

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use penumbra::MOON_RADIUS_M;
use penumbra::shadow::{SUN_ANGULAR_RADIUS_RAD, brute, dp};
use penumbra::terrain::HeightField;

const GRID_240M: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/data/lola-south-pole-moondao/ldem75s_crop_240m_pm184km.tif"
);

fn light_az_el(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    [az.sin() * el.cos(), az.cos() * el.cos(), el.sin()]
}

/// The whole 1536² grid as a model-space field centred on the pole (curvature drop added).
fn real_grid() -> Option<HeightField> {
    let file = match std::fs::File::open(GRID_240M) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("skipping real-grid benches: {GRID_240M}: {e}");
            return None;
        }
    };
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(file)).ok()?;
    let (w, h) = dec.dimensions().ok()?;
    let tiff::decoder::DecodingResult::F32(z) = dec.read_image().ok()? else {
        return None;
    };
    let (w, h) = (w as usize, h as usize);
    let mut hf = HeightField::flat(h, w, 240.0);
    for r in 0..h {
        for c in 0..w {
            let (x, y) = hf.xy_from_row_col(r as f64, c as f64);
            hf.z_m[r * w + c] =
                (z[r * w + c] as f64 - (x * x + y * y) / (2.0 * MOON_RADIUS_M)) as f32;
        }
    }
    Some(hf)
}

/// Rolling synthetic terrain (sum of sinusoids, ±700 m) on a 240 m grid, with curvature.
fn synthetic(n: usize) -> HeightField {
    let mut hf = HeightField::flat(n, n, 240.0);
    for r in 0..n {
        for c in 0..n {
            let (x, y) = hf.xy_from_row_col(r as f64, c as f64);
            let (u, v) = (x / 3000.0, y / 3000.0);
            let z = 400.0 * (u.sin() * (0.7 * v).cos())
                + 200.0 * (0.37 * u + 1.3 * v).sin()
                + 100.0 * (2.1 * u - 0.4 * v).cos()
                - (x * x + y * y) / (2.0 * MOON_RADIUS_M);
            hf.z_m[r * n + c] = z as f32;
        }
    }
    hf
}

fn configure(c: &mut Criterion) -> criterion::BenchmarkGroup<'_, criterion::measurement::WallTime> {
    let mut g = c.benchmark_group("shadow");
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(3));
    g
}

fn bench_maps(c: &mut Criterion) {
    let light = light_az_el(37.0, 1.5);
    let mut fields = vec![("synthetic512", synthetic(512))];
    if let Some(hf) = real_grid() {
        fields.push(("lola240m_1536", hf));
    }
    let mut g = configure(c);
    for (name, hf) in &fields {
        g.throughput(Throughput::Elements((hf.rows * hf.cols) as u64));
        g.bench_function(BenchmarkId::new("hard_brute", name), |b| {
            b.iter(|| {
                penumbra::shadow::Engine::Brute
                    .hard_mask(hf, 2.0, light)
                    .unwrap()
            })
        });
        g.bench_function(BenchmarkId::new("hard_smap", name), |b| {
            b.iter(|| {
                penumbra::shadow::Engine::Combined
                    .hard_mask(hf, 2.0, light)
                    .unwrap()
            })
        });
        // A Sun below the model horizontal: the rays descend and now march until terrain or the
        // grid edge (no "sphere below" shortcut; issue 13).
        let below = light_az_el(37.0, -0.5);
        g.bench_function(BenchmarkId::new("hard_smap_below", name), |b| {
            b.iter(|| {
                penumbra::shadow::Engine::Combined
                    .hard_mask(hf, 2.0, below)
                    .unwrap()
            })
        });
        g.bench_function(BenchmarkId::new("hard_brute_below", name), |b| {
            b.iter(|| {
                penumbra::shadow::Engine::Brute
                    .hard_mask(hf, 2.0, below)
                    .unwrap()
            })
        });
        g.bench_function(BenchmarkId::new("soft_dp", name), |b| {
            b.iter(|| {
                dp::visible_fraction(hf, 2.0, light, SUN_ANGULAR_RADIUS_RAD, &Default::default())
                    .unwrap()
            })
        });
        g.bench_function(BenchmarkId::new("soft_combined", name), |b| {
            b.iter(|| dp::soft_combined(hf, 2.0, light, SUN_ANGULAR_RADIUS_RAD).unwrap())
        });
        for step in [0.5, 1.0] {
            g.bench_function(
                BenchmarkId::new(format!("soft_uniform_step{step}"), name),
                |b| {
                    b.iter(|| {
                        brute::visible_fraction_uniform(
                            hf,
                            2.0,
                            light,
                            SUN_ANGULAR_RADIUS_RAD,
                            step,
                        )
                        .unwrap()
                    })
                },
            );
        }
    }
    g.finish();
}

fn bench_sizes(c: &mut Criterion) {
    let light = light_az_el(143.0, 1.5);
    let mut g = configure(c);
    for n in [128usize, 256, 512] {
        let hf = synthetic(n);
        g.throughput(Throughput::Elements((n * n) as u64));
        g.bench_function(BenchmarkId::new("sweep_hard_brute", n), |b| {
            b.iter(|| {
                penumbra::shadow::Engine::Brute
                    .hard_mask(&hf, 2.0, light)
                    .unwrap()
            })
        });
        g.bench_function(BenchmarkId::new("sweep_hard_smap", n), |b| {
            b.iter(|| {
                penumbra::shadow::Engine::Combined
                    .hard_mask(&hf, 2.0, light)
                    .unwrap()
            })
        });
        g.bench_function(BenchmarkId::new("sweep_soft_dp", n), |b| {
            b.iter(|| {
                dp::visible_fraction(&hf, 2.0, light, SUN_ANGULAR_RADIUS_RAD, &Default::default())
                    .unwrap()
            })
        });
    }
    g.finish();
}

// `criterion_group!` generates an undocumented `pub fn`; a private module keeps it out of the
// crate's public surface (and out of `missing_docs`).
mod group {
    use super::*;
    criterion_group!(benches, bench_maps, bench_sizes);
}
use group::benches;
criterion_main!(benches);

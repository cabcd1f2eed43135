//! The two per-site series engines on the synthetic DEM (400² at 100 m), eight days hourly (192
//! epochs), for 1, 10 and 100 sites: everything `run_series` computes except the files, sites in
//! parallel as in `run_series`. `horizon`: per-site horizons (fast scan, 0.25°) + the strip
//! integral per epoch; `smap_dp`: the model grid + max mipmap (once), the DP horizon profile per
//! site and one DP search per site, epoch and disc, then the per-epoch ephemeris pass that feeds
//! the CSV rows. `smap_dp_gpu` (feature `gpu`, skipped with a printed line when no adapter
//! exists): the same on the GPU (`series --engine smap-dp --backend gpu`); the device and
//! pipelines are built once per process, in the warm-up.
//!
//! `PENUMBRA_BENCH_KERNELS` overrides the kernel folder (default: the crate's `kernels/`), for
//! `tools/gpu-bench.sh` on a machine where the crate is elsewhere.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use penumbra::compute::Backend;
use penumbra::compute::site_dp::{ProfileParams, SiteDpRequest, site_dp};
use penumbra::ephem::{self, Kernels};
use penumbra::model::{ObserverHeight, Site};
use penumbra::products::series::{self, SeriesConfig, SiteFractions};
use penumbra::terrain::{TerrainStack, synth};
use rayon::prelude::*;

fn sites(n: usize) -> Vec<Site> {
    // A spiral of sites between 3 and 15 km from the pole.
    (0..n)
        .map(|i| {
            let t = i as f64 / n.max(1) as f64;
            Site::new(
                &format!("s{i}"),
                -89.9 + 0.4 * t,
                (i as f64 * 137.5) % 360.0,
                ObserverHeight::DEFAULT,
            )
            .unwrap()
        })
        .collect()
}

/// The smap-dp engine's request for `sites`.
fn dp_request<'a>(
    stack: &'a TerrainStack,
    sites: &'a [Site],
    table: &'a [ephem::MoonGeometry],
    config: &SeriesConfig,
) -> SiteDpRequest<'a> {
    SiteDpRequest {
        stack,
        sites,
        table,
        profile: ProfileParams {
            az_step_deg: config.az_step_deg,
            method: config.horizon_method,
        },
        limb: config.limb_darkening.law(),
        abcorr: config.abcorr,
    }
}

/// The sum of every site's Sun fractions through the per-epoch pass of `series`.
fn fraction_sum(
    table: &[ephem::MoonGeometry],
    sites: &[Site],
    horizons: &[penumbra::horizon::Horizon],
    given: Option<&[(Vec<f64>, Vec<f64>)]>,
    config: &SeriesConfig,
) -> f64 {
    sites
        .par_iter()
        .zip(horizons)
        .enumerate()
        .map(|(i, (s, h))| {
            let place =
                ephem::Site::new(s.lat_deg(), s.lon_deg(), h.ground_height_m + 2.0).unwrap();
            let source = match given {
                Some(f) => SiteFractions::Given {
                    sun: &f[i].0,
                    earth: &f[i].1,
                },
                None => SiteFractions::FromHorizon,
            };
            let (f, _) =
                series::site_fractions(table, &place, h, source, config, |_| false, |_, _| Ok(()))
                    .unwrap();
            f.iter().sum::<f64>()
        })
        .sum::<f64>()
}

fn bench_engines(c: &mut Criterion) {
    let kernels_dir = std::env::var_os("PENUMBRA_BENCH_KERNELS")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/kernels").into());
    let kernels = Kernels::load(&kernels_dir).unwrap();
    #[cfg(feature = "gpu")]
    let gpu = match penumbra::gpu::GpuContext::new() {
        Ok(ctx) => {
            eprintln!(
                "series_engines/smap_dp_gpu on adapter {}",
                ctx.adapter_name()
            );
            true
        }
        Err(e) => {
            eprintln!("series_engines/smap_dp_gpu skipped: {e}");
            false
        }
    };
    let stack = TerrainStack::new(vec![
        synth::south_polar_dem(&synth::SynthParams::default()).unwrap(),
    ]);
    let start = ephem::time::parse_utc("2027-01-25").unwrap();
    let stop = ephem::time::parse_utc("2027-02-01T23:00:00").unwrap();
    let epochs =
        ephem::time::epoch_range(start, stop, ephem::time::parse_step("1h").unwrap()).unwrap();
    assert_eq!(epochs.len(), 192);
    let table = ephem::moon_geometry_table(&kernels, &epochs).unwrap();
    let config = SeriesConfig {
        plots: false,
        write_csv: false,
        ..SeriesConfig::default()
    };
    let mut group = c.benchmark_group("series_engines");
    group.sample_size(10);
    for n in [1usize, 10, 100] {
        let sites = sites(n);
        group.bench_with_input(BenchmarkId::new("horizon", n), &sites, |b, sites| {
            b.iter(|| {
                let (horizons, _) = penumbra::compute::horizons::site_horizons(
                    Backend::Cpu,
                    &stack,
                    sites,
                    config.az_step_deg,
                    config.horizon_method,
                )
                .unwrap();
                fraction_sum(&table, sites, &horizons, None, &config)
            })
        });
        group.bench_with_input(BenchmarkId::new("smap_dp", n), &sites, |b, sites| {
            b.iter(|| {
                let run =
                    site_dp(Backend::Cpu, dp_request(&stack, sites, &table, &config)).unwrap();
                fraction_sum(&table, sites, &run.horizons, Some(&run.fractions), &config)
            })
        });
        #[cfg(feature = "gpu")]
        if gpu {
            group.bench_with_input(BenchmarkId::new("smap_dp_gpu", n), &sites, |b, sites| {
                b.iter(|| {
                    let run =
                        site_dp(Backend::Gpu, dp_request(&stack, sites, &table, &config)).unwrap();
                    fraction_sum(&table, sites, &run.horizons, Some(&run.fractions), &config)
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_engines);
criterion_main!(benches);

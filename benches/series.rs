//! The two per-site series engines (issue 7 item 3) on the synthetic DEM (400² at 100 m), eight
//! days hourly (192 epochs), for 1, 10 and 100 sites: everything `run_series` computes except the
//! files, sites in parallel as in `run_series`. `horizon`: per-site horizons (fast scan, 0.25°) + the strip integral per epoch;
//! `smap_dp`: the model grid + max mipmap (once), the DP horizon profile per site (for the CSV
//! columns and plots) and one DP search per site, epoch and disc.
//! `smap_dp_gpu` (feature `gpu`, skipped with a printed line when no adapter exists): the same
//! on the GPU (`series --engine smap-dp --backend gpu`): model grid, f32 grid + mipmap upload,
//! the horizon profiles and every (site, epoch, disc) search of `shaders/dp_sites.wgsl`, plus
//! the CPU's per-epoch ephemeris pass that feeds the CSV rows ([`series::site_fractions_given`]);
//! the device and pipelines are built once, outside the timing (as once per process).
//!
//! `PENUMBRA_BENCH_KERNELS` overrides the kernel folder (default: the crate's `kernels/`), for
//! `tools/gpu-bench.sh` on a machine where the crate is elsewhere.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use penumbra::ephem::{self, Kernels, Site};
use penumbra::series::dp::SmapDpSites;
use penumbra::series::{self, SeriesConfig, SeriesEngine, SeriesSite};
use penumbra::terrain::{TerrainStack, synth};
use rayon::prelude::*;

fn sites(n: usize) -> Vec<SeriesSite> {
    // A spiral of sites between 3 and 15 km from the pole.
    (0..n)
        .map(|i| {
            let t = i as f64 / n.max(1) as f64;
            SeriesSite {
                name: format!("s{i}"),
                lat_deg: -89.9 + 0.4 * t,
                lon_deg: (i as f64 * 137.5) % 360.0,
                height_above_ground_m: 2.0,
            }
        })
        .collect()
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
            Some(ctx)
        }
        Err(e) => {
            eprintln!("series_engines/smap_dp_gpu skipped: {e}");
            None
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
                let horizons = series::site_horizons(&stack, sites, &config).unwrap();
                sites
                    .par_iter()
                    .zip(&horizons)
                    .map(|(s, h)| {
                        let site =
                            Site::new(s.lat_deg, s.lon_deg, h.ground_height_m + 2.0).unwrap();
                        let (f, _) = series::site_fractions(
                            &table,
                            &site,
                            h,
                            &config,
                            |_| false,
                            |_, _| Ok(()),
                        )
                        .unwrap();
                        f.iter().sum::<f64>()
                    })
                    .sum::<f64>()
            })
        });
        let cfg = SeriesConfig {
            engine: SeriesEngine::SmapDp,
            ..config
        };
        group.bench_with_input(BenchmarkId::new("smap_dp", n), &sites, |b, sites| {
            b.iter(|| {
                let dp = SmapDpSites::new(&stack, sites).unwrap();
                sites
                    .par_iter()
                    .enumerate()
                    .map(|(i, s)| {
                        let site =
                            Site::new(s.lat_deg, s.lon_deg, dp.ground_height_m(i) + 2.0).unwrap();
                        let h = dp.horizon(i, s, &site, &cfg).unwrap();
                        let (f, _) = series::site_fractions_smap_dp(
                            &table,
                            &site,
                            &dp,
                            i,
                            &h,
                            &cfg,
                            |_| false,
                            |_, _| Ok(()),
                        )
                        .unwrap();
                        f.iter().sum::<f64>()
                    })
                    .sum::<f64>()
            })
        });
        #[cfg(feature = "gpu")]
        if let Some(ctx) = &gpu {
            group.bench_with_input(BenchmarkId::new("smap_dp_gpu", n), &sites, |b, sites| {
                b.iter(|| {
                    let dp = SmapDpSites::new(&stack, sites).unwrap();
                    let on_gpu = penumbra::series::dp::SmapDpGpu::new(ctx, &dp).unwrap();
                    let ephem_sites: Vec<Site> = sites
                        .iter()
                        .enumerate()
                        .map(|(i, s)| {
                            Site::new(s.lat_deg, s.lon_deg, dp.ground_height_m(i) + 2.0).unwrap()
                        })
                        .collect();
                    let horizons = on_gpu.horizons(&dp, sites, &ephem_sites, &cfg).unwrap();
                    let fractions = on_gpu.fractions(&dp, &table, &ephem_sites, &cfg).unwrap();
                    ephem_sites
                        .par_iter()
                        .zip(&horizons)
                        .zip(&fractions)
                        .map(|((site, h), (sun, earth))| {
                            let (f, _) = series::site_fractions_given(
                                &table,
                                site,
                                h,
                                sun,
                                earth,
                                &cfg,
                                |_| false,
                                |_, _| Ok(()),
                            )
                            .unwrap();
                            f.iter().sum::<f64>()
                        })
                        .sum::<f64>()
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_engines);
criterion_main!(benches);

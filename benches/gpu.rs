//! GPU vs CPU twin, side by side in one criterion group per kernel (anise `crit_*` layout), on
//! synthetic hills: `dp_soft` (one soft map at 1.5°, from the cells and from the same observers
//! as point records; throughput cells), `fourier_build` / `fourier_eval` (Fourier horizon maps,
//! CPU engine vs GPU; throughput rays = cells × azimuths, and cells), and `line_sweep` (the
//! whole-grid line sweep: the f64 CPU sweep, the twin and the GPU path end to end, and the looks
//! alone on one packed batch, twin vs GPU; throughput pixel-azimuths), and `horizon_stats` (the
//! horizons engine's epoch loop: the CPU engine, the twin kernel and the GPU; pixel-epochs).
//!
//! Run: `WGPU_BACKEND=vulkan cargo bench --bench gpu` (GPU part skipped with a printed reason
//! when no adapter exists). On a GPU machine without cargo: `tools/gpu-bench.sh`.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use penumbra::gpu::{DEFAULT_BAND_BYTES, GpuContext};
use penumbra::terrain::HeightField;
use penumbra::twins::{self, MarchGrid, RowBand};

fn sun_dir(az_deg: f64, el_deg: f64) -> Vector3<f64> {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    Vector3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin())
}

/// 20 m cells: three Gaussian hills and the Moon's curvature drop.
fn hills(n: usize) -> MarchGrid {
    MarchGrid::from_height_field(&hills_hf(n), 2.0).expect("valid grid")
}

/// The height field behind [`hills`].
fn hills_hf(n: usize) -> HeightField {
    let mut hf = HeightField::flat(n, n, 20.0);
    let half_m = n as f64 * 10.0;
    for row in 0..n {
        for col in 0..n {
            let (x, y) = hf.xy_from_row_col(row as f64, col as f64);
            let mut z = -(x * x + y * y) / (2.0 * penumbra::MOON_RADIUS_M);
            for (cx, cy, h, s) in [
                (0.2, 0.3, 400.0, 600.0),
                (-0.5, -0.1, 250.0, 300.0),
                (0.6, -0.6, 300.0, 400.0),
            ] {
                let (dx, dy) = (x - cx * half_m, y - cy * half_m);
                z += h * (-(dx * dx + dy * dy) / (2.0 * s * s)).exp();
            }
            hf.z_m[row * n + col] = z as f32;
        }
    }
    hf
}

fn context() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => {
            eprintln!(
                "GPU bench adapter: {} ({})",
                ctx.adapter_name(),
                ctx.adapter_kind()
            );
            Some(ctx)
        }
        Err(e) => {
            eprintln!("skipping the GPU half of the bench: {e}");
            None
        }
    }
}

/// One soft-shadow map (Sun disc, DP max-mipmap cost + disc occlusion) at 1.5°: the f64 CPU
/// engine (`dp::visible_fraction`, rayon), the f32 twin and the GPU kernel (mipmap built and
/// uploaded once, outside the timing, as in a sweep).
fn bench_dp_soft(c: &mut Criterion, ctx: Option<&GpuContext>) {
    use penumbra::gpu::dp::{GpuDpGrid, dp_visible_gpu};
    use penumbra::shadow::{SUN_ANGULAR_RADIUS_RAD, dp};
    let mut group = c.benchmark_group("dp_soft");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(6));
    let dir = sun_dir(151.0, 1.5);
    let light = twins::disc_light_to_f32(&dir, SUN_ANGULAR_RADIUS_RAD);
    for n in [256, 512] {
        let hf = hills_hf(n);
        let grid = MarchGrid::from_height_field(&hf, 2.0).expect("valid grid");
        let mip = twins::DpMip::build(&grid);
        group.throughput(Throughput::Elements(grid.cells() as u64));
        group.bench_with_input(BenchmarkId::new("cpu_dp", n), &hf, |b, hf| {
            b.iter(|| {
                dp::visible_fraction(
                    hf,
                    2.0,
                    dir.into(),
                    SUN_ANGULAR_RADIUS_RAD,
                    &dp::DpConfig::default(),
                )
                .expect("cpu dp")
            })
        });
        group.bench_with_input(BenchmarkId::new("cpu_twin", n), &grid, |b, grid| {
            b.iter(|| twins::dp_visible(grid, &mip, &[light], 0, RowBand::whole(grid)))
        });
        // The same observers as point records (a map's DEM pixels take this path,
        // `dp_points.wgsl`), the own half cell left out.
        let points: Vec<[f32; 4]> = (0..grid.rows)
            .flat_map(|row| (0..grid.cols).map(move |col| (row, col)))
            .map(|(row, col)| {
                let o = twins::dp_observer(&grid, row, col);
                [o.u0, o.v0, o.z0, 0.5]
            })
            .collect();
        group.bench_with_input(BenchmarkId::new("cpu_twin_points", n), &grid, |b, grid| {
            b.iter(|| twins::dp_points(grid, &mip, &points, light))
        });
        if let Some(ctx) = ctx {
            let gpu_grid = GpuDpGrid::upload(ctx, &grid, &mip).expect("upload");
            group.bench_with_input(BenchmarkId::new("gpu", n), &gpu_grid, |b, gpu_grid| {
                b.iter(|| dp_visible_gpu(ctx, gpu_grid, light, DEFAULT_BAND_BYTES).expect("gpu dp"))
            });
            group.bench_with_input(
                BenchmarkId::new("gpu_points", n),
                &gpu_grid,
                |b, gpu_grid| {
                    b.iter(|| {
                        penumbra::gpu::dp::dp_points_gpu(
                            ctx,
                            gpu_grid,
                            &points,
                            light,
                            DEFAULT_BAND_BYTES,
                        )
                        .expect("gpu dp points")
                    })
                },
            );
        }
    }
    group.finish();
}

/// Fourier horizon-map build (paper 001): the f64 CPU engine (`HorizonMap::build_with`, rayon)
/// and the GPU build (`build_horizon_map_gpu`: height upload, kernel, readback, f16 conversion),
/// `PENUMBRA_BENCH_FOURIER_AZ` azimuths (default 64), whole-grid rays, 16 coefficients.
/// Throughput is rays (cells × azimuths). Then the one-light evaluation (`fourier_eval`, soft Sun
/// at 1.5°) of the CPU-built map: CPU engine vs GPU (coefficients uploaded once).
fn bench_fourier(c: &mut Criterion, ctx: Option<&GpuContext>) {
    use penumbra::gpu::fourier::{GpuHorizonMap, build_horizon_map_gpu};
    use penumbra::shadow::SUN_ANGULAR_RADIUS_RAD;
    use penumbra::shadow::fourier::{self, HorizonMap, HorizonMapParams};
    let n_az: usize = std::env::var("PENUMBRA_BENCH_FOURIER_AZ")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64);
    let mut group = c.benchmark_group("fourier_build");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(6));
    let mut maps = Vec::new();
    for n in [128, 256] {
        let hf = hills_hf(n);
        let params = HorizonMapParams {
            observer_height_m: 2.0,
            n_azimuths: n_az,
            max_distance_cells: 2 * n,
            n_coeffs: fourier::DEFAULT_COEFFS,
        };
        group.throughput(Throughput::Elements((n * n * n_az) as u64));
        group.bench_with_input(BenchmarkId::new("cpu", n), &hf, |b, hf| {
            b.iter(|| HorizonMap::build_with(hf, 2.0, n_az, 2 * n, 16).expect("cpu build"))
        });
        if let Some(ctx) = ctx {
            group.bench_with_input(BenchmarkId::new("gpu", n), &hf, |b, hf| {
                b.iter(|| build_horizon_map_gpu(ctx, hf, &params).expect("gpu build"))
            });
        }
        maps.push((
            n,
            HorizonMap::build_with(&hf, 2.0, n_az, 2 * n, 16).expect("cpu build"),
        ));
    }
    group.finish();
    let mut group = c.benchmark_group("fourier_eval");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(3));
    let light: [f64; 3] = sun_dir(151.0, 1.5).into();
    for (n, map) in &maps {
        group.throughput(Throughput::Elements((n * n) as u64));
        group.bench_with_input(BenchmarkId::new("cpu", n), map, |b, map| {
            b.iter(|| fourier::visible_fraction(map, light, SUN_ANGULAR_RADIUS_RAD).expect("cpu"))
        });
        if let Some(ctx) = ctx {
            let on_gpu = GpuHorizonMap::upload(ctx, map, DEFAULT_BAND_BYTES).expect("upload");
            group.bench_with_input(BenchmarkId::new("gpu", n), &on_gpu, |b, on_gpu| {
                b.iter(|| {
                    on_gpu
                        .visible_fraction(ctx, light, SUN_ANGULAR_RADIUS_RAD)
                        .expect("gpu eval")
                })
            });
        }
    }
    group.finish();
}

/// One-light DP soft map, whole-grid kernel vs 2-D tiles (docs/gpu.md, "Large grids"), Sun at
/// 1.5° elevation. Size `PENUMBRA_BENCH_TILED_N` (default 512; `tools/gpu-bench.sh` also runs
/// 20000 on a GPU machine), tile side `PENUMBRA_BENCH_TILE_CELLS` (default N / 4, at most 2048).
/// The untiled variant is skipped with a printed reason where the grid exceeds one binding.
fn bench_dp_tiled(c: &mut Criterion, ctx: Option<&GpuContext>) {
    use penumbra::gpu::dp::{GpuDpGrid, dp_visible_gpu};
    use penumbra::gpu::tiles::{DpTileOptions, dp_visible_tiled_gpu};
    use penumbra::shadow::SUN_ANGULAR_RADIUS_RAD;
    let Some(ctx) = ctx else { return };
    let env = |name: &str| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse::<usize>().ok())
    };
    let n = env("PENUMBRA_BENCH_TILED_N").unwrap_or(512);
    let tile = env("PENUMBRA_BENCH_TILE_CELLS").unwrap_or((n / 4).clamp(2, 2048)) as u32;
    let mut group = c.benchmark_group("dp_tiled");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(if n > 4096 { 60 } else { 6 }));
    let light = twins::disc_light_to_f32(&sun_dir(151.0, 1.5), SUN_ANGULAR_RADIUS_RAD);
    let grid = hills(n);
    group.throughput(Throughput::Elements(grid.cells() as u64));
    let mip = twins::DpMip::build(&grid);
    match GpuDpGrid::upload(ctx, &grid, &mip) {
        Ok(gpu_grid) => {
            group.bench_with_input(BenchmarkId::new("gpu_untiled", n), &gpu_grid, |b, g| {
                b.iter(|| dp_visible_gpu(ctx, g, light, DEFAULT_BAND_BYTES).expect("gpu dp"))
            });
        }
        Err(e) => eprintln!("dp_tiled/gpu_untiled/{n}: skipped: {e}"),
    }
    drop(mip);
    let options = DpTileOptions::new(tile);
    let once = dp_visible_tiled_gpu(ctx, &grid, light, options).expect("tiled dp");
    eprintln!("dp_tiled/gpu_tiled_{tile}/{n}: {:?}", once.stats);
    group.bench_with_input(
        BenchmarkId::new(format!("gpu_tiled_{tile}"), n),
        &grid,
        |b, grid| b.iter(|| dp_visible_tiled_gpu(ctx, grid, light, options).expect("tiled dp")),
    );
    group.finish();
}

/// The line sweep on a 256² × 100 m polar DEM 60 km from the pole (hills and 15 m roughness),
/// 64 requested azimuths, max step 8.
fn bench_line_sweep(c: &mut Criterion, ctx: Option<&GpuContext>) {
    use penumbra::horizon::{HorizonSweep, SweepParams, SweepScratch};
    use penumbra::terrain::TerrainStack;
    use penumbra::twins::line_sweep::{
        LineBatch, SweepGrid, TWIN_BATCH_SAMPLES, line_sweep, sweep_twin,
    };
    let n = 256;
    let dem = penumbra::terrain::synth::square_dem_at(n, 100.0, (40e3, -45e3), "hills", |x, y| {
        let hash = ((x * 12.9898 + y * 78.233).sin() * 43758.5453).fract();
        800.0 * (x / 9_000.0).sin() * (y / 7_000.0).cos() + 15.0 * hash
    });
    let stack = TerrainStack::new(vec![dem]);
    let params = SweepParams {
        observer_height_m: 2.0,
        azimuths: 64,
        max_step: 8,
    };
    let sweep = HorizonSweep::new(&stack, params).expect("sweep");
    let n_dirs = sweep.directions().len();
    let mut group = c.benchmark_group("line_sweep");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    group.throughput(Throughput::Elements((n * n * n_dirs) as u64));
    let sink = |_: penumbra::horizon::SweepBand<'_>| -> Result<(), String> { Ok(()) };
    group.bench_function(BenchmarkId::new("cpu_f64", n), |b| {
        b.iter(|| sweep.run(sink, |_| {}).expect("cpu sweep"))
    });
    group.bench_function(BenchmarkId::new("twin", n), |b| {
        b.iter(|| sweep_twin(&sweep, sink, |_| {}).expect("twin sweep"))
    });
    if let Some(ctx) = ctx {
        group.bench_function(BenchmarkId::new("gpu", n), |b| {
            b.iter(|| {
                penumbra::gpu::line_sweep::sweep_gpu::<penumbra::gpu::GpuError>(
                    ctx,
                    &sweep,
                    |_| Ok(()),
                    |_| {},
                )
                .expect("gpu sweep")
            })
        });
    }
    // The looks alone: every line of as many directions as one batch of at most
    // `TWIN_BATCH_SAMPLES` holds (lavapipe's binding limit).
    let grid = SweepGrid::new(&sweep);
    let cols = sweep.grid_dem().grid.cols;
    let kept = 0..sweep.grid_dem().grid.rows * cols;
    let mut batch = LineBatch::default();
    let mut scratch = SweepScratch::default();
    let mut looks = 0;
    for (canonical, f, bwd) in sweep.line_directions() {
        let wanted = u32::from(f.is_some()) | (u32::from(bwd.is_some()) << 1);
        let mut dir_batch = LineBatch::default();
        for key in sweep.line_keys(canonical) {
            sweep.with_line(canonical, key, &mut scratch, |line| {
                dir_batch.push_line(&line, wanted, &kept)
            });
        }
        if batch.samples.len() + dir_batch.samples.len() > TWIN_BATCH_SAMPLES {
            break;
        }
        batch.append(&dir_batch);
        looks += usize::from(f.is_some()) + usize::from(bwd.is_some());
    }
    group.throughput(Throughput::Elements((n * n * looks) as u64));
    group.bench_function(BenchmarkId::new("looks_twin", n), |b| {
        b.iter(|| line_sweep(&grid, &batch))
    });
    if let Some(ctx) = ctx {
        let runner = penumbra::gpu::line_sweep::GpuLineSweep::new(ctx, &grid).expect("runner");
        group.bench_function(BenchmarkId::new("looks_gpu", n), |b| {
            b.iter(|| runner.run_batch(ctx, &batch).expect("gpu looks"))
        });
    }
    group.finish();
}

/// The horizons engine's epoch loop: the CPU engine (sector tables, SIMD), its f32
/// twin kernel (rayon) and `horizon_stats.wgsl`, each over every pixel of a rough 128² × 150 m
/// synthetic DEM round the pole (180-azimuth horizons in memory) and 2027 every 6 h (1,460
/// epochs, Sun and Earth); the block geometry and the below-sphere re-runs are inside the timing,
/// the sweep and the GPU pipeline outside. Throughput: pixel-epochs.
fn bench_horizon_stats(c: &mut Criterion, ctx: Option<&GpuContext>) {
    use penumbra::horizon::statistics::{
        CellKernel, NoStore, StatisticsEngine, StatisticsParams, testing::rough_terrain_2027,
    };
    use penumbra::twins::horizon_stats::TwinKernel;
    let n = 128;
    let (stack, mut horizons, bodies) =
        rough_terrain_2027(n, 1, 6.0, &penumbra::ephem::kernels::default_kernel_dir());
    let engine = StatisticsEngine::new(
        &stack,
        StatisticsParams {
            limb: penumbra::illum::LimbDarkening::EDDINGTON,
            visible_min_fraction: 1e-6,
            full_min_fraction: 0.999,
        },
    )
    .expect("engine");
    let mut group = c.benchmark_group("horizon_stats");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    group.throughput(Throughput::Elements((n * n * bodies.len()) as u64));
    let mut run = |kernel: Option<&mut dyn CellKernel>| {
        engine
            .run_rows_on(&mut horizons, &bodies, &mut NoStore, 0..n, kernel, |_| true)
            .expect("statistics")
            .sun_visible_count[n * n / 2]
    };
    group.bench_function(BenchmarkId::new("cpu_engine", n), |b| b.iter(|| run(None)));
    group.bench_function(BenchmarkId::new("twin", n), |b| {
        b.iter(|| run(Some(&mut TwinKernel::default())))
    });
    if let Some(ctx) = ctx {
        let mut gpu = penumbra::gpu::horizon_stats::GpuHorizonStats::new(ctx).expect("pipeline");
        group.bench_function(BenchmarkId::new("gpu", n), |b| {
            b.iter(|| run(Some(&mut gpu)))
        });
    }
    group.finish();
}

fn bench_gpu(c: &mut Criterion) {
    let ctx = context();
    bench_dp_soft(c, ctx.as_ref());
    bench_fourier(c, ctx.as_ref());
    bench_dp_tiled(c, ctx.as_ref());
    bench_line_sweep(c, ctx.as_ref());
    bench_horizon_stats(c, ctx.as_ref());
}

criterion_group!(benches, bench_gpu);
criterion_main!(benches);

//! Renderer benches.
//!
//! - `render_synthetic_320x240`: one 320 x 240 frame of the synthetic DEM (400 x 400 px at
//!   100 m) from a site camera: the per-frame shadow fractions (Sun + Earth, Combined engine) and
//!   ray casting + shading with the max-mipmap caster and with uniform half-cell stepping; and
//!   the GPU DP fractions that replace the Combined engine on the GPU backend
//!   (`scene_fractions_gpu_dp`, skipped without an adapter).
//! - `render_equal_error_320x240`: the same frame; the image error (`render::cast::image_error`)
//!   of each caster against a reference (uniform steps of 1/32 cell + bisection) is printed, and
//!   the mipmap caster is timed against the coarsest uniform step whose mean error is at most the
//!   mipmap caster's (speed-up at equal image error).
//! - `render_1080p`: a 1920 x 1080 frame, CPU mipmap, CPU uniform (half cell) and the GPU
//!   (`gpu::render`, skipped with a printed reason without an adapter), on the real 1536² LOLA
//!   grid (`../shared/data/lola-south-pole-moondao/ldem75s_crop_240m_pm184km.tif`, by path) when
//!   present (or `$PENUMBRA_RENDER_BENCH_DEM`), else the synthetic DEM. Visible fractions are set to 1 there: the cast + shade
//!   cost does not depend on their values, and their computation is the separate per-frame cost
//!   of `scene_fractions_combined`.
//!
//! Run: `cargo bench --bench render -- <group> --warm-up-time 1 --measurement-time 3`
//! (GPU on lavapipe: `WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=/tmp`).

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use penumbra::render::cast::image_error;
use penumbra::render::{Camera, Lights, Scene, TraceMethod};
use penumbra::shadow::Engine;

const LOLA_240M: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/data/lola-south-pole-moondao/ldem75s_crop_240m_pm184km.tif"
);

struct Setup {
    grid: penumbra::model::MapGrid,
    camera: Camera,
    lights: Lights,
}

/// The terrain (synthetic or a DEM file), a camera 10 m above (-89.6, 0) looking az 20 deg,
/// el -2 deg, fov 60 deg, Sun at az 30 deg el 1 deg, Earth at az 356 deg el 5.8 deg.
fn setup(dem: Option<&str>) -> Setup {
    let source = match dem {
        Some(path) => penumbra::products::TerrainSource::Dems(vec![path.into()]),
        None => penumbra::products::TerrainSource::Synthetic(Default::default()),
    };
    let (stack, _) = source.load().unwrap();
    let grid = penumbra::model::MapGrid::new(&stack).unwrap();
    let hf = &grid.hf;
    let lights = Lights {
        sun: grid.light_from_az_el_deg(30.0, 1.0),
        sun_radius_rad: 0.267_f64.to_radians(),
        earth: grid.light_from_az_el_deg(356.0, 5.8),
        earth_radius_rad: 0.9_f64.to_radians(),
    };
    let (lat, lon) = (-89.6, 0.0);
    let (ground_m, _) = stack.height_at_lat_lon_m_checked(lat, lon).unwrap();
    let pos = penumbra::terrain::model_space::ModelFrame::of(hf).model_from_lat_lon_height(
        lat,
        lon,
        ground_m + 10.0,
    );
    let model_from_enu =
        hf.model_from_moon_me() * penumbra::frames::enu_from_moon_me(lat, lon).transpose();
    let camera = Camera::from_az_el_deg(pos, &model_from_enu, 20.0, -2.0, 60.0).unwrap();
    Setup {
        grid,
        camera,
        lights,
    }
}

fn bench_render(c: &mut Criterion) {
    let s = setup(None);
    let hf = &s.grid.hf;
    let mut group = c.benchmark_group("render_synthetic_320x240");
    group.sample_size(10);
    group.bench_function("scene_fractions_combined", |b| {
        b.iter(|| Scene::new(hf, s.lights, Engine::Combined).unwrap())
    });
    // What `penumbra render` runs on the GPU backend instead: the GPU DP kernel (grid uploaded
    // once, outside the loop; two kernel runs + readback per frame).
    #[cfg(feature = "gpu")]
    match penumbra::gpu::GpuContext::new() {
        Ok(ctx) => {
            let fr = penumbra::compute::gpu_maps::GpuSceneFractions::upload(&ctx, hf).unwrap();
            group.bench_function(
                format!("scene_fractions_gpu_dp ({})", ctx.adapter_name()),
                |b| b.iter(|| fr.fractions(&ctx, &s.lights).unwrap()),
            );
        }
        Err(e) => eprintln!("render_synthetic: skipping the GPU fractions: {e}"),
    }
    let scene = Scene::new(hf, s.lights, Engine::Combined).unwrap();
    group.throughput(Throughput::Elements(320 * 240));
    group.bench_function("cast_and_shade", |b| {
        b.iter(|| scene.render(&s.camera, 320, 240).unwrap())
    });
    let uniform = Scene::new(hf, s.lights, Engine::Combined)
        .unwrap()
        .with_trace_method(TraceMethod::Uniform { step_cells: 0.5 });
    group.bench_function("cast_and_shade_uniform_half_cell", |b| {
        b.iter(|| uniform.render(&s.camera, 320, 240).unwrap())
    });
    group.finish();
}

fn bench_equal_error(c: &mut Criterion) {
    let s = setup(None);
    let hf = &s.grid.hf;
    let base = Scene::new(hf, s.lights, Engine::Combined).unwrap();
    let (sun_f, earth_f) = base.fractions();
    let scene = |m: TraceMethod| {
        Scene::with_fractions(hf, s.lights, sun_f.to_vec(), earth_f.to_vec()).with_trace_method(m)
    };
    let (w, h) = (320, 240);
    let reference = scene(TraceMethod::Uniform {
        step_cells: 1.0 / 32.0,
    })
    .render(&s.camera, w, h)
    .unwrap();
    let mip_img = base.render(&s.camera, w, h).unwrap();
    let mip_err = image_error(&mip_img, &reference);
    eprintln!("image error vs uniform 1/32 cell: max-mipmap {mip_err:?}");
    let mut chosen = None;
    for n in [2.0, 4.0, 8.0, 16.0] {
        let img = scene(TraceMethod::Uniform {
            step_cells: 1.0 / n,
        })
        .render(&s.camera, w, h)
        .unwrap();
        let e = image_error(&img, &reference);
        eprintln!("image error vs uniform 1/32 cell: uniform 1/{n} cell {e:?}");
        if chosen.is_none() && e.mean_rel <= mip_err.mean_rel {
            chosen = Some(n);
        }
    }
    let n = chosen.unwrap_or(16.0);
    eprintln!("equal-error uniform step: 1/{n} cell");
    let mut group = c.benchmark_group("render_equal_error_320x240");
    group.sample_size(10);
    group.throughput(Throughput::Elements(u64::from(w * h)));
    group.bench_function("max_mipmap", |b| {
        b.iter(|| base.render(&s.camera, w, h).unwrap())
    });
    let uniform = scene(TraceMethod::Uniform {
        step_cells: 1.0 / n,
    });
    group.bench_function(format!("uniform_1_over_{n}_cell"), |b| {
        b.iter(|| uniform.render(&s.camera, w, h).unwrap())
    });
    group.finish();
}

fn bench_1080p(c: &mut Criterion) {
    // PENUMBRA_RENDER_BENCH_DEM overrides the path (tools/gpu-bench.sh stages the grid).
    let path = std::env::var("PENUMBRA_RENDER_BENCH_DEM").unwrap_or_else(|_| LOLA_240M.into());
    let dem = std::path::Path::new(&path)
        .exists()
        .then_some(path.as_str());
    if dem.is_none() {
        eprintln!("render_1080p: {path} absent; using the synthetic DEM");
    }
    let s = setup(dem);
    let hf = &s.grid.hf;
    let ones = vec![1.0_f32; hf.z_m.len()];
    let scene = Scene::with_fractions(hf, s.lights, ones.clone(), ones);
    let (w, h) = (1920, 1080);
    let name = if dem.is_some() {
        format!("render_1080p_lola_{}x{}", hf.rows, hf.cols)
    } else {
        format!("render_1080p_synthetic_{}x{}", hf.rows, hf.cols)
    };
    let mut group = c.benchmark_group(name);
    group.sample_size(10);
    group.throughput(Throughput::Elements(u64::from(w * h)));
    #[cfg(feature = "gpu")]
    match penumbra::gpu::GpuContext::new() {
        Ok(ctx) => {
            use penumbra::gpu::render::{GpuRenderScene, RenderGpuOptions, render_radiance_gpu};
            let gpu_scene = GpuRenderScene::upload(&ctx, &scene).unwrap();
            group.bench_function(format!("gpu ({})", ctx.adapter_name()), |b| {
                b.iter(|| {
                    render_radiance_gpu(
                        &ctx,
                        &gpu_scene,
                        &s.camera,
                        w,
                        h,
                        RenderGpuOptions::default(),
                    )
                    .unwrap()
                })
            });
        }
        Err(e) => eprintln!("render_1080p: skipping the GPU: {e}"),
    }
    group.bench_function("cpu_max_mipmap", |b| {
        b.iter(|| scene.render(&s.camera, w, h).unwrap())
    });
    let uniform = Scene::with_fractions(
        hf,
        s.lights,
        vec![1.0; hf.z_m.len()],
        vec![1.0; hf.z_m.len()],
    )
    .with_trace_method(TraceMethod::Uniform { step_cells: 0.5 });
    group.bench_function("cpu_uniform_half_cell", |b| {
        b.iter(|| uniform.render(&s.camera, w, h).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench_render, bench_equal_error, bench_1080p);
criterion_main!(benches);

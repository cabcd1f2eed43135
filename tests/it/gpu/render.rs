//! Max-mipmap ray casting (CPU) and the GPU render path: accuracy of the caster against fine
//! uniform stepping, GPU-vs-CPU parity on the synthetic DEM and on a flat plane, row-band tiling,
//! the `--backend` switch of `penumbra render`, and naga validation of shaders/render.wgsl.
//!
//! GPU tests need an adapter (lavapipe: `WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=/tmp`); without one
//! they fail naming it, unless `PENUMBRA_SKIP=gpu` counts them as skipped.

use penumbra::render::cast::image_error;
use penumbra::render::{Camera, Lights, Sample, Scene, TraceMethod};
use penumbra::shadow::Engine;

#[cfg(feature = "gpu")]
fn dir_az_el_deg(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let v = penumbra::frames::enu_from_az_el_deg(az_deg, el_deg);
    [v.x, v.y, v.z]
}

/// The synthetic DEM (400 x 400 px at 100 m) seen from 10 m above (-89.6, 0), looking az 20 deg,
/// el -2 deg (the render bench's scene), Sun at az 30 deg el 1 deg, Earth at az 356 deg el 5.8.
fn synthetic_scene() -> (penumbra::model::MapGrid, Lights, Camera) {
    let source = penumbra::products::TerrainSource::Synthetic(Default::default());
    let (stack, _) = source.load().unwrap();
    let grid = penumbra::model::MapGrid::new(&stack).unwrap();
    let lights = Lights {
        sun: grid.light_from_az_el_deg(30.0, 1.0),
        sun_radius_rad: 0.267_f64.to_radians(),
        earth: grid.light_from_az_el_deg(356.0, 5.8),
        earth_radius_rad: 0.9_f64.to_radians(),
    };
    let (lat, lon) = (-89.6, 0.0);
    let (ground_m, _) = stack.height_at_lat_lon_m_checked(lat, lon).unwrap();
    let hf = &grid.hf;
    let pos = penumbra::terrain::model_space::ModelFrame::of(hf).model_from_lat_lon_height(
        lat,
        lon,
        ground_m + 10.0,
    );
    let model_from_enu =
        hf.model_from_moon_me() * penumbra::frames::enu_from_moon_me(lat, lon).transpose();
    let camera = Camera::from_az_el_deg(pos, &model_from_enu, 20.0, -2.0, 60.0).unwrap();
    (grid, lights, camera)
}

fn terrain_pixels(img: &[Sample]) -> usize {
    img.iter()
        .filter(|s| matches!(s, Sample::Terrain { .. }))
        .count()
}

/// Mipmap casting vs a reference of uniform steps of 1/16 cell + 30 bisections, on the synthetic
/// DEM at 96 x 72 px (real shadow fractions): the mipmap image is within the reference's own
/// stepping error, and uniform half-cell stepping (the first cut) is worse.
#[test]
fn mipmap_caster_matches_fine_uniform_stepping() {
    let (grid, lights, camera) = synthetic_scene();
    let hf = &grid.hf;
    let mip = Scene::new(hf, lights, Engine::Combined).unwrap();
    let (sun_f, earth_f) = mip.fractions();
    let with = |m| {
        Scene::with_fractions(hf, lights, sun_f.to_vec(), earth_f.to_vec()).with_trace_method(m)
    };
    let (w, h) = (96, 72);
    let reference = with(TraceMethod::Uniform {
        step_cells: 1.0 / 16.0,
    })
    .render(&camera, w, h)
    .unwrap();
    let mip_img = mip.render(&camera, w, h).unwrap();
    let half = with(TraceMethod::Uniform { step_cells: 0.5 })
        .render(&camera, w, h)
        .unwrap();
    let e_mip = image_error(&mip_img, &reference);
    let e_half = image_error(&half, &reference);
    eprintln!("vs uniform 1/16 cell: mipmap {e_mip:?}");
    eprintln!("vs uniform 1/16 cell: uniform 1/2 cell {e_half:?}");
    assert!(terrain_pixels(&reference) > w as usize * h as usize / 4);
    assert!(
        e_mip.mean_rel < 2e-3,
        "mipmap mean error {}",
        e_mip.mean_rel
    );
    assert!(
        e_mip.class_mismatch <= 2,
        "{} silhouette pixels",
        e_mip.class_mismatch
    );
    assert!(
        e_half.mean_rel > e_mip.mean_rel,
        "half-cell stepping ({}) not worse than mipmap ({})",
        e_half.mean_rel,
        e_mip.mean_rel
    );
}

/// naga validates shaders/render.wgsl with shared/brdf.wgsl composed before it, and brdf.wgsl
/// has the shared signature `brdf_per_sr(model: u32, cos_i, cos_e, cos_g, albedo: f32) -> f32`.
#[test]
fn naga_validates_render_shader_and_brdf_signature() {
    let render = penumbra::gpu::shaders::RENDER;
    assert_eq!(render.parts, ["shared/brdf.wgsl"]);
    let module = crate::util::naga_validate(render.name, render.source);
    let (_, f) = module
        .functions
        .iter()
        .find(|(_, f)| f.name.as_deref() == Some("brdf_per_sr"))
        .expect("brdf_per_sr defined");
    let names: Vec<_> = f
        .arguments
        .iter()
        .map(|a| a.name.clone().unwrap())
        .collect();
    assert_eq!(names, ["model", "cos_i", "cos_e", "cos_g", "albedo"]);
    let scalar = |h| match module.types[h].inner {
        naga::TypeInner::Scalar(s) => s,
        ref other => panic!("not a scalar: {other:?}"),
    };
    assert_eq!(scalar(f.arguments[0].ty), naga::Scalar::U32);
    for a in &f.arguments[1..] {
        assert_eq!(scalar(a.ty), naga::Scalar::F32);
    }
    assert_eq!(scalar(f.result.as_ref().unwrap().ty), naga::Scalar::F32);
    let entries: Vec<_> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    assert_eq!(entries, ["render"]);
}

#[cfg(feature = "gpu")]
mod on_gpu {
    use nalgebra::{Matrix3, Vector3};
    use penumbra::gpu::render::{
        GpuRenderScene, RenderGpuOptions, render_gpu, render_radiance_gpu,
    };
    use penumbra::render::DEFAULT_ALBEDO;
    use penumbra::terrain::HeightField;

    use super::*;

    /// Bounds of `gpu_fractions_image_matches_cpu_fractions_image` (measured values in
    /// docs/VALIDATION.md).
    /// Mean |GPU - CPU| visible fraction per cell (measured: Sun 3.4e-4, Earth 8.2e-6).
    const FRACTION_MEAN_BOUND: f64 = 2e-3;
    /// Share of cells whose fraction differs by > 0.1, % (measured: Sun 0.058, Earth 0.001).
    const FRACTION_BIG_PCT_BOUND: f64 = 0.5;
    /// Share of pixels differing by > 5 % of L_p99 (measured: 0).
    const IMAGE_BIG_FRACTION_BOUND: f64 = 0.005;
    /// Max |dL| / L_p99 over the other pixels (measured 4.7e-5).
    const IMAGE_MAX_BOUND: f64 = 1e-3;
    /// Mean |dL| / L_p99 (measured 1.3e-8).
    const IMAGE_MEAN_BOUND: f64 = 1e-5;

    use crate::util::gpu;

    /// Per-pixel comparison of a GPU image with the CPU image: pixels whose class differs or
    /// whose |dL| exceeds 5 % of the CPU image's p99 radiance are "silhouette" pixels (the f32
    /// ray hits a different surface at a grazing edge); the rest give max and mean |dL| / L_p99
    /// and max |dL| / L over pixels with L > 1 % of L_p99.
    struct Parity {
        silhouette: usize,
        max_scaled: f64,
        mean_scaled: f64,
        max_rel: f64,
        pixels: usize,
    }

    fn parity(gpu: &[Sample], cpu: &[Sample]) -> Parity {
        let scale = penumbra::render::terrain_radiance_p99(cpu).unwrap_or(2.0);
        let mut p = Parity {
            silhouette: 0,
            max_scaled: 0.0,
            mean_scaled: 0.0,
            max_rel: 0.0,
            pixels: cpu.len(),
        };
        let mut n = 0;
        for (g, c) in gpu.iter().zip(cpu) {
            match (g, c) {
                (
                    Sample::Terrain {
                        radiance_w_m2_sr: lg,
                    },
                    Sample::Terrain {
                        radiance_w_m2_sr: lc,
                    },
                ) => {
                    let d = f64::from((lg - lc).abs());
                    if d > 0.05 * scale {
                        p.silhouette += 1;
                        continue;
                    }
                    p.max_scaled = p.max_scaled.max(d / scale);
                    p.mean_scaled += d / scale;
                    n += 1;
                    if f64::from(*lc) > 0.01 * scale {
                        p.max_rel = p.max_rel.max(d / f64::from(*lc));
                    }
                }
                (a, b) if a == b => {}
                _ => p.silhouette += 1,
            }
        }
        p.mean_scaled /= f64::from(n.max(1));
        p
    }

    /// The synthetic DEM scene at 160 x 120 px: GPU (f32) vs CPU (f64) max-mipmap renderer, with
    /// the Lambert BRDF and with Hapke (the WGSL twin of `render::brdf`).
    #[test]
    fn gpu_matches_cpu_on_the_synthetic_dem() {
        let Some(ctx) = gpu() else { return };
        let (grid, lights, camera) = synthetic_scene();
        for brdf in [
            penumbra::render::Brdf::Lambert {
                albedo: penumbra::render::DEFAULT_ALBEDO,
            },
            penumbra::render::Brdf::Hapke(penumbra::render::HapkeParams::MOON_643NM),
        ] {
            let scene = Scene::new(&grid.hf, lights, Engine::Combined)
                .unwrap()
                .with_brdf(brdf);
            let (w, h) = (160, 120);
            let cpu = scene.render(&camera, w, h).unwrap();
            let gs = GpuRenderScene::upload(ctx, &scene).unwrap();
            let gpu = render_gpu(ctx, &gs, &camera, w, h, RenderGpuOptions::default()).unwrap();
            let p = parity(&gpu, &cpu);
            eprintln!(
                "synthetic DEM {w}x{h} {brdf:?}: {} terrain px, silhouette {} ({:.3} %), max \
                 |dL|/L_p99 {:.2e}, mean {:.2e}, max |dL|/L {:.2e}",
                terrain_pixels(&cpu),
                p.silhouette,
                100.0 * p.silhouette as f64 / p.pixels as f64,
                p.max_scaled,
                p.mean_scaled,
                p.max_rel
            );
            assert!(terrain_pixels(&cpu) > p.pixels / 4);
            assert!((p.silhouette as f64) < 0.005 * p.pixels as f64);
            assert!(p.max_scaled < 0.02, "max |dL|/L_p99 {}", p.max_scaled);
            assert!(p.mean_scaled < 1e-3, "mean |dL|/L_p99 {}", p.mean_scaled);
        }
    }

    /// `penumbra render` on the GPU takes its per-cell Sun and Earth fractions from the GPU DP
    /// kernel (`compute::gpu_maps::GpuSceneFractions`) instead of the CPU engine (`Scene::new`, Combined).
    /// Synthetic DEM scene, both scenes rendered by the same CPU renderer so that only the
    /// fractions differ: fraction and image differences are printed and bounded.
    #[test]
    fn gpu_fractions_image_matches_cpu_fractions_image() {
        let Some(ctx) = gpu() else { return };
        let (grid, lights, camera) = synthetic_scene();
        let hf = &grid.hf;
        let brdf = penumbra::render::Brdf::Hapke(penumbra::render::HapkeParams::MOON_643NM);
        let cpu_scene = Scene::new(hf, lights, Engine::Combined)
            .unwrap()
            .with_brdf(brdf);
        let fr = penumbra::compute::gpu_maps::GpuSceneFractions::upload(ctx, hf).unwrap();
        let (sun, earth) = fr.fractions(ctx, &lights).unwrap();
        let (cpu_sun, cpu_earth) = cpu_scene.fractions();
        for (name, g, c) in [("sun", &sun, cpu_sun), ("earth", &earth, cpu_earth)] {
            assert_eq!(g.len(), c.len());
            let (mut max_d, mut sum_d, mut n, mut big) = (0.0_f32, 0.0_f64, 0_usize, 0_usize);
            for (a, b) in g.iter().zip(c) {
                assert_eq!(a.is_nan(), b.is_nan(), "{name}: hole mismatch");
                if a.is_nan() {
                    continue;
                }
                let d = (a - b).abs();
                max_d = max_d.max(d);
                sum_d += f64::from(d);
                n += 1;
                if d > 0.1 {
                    big += 1;
                }
            }
            let mean_d = sum_d / n as f64;
            let big_pct = 100.0 * big as f64 / n as f64;
            eprintln!(
                "{name} fraction GPU DP vs CPU Combined over {n} cells: max |df| {max_d:.3e}, \
                 mean {mean_d:.3e}, cells with |df| > 0.1: {big_pct:.3} %"
            );
            assert!(mean_d < FRACTION_MEAN_BOUND, "{name}: mean |df| {mean_d}");
            assert!(
                big_pct < FRACTION_BIG_PCT_BOUND,
                "{name}: {big_pct} % cells off by > 0.1"
            );
        }
        let gpu_scene = Scene::with_fractions(hf, lights, sun, earth).with_brdf(brdf);
        let (w, h) = (160, 120);
        let cpu_img = cpu_scene.render(&camera, w, h).unwrap();
        let gpu_img = gpu_scene.render(&camera, w, h).unwrap();
        let p = parity(&gpu_img, &cpu_img);
        eprintln!(
            "GPU-fraction vs CPU-fraction image {w}x{h}: {} terrain px, differing > 5 % of \
             L_p99: {} ({:.3} %), max |dL|/L_p99 of the rest {:.2e}, mean {:.2e}",
            terrain_pixels(&cpu_img),
            p.silhouette,
            100.0 * p.silhouette as f64 / p.pixels as f64,
            p.max_scaled,
            p.mean_scaled
        );
        assert!(terrain_pixels(&cpu_img) > p.pixels / 4);
        assert!(
            (p.silhouette as f64) < IMAGE_BIG_FRACTION_BOUND * p.pixels as f64,
            "{} px differ by > 5 % of L_p99",
            p.silhouette
        );
        assert!(
            p.max_scaled < IMAGE_MAX_BOUND,
            "max |dL|/L_p99 {}",
            p.max_scaled
        );
        assert!(
            p.mean_scaled < IMAGE_MEAN_BOUND,
            "mean |dL|/L_p99 {}",
            p.mean_scaled
        );
    }

    /// A flat plane (64 x 64 cells of 10 m) from 100 m up, Sun at 30 deg: GPU vs CPU and both vs
    /// the analytic Lambert radiance albedo * S * sin(e) / pi.
    #[test]
    fn gpu_matches_cpu_and_lambert_on_a_flat_plane() {
        let Some(ctx) = gpu() else { return };
        let hf = HeightField::flat(64, 64, 10.0);
        let sun_el_deg: f64 = 30.0;
        let lights = Lights {
            sun: dir_az_el_deg(135.0, sun_el_deg),
            sun_radius_rad: 0.267_f64.to_radians(),
            earth: dir_az_el_deg(0.0, -30.0),
            earth_radius_rad: 0.95_f64.to_radians(),
        };
        let scene = Scene::new(&hf, lights, Engine::Combined).unwrap();
        let cam = Camera::from_az_el_deg(
            Vector3::new(0.0, 0.0, 100.0),
            &Matrix3::identity(),
            30.0,
            -60.0,
            40.0,
        )
        .unwrap();
        let (w, h) = (64, 48);
        let cpu = scene.render(&cam, w, h).unwrap();
        let gs = GpuRenderScene::upload(ctx, &scene).unwrap();
        let gpu = render_gpu(ctx, &gs, &cam, w, h, RenderGpuOptions::default()).unwrap();
        let want = DEFAULT_ALBEDO * penumbra::SOLAR_CONSTANT_W_M2 * sun_el_deg.to_radians().sin()
            / std::f64::consts::PI;
        let mut max_rel_gpu_cpu = 0.0_f64;
        let mut max_rel_gpu_lambert = 0.0_f64;
        for (g, c) in gpu.iter().zip(&cpu) {
            let (
                Sample::Terrain {
                    radiance_w_m2_sr: lg,
                },
                Sample::Terrain {
                    radiance_w_m2_sr: lc,
                },
            ) = (g, c)
            else {
                panic!("not terrain: gpu {g:?} cpu {c:?}");
            };
            let (lg, lc) = (f64::from(*lg), f64::from(*lc));
            max_rel_gpu_cpu = max_rel_gpu_cpu.max((lg - lc).abs() / lc);
            max_rel_gpu_lambert = max_rel_gpu_lambert.max((lg - want).abs() / want);
        }
        eprintln!(
            "flat plane: max |dL|/L GPU vs CPU {max_rel_gpu_cpu:.2e}, GPU vs Lambert \
             {max_rel_gpu_lambert:.2e}"
        );
        assert!(max_rel_gpu_cpu < 1e-5, "{max_rel_gpu_cpu}");
        assert!(max_rel_gpu_lambert < 0.01, "{max_rel_gpu_lambert}");
    }

    /// Row bands of 1 and 7 rows give the same radiance as one band (bit for bit), and the
    /// sky discs come out where the CPU puts them (a camera looking at the Sun).
    #[test]
    fn gpu_row_bands_are_seamless_and_discs_match() {
        let Some(ctx) = gpu() else { return };
        let (grid, lights, _) = synthetic_scene();
        let scene = Scene::new(&grid.hf, lights, Engine::Combined).unwrap();
        let gs = GpuRenderScene::upload(ctx, &scene).unwrap();
        // Look at the Sun (az 30, el 1 at the map centre) from 100 m above the highest point
        // (terrain hides it from the ground).
        let hf = &grid.hf;
        let z = scene.caster().z_range_m().1 + 100.0;
        let sun = Vector3::from(lights.sun);
        let up = Vector3::new(0.0, 0.0, 1.0);
        let right = sun.cross(&up).normalize();
        let cam = Camera {
            pos_model_m: Vector3::new(0.0, 0.0, z),
            forward_model: sun,
            right_model: right,
            up_model: right.cross(&sun).normalize(),
            fov_deg: 3.0,
        };
        let (w, h) = (40, 30);
        let one = render_radiance_gpu(ctx, &gs, &cam, w, h, RenderGpuOptions::default()).unwrap();
        for rows in [1_u64, 7] {
            let banded = render_radiance_gpu(
                ctx,
                &gs,
                &cam,
                w,
                h,
                RenderGpuOptions {
                    band_bytes: rows * 4 * u64::from(w),
                },
            )
            .unwrap();
            assert!(
                one.iter()
                    .zip(&banded)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "bands of {rows} rows differ"
            );
        }
        let gpu = penumbra::gpu::render::samples_from_radiance(&one);
        let cpu = scene.render(&cam, w, h).unwrap();
        let sun_px = |img: &[Sample]| img.iter().filter(|s| **s == Sample::Sun).count();
        let differ = gpu.iter().zip(&cpu).filter(|(a, b)| a != b).count();
        eprintln!(
            "Sun disc: {} px GPU, {} px CPU, {differ} px differ ({}x{} cells)",
            sun_px(&gpu),
            sun_px(&cpu),
            hf.rows,
            hf.cols
        );
        assert!(
            sun_px(&cpu) > 20,
            "the Sun's disc covers {} px",
            sun_px(&cpu)
        );
        assert!(differ <= 4, "{differ} px differ");
    }

    /// `penumbra render --backend gpu` writes the same-size PNG as `--backend cpu`.
    #[test]
    fn cli_backend_gpu_renders() {
        if gpu().is_none() {
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let k = crate::util::kernels_dir();
        let k = k.to_str().unwrap();
        for backend in ["gpu", "cpu"] {
            let out = dir.path().join(format!("{backend}.png"));
            let o = crate::util::penumbra(
                dir.path(),
                &[
                    "render",
                    "--synthetic",
                    "--lat-deg",
                    "-89.6",
                    "--lon-deg",
                    "0",
                    "--height-m",
                    "10",
                    "--look-az-deg",
                    "20",
                    "--look-el-deg",
                    "-2",
                    "--utc",
                    "2027-01-20T00:00",
                    "--width",
                    "48",
                    "--height",
                    "32",
                    "--backend",
                    backend,
                    "--kernels",
                    k,
                    "--out",
                    out.to_str().unwrap(),
                    "--out-radiance",
                    dir.path().join(format!("{backend}.tif")).to_str().unwrap(),
                ],
            );
            assert!(
                o.status.success(),
                "{backend}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            let img = image::open(&out).unwrap();
            assert_eq!((img.width(), img.height()), (48, 32));
        }
        // End to end, `--backend gpu` (GPU DP fractions + GPU caster, f32) vs `--backend cpu`
        // (Combined engine + CPU caster, f64): radiance TIFFs, |dL| relative to the CPU image's
        // p99 radiance (measured values in docs/VALIDATION.md).
        let read = |name: &str| {
            let bytes = std::fs::read(dir.path().join(name)).unwrap();
            let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(bytes)).unwrap();
            let tiff::decoder::DecodingResult::F32(v) = dec.read_image().unwrap() else {
                panic!("f32 TIFF expected")
            };
            // Sky is NaN (nodata): compared as no radiance, so a pixel that is sky in one image
            // and terrain in the other counts with the terrain's radiance.
            v.into_iter()
                .map(|l| if l.is_nan() { 0.0 } else { l })
                .collect::<Vec<f32>>()
        };
        let (g, c) = (read("gpu.tif"), read("cpu.tif"));
        let mut sorted: Vec<f32> = c.clone();
        sorted.sort_by(f32::total_cmp);
        let p99 = f64::from(sorted[sorted.len() * 99 / 100]);
        assert!(p99 > 0.0);
        let d: Vec<f64> = g
            .iter()
            .zip(&c)
            .map(|(a, b)| f64::from((a - b).abs()) / p99)
            .collect();
        let big = d.iter().filter(|&&x| x > 0.05).count();
        let max = d.iter().copied().fold(0.0, f64::max);
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        eprintln!(
            "penumbra render 48x32 --backend gpu vs cpu: px with |dL| > 5 % L_p99: {big}, \
             max |dL|/L_p99 {max:.2e}, mean {mean:.2e}"
        );
        assert!(big <= 8, "{big} px differ by > 5 % of L_p99");
        assert!(mean < 1e-4, "mean |dL|/L_p99 {mean}");
    }
}

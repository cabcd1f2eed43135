//! CPU reference renderer: one 320 x 240 frame of the synthetic DEM (400 x 400 px at 100 m)
//! from a site camera, split into the per-frame shadow fractions (Sun + Earth, Combined engine)
//! and the ray casting + shading.
//!
//! Run: `cargo bench --bench render`.

#![allow(
    missing_docs,
    reason = "criterion's macros generate undocumented items"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use penumbra::render::{Camera, Lights, Scene};
use penumbra::shadow::Engine;

fn bench_render(c: &mut Criterion) {
    let args = penumbra::cli::TerrainArgs {
        dem: vec![],
        synthetic: true,
    };
    let (stack, _) = penumbra::app::load_terrain(&args).unwrap();
    let grid = penumbra::map::MapGrid::new(&stack).unwrap();
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

    let mut group = c.benchmark_group("render_synthetic_320x240");
    group.sample_size(10);
    group.bench_function("scene_fractions_combined", |b| {
        b.iter(|| Scene::new(hf, lights, Engine::Combined).unwrap())
    });
    let scene = Scene::new(hf, lights, Engine::Combined).unwrap();
    group.throughput(Throughput::Elements(320 * 240));
    group.bench_function("cast_and_shade", |b| {
        b.iter(|| scene.render(&camera, 320, 240).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);

//! `penumbra render`: analytic Lambert radiance on a plane, a wall's shadow, the CLI, bad input.

use nalgebra::{Matrix3, Vector3};
use penumbra::render::{Camera, DEFAULT_ALBEDO, Lights, Sample, Scene};
use penumbra::shadow::Engine;
use penumbra::terrain::HeightField;

use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, png_text};

fn dir_az_el_deg(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let v = penumbra::frames::enu_from_az_el_deg(az_deg, el_deg);
    [v.x, v.y, v.z]
}

fn lambert_w_m2_sr(sun_el_deg: f64) -> f64 {
    DEFAULT_ALBEDO * penumbra::SOLAR_CONSTANT_W_M2 * sun_el_deg.to_radians().sin()
        / std::f64::consts::PI
}

fn terrain_radiance(s: Sample) -> f64 {
    match s {
        Sample::Terrain { radiance_w_m2_sr } => f64::from(radiance_w_m2_sr),
        other => panic!("expected terrain, got {other:?}"),
    }
}

/// A flat plane lit by a Sun at elevation e (Earth below the horizon): every ground pixel of a
/// camera looking down has radiance albedo * S * sin(e) / pi (the shadow engine runs for real).
#[test]
fn flat_plane_matches_lambert() {
    let hf = HeightField::flat(64, 64, 10.0);
    for sun_el_deg in [10.0, 30.0, 60.0] {
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
        let img = scene.render(&cam, 16, 12).unwrap();
        let want = lambert_w_m2_sr(sun_el_deg);
        let max_rel = img
            .iter()
            .map(|s| (terrain_radiance(*s) - want).abs() / want)
            .fold(0.0_f64, f64::max);
        eprintln!("sun el {sun_el_deg} deg: analytic {want:.4}, max relative error {max_rel:.2e}");
        for s in img {
            let got = terrain_radiance(s);
            let rel = (got - want).abs() / want;
            assert!(
                rel < 0.01,
                "sun el {sun_el_deg}: {got} vs analytic {want} ({rel})"
            );
        }
    }
}

/// A wall (20 m tall, 2 cells thick) on a flat 1 m grid, Sun from the east at 20 deg: the
/// shadow on the west side is 20 / tan(20 deg) = 55 m long. Ground 20 m west of the wall is
/// dark (< 5 % of the lit value), ground 100 m west is lit (> 50 %).
#[test]
fn wall_casts_its_analytic_shadow() {
    let mut hf = HeightField::flat(64, 256, 1.0);
    let wall_col = 188; // x = -128 + 188.5 = 60.5 m
    for row in 0..hf.rows {
        for col in [wall_col, wall_col + 1] {
            hf.z_m[row * hf.cols + col] = 20.0;
        }
    }
    let (wall_x, _) = hf.xy_from_row_col(0.0, wall_col as f64);
    let sun_el_deg = 20.0;
    let lights = Lights {
        sun: dir_az_el_deg(90.0, sun_el_deg),
        sun_radius_rad: 0.267_f64.to_radians(),
        earth: dir_az_el_deg(0.0, -30.0),
        earth_radius_rad: 0.95_f64.to_radians(),
    };
    let scene = Scene::new(&hf, lights, Engine::Combined).unwrap();
    let lit = lambert_w_m2_sr(sun_el_deg);
    let shadow_len_m = 20.0 / sun_el_deg.to_radians().tan();
    let look = |x_m: f64| {
        // A ray from 50 m up, slightly slanted, onto ground point (x, 0).
        let target = Vector3::new(x_m, 0.0, 0.0);
        let origin = Vector3::new(x_m - 5.0, -5.0, 50.0);
        terrain_radiance(scene.sample(&origin, &(target - origin).normalize()))
    };
    let inside = look(wall_x - 20.0);
    let outside = look(wall_x - 100.0);
    let just_inside = look(wall_x - shadow_len_m + 3.0);
    let just_outside = look(wall_x - shadow_len_m - 3.0);
    eprintln!(
        "lit {lit:.3}: inside {inside:.3}, outside {outside:.3}, edge -3 m {just_inside:.3}, \
         edge +3 m {just_outside:.3}"
    );
    assert!(inside < 0.05 * lit, "inside {inside} vs lit {lit}");
    assert!(outside > 0.5 * lit, "outside {outside} vs lit {lit}");
    assert!(
        just_inside < 0.05 * lit,
        "3 m inside the edge: {just_inside}"
    );
    assert!(
        just_outside > 0.5 * lit,
        "3 m outside the edge: {just_outside}"
    );
}

fn render_args<'a>(out: &'a str, k: &'a str) -> Vec<&'a str> {
    vec![
        "render",
        "--synthetic",
        "--lat-deg",
        "-89.6",
        "--lon-deg",
        "0",
        "--height-m",
        "10",
        "--look-az-deg",
        "90",
        "--look-el-deg",
        "-2",
        "--fov-deg",
        "60",
        "--utc",
        "2027-02-05T00:00",
        "--width",
        "64",
        "--height",
        "48",
        "--out",
        out,
        "--kernels",
        k,
    ]
}

/// The command: 2027-02-05 is dark at this site (Sun -0.236 deg, Earth -2.5 deg per
/// `penumbra ephem`), so the frame is black but valid; its tEXt Sun elevation agrees with the
/// ephemeris. 2027-01-20 (Sun +0.93 deg at az 32, Earth +5.8 deg at az 356) looking north-east
/// gives a lit frame that is not blank.
#[test]
fn cli_renders_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let out = penumbra(dir.path(), &render_args("f.png", k.to_str().unwrap()));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(dir.path().join("f.png")).unwrap();
    let img = image::load_from_memory(&bytes).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (64, 48));
    assert_eq!(
        png_text(&bytes, "penumbra:epoch_utc").as_deref(),
        Some("2027-02-05T00:00:00Z")
    );
    let sun_el_deg: f64 = png_text(&bytes, "penumbra:sun_elevation_deg")
        .expect("tEXt Sun elevation")
        .parse()
        .unwrap();
    // Oracle: `penumbra ephem --lat-deg -89.6 --lon-deg 0 --utc 2027-02-05T00:00` (site frame).
    let eph = penumbra(
        dir.path(),
        &[
            "ephem",
            "--lat-deg",
            "-89.6",
            "--lon-deg",
            "0",
            "--utc",
            "2027-02-05T00:00",
            "--kernels",
            k.to_str().unwrap(),
        ],
    );
    let csv = String::from_utf8_lossy(&eph.stdout);
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    let eph_el_deg: f64 = row[2].parse().unwrap();
    assert!(
        (sun_el_deg - eph_el_deg).abs() < 0.01,
        "tEXt {sun_el_deg} vs ephem {eph_el_deg}"
    );

    let mut args = render_args("lit.png", k.to_str().unwrap());
    let i = args.iter().position(|a| *a == "--utc").unwrap();
    args[i + 1] = "2027-01-20T00:00";
    let i = args.iter().position(|a| *a == "--look-az-deg").unwrap();
    args[i + 1] = "20";
    let out = penumbra(dir.path(), &args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(dir.path().join("lit.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (64, 48));
    let grey_lit = img
        .pixels()
        .filter(|p| p[0] == p[1] && p[1] == p[2] && p[0] > 20)
        .count();
    eprintln!(
        "lit frame: {grey_lit} of {} pixels are lit terrain",
        64 * 48
    );
    assert!(
        grey_lit > 64,
        "the lit frame is (nearly) blank: {grey_lit} lit pixels"
    );
}

#[test]
fn cli_bad_inputs_exit_2_without_file() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let ks = k.to_str().unwrap().to_string();
    let cases: [(&str, &str, &str); 5] = [
        ("--fov-deg", "0", "fov"),
        ("--fov-deg", "180", "fov"),
        ("--width", "0", "image size"),
        ("--height", "0", "image size"),
        ("--height-m", "-5", "observer height -5 m must be"),
    ];
    for (flag, value, needle) in cases {
        let mut args = render_args("bad.png", &ks);
        let i = args.iter().position(|a| *a == flag).unwrap();
        args[i + 1] = value;
        let out = penumbra(dir.path(), &args);
        assert_clean_error(&out, needle);
        assert!(
            files_in(dir.path()).is_empty(),
            "{flag} {value}: files left"
        );
    }
}

//! The renderer and `penumbra render`: analytic Lambert radiance on a plane, a wall's shadow,
//! a whole image of a wall scene computed in closed form (sky, lit ground, penumbra, full
//! shadow), earthshine against an integrated Lambert sphere, the orbital camera, epoch ranges
//! with numbered frames, the float radiance TIFF, one exposure per sequence, scenario views, the
//! CLI and bad input. The BRDFs are in `brdf`, camera paths in `path`, the GPU render
//! path in `gpu::render`.

mod brdf;
mod path;

use std::f64::consts::PI;

use nalgebra::{Matrix3, Vector3};
use penumbra::render::brdf::Brdf;
use penumbra::render::{Camera, DEFAULT_ALBEDO, Lights, Sample, Scene};
use penumbra::shadow::Engine;
use penumbra::terrain::HeightField;

use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, png_text, render_scenario};

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

/// What a ray meets in the closed-form scene of [`analytic_wall_scene_image`].
#[derive(Debug, Clone, Copy, PartialEq)]
enum WallHit {
    /// Nothing: the ray leaves over the grid's edge or above the horizon.
    Sky,
    /// Level ground (z = 0) at model x, m.
    Ground { x_m: f64 },
    /// The wall: its ramps or its top.
    Wall,
}

/// The scene of [`analytic_wall_scene_image`] in closed form. Every row of the grid holds the
/// same heights, so each bilinear patch between four cell centres is a plane and the terrain is
/// exactly the extrusion along y of the polyline `profile` (x, z): ground from the grid's west
/// outer edge to the cell centre west of the wall, a one-cell ramp up to the first wall node, the
/// flat top, a ramp down, ground to the east outer edge; y spans the outer edges `y_min_m ..
/// y_max_m`.
struct WallScene {
    profile: [(f64, f64); 6],
    y_min_m: f64,
    y_max_m: f64,
}

impl WallScene {
    /// The first surface met by `origin + t * dir` (t > 0): each of the five planar pieces is
    /// intersected as a plane and the crossing kept if it lies on the piece.
    fn first_hit(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> WallHit {
        let mut best: Option<(f64, WallHit)> = None;
        for (k, w) in self.profile.windows(2).enumerate() {
            let ((x0, z0), (x1, z1)) = (w[0], w[1]);
            // The piece's plane: normal (-(z1 - z0), 0, x1 - x0) through (x0, ., z0).
            let (nx, nz) = (-(z1 - z0), x1 - x0);
            let den = nx * dir.x + nz * dir.z;
            if den.abs() < 1e-15 {
                continue;
            }
            let t = (nx * (x0 - origin.x) + nz * (z0 - origin.z)) / den;
            let (x, y) = (origin.x + t * dir.x, origin.y + t * dir.y);
            if t <= 0.0 || x < x0 || x > x1 || y < self.y_min_m || y > self.y_max_m {
                continue;
            }
            if best.is_none_or(|(tb, _)| t < tb) {
                let hit = if k == 0 || k == 4 {
                    WallHit::Ground { x_m: x }
                } else {
                    WallHit::Wall
                };
                best = Some((t, hit));
            }
        }
        best.map_or(WallHit::Sky, |(_, h)| h)
    }
}

/// Visible fraction of a uniform disc of angular radius `r` whose centre is `delta` above a
/// straight horizontal horizon: the area above the chord at signed distance `-delta` from the
/// centre, over the disc's, `(pi - acos t + t sqrt(1 - t^2)) / pi` with `t = delta / r` in
/// [-1, 1].
fn disc_fraction_above(delta_rad: f64, r_rad: f64) -> f64 {
    let t = (delta_rad / r_rad).clamp(-1.0, 1.0);
    (PI - t.acos() + t * (1.0 - t * t).sqrt()) / PI
}

/// A whole rendered image (48 x 32 px, one ray per pixel centre) against a scene known in closed
/// form. Flat 256 x 200 grid of 1 m cells with a wall 10 m high and three cell centres thick
/// (x = 92.5..94.5 m, every row), the Sun due east (+x) at 4 deg elevation, angular radius 0.267
/// deg, Lambert albedo 0.12, the Earth below the horizon. The camera at (-110, -95, 40) m looks at
/// azimuth 40 deg, 26 deg down, 80 deg field of view; the frame holds lit ground, the penumbra
/// band, the full shadow, the wall and sky beyond the grid's edges.
///
/// The test computes each pixel independently of penumbra's code: the camera ray from the
/// documented pinhole model (`u = (2 (col + 1/2) / w - 1) tan(fov/2)`, `v` alike scaled by
/// `h / w`), its first intersection with the planar pieces of the terrain (see [`WallScene`]) or
/// none (sky), and for ground at distance `d` west of the wall's top edge the elevation
/// `a = atan(H / d)` of that edge, the visible fraction of the Sun's disc above it
/// ([`disc_fraction_above`], the straight edge's curvature on the sky is ~1e-4 of the disc) and
/// the radiance `albedo S sin(e) / pi * fraction` (`L_lit` times the fraction).
///
/// Requirements: every pixel the closed form calls sky is `Sample::Sky` (377 px), every pixel it
/// calls terrain is terrain with a finite radiance >= 0 (none may turn to sky or NaN); on ground
/// pixels more than one cell from the wall's footprint (1125 px: 696 lit, 156 in the penumbra,
/// 273 in full shadow; the 34 px of the wall and of the ground within one cell of it, shaded with
/// a central-difference normal that spans the ramp, are excluded and counted)
/// |L - L_analytic| / L_lit <= 5e-3 at most, <= 2e-4 on average and <= 1e-3 on average over the
/// penumbra pixels. Measured: max 3.56e-3 (in the penumbra), mean 7.2e-5, p95 5.5e-4, penumbra
/// mean 4.8e-4. The engine's fractions at the cell centres are exact (2.8e-8, f32); all of the
/// error is their bilinear interpolation across 1 m cells, which for this profile is at most
/// 3.65e-3 (at the band's dark end, where the fraction grows as s^1.5). The bound is a
/// requirement: the shadow edge one cell (1 m) longer gives 6.7e-2 (mid-band slope 0.067 per m)
/// and a hard shadow without penumbra 0.5, both checked here to exceed twice the bound. Pixels
/// whose ray passes within 1 cm of a silhouette or the grid's edge (sky or terrain changes when
/// the camera moves by 1 cm; none in this frame) are left out and counted.
#[test]
fn analytic_wall_scene_image() {
    const ROWS: usize = 200;
    const COLS: usize = 256;
    const WALL_COL: usize = 220;
    const WALL_COLS: usize = 3;
    const WIDTH: u32 = 48;
    const HEIGHT: u32 = 32;
    const MAX_BOUND: f64 = 5e-3;
    const MEAN_BOUND: f64 = 2e-4;
    const BAND_MEAN_BOUND: f64 = 1e-3;
    let wall_h_m = 10.0;
    let sun_el = 4.0_f64.to_radians();
    let sun_r = 0.267_f64.to_radians();
    let mut hf = HeightField::flat(ROWS, COLS, 1.0);
    for row in 0..ROWS {
        for col in WALL_COL..WALL_COL + WALL_COLS {
            hf.z_m[row * COLS + col] = wall_h_m as f32;
        }
    }
    // The closed form, from the documented grid convention (cell centres half a cell inside the
    // outer edges, the grid centred on the origin, north up) only.
    let node_x = |col: usize| -(COLS as f64) / 2.0 + col as f64 + 0.5;
    let edge_x = COLS as f64 / 2.0;
    let edge_y = ROWS as f64 / 2.0;
    let top_west_x = node_x(WALL_COL);
    let analytic = WallScene {
        profile: [
            (-edge_x, 0.0),
            (node_x(WALL_COL - 1), 0.0),
            (top_west_x, wall_h_m),
            (node_x(WALL_COL + WALL_COLS - 1), wall_h_m),
            (node_x(WALL_COL + WALL_COLS), 0.0),
            (edge_x, 0.0),
        ],
        y_min_m: -edge_y,
        y_max_m: edge_y,
    };
    // Ground within one cell of the ramps' feet is shaded with a tilted normal: not compared.
    let near_wall = |x: f64| x > node_x(WALL_COL - 2) && x < node_x(WALL_COL + WALL_COLS + 1);
    let l_lit = lambert_w_m2_sr(4.0);
    // The fraction of the Sun seen from ground at x, with the wall's top edge moved west by
    // `shift_m` (a perturbed model, to show the bound would catch it) or a hard shadow.
    let fraction = |x: f64, shift_m: f64, hard: bool| {
        let d = top_west_x - shift_m - x;
        if d <= 0.0 {
            return 1.0; // east of the wall: nothing between the ground and the Sun
        }
        let delta = sun_el - wall_h_m.atan2(d);
        if hard {
            f64::from(u8::from(delta > 0.0))
        } else {
            disc_fraction_above(delta, sun_r)
        }
    };

    let sun = [sun_el.cos(), 0.0, sun_el.sin()];
    let earth = dir_az_el_deg(200.0, -30.0);
    let earth_r = 0.95_f64.to_radians();
    let lights = Lights {
        sun,
        sun_radius_rad: sun_r,
        earth,
        earth_radius_rad: earth_r,
    };
    let scene = Scene::new(&hf, lights, Engine::Combined).unwrap();
    // Diagnostic: the engine's fractions at the cell centres (every row alike) against the
    // closed form, away from the wall; the image adds their bilinear interpolation.
    let node_err = (0..WALL_COL - 1)
        .flat_map(|col| (0..ROWS).map(move |row| (row, col)))
        .map(|(row, col)| {
            let got = f64::from(scene.fractions().0[row * COLS + col]);
            (got - fraction(node_x(col), 0.0, false)).abs()
        })
        .fold(0.0_f64, f64::max);
    let origin = Vector3::new(-110.0, -95.0, 40.0);
    let (az, el, fov) = (40.0_f64, -26.0_f64, 80.0_f64);
    let cam = Camera::from_az_el_deg(origin, &Matrix3::identity(), az, el, fov).unwrap();
    let img = scene.render(&cam, WIDTH, HEIGHT).unwrap();

    // The pinhole camera, written out: forward from azimuth/elevation (ENU), right = forward x
    // up, the image's up = right x forward.
    let (az, el) = (az.to_radians(), el.to_radians());
    let fwd = Vector3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin());
    let right = fwd.cross(&Vector3::z()).normalize();
    let up = right.cross(&fwd).normalize();
    let tan_half = (fov.to_radians() / 2.0).tan();
    let (w, h) = (f64::from(WIDTH), f64::from(HEIGHT));

    let class = |hit: WallHit| match hit {
        WallHit::Sky => 0,
        WallHit::Ground { .. } => 1,
        WallHit::Wall => 2,
    };
    let angle = |d: &Vector3<f64>, v: [f64; 3]| d.dot(&Vector3::from(v)).clamp(-1.0, 1.0).acos();
    let (mut sky, mut ambiguous, mut excluded) = (0, 0, 0);
    let (mut lit, mut dark, mut band) = (0, 0, 0);
    let mut failures = Vec::new();
    // Per compared pixel: |dL| / L_lit against the model, the shifted model and the hard shadow.
    let (mut errs, mut band_errs) = (Vec::new(), Vec::new());
    let (mut shifted_max, mut hard_max) = (0.0_f64, 0.0_f64);
    for i in 0..HEIGHT {
        for j in 0..WIDTH {
            let u = (2.0 * (f64::from(j) + 0.5) / w - 1.0) * tan_half;
            let v = (1.0 - 2.0 * (f64::from(i) + 0.5) / h) * tan_half * h / w;
            let dir = (fwd + u * right + v * up).normalize();
            let hit = analytic.first_hit(&origin, &dir);
            let moved = [
                Vector3::new(0.01, 0.0, 0.0),
                Vector3::new(-0.01, 0.0, 0.0),
                Vector3::new(0.0, 0.01, 0.0),
                Vector3::new(0.0, -0.01, 0.0),
                Vector3::new(0.0, 0.0, 0.01),
                Vector3::new(0.0, 0.0, -0.01),
            ];
            if moved
                .iter()
                .any(|m| class(analytic.first_hit(&(origin + m), &dir)) != class(hit))
            {
                ambiguous += 1;
                continue;
            }
            let got = img[(i * WIDTH + j) as usize];
            let px = format!("pixel (row {i}, col {j}), analytic {hit:?}");
            let terrain = match got {
                Sample::Terrain { radiance_w_m2_sr } => Some(f64::from(radiance_w_m2_sr)),
                _ => None,
            };
            match hit {
                WallHit::Sky => {
                    sky += 1;
                    // The scene keeps the discs of the Sun and the Earth out of the frame.
                    assert!(angle(&dir, sun) > 2.0 * sun_r && angle(&dir, earth) > 2.0 * earth_r);
                    if got != Sample::Sky {
                        failures.push(format!("{px}: got {got:?}, want sky"));
                    }
                }
                _ if !terrain.is_some_and(|l| l.is_finite() && l >= 0.0) => {
                    failures.push(format!("{px}: got {got:?}, want terrain"));
                }
                WallHit::Wall => excluded += 1,
                WallHit::Ground { x_m } if near_wall(x_m) => excluded += 1,
                WallHit::Ground { x_m } => {
                    let l = terrain.unwrap_or(f64::NAN);
                    let f = fraction(x_m, 0.0, false);
                    let err = (l - l_lit * f).abs() / l_lit;
                    errs.push(err);
                    shifted_max =
                        shifted_max.max((l - l_lit * fraction(x_m, 1.0, false)).abs() / l_lit);
                    hard_max = hard_max.max((l - l_lit * fraction(x_m, 0.0, true)).abs() / l_lit);
                    if f >= 1.0 {
                        lit += 1;
                    } else if f <= 0.0 {
                        dark += 1;
                    } else {
                        band += 1;
                        band_errs.push(err);
                    }
                }
            }
        }
    }
    let stats = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        (q(1.0), v.iter().sum::<f64>() / v.len() as f64, q(0.95))
    };
    let (max, mean, p95) = stats(&mut errs);
    let (band_max, band_mean, _) = stats(&mut band_errs);
    eprintln!(
        "analytic wall scene, {WIDTH} x {HEIGHT} px: {} compared ({lit} lit, {band} penumbra, \
         {dark} full shadow), {excluded} excluded (wall, ground within one cell of it), {sky} \
         sky, {ambiguous} within 1 cm of a silhouette or edge",
        errs.len()
    );
    eprintln!(
        "|dL| / L_lit (L_lit {l_lit:.4} W m^-2 sr^-1): max {max:.2e}, mean {mean:.2e}, p95 \
         {p95:.2e}; penumbra max {band_max:.2e}, mean {band_mean:.2e}; against a shadow 1 m \
         longer max {shifted_max:.2e}, against a hard shadow max {hard_max:.2e}; engine's \
         fractions at the cell centres west of the wall: max |error| {node_err:.2e}"
    );
    assert!(
        failures.is_empty(),
        "{} pixels of the wrong kind:\n{}",
        failures.len(),
        failures[..failures.len().min(10)].join("\n")
    );
    // The frame holds every kind of pixel.
    assert!(lit >= 100 && band >= 50 && dark >= 100 && sky >= 100 && excluded >= 10);
    assert!(ambiguous <= 10, "{ambiguous} ambiguous pixels");
    assert!(
        max <= MAX_BOUND && mean <= MEAN_BOUND && band_mean <= BAND_MEAN_BOUND,
        "max {max:.3e} mean {mean:.3e} penumbra mean {band_mean:.3e}"
    );
    // The bound is tight enough to see the shadow's edge moved by one cell or no penumbra.
    assert!(shifted_max > 2.0 * MAX_BOUND && hard_max > 2.0 * MAX_BOUND);
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

/// The issue's command: 2027-02-05 is dark at this site (Sun -0.236 deg, Earth -2.5 deg per
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

/// Arguments of an orbital view of the synthetic terrain (camera 30 km above the sphere over
/// -89.5 deg, looking at -89.6 deg, 0 E) at a lit epoch (Sun +0.93 deg at -89.6, 0).
fn orbit_args<'a>(out: &'a str, k: &'a str) -> Vec<&'a str> {
    vec![
        "render",
        "--synthetic",
        "--camera",
        "orbit",
        "--lat-deg",
        "-89.3",
        "--lon-deg",
        "0",
        "--altitude-km",
        "30",
        "--target-lat-deg",
        "-89.6",
        "--target-lon-deg",
        "0",
        "--fov-deg",
        "40",
        "--utc",
        "2027-01-20T00:00",
        "--width",
        "48",
        "--height",
        "32",
        "--out",
        out,
        "--kernels",
        k,
    ]
}

/// The orbital camera sees lit terrain around its target: the centre pixel is terrain (not sky)
/// and many pixels are lit.
#[test]
fn cli_orbit_camera_sees_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let out = penumbra(dir.path(), &orbit_args("o.png", k.to_str().unwrap()));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(dir.path().join("o.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (48, 32));
    let grey = |p: &image::Rgb<u8>| p[0] == p[1] && p[1] == p[2];
    let lit = img.pixels().filter(|p| grey(p) && p[0] > 20).count();
    eprintln!("orbit view: {lit} of {} pixels are lit terrain", 48 * 32);
    assert!(lit > 48 * 32 / 4, "only {lit} lit pixels");
}

/// Bad orbit input: a camera below the terrain, a missing altitude, fov 0 -> exit 2, one line,
/// no file.
#[test]
fn cli_orbit_bad_inputs_exit_2_without_file() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let ks = k.to_str().unwrap().to_string();
    for (flag, value, needle) in [
        ("--altitude-km", "-8", "inside the terrain"),
        ("--fov-deg", "0", "fov"),
        ("--fov-deg", "180", "fov"),
        ("--width", "0", "image size"),
    ] {
        let mut args = orbit_args("bad.png", &ks);
        let i = args.iter().position(|a| *a == flag).unwrap();
        args[i + 1] = value;
        let out = penumbra(dir.path(), &args);
        assert_clean_error(&out, needle);
        assert!(
            files_in(dir.path()).is_empty(),
            "{flag} {value}: files left"
        );
    }
    let mut args = orbit_args("bad.png", &ks);
    let i = args.iter().position(|a| *a == "--altitude-km").unwrap();
    args.drain(i..i + 2);
    assert_clean_error(&penumbra(dir.path(), &args), "--altitude-km");
    assert!(files_in(dir.path()).is_empty());
}

/// `--start/--stop/--step` writes numbered frames with their own epochs, and `--out-radiance`
/// writes numbered 32-bit float TIFFs whose values decode back to a radiance image consistent
/// with the PNG: sky pixels (black) have radiance 0 and lit pixels radiance > 0.
#[test]
fn cli_epoch_range_writes_numbered_frames_and_radiance() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let mut args = orbit_args("seq.png", k.to_str().unwrap());
    let i = args.iter().position(|a| *a == "--utc").unwrap();
    args.splice(
        i..i + 2,
        [
            "--start",
            "2027-01-20T00:00",
            "--stop",
            "2027-01-20T12:00",
            "--step",
            "6h",
            "--out-radiance",
            "rad.tif",
        ],
    );
    let out = penumbra(dir.path(), &args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut names = files_in(dir.path());
    names.sort();
    assert_eq!(
        names,
        [
            "rad_0000.tif",
            "rad_0001.tif",
            "rad_0002.tif",
            "seq.run.json",
            "seq_0000.png",
            "seq_0001.png",
            "seq_0002.png"
        ]
    );
    // The provenance lists exactly the files written, and the epochs.
    let prov: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("seq.run.json")).unwrap()).unwrap();
    let mut listed: Vec<String> = prov["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    listed.sort();
    let mut written = names.clone();
    written.retain(|n| n != "seq.run.json");
    assert_eq!(listed, written);
    assert_eq!(prov["epoch_count"], 3);
    assert_eq!(prov["epoch_start_utc"], "2027-01-20T00:00:00Z");
    for (k, want_utc) in [
        "2027-01-20T00:00:00Z",
        "2027-01-20T06:00:00Z",
        "2027-01-20T12:00:00Z",
    ]
    .iter()
    .enumerate()
    {
        let bytes = std::fs::read(dir.path().join(format!("seq_{k:04}.png"))).unwrap();
        let utc = crate::util::png_text(&bytes, "penumbra:epoch_utc");
        assert_eq!(utc.as_deref(), Some(*want_utc));
        let rgb = image::load_from_memory(&bytes).unwrap().to_rgb8();
        let mut dec = tiff::decoder::Decoder::new(
            std::fs::File::open(dir.path().join(format!("rad_{k:04}.tif"))).unwrap(),
        )
        .unwrap();
        assert_eq!(dec.dimensions().unwrap(), (48, 32));
        let tiff::decoder::DecodingResult::F32(rad) = dec.read_image().unwrap() else {
            panic!("not f32")
        };
        let max_l = rad.iter().copied().fold(0.0_f32, f32::max);
        let mut lit = 0;
        for (p, l) in rgb.pixels().zip(&rad) {
            if p[0] == p[1] && p[1] == p[2] && p[0] > 20 {
                assert!(*l > 0.0);
                lit += 1;
            }
            if p.0 == [0, 0, 0] {
                assert!(
                    l.is_nan() || *l < 0.01 * max_l,
                    "black pixel with radiance {l} (max {max_l})"
                );
            }
        }
        assert!(lit > 100, "frame {k}: {lit} lit pixels");
        // Sky is nodata (NaN), declared; the unit and the frame's epoch are in the metadata.
        let md = dec
            .get_tag_ascii_string(tiff::tags::Tag::Unknown(42112))
            .unwrap();
        assert!(md.contains("W m-2 sr-1") && md.contains(want_utc), "{md}");
        assert_eq!(
            dec.get_tag_ascii_string(tiff::tags::Tag::Unknown(42113))
                .unwrap(),
            "nan"
        );
    }
}

/// The float radiance TIFF holds exactly the in-memory radiance of a rendered frame (the hills
/// scene: values vary, some pixels are shadowed or sky).
#[test]
fn radiance_tiff_round_trips_the_frame() {
    let (w, h) = (32, 24);
    let rad = hills_scene_radiance();
    let bytes = penumbra::render::encode_f32_tiff(&rad, w, h, &[("k", "v")]).unwrap();
    let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(bytes)).unwrap();
    assert_eq!(dec.dimensions().unwrap(), (w, h));
    let tiff::decoder::DecodingResult::F32(back) = dec.read_image().unwrap() else {
        panic!("not f32")
    };
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back), bits(&rad));
    let lit = rad.iter().filter(|l| **l > 0.0).count();
    let sky = rad.iter().filter(|l| l.is_nan()).count();
    eprintln!(
        "radiance TIFF: {lit} of {} pixels > 0, {sky} sky (NaN)",
        rad.len()
    );
    assert!(lit > 0 && lit < rad.len() && sky > 10);
}

/// A synthetic scene for the radiance TIFF: a 64 x 64 grid of 10 m cells with sine hills of
/// +-20 m, Sun at 8 deg elevation from azimuth ~37 deg, Earth at 8 deg from the south, Hapke
/// BRDF; a 32 x 24 view from (-300, -300, 150) m looking north-east 15 deg down.
fn hills_scene_radiance() -> Vec<f32> {
    use nalgebra::{Matrix3, Vector3};
    use penumbra::render::{Camera, Lights, Scene, radiance_image};
    let mut hf = penumbra::terrain::HeightField::flat(64, 64, 10.0);
    for row in 0..64 {
        for col in 0..64 {
            hf.z_m[row * 64 + col] =
                (20.0 * (row as f64 / 7.0).sin() * (col as f64 / 5.0).cos()) as f32;
        }
    }
    let el = 8.0_f64.to_radians();
    let lights = Lights {
        sun: [el.cos() * 0.6, el.cos() * 0.8, el.sin()],
        sun_radius_rad: 0.267_f64.to_radians(),
        earth: [0.0, -el.cos(), el.sin()],
        earth_radius_rad: 0.95_f64.to_radians(),
    };
    let scene = Scene::new(&hf, lights, penumbra::shadow::Engine::Combined)
        .unwrap()
        .with_brdf(Brdf::default());
    let cam = Camera::from_az_el_deg(
        Vector3::new(-300.0, -300.0, 150.0),
        &Matrix3::identity(),
        45.0,
        -15.0,
        60.0,
    )
    .unwrap();
    radiance_image(&scene.render(&cam, 32, 24).unwrap())
}

/// Earthshine: `Lights::earth_irradiance_w_m2` against a direct integration of the light of a
/// Lambert sphere (albedo = Bond albedo 0.306, lit by the solar constant) over the Earth's
/// surface, seen from the Moon at 384,400 km, for elongations 180 (full Earth), 120, 90 and
/// 30 deg. The formula `p S (R/d)^2 Phi(alpha)` is the far-field limit; at d = 60 R the nearer
/// half of the lit disc is up to 2 R/d closer, which the direct sum sees (measured +1.2 % at
/// full Earth; for a thin crescent, where part of the lit limb is hidden at finite distance,
/// +11 % of a tiny value, 1.1e-4 W/m^2 at 30 deg), so the bound is 3 % of the value or 0.2 % of
/// the full-Earth irradiance, whichever is larger (integration grid 600 x 1200).
#[test]
fn earthshine_matches_an_integrated_lambert_sphere() {
    use penumbra::render::{EARTH_BOND_ALBEDO, Lights};
    let (r_km, d_km) = (6378.1366_f64, 384_400.0_f64);
    let s = penumbra::SOLAR_CONSTANT_W_M2;
    let earth = [1.0, 0.0, 0.0];
    for elong_deg in [180.0_f64, 120.0, 90.0, 30.0] {
        let el = elong_deg.to_radians();
        let sun = [el.cos(), el.sin(), 0.0];
        let lights = Lights {
            sun,
            sun_radius_rad: 0.00465,
            earth,
            earth_radius_rad: (r_km / d_km).asin(),
        };
        let got = lights.earth_irradiance_w_m2();
        // Oracle: sum over surface elements of the Earth (centre at d * earth).
        let (nt, np) = (600, 1200);
        let mut e = 0.0;
        for it in 0..nt {
            let th = (it as f64 + 0.5) / nt as f64 * PI;
            for ip in 0..np {
                let ph = (ip as f64 + 0.5) / np as f64 * 2.0 * PI;
                let n = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
                let cos_sun = n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2];
                if cos_sun <= 0.0 {
                    continue;
                }
                let p = [d_km + r_km * n[0], r_km * n[1], r_km * n[2]];
                let dist = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                let to_moon = [-p[0] / dist, -p[1] / dist, -p[2] / dist];
                let cos_obs = n[0] * to_moon[0] + n[1] * to_moon[1] + n[2] * to_moon[2];
                if cos_obs <= 0.0 {
                    continue;
                }
                let radiance = EARTH_BOND_ALBEDO * s * cos_sun / PI;
                let d_area = r_km * r_km * th.sin() * (PI / nt as f64) * (2.0 * PI / np as f64);
                // Irradiance on a surface facing the Earth: cos of arrival ~ -to_moon . earth.
                e += radiance * cos_obs * d_area / (dist * dist) * (-to_moon[0]);
            }
        }
        eprintln!("elongation {elong_deg} deg: earthshine {got:.5} W/m^2, integrated {e:.5}");
        let bound = (0.03 * e).max(0.002 * penumbra::render::FULL_EARTH_IRRADIANCE_W_M2);
        assert!((got - e).abs() <= bound, "{got} vs {e}");
    }
}

/// `[[render.views]]` in a scenario renders through `penumbra render`: a site view (one frame)
/// and an orbital sequence (numbered frames) land in `<output_dir>/render/` with the epochs in
/// their metadata; an unknown view key is an error naming the key, with no render output.
#[test]
fn scenario_render_views() {
    let dir = tempfile::tempdir().unwrap();
    let views = r#"
[[render.views]]
out = "site.png"
lat_deg = -89.6
lon_deg = 0.0
height_m = 10.0
look_az_deg = 20.0
look_el_deg = -2.0
utc = "2027-01-20T00:00:00"
width = 24
height = 16

[[render.views]]
out = "seq.png"
camera = "orbit"
lat_deg = -89.6
lon_deg = 0.0
altitude_km = 20.0
fov_deg = 30.0
start = "2027-01-20T00:00:00"
stop = "2027-01-20T06:00:00"
step = "6h"
width = 16
height = 12
"#;
    let rdir =
        crate::util::run_scenario_ok(dir.path(), &render_scenario("r", "2027-01-20T02:00", views))
            .join("render");
    assert_eq!(
        files_in(&rdir),
        ["seq_0000.png", "seq_0001.png", "site.png"]
    );
    let img = image::open(rdir.join("site.png")).unwrap();
    assert_eq!((img.width(), img.height()), (24, 16));
    let bytes = std::fs::read(rdir.join("seq_0001.png")).unwrap();
    let utc = crate::util::png_text(&bytes, "penumbra:epoch_utc");
    assert_eq!(utc.as_deref(), Some("2027-01-20T06:00:00Z"));

    let dir = tempfile::tempdir().unwrap();
    let bad = "[[render.views]]\nout = \"x.png\"\nlat_deg = -89.6\nlon_deg = 0.0\nfrobnicate = 1\nutc = \"2027-01-20\"\n";
    std::fs::write(
        dir.path().join("s.toml"),
        render_scenario("r", "2027-01-20T02:00", bad),
    )
    .unwrap();
    let out = penumbra(dir.path(), &["run", "s.toml"]);
    assert_clean_error(&out, "frobnicate");
    assert!(!dir.path().join("res/render").exists());
}

/// Reads a rendered sequence's frame `k`: the PNG's grey levels, its exposure metadata and the
/// radiance TIFF.
fn frame_levels_and_radiance(
    dir: &std::path::Path,
    k: usize,
) -> (Vec<u8>, String, String, Vec<f32>) {
    let bytes = std::fs::read(dir.join(format!("seq_{k:04}.png"))).unwrap();
    let exposure = crate::util::png_text(&bytes, "penumbra:exposure").unwrap();
    let mode = crate::util::png_text(&bytes, "penumbra:exposure_mode").unwrap();
    let grey: Vec<u8> = image::load_from_memory(&bytes)
        .unwrap()
        .to_rgb8()
        .pixels()
        .map(|p| p[0])
        .collect();
    let mut dec = tiff::decoder::Decoder::new(
        std::fs::File::open(dir.join(format!("rad_{k:04}.tif"))).unwrap(),
    )
    .unwrap();
    let tiff::decoder::DecodingResult::F32(rad) = dec.read_image().unwrap() else {
        panic!("not f32")
    };
    (grey, exposure, mode, rad)
}

/// Frames of a sequence share one exposure by default (`--exposure sequence`): every frame's
/// terrain pixel has grey level `srgb(tone_curve(e · L))` of its own radiance with the same `e`
/// (no flicker), recomputed here from the radiance TIFF with the documented formula, and `e`
/// puts the brightest frame's 99th-percentile radiance near `x = 1.4` (within the 10 % a
/// quarter-size pre-render allows). `--exposure auto` gives each frame exactly `1.4 / p99` of its
/// own radiance. Earthshine-only radiance stays black by default (the exposure is never brighter
/// than for level ground under a 1° Sun) and looks lit at `auto`. The tone curve keeps lit
/// terrain's shading: on the demo's ridge view (the issue's scene: lit terrain at levels 178–205)
/// the 5th–95th percentile spread of lit terrain levels is ≥ 1.4× the old Reinhard curve's at the
/// old automatic exposure (99th percentile → x = 2).
#[test]
fn sequences_have_one_exposure_and_shading_survives_the_tone_curve() {
    use penumbra::render::{
        AUTO_EXPOSED_P99, DAYLIGHT_FLOOR_RADIANCE_W_M2_SR, Exposure, Sample, srgb_level,
        tone_curve, tone_map,
    };
    let k = kernels_dir();
    let p99 = |rad: &[f32]| {
        let mut lit: Vec<f64> = rad
            .iter()
            .filter(|l| l.is_finite() && **l > 0.0)
            .map(|l| f64::from(*l))
            .collect();
        lit.sort_by(f64::total_cmp);
        lit[((lit.len() - 1) as f64 * 0.99).round() as usize]
    };
    let run = |extra: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        let mut args = orbit_args("seq.png", k.to_str().unwrap());
        let i = args.iter().position(|a| *a == "--utc").unwrap();
        args.splice(
            i..i + 2,
            [
                "--start",
                "2027-01-20T00:00",
                "--stop",
                "2027-01-21T00:00",
                "--step",
                "12h",
                "--out-radiance",
                "rad.tif",
            ],
        );
        args.extend_from_slice(extra);
        let out = penumbra(dir.path(), &args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        dir
    };
    let seq = run(&[]);
    let frames: Vec<_> = (0..3)
        .map(|k| frame_levels_and_radiance(seq.path(), k))
        .collect();
    let e: f64 = frames[0].1.parse().unwrap();
    let brightest = frames.iter().map(|f| p99(&f.3)).fold(0.0, f64::max);
    let want = AUTO_EXPOSED_P99 / brightest.max(DAYLIGHT_FLOOR_RADIANCE_W_M2_SR);
    assert!(
        (e / want - 1.0).abs() < 0.1,
        "exposure {e}, full-size frames say {want}"
    );
    for (k, (grey, exposure, mode, rad)) in frames.iter().enumerate() {
        assert_eq!(mode, "sequence");
        assert_eq!(
            *exposure, frames[0].1,
            "frame {k}: one exposure per sequence"
        );
        for (g, l) in grey.iter().zip(rad) {
            if l.is_finite() {
                let want = srgb_level(tone_curve(e * f64::from(*l)));
                assert!(
                    (i32::from(*g) - i32::from(want)).abs() <= 1,
                    "frame {k}: radiance {l} gives level {g}, the curve says {want}"
                );
            }
        }
    }
    // Per-frame automatic exposure: each frame its own value.
    let auto = run(&["--exposure", "auto"]);
    for k in 0..3 {
        let (_, exposure, mode, rad) = frame_levels_and_radiance(auto.path(), k);
        assert_eq!(mode, "auto");
        assert_eq!(exposure, format!("{:.6e}", AUTO_EXPOSED_P99 / p99(&rad)));
    }

    // Shading on the demo's ridge view, one frame.
    let dir = tempfile::tempdir().unwrap();
    let out = penumbra(
        dir.path(),
        &[
            "render",
            "--synthetic",
            "--camera",
            "site",
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
            "--fov-deg",
            "60",
            "--utc",
            "2027-01-20T00:00:00",
            "--width",
            "160",
            "--height-px",
            "100",
            "--out",
            "v.png",
            "--out-radiance",
            "v.tif",
            "--kernels",
            k.to_str().unwrap(),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut dec =
        tiff::decoder::Decoder::new(std::fs::File::open(dir.path().join("v.tif")).unwrap())
            .unwrap();
    let tiff::decoder::DecodingResult::F32(rad) = dec.read_image().unwrap() else {
        panic!("not f32")
    };
    let grey: Vec<u8> = image::open(dir.path().join("v.png"))
        .unwrap()
        .to_rgb8()
        .pixels()
        .map(|p| p[0])
        .collect();
    let top = p99(&rad);
    let (mut new, mut old) = (Vec::new(), Vec::new());
    for (g, l) in grey.iter().zip(&rad) {
        if l.is_finite() && *l > 0.0 {
            new.push(f64::from(*g));
            let x = 2.0 / top * f64::from(*l);
            old.push(f64::from(srgb_level(x / (1.0 + x))));
        }
    }
    let spread = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        (q(0.05), q(0.95))
    };
    let (n5, n95) = spread(&mut new);
    let (o5, o95) = spread(&mut old);
    eprintln!(
        "ridge view, lit terrain levels p5..p95: {n5}..{n95} now, {o5}..{o95} with the old curve"
    );
    assert!(n95 - n5 >= 1.4 * (o95 - o5), "{n5}..{n95} vs {o5}..{o95}");

    // Earthshine only (1.7e-6 W m-2 sr-1): black by default, lit at auto.
    let night = [Sample::Terrain {
        radiance_w_m2_sr: 1.7e-6,
    }];
    assert_eq!(tone_map(&night, Exposure::Sequence.value(&night))[0], 0);
    assert!(tone_map(&night, Exposure::Auto.value(&night))[0] > 200);
    // Flags and scenario values: sequence, auto, a number; anything else refused.
    assert_eq!("Sequence".parse::<Exposure>(), Ok(Exposure::Sequence));
    assert_eq!("0.5".parse::<Exposure>(), Ok(Exposure::Fixed(0.5)));
    for bad in ["0", "-1", "nan", "inf", "bright"] {
        assert!(bad.parse::<Exposure>().is_err(), "{bad}");
    }
}

/// Frames are annotated (issue 47): a 480 × 240 site frame (-89.6°, 0°, 10 m up, looking at
/// azimuth 200°, 2° down, 60° field of view, 2027-01-20T00:00) carries, drawn into the picture,
/// the epoch, the Sun's and the Earth's elevation and azimuth and the camera in a box in the
/// bottom-left corner, and azimuth ticks along the top edge. Oracles: `penumbra ephem` at the
/// site (Sun az 31.878°, el 0.932°; Earth az 356.484°, el 5.795°: the PNG's text chunks within
/// 0.01°), and the pinhole model for the ticks: the tick of azimuth `a` at column
/// `((tan(a - 200°) / tan 30°) + 1) · 240 − 0.5` (±2 px: the centre row is 1° below level and the
/// marks are 2 px wide), 180° … 220° every 10° (170° and 230° fall on the edges). Against the same frame with `--no-annotation`, the
/// pixels that differ all lie in the box or the tick strip.
#[test]
fn frames_carry_their_epoch_sun_earth_and_azimuth_ticks() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let k = k.to_str().unwrap();
    let frame = |out: &str, bare: bool| {
        let mut args = vec![
            "render",
            "--synthetic",
            "--lat-deg",
            "-89.6",
            "--lon-deg",
            "0",
            "--height-m",
            "10",
            "--look-az-deg",
            "200",
            "--look-el-deg",
            "-2",
            "--fov-deg",
            "60",
            "--utc",
            "2027-01-20T00:00",
            "--width",
            "480",
            "--height",
            "240",
            "--backend",
            "cpu",
            "--out",
            out,
            "--kernels",
            k,
        ];
        if bare {
            args.push("--no-annotation");
        }
        let o = penumbra(dir.path(), &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(dir.path().join(out)).unwrap()
    };
    let (annotated, bare) = (frame("a.png", false), frame("b.png", true));
    for (key, want) in [
        ("penumbra:sun_azimuth_deg", 31.878),
        ("penumbra:sun_elevation_deg", 0.932),
        ("penumbra:earth_azimuth_deg", 356.484),
        ("penumbra:earth_elevation_deg", 5.795),
    ] {
        let got: f64 = png_text(&annotated, key).unwrap().parse().unwrap();
        assert!((got - want).abs() < 0.01, "{key}: {got} vs ephem {want}");
    }
    let a = image::load_from_memory(&annotated).unwrap().to_rgb8();
    let b = image::load_from_memory(&bare).unwrap().to_rgb8();
    // The tick marks: white runs on row 1 (the sky above is black).
    let white: Vec<u32> = (0..480)
        .filter(|&c| a.get_pixel(c, 1).0 == [255, 255, 255])
        .collect();
    let mut runs: Vec<(u32, u32)> = Vec::new();
    for c in white {
        match runs.last_mut() {
            Some((_, end)) if *end + 1 == c => *end = c,
            _ => runs.push((c, c)),
        }
    }
    let want: Vec<f64> = [180.0_f64, 190.0, 200.0, 210.0, 220.0]
        .iter()
        .map(|a| {
            ((a - 200.0_f64).to_radians().tan() / 30.0_f64.to_radians().tan() + 1.0) * 240.0 - 0.5
        })
        .collect();
    eprintln!("tick runs {runs:?}; pinhole columns {want:?}");
    assert_eq!(runs.len(), want.len(), "{runs:?}");
    for ((s, e), w) in runs.iter().zip(&want) {
        let mid = f64::from(s + e) / 2.0;
        assert!((mid - w).abs() <= 2.0, "tick at {mid} vs {w}");
    }
    // Where the two frames differ: the box (bottom-left) and the tick strip (top) only.
    let (mut in_box, mut in_strip) = (0usize, 0usize);
    for (x, y, p) in a.enumerate_pixels() {
        if p != b.get_pixel(x, y) {
            if y >= 240 - 70 && x < 480 {
                in_box += 1;
            } else if y < 40 {
                in_strip += 1;
            } else {
                panic!("pixel ({x}, {y}) changed outside the box and the strip");
            }
        }
    }
    eprintln!("annotation: {in_box} px in the box, {in_strip} px in the tick strip");
    assert!(in_box > 1000 && in_strip > 50, "{in_box} {in_strip}");
}

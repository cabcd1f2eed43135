//! Fourier-compressed horizon maps (paper 001): the sampled horizon against an analytic ridge,
//! the truncated DFT against the untruncated samples, hard masks and soft fractions against the
//! brute-force engine, f16/TIFF round trips and the CLI.

use half::f16;
use penumbra::MOON_RADIUS_M;
use penumbra::shadow::accuracy::{compare_fractions, compare_masks};
use penumbra::shadow::fourier::{self, HorizonMap};
use penumbra::shadow::{SUN_ANGULAR_RADIUS_RAD, brute};
use penumbra::terrain::HeightField;

use crate::util::{assert_clean_error, penumbra, shared_lola};

/// Light direction in model space from azimuth (from north, clockwise) and elevation.
fn light_az_el(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    [az.sin() * el.cos(), az.cos() * el.cos(), el.sin()]
}

/// A rough synthetic field (fBm, 400 m relief, 100 m cells) with the curvature drop.
fn synthetic_field(n: usize) -> HeightField {
    let mut hf = HeightField::flat(n, n, 100.0);
    for r in 0..n {
        for c in 0..n {
            let (x, y) = hf.xy_from_row_col(r as f64, c as f64);
            let h = 400.0 * penumbra::terrain::synth::fbm(x / 2500.0, y / 2500.0, 5, 0.5, 7);
            hf.z_m[r * n + c] = (h - (x * x + y * y) / (2.0 * MOON_RADIUS_M)) as f32;
        }
    }
    hf
}

/// A `size²` crop of the 240 m grid around the pole, with the curvature drop; `None` (printed
/// reason) if the file is absent.
fn real_crop(size: usize) -> Option<HeightField> {
    let path = shared_lola("ldem75s_crop_240m_pm184km.tif")?;
    let dem = penumbra::terrain::read_geotiff(&path).expect("read the 240 m grid");
    let (h, w) = (dem.grid.rows, dem.grid.cols);
    let (r0, c0) = (h / 2 - size / 2, w / 2 - size / 2);
    let mut hf = HeightField::flat(size, size, 240.0);
    for r in 0..size {
        for c in 0..size {
            let (x, y) = hf.xy_from_row_col(r as f64, c as f64);
            let z = dem.heights_m[(r0 + r) * w + (c0 + c)] as f64;
            hf.z_m[r * size + c] = (z - (x * x + y * y) / (2.0 * MOON_RADIUS_M)) as f32;
        }
    }
    Some(hf)
}

/// Degrees of |truncated − sampled| over all valid cells and azimuth samples: (mean, p99, max).
fn truncation_error_deg(map: &HorizonMap, sampled: &[f32]) -> (f64, f64, f64) {
    let n_az = map.meta.n_azimuths;
    let mut errs = Vec::new();
    for row in 0..map.meta.rows {
        for col in 0..map.meta.cols {
            let cell = row * map.meta.cols + col;
            for n in 0..n_az {
                let truth = sampled[cell * n_az + n];
                if truth.is_nan() {
                    continue;
                }
                let az = std::f64::consts::TAU * n as f64 / n_az as f64;
                errs.push(
                    ((map.elevation_rad(row, col, az) - truth) as f64)
                        .abs()
                        .to_degrees(),
                );
            }
        }
    }
    errs.sort_by(f64::total_cmp);
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    let p99 = errs[(errs.len() as f64 * 0.99) as usize];
    (mean, p99, *errs.last().unwrap())
}

#[test]
fn sampled_horizon_matches_an_analytic_ridge() {
    // A flat plane with one ridge row of height H: from a cell D metres south of the ridge, the
    // horizon toward azimuth θ (|θ| small enough to hit the ridge inside the grid) is
    // atan((H − z_obs) cos θ / D) (the ridge-row crossing dominates the tent's flanks).
    let (n, px, ridge_row, h_ridge) = (81, 20.0, 10usize, 100.0f32);
    let mut hf = HeightField::flat(n, n, px);
    for c in 0..n {
        hf.z_m[ridge_row * n + c] = h_ridge;
    }
    let n_az = 64;
    let sampled = fourier::sampled_horizons_rad(&hf, 2.0, n_az, 200).unwrap();
    let mut checked = 0;
    for (row, col) in [(60usize, 40usize), (40, 30), (75, 50)] {
        let (x, y) = hf.xy_from_row_col(row as f64, col as f64);
        let up = hf.up_at(x, y, 0.0);
        let obs = 2.0 * up + nalgebra::Vector3::new(x, y, 0.0);
        let (_, ridge_y) = hf.xy_from_row_col(ridge_row as f64, 0.0);
        let d = ridge_y - obs.y;
        for k in 0..n_az {
            let th = std::f64::consts::TAU * k as f64 / n_az as f64;
            let reach_x = obs.x + d * th.tan();
            let (x_min, _) = hf.xy_from_row_col(0.0, 0.0);
            let (x_max, _) = hf.xy_from_row_col(0.0, (n - 1) as f64);
            if th.cos() < 0.2 || !(x_min..=x_max).contains(&reach_x) {
                continue;
            }
            let want = ((h_ridge as f64 - obs.z) * th.cos() / d).atan();
            let got = sampled[(row * n + col) * n_az + k] as f64;
            assert!(
                (got - want).abs() < 1e-6,
                "cell ({row},{col}) az {:.2} deg: {got} vs {want}",
                th.to_degrees()
            );
            checked += 1;
        }
    }
    assert!(checked > 20, "{checked} azimuths checked");
}

/// Reports and bounds the truncation error on one field.
fn check_truncation(name: &str, hf: &HeightField, bound_p99_deg: f64, bound_mip_p99_deg: f64) {
    let n_az = 64;
    let max_d = hf.rows + hf.cols;
    let sampled = fourier::sampled_horizons_rad(hf, 2.0, n_az, max_d).unwrap();
    let map = HorizonMap::build(hf, 2.0, n_az, max_d).unwrap();
    let (mean, p99, max) = truncation_error_deg(&map, &sampled);
    let (m_mean, m_p99, m_max) = truncation_error_deg(&map.mipmapped(), &sampled);
    eprintln!(
        "{name} {}x{} ({n_az} az, 16 coeffs): |err| mean {mean:.4} p99 {p99:.4} max {max:.4} deg; \
         mipmapped mean {m_mean:.4} p99 {m_p99:.4} max {m_max:.4} deg",
        hf.rows, hf.cols
    );
    assert!(p99 < bound_p99_deg, "{name}: p99 {p99}");
    assert!(m_p99 < bound_mip_p99_deg, "{name}: mip p99 {m_p99}");
    // Mip downsampling only adds error on average.
    assert!(m_mean >= mean * 0.99, "{name}: mip mean {m_mean} < {mean}");
}

#[test]
fn truncated_dft_vs_sampled_horizon_synthetic() {
    // Measured: p99 0.91 deg, mipmapped p99 2.76 deg (bounds: about 1.5x margin).
    check_truncation("synthetic", &synthetic_field(64), 1.5, 4.0);
}

#[test]
fn truncated_dft_vs_sampled_horizon_real_240m() {
    let Some(hf) = real_crop(128) else {
        return;
    };
    // Measured: p99 0.57 deg, mipmapped p99 0.93 deg (bounds: about 1.7x margin).
    check_truncation("real 240 m", &hf, 1.0, 1.5);
}

/// Hard masks vs brute force at Sun elevations 1.5° and 5°: (raw % differ, % differ away from
/// the reference's shadow edges) per light.
fn mask_disagreement(hf: &HeightField, map: &HorizonMap) -> Vec<(f64, f64, f64, f64)> {
    let mut out = Vec::new();
    for el in [1.5, 5.0] {
        for az in [0.0, 37.0, 143.0, 301.0] {
            let l = light_az_el(az, el);
            let reference = penumbra::shadow::Engine::Brute
                .hard_mask(hf, 2.0, l)
                .unwrap();
            let mask = fourier::hard_mask(map, l).unwrap();
            let raw = reference.iter().zip(&mask).filter(|(a, b)| a != b).count() as f64 * 100.0
                / reference.len() as f64;
            let cmp = compare_masks(&reference, &mask, hf.rows, hf.cols);
            eprintln!(
                "el {el} az {az}: {raw:.2}% of all cells differ, {:.2}% away from edges \
                 ({:.1}% shadow)",
                cmp.disagree_percent(),
                100.0 * cmp.shadow_share
            );
            out.push((el, az, raw, cmp.disagree_percent()));
        }
    }
    out
}

#[test]
fn hard_mask_vs_brute_force() {
    let mut fields = vec![("synthetic", synthetic_field(64))];
    if let Some(hf) = real_crop(128) {
        fields.push(("real 240 m", hf));
    }
    for (name, hf) in fields {
        let map = HorizonMap::build(&hf, 2.0, 64, hf.rows + hf.cols).unwrap();
        eprintln!("{name}:");
        for (el, az, raw, away) in mask_disagreement(&hf, &map) {
            assert!(raw < 3.0, "{name} el {el} az {az}: {raw}% differ");
            assert!(
                away < 1.0,
                "{name} el {el} az {az}: {away}% differ away from edges"
            );
        }
    }
}

#[test]
fn soft_fraction_vs_brute_force() {
    let hf = synthetic_field(64);
    let map = HorizonMap::build(&hf, 2.0, 64, 128).unwrap();
    for (az, el) in [(37.0, 1.5), (143.0, 0.3)] {
        let l = light_az_el(az, el);
        let reference = brute::visible_fraction(&hf, 2.0, l, SUN_ANGULAR_RADIUS_RAD, 64).unwrap();
        let f = fourier::visible_fraction(&map, l, SUN_ANGULAR_RADIUS_RAD).unwrap();
        let cmp = compare_fractions(&reference, &f);
        eprintln!(
            "soft az {az} el {el}: mean |d| {:.4}, max {:.3}, penumbra cells {} mean |d| {:.3}",
            cmp.mean_abs, cmp.max_abs, cmp.penumbra, cmp.mean_abs_penumbra
        );
        // Measured: 0.0054 (el 1.5 deg) and 0.0286 (el 0.3 deg, mostly penumbra).
        assert!(cmp.mean_abs < 0.05, "mean |d| {}", cmp.mean_abs);
    }
}

#[test]
fn f16_and_tiff_round_trips_are_exact() {
    let hf = synthetic_field(24);
    let map = HorizonMap::build(&hf, 2.0, 32, 48).unwrap();
    for v in &map.coeffs {
        assert_eq!(f16::from_f32(v.to_f32()).to_bits(), v.to_bits());
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hm.tif");
    map.write_tiff(&path).unwrap();
    let back = HorizonMap::read_tiff(&path).unwrap();
    assert_eq!(back.meta, map.meta);
    let bits = |m: &HorizonMap| m.coeffs.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back), bits(&map));
    // Hole cells stay NaN.
    let mut holed = hf.clone();
    holed.z_m[5] = f32::NAN;
    let m2 = HorizonMap::build(&holed, 2.0, 32, 48).unwrap();
    assert!(m2.elevation_rad(0, 5, 0.3).is_nan());
    assert_eq!(
        fourier::hard_mask(&m2, light_az_el(10.0, 3.0)).unwrap()[5],
        255
    );
}

#[test]
fn cli_build_and_info() {
    let dir = tempfile::tempdir().unwrap();
    let out = penumbra(
        dir.path(),
        &[
            "horizon-map",
            "build",
            "--synthetic",
            "--azimuths",
            "32",
            "--max-distance-cells",
            "6",
            "--out",
            "hm.tif",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let map = HorizonMap::read_tiff(&dir.path().join("hm.tif")).unwrap();
    assert_eq!(map.meta.n_azimuths, 32);
    assert_eq!(map.meta.n_coeffs, 16);
    let info = penumbra(dir.path(), &["horizon-map", "info", "hm.tif"]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(info.status.success());
    assert!(
        text.contains(&format!("{} rows x {} cols", map.meta.rows, map.meta.cols)),
        "{text}"
    );
    assert!(text.contains("16 complex"), "{text}");

    let missing = penumbra(dir.path(), &["horizon-map", "info", "missing.tif"]);
    assert_clean_error(&missing, "missing.tif");
    let bad = penumbra(
        dir.path(),
        &[
            "horizon-map",
            "build",
            "--dem",
            "nope.tif",
            "--out",
            "x.tif",
        ],
    );
    assert_clean_error(&bad, "nope.tif");
    assert!(!dir.path().join("x.tif").exists());
}

/// `horizon-map build` pages are georeferenced: GDAL (PROJ's orthographic, inverted by
/// `gdaltransform`) puts each pixel centre at the lat/lon whose model coordinates — by penumbra's
/// own frame code (`ModelFrame`) — are that pixel's centre.
#[test]
fn horizon_map_pages_are_georeferenced_for_gdal() {
    if !crate::util::tool("gdaltransform", "gdal-bin") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = penumbra(
        dir.path(),
        &[
            "horizon-map",
            "build",
            "--synthetic",
            "--azimuths",
            "32",
            "--max-distance-cells",
            "4",
            "--out",
            "hm.tif",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let path = dir.path().join("hm.tif");
    let m = HorizonMap::read_tiff(&path).unwrap().meta;
    let pixels = [
        (0usize, 0usize),
        (m.cols - 1, 0),
        (m.cols / 3, m.rows / 2),
        (m.cols - 1, m.rows - 1),
    ];
    let input: String = pixels
        .iter()
        .map(|(i, j)| format!("{} {}\n", *i as f64 + 0.5, *j as f64 + 0.5))
        .collect();
    let mut child = std::process::Command::new("gdaltransform")
        .args(["-t_srs", "+proj=longlat +R=1737400 +no_defs"])
        .arg(format!("GTIFF_DIR:3:{}", path.display()))
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write as _;
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let got = child.wait_with_output().unwrap();
    assert!(got.status.success());
    let frame = penumbra::terrain::ModelFrame::rotated(
        m.centre_lat_deg,
        m.centre_lon_deg,
        m.rotation_deg.to_radians(),
    );
    for ((i, j), line) in pixels
        .iter()
        .zip(String::from_utf8_lossy(&got.stdout).lines())
    {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|t| t.parse().unwrap())
            .collect();
        let (lon, lat) = (v[0], v[1]);
        // The sphere point's model x/y (orthographic: its components along model x and y).
        let p = penumbra::frames::site_in_moon_me_km(lat, lon, 0.0) * 1000.0;
        let model = frame.model_from_moon_me * p;
        let want = (
            m.x_left_m + (*i as f64 + 0.5) * m.px_m,
            m.y_top_m - (*j as f64 + 0.5) * m.px_m,
        );
        assert!(
            (model.x - want.0).abs() < 1e-3 && (model.y - want.1).abs() < 1e-3,
            "pixel ({i}, {j}): GDAL lat {lat} lon {lon} -> model ({}, {}), want {want:?}",
            model.x,
            model.y
        );
    }
}

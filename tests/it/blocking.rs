//! The one blocking rule (docs/ARCHITECTURE.md "Blocking"), against analytic answers that share
//! none of the engines' conventions: an isolated cone on the reference sphere, whose summit sees
//! the Sun down to the dip of the sphere's horizon, `acos(R / (R + H + h))`, well below the local
//! horizontal plane. Every map engine (CPU, and the GPU DP kernel when an adapter exists) and the
//! per-site horizon engine must agree with it.

use crate::util::{penumbra, penumbra_ok, read_tif};

/// Cone height (m), base radius (m), grid size (cells), cell (m). The apex sits on the centre of
/// pixel (`APEX_ROW`, `APEX_COL`), half a pixel from the pole in x and y, so that it is also a
/// cell centre of the map's model grid (which is centred on the pole with axes along the
/// projection's there): the analytic case tests the blocking rule, not the resampling.
const CONE_H_M: f64 = 2000.0;
const CONE_BASE_M: f64 = 5000.0;
const N: usize = 240;
const PX_M: f64 = 1000.0;
const OBSERVER_M: f64 = 2.0;
const APEX_ROW: usize = 119;
const APEX_COL: usize = 120;
const APEX_X_M: f64 = 500.0;
const APEX_Y_M: f64 = 500.0;

/// The dip (deg, positive) of the sphere's horizon seen from the summit.
fn summit_dip_deg() -> f64 {
    let r = penumbra::MOON_RADIUS_M;
    (r / (r + CONE_H_M + OBSERVER_M)).acos().to_degrees()
}

/// Writes the cone DEM (polar stereographic, centred on the south pole) into `dir`.
fn write_cone(dir: &std::path::Path) -> std::path::PathBuf {
    let dem = penumbra::terrain::synth::dem_from_fn(N, N, PX_M, "cone", |x, y| {
        let r = (x - APEX_X_M).hypot(y - APEX_Y_M);
        (CONE_H_M * (1.0 - r / CONE_BASE_M)).max(0.0)
    });
    let path = dir.join("cone.tif");
    penumbra::terrain::write_dem(&path, &dem, &[]).unwrap();
    path
}

/// The summit pixel's value of a one-light map.
fn summit_value(dir: &std::path::Path, name: &str) -> f32 {
    let dem = read_tif(dir, name);
    dem.heights_m[APEX_ROW * N + APEX_COL]
}

/// `penumbra map` of the cone for one light (engine, backend, az / el at the map centre, deg),
/// writing `m.tif` (mask) and `f.tif` (fraction) into `dir`.
fn cone_map(
    dir: &std::path::Path,
    cone: &str,
    engine: &str,
    backend: &str,
    az_deg: f64,
    el_deg: f64,
) -> std::process::Output {
    let (az, el) = (format!("{az_deg}"), format!("{el_deg}"));
    penumbra(
        dir,
        &[
            "map",
            "--dem",
            cone,
            "--engine",
            engine,
            "--backend",
            backend,
            "--sun-az-deg",
            &az,
            "--sun-el-deg",
            &el,
            "--out-mask",
            "m.tif",
            "--out-fraction",
            "f.tif",
        ],
    )
}

/// Asserts the summit of the last [`cone_map`] in `dir`: mask `lit` (1 or 0), and a fraction
/// above 0.6 when lit, below 0.4 when not (0.1° above the edge leaves less than a third of the
/// disc of radius 0.2666° hidden, 0.1° below leaves less than a third visible).
fn assert_summit(dir: &std::path::Path, lit: bool, what: &str) {
    let mask = summit_value(dir, "m.tif");
    let frac = summit_value(dir, "f.tif");
    eprintln!("{what}: mask {mask} fraction {frac}");
    assert_eq!(mask, if lit { 1.0 } else { 0.0 }, "{what}: mask");
    if lit {
        assert!(frac > 0.6, "{what}: fraction {frac}");
    } else {
        assert!(frac < 0.4, "{what}: fraction {frac}");
    }
}

#[test]
fn cone_summit_sees_the_sun_down_to_the_dip_in_every_map_engine() {
    let tmp = tempfile::tempdir().unwrap();
    let cone = write_cone(tmp.path());
    let cone = cone.to_str().unwrap();
    let dip = summit_dip_deg();
    assert!((dip - 2.74).abs() < 0.01, "dip {dip}");
    // The light's --sun-el-deg is its elevation at the map centre (the pole); the apex's local
    // vertical is tilted by 707 m / R = 0.023° from it, within the ±0.1° margins below.
    for engine in ["brute", "smap", "dp", "combined", "fourier"] {
        for az in [30.0_f64, 200.0] {
            for (el, lit) in [(-dip + 0.1, true), (-dip - 0.1, false)] {
                let out = cone_map(tmp.path(), cone, engine, "cpu", az, el);
                assert!(
                    out.status.success(),
                    "{}",
                    String::from_utf8_lossy(&out.stderr)
                );
                assert_summit(tmp.path(), lit, &format!("{engine} az {az} el {el:.3}"));
            }
        }
    }
}

#[test]
fn cone_summit_on_the_gpu_dp_kernel() {
    let tmp = tempfile::tempdir().unwrap();
    let cone = write_cone(tmp.path());
    let cone = cone.to_str().unwrap();
    let dip = summit_dip_deg();
    for (el, lit) in [(-dip + 0.1, true), (-dip - 0.1, false)] {
        let out = cone_map(tmp.path(), cone, "dp", "gpu", 75.0, el);
        if !out.status.success() {
            let required = std::env::var("PENUMBRA_REQUIRE_GPU").is_ok_and(|v| v == "1");
            assert!(!required, "{}", String::from_utf8_lossy(&out.stderr));
            eprintln!(
                "skipping GPU case: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            );
            return;
        }
        assert_summit(tmp.path(), lit, &format!("gpu el {el:.3}"));
    }
}

#[test]
fn cone_summit_horizon_is_the_dip() {
    let tmp = tempfile::tempdir().unwrap();
    let cone = write_cone(tmp.path());
    // The apex's latitude / longitude (south polar stereographic, k0 = 1).
    let rho = APEX_X_M.hypot(APEX_Y_M);
    let colat = 2.0 * (rho / (2.0 * penumbra::MOON_RADIUS_M)).atan();
    let apex_lat = format!("{}", -(90.0 - colat.to_degrees()));
    let apex_lon = format!("{}", APEX_X_M.atan2(APEX_Y_M).to_degrees());
    penumbra_ok(
        tmp.path(),
        &[
            "horizon",
            "--dem",
            cone.to_str().unwrap(),
            "--lat-deg",
            &apex_lat,
            "--lon-deg",
            &apex_lon,
            "--az-step-deg",
            "15",
            "--out",
            "h.csv",
        ],
    );
    let text = std::fs::read_to_string(tmp.path().join("h.csv")).unwrap();
    let dip = summit_dip_deg();
    let mut n = 0;
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let el: f64 = line.split(',').nth(1).unwrap().trim().parse().unwrap();
        assert!((el + dip).abs() < 0.01, "{line}: expected {:.4}", -dip);
        n += 1;
    }
    assert_eq!(n, 24);
}

#[test]
fn a_dem_too_small_for_its_horizon_is_reported() {
    // 40 km across: rays from the summit toward a Sun 2.9° down leave the grid above the sphere
    // but meet it about 45 km out; the map calls the summit lit (no terrain on the grid blocks)
    // and must say that the DEM is too small there.
    let tmp = tempfile::tempdir().unwrap();
    let dem = penumbra::terrain::synth::dem_from_fn(40, 40, 1000.0, "cone", |x, y| {
        (CONE_H_M * (1.0 - (x - APEX_X_M).hypot(y - APEX_Y_M) / CONE_BASE_M)).max(0.0)
    });
    let path = tmp.path().join("small.tif");
    penumbra::terrain::write_dem(&path, &dem, &[]).unwrap();
    let el = format!("{}", -summit_dip_deg() - 0.15);
    let out = penumbra_ok(
        tmp.path(),
        &[
            "map",
            "--dem",
            path.to_str().unwrap(),
            "--backend",
            "cpu",
            "--sun-az-deg",
            "10",
            "--sun-el-deg",
            &el,
            "--out-fraction",
            "f.tif",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("toward the reference sphere") && stderr.contains("far-field"),
        "{stderr}"
    );
}

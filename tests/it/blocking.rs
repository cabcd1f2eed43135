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
    for engine in ["dp", "combined", "fourier"] {
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
    // Brute force, the tests' oracle (a library engine, not a `--engine`), on the same grid and
    // observers as the map.
    use penumbra::model::{MapEngine, MapEngineKind, MapGrid};
    let stack = penumbra::terrain::TerrainStack::new(vec![read_tif(tmp.path(), "cone.tif")]);
    let grid = MapGrid::new(&stack).unwrap();
    let observers = grid.pixel_observers(OBSERVER_M);
    let brute = MapEngine::new(
        MapEngineKind::Direct(penumbra::shadow::Engine::Brute),
        &grid,
        OBSERVER_M,
    )
    .unwrap();
    let radius_rad = penumbra::shadow::SUN_ANGULAR_RADIUS_RAD;
    for az in [30.0_f64, 200.0] {
        for (el, lit) in [(-dip + 0.1, true), (-dip - 0.1, false)] {
            let light = grid.light_from_az_el_deg(az, el);
            let summit = APEX_ROW * N + APEX_COL;
            let mask = brute
                .hard_mask_on_dem(&grid, Some(&observers), OBSERVER_M, light)
                .unwrap()[summit];
            let frac = brute
                .visible_fraction_on_dem(&grid, Some(&observers), OBSERVER_M, light, radius_rad)
                .unwrap()[summit];
            eprintln!("brute az {az} el {el:.3}: mask {mask} fraction {frac}");
            assert_eq!(mask, u8::from(lit), "brute az {az} el {el:.3}: mask");
            assert!(
                if lit { frac > 0.6 } else { frac < 0.4 },
                "brute az {az} el {el:.3}: fraction {frac}"
            );
        }
    }
}

#[cfg(feature = "gpu")]
#[test]
fn cone_summit_on_the_gpu_dp_kernel() {
    if crate::util::gpu().is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cone = write_cone(tmp.path());
    let cone = cone.to_str().unwrap();
    let dip = summit_dip_deg();
    for (el, lit) in [(-dip + 0.1, true), (-dip - 0.1, false)] {
        let out = cone_map(tmp.path(), cone, "dp", "gpu", 75.0, el);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
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

/// A DEM of sharp features on 160² cells of 20 m whose centre is at map point (`cx_m`, `cy_m`)
/// (south polar stereographic): three plateaus (0, 40, 80 m) joined by vertical one-pixel steps,
/// a one-pixel wall 60 m high, a 3 x 3 pit 50 m deep and a 4 x 4 nodata hole.
fn sharp_dem(cx_m: f64, cy_m: f64) -> penumbra::terrain::Dem {
    const SN: usize = 160;
    const SPX: f64 = 20.0;
    let grid = penumbra::terrain::GridGeometry {
        rows: SN,
        cols: SN,
        x_left_m: cx_m - SN as f64 * SPX / 2.0,
        y_top_m: cy_m + SN as f64 * SPX / 2.0,
        px_x_m: SPX,
        px_y_m: SPX,
    };
    let heights_m = (0..SN * SN)
        .map(|i| {
            let (r, c) = (i / SN, i % SN);
            let mut h: f32 = match c {
                0..50 => 0.0,
                50..100 => 40.0,
                _ => 80.0,
            };
            if r == 80 && (20..140).contains(&c) {
                h += 60.0;
            }
            if (40..43).contains(&r) && (120..123).contains(&c) {
                h -= 50.0;
            }
            if (120..124).contains(&r) && (30..34).contains(&c) {
                h = f32::NAN;
            }
            h
        })
        .collect();
    penumbra::terrain::Dem {
        grid,
        projection: penumbra::terrain::Projection::LOLA_SOUTH_POLAR,
        heights_m,
        name: "sharp".into(),
    }
}

/// Per engine (the CPU engines from the model cells, the CPU DP and the GPU DP kernel's twin
/// from the DEM pixels), the share of "stable" pixels (the oracle's answer is the same for the light and
/// for the light moved by ±0.5° in azimuth and in elevation) whose hard mask differs from an
/// exact ray cast on the DEM's own surface (the per-site horizon engine toward the pixel's own
/// azimuth of the light, exact method), over 10 lights; every 3rd pixel.
fn sharp_mask_errors(dem: penumbra::terrain::Dem) -> Vec<(&'static str, f64, usize)> {
    use penumbra::horizon::{HorizonEngine, HorizonMethod, HorizonParams};
    use penumbra::shadow::Engine;
    use rayon::prelude::*;
    let stack = penumbra::terrain::TerrainStack::new(vec![dem]);
    let grid = penumbra::model::MapGrid::new(&stack).unwrap();
    let dem = &stack.layers[0];
    let (cx, cy) = dem.grid.xy_from_row_col(79.5, 79.5);
    let (clat, clon) = dem.projection.lat_lon_from_xy(cx, cy);
    let moon_from_centre = penumbra::frames::enu_from_moon_me(clat, clon).transpose();
    let engine = HorizonEngine::new(&stack);
    let params = HorizonParams {
        observer_height_m: 2.0,
        method: HorizonMethod::Exact,
        ..HorizonParams::default()
    };
    let pixels: Vec<(usize, usize)> = (0..160)
        .step_by(3)
        .flat_map(|r| (0..160).step_by(3).map(move |c| (r, c)))
        .filter(|&(r, c)| !dem.heights_m[r * 160 + c].is_nan())
        .collect();
    let engines = [
        ("brute", Engine::Brute),
        ("dp", Engine::Dp),
        ("combined", Engine::Combined),
    ];
    // The GPU's DP kernel from the DEM pixels (`dp_points.wgsl`) through its f32 twin, and the
    // CPU DP from the pixels (the maps' default on both backends).
    let observers = grid.pixel_observers(2.0);
    let march = penumbra::twins::MarchGrid::from_height_field(&grid.hf, 2.0).unwrap();
    let mip = penumbra::twins::DpMip::build(&march);
    let (pixel_of_point, points) = penumbra::twins::pixel_point_records(&march, &observers);
    let dp_engine = penumbra::model::MapEngine::new(
        penumbra::model::MapEngineKind::Direct(Engine::Dp),
        &grid,
        2.0,
    )
    .unwrap();
    let mut wrong = vec![0usize; engines.len() + 2];
    let mut stable = 0usize;
    for az in [20.0, 95.0, 160.0, 250.0, 330.0] {
        for el in [1.0, 3.0] {
            let dir = |daz: f64, del: f64| {
                moon_from_centre * penumbra::frames::enu_from_az_el_deg(az + daz, el + del)
            };
            let oracle: Vec<Option<bool>> = pixels
                .par_iter()
                .map(|&(r, c)| {
                    let (x, y) = dem.grid.xy_from_row_col(r as f64, c as f64);
                    let (lat, lon) = dem.projection.lat_lon_from_xy(x, y);
                    let enu = penumbra::frames::enu_from_moon_me(lat, lon);
                    let lit = |d: nalgebra::Vector3<f64>| {
                        let (a, e) = penumbra::frames::az_el_deg_from_enu(&(enu * d));
                        let (h, _) = engine.horizon_toward(lat, lon, a, &params).unwrap();
                        e > h
                    };
                    let l0 = lit(dir(0.0, 0.0));
                    let same = [(0.5, 0.0), (-0.5, 0.0), (0.0, 0.5), (0.0, -0.5)]
                        .iter()
                        .all(|&(da, de)| lit(dir(da, de)) == l0);
                    same.then_some(l0)
                })
                .collect();
            stable += oracle.iter().flatten().count();
            let light = grid.light_from_moon_me(&dir(0.0, 0.0));
            let mut masks: Vec<Vec<u8>> = engines
                .iter()
                .map(|(_, e)| grid.to_output_u8(&e.hard_mask(&grid.hf, 2.0, light).unwrap()))
                .collect();
            masks.push(
                dp_engine
                    .hard_mask_on_dem(&grid, Some(&observers), 2.0, light)
                    .unwrap(),
            );
            let hard = penumbra::twins::disc_light_to_f32(&light.into(), 0.0);
            let mut twin = vec![255_u8; observers.len()];
            for (&p, &f) in pixel_of_point
                .iter()
                .zip(&penumbra::twins::dp_points(&march, &mip, &points, hard))
            {
                twin[p] = u8::from(f > 0.5);
            }
            masks.push(twin);
            for (k, mask) in masks.iter().enumerate() {
                wrong[k] += pixels
                    .iter()
                    .zip(&oracle)
                    .filter(|((r, c), o)| o.is_some_and(|lit| (mask[r * 160 + c] == 1) != lit))
                    .count();
            }
        }
    }
    engines
        .iter()
        .map(|(name, _)| *name)
        .chain(["dp (pixels)", "gpu dp twin (pixels)"])
        .zip(wrong)
        .map(|(name, w)| (name, 100.0 * w as f64 / stable as f64, stable))
        .collect()
}

#[test]
fn hard_masks_on_sharp_steps_match_an_exact_ray_cast_on_the_dem() {
    // At the pole, and centred on the Connecting Ridge (-89.45°, -137.3°: the DEM grid is then
    // rotated by 137° against the local north).
    let p = penumbra::terrain::Projection::LOLA_SOUTH_POLAR;
    let (rx, ry) = p.xy_from_lat_lon(-89.45, -137.3);
    let (rx, ry) = ((rx / 20.0).round() * 20.0, (ry / 20.0).round() * 20.0);
    for (place, cx, cy) in [("pole", 0.0, 0.0), ("ridge", rx, ry)] {
        for (engine, pct, stable) in sharp_mask_errors(sharp_dem(cx, cy)) {
            eprintln!(
                "sharp DEM at the {place}: {engine} {pct:.3}% of {stable} stable pixel-lights wrong"
            );
            // Issue 13's tolerance for sharp steps.
            assert!(pct <= 0.5, "{place} {engine}: {pct:.3}%");
        }
    }
}

/// One-light soft Sun fractions of the map engines (combined and DP, from the DEM pixels: the
/// product path of `map --out-fraction`) against the per-site engine's exact horizons at ≥ 40
/// pixel-lights whose disc is partly hidden (0.02 < f < 0.98). The oracle integrates the Sun's
/// disc (radius 0.267°) in 96 vertical strips, each clipped by an exact ray cast on the DEM's own
/// surface toward the strip's azimuth (`HorizonEngine::horizon_toward`). It shares with the map
/// the bilinear surface of the DEM pixels and the observer 2 m above each pixel's centre; it
/// shares neither the model grid, nor the max-mipmap, nor the SMap verdicts, nor the near-field
/// code. Pixels within 16 px of the DEM's edge are left out (beyond the edge both see no
/// terrain; the edge strip is measured by the DSK oracle). Returns, per engine, the |Δf| of
/// every compared pixel-light.
fn sharp_soft_errors(
    dem: penumbra::terrain::Dem,
    lights: &[(f64, f64)],
) -> Vec<(&'static str, Vec<f64>)> {
    use penumbra::horizon::{HorizonEngine, HorizonMethod, HorizonParams};
    use penumbra::model::{MapEngine, MapEngineKind};
    use penumbra::shadow::Engine;
    use rayon::prelude::*;
    let sun_r_deg = 0.267_f64;
    let stack = penumbra::terrain::TerrainStack::new(vec![dem]);
    let grid = penumbra::model::MapGrid::new(&stack).unwrap();
    let dem = &stack.layers[0];
    let (rows, cols) = (dem.grid.rows, dem.grid.cols);
    let (cx, cy) = dem
        .grid
        .xy_from_row_col((rows as f64 - 1.0) / 2.0, (cols as f64 - 1.0) / 2.0);
    let (clat, clon) = dem.projection.lat_lon_from_xy(cx, cy);
    let moon_from_centre = penumbra::frames::enu_from_moon_me(clat, clon).transpose();
    let engine = HorizonEngine::new(&stack);
    let params = HorizonParams {
        observer_height_m: 2.0,
        method: HorizonMethod::Exact,
        ..HorizonParams::default()
    };
    let margin = 16;
    let pixels: Vec<(usize, usize)> = (margin..rows - margin)
        .step_by(2)
        .flat_map(|r| (margin..cols - margin).step_by(2).map(move |c| (r, c)))
        .filter(|&(r, c)| !dem.heights_m[r * cols + c].is_nan())
        .collect();
    let observers = grid.pixel_observers(2.0);
    let engines = [("combined", Engine::Combined), ("dp", Engine::Dp)].map(|(name, e)| {
        (
            name,
            MapEngine::new(MapEngineKind::Direct(e), &grid, 2.0).unwrap(),
        )
    });
    let mut errors: Vec<(&'static str, Vec<f64>)> =
        engines.iter().map(|(n, _)| (*n, Vec::new())).collect();
    for &(az, el) in lights {
        let d = moon_from_centre * penumbra::frames::enu_from_az_el_deg(az, el);
        let oracle: Vec<Option<f64>> = pixels
            .par_iter()
            .map(|&(r, c)| {
                let (x, y) = dem.grid.xy_from_row_col(r as f64, c as f64);
                let (lat, lon) = dem.projection.lat_lon_from_xy(x, y);
                let enu = penumbra::frames::enu_from_moon_me(lat, lon);
                let (a0, e0) = penumbra::frames::az_el_deg_from_enu(&(enu * d));
                let h = |a: f64| engine.horizon_toward(lat, lon, a, &params).unwrap().0;
                if (e0 - h(a0)).abs() > 3.0 * sun_r_deg {
                    return None;
                }
                let k = 96;
                let dx = 2.0 * sun_r_deg / k as f64;
                let (mut seen, mut whole) = (0.0, 0.0);
                for i in 0..k {
                    let x = -sun_r_deg + (i as f64 + 0.5) * dx;
                    let half = (sun_r_deg * sun_r_deg - x * x).sqrt();
                    let hk = h(a0 + x / e0.to_radians().cos());
                    seen += (e0 + half - hk.max(e0 - half)).clamp(0.0, 2.0 * half) * dx;
                    whole += 2.0 * half * dx;
                }
                let f = seen / whole;
                (f > 0.02 && f < 0.98).then_some(f)
            })
            .collect();
        let light = grid.light_from_moon_me(&d);
        for ((_, e), (_, errs)) in engines.iter().zip(errors.iter_mut()) {
            let map = e
                .visible_fraction_on_dem(
                    &grid,
                    Some(&observers),
                    2.0,
                    light,
                    sun_r_deg.to_radians(),
                )
                .unwrap();
            for (&(r, c), o) in pixels.iter().zip(&oracle) {
                if let Some(f) = o {
                    let m = f64::from(map[r * cols + c]);
                    errs.push((m - f).abs());
                }
            }
        }
    }
    errors
}

/// Deliver 3 of issue 48: one-light soft maps on sharp terrain. Three DEMs: the sharp steps of
/// [`sharp_dem`] (plateaus joined by one-pixel steps, a one-pixel wall, a pit) at the pole and
/// rotated 137° at the Connecting Ridge, and the synthetic south-polar DEM (craters, fBm) at its
/// own 100 m pixel (at 20 m its crater walls are kilometre-high cliffs); 10 lights each.
///
/// The target, per engine and DEM over ≥ 40 partly hidden pixel-lights, is mean |Δf|
/// ≤ 0.02, ≥ 95 % within 0.05, none beyond 0.25. **It is not met** (docs/VALIDATION.md): measured
/// DP mean 0.0176 / 0.0108 / 0.0197 with 92.3 / 95.3 / 88.5 % within 0.05 and max 0.83 / 0.74 /
/// 0.72; combined 0.0353 / 0.0553 / 0.0197 (its SMap limb verdicts are wrong near the steps).
/// Until it is, each row's bounds are the measured numbers with a margin (mean +15 %, share
/// within 0.05 −2 pp, max +0.05, capped at 1): a regression fails, and a row that reaches the
/// target says so.
#[test]
fn soft_fractions_on_sharp_terrain_match_exact_horizons() {
    let p = penumbra::terrain::Projection::LOLA_SOUTH_POLAR;
    let (rx, ry) = p.xy_from_lat_lon(-89.45, -137.3);
    let (rx, ry) = ((rx / 20.0).round() * 20.0, (ry / 20.0).round() * 20.0);
    let synthetic =
        penumbra::terrain::synth::south_polar_dem(&penumbra::terrain::synth::SynthParams {
            size_px: 160,
            px_m: 100.0,
            seed: 7,
        })
        .unwrap();
    let lights: Vec<(f64, f64)> = [20.0, 95.0, 160.0, 250.0, 330.0]
        .iter()
        .flat_map(|&az| [(az, 1.0), (az, 3.0)])
        .collect();
    // (mean, % within 0.05, max) measured on 2026-12-08, per DEM: combined, then dp.
    let measured = [
        [(0.0353, 86.5, 0.833), (0.0176, 92.3, 0.833)],
        [(0.0553, 83.4, 0.876), (0.0108, 95.3, 0.737)],
        [(0.0197, 88.5, 0.718), (0.0197, 88.5, 0.718)],
    ];
    let mut failed: Vec<String> = Vec::new();
    for ((place, dem), rows) in [
        ("steps at the pole", sharp_dem(0.0, 0.0)),
        ("steps at the ridge", sharp_dem(rx, ry)),
        ("synthetic craters", synthetic),
    ]
    .into_iter()
    .zip(measured)
    {
        for ((engine, mut errs), (m_mean, m_within, m_max)) in
            sharp_soft_errors(dem, &lights).into_iter().zip(rows)
        {
            errs.sort_by(f64::total_cmp);
            let n = errs.len();
            let mean = errs.iter().sum::<f64>() / n as f64;
            let within = 100.0 * errs.iter().filter(|e| **e <= 0.05).count() as f64 / n as f64;
            let max = errs[n - 1];
            let target = mean <= 0.02 && within >= 95.0 && max <= 0.25;
            eprintln!(
                "{place}: {engine}: {n} partly hidden pixel-lights, mean |df| {mean:.4}, \
                 {within:.1}% within 0.05, p99 {:.3}, max {max:.3}: {}",
                errs[(n * 99 / 100).min(n - 1)],
                if target {
                    "target met"
                } else {
                    "KNOWN GAP (target: mean 0.02, 95 %, max 0.25)"
                }
            );
            let bound = (m_mean * 1.15, m_within - 2.0, (m_max + 0.05_f64).min(1.0));
            if n < 40 || !(target || (mean <= bound.0 && within >= bound.1 && max <= bound.2)) {
                failed.push(format!(
                    "{place} {engine}: {n} pixel-lights, mean {mean:.4}, {within:.1}% within \
                     0.05, max {max:.3} (bounds: n >= 40 and mean <= {:.4}, >= {:.1}%, max <= \
                     {:.3})",
                    bound.0, bound.1, bound.2
                ));
            }
        }
    }
    assert!(failed.is_empty(), "{failed:#?}");
}

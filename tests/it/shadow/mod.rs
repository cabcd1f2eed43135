//! Shadow engines against analytic shadows and against the brute-force reference, on synthetic
//! height fields and on a crop of the real 240 m LOLA south-pole grid. Fourier horizon maps are
//! in `fourier`.

mod fourier;

use penumbra::MOON_RADIUS_M;
use penumbra::shadow::accuracy::{compare_fractions, compare_masks};
use penumbra::shadow::{
    EARTH_ANGULAR_RADIUS_RAD, Engine, MASK_LIT, MASK_NODATA, MASK_SHADOW, SUN_ANGULAR_RADIUS_RAD,
    ShadowError, brute, dp,
};
use penumbra::terrain::HeightField;

/// The shared 240 m grid (1536², float32 strip GeoTIFF, pole at the centre).
const GRID_240M: &str = "ldem75s_crop_240m_pm184km.tif";

/// Light direction in model space (ENU at the model origin) from azimuth (from north,
/// clockwise) and elevation.
fn light_az_el(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    [az.sin() * el.cos(), az.cos() * el.cos(), el.sin()]
}

/// Reads a float32 GeoTIFF with the `tiff` crate (test helper; the terrain module's reader will
/// replace it). Returns (cols, rows, heights).
fn read_f32_tiff(path: &std::path::Path) -> (usize, usize, Vec<f32>) {
    let file =
        std::fs::File::open(path).unwrap_or_else(|e| panic!("cannot open {}: {e}", path.display()));
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(file))
        .unwrap_or_else(|e| panic!("{} does not decode: {e}", path.display()));
    let (w, h) = dec.dimensions().expect("dimensions");
    match dec.read_image().expect("read the image") {
        tiff::decoder::DecodingResult::F32(v) => (w as usize, h as usize, v),
        _ => panic!("{} is not float32", path.display()),
    }
}

/// A `size²` crop of the 240 m grid centred on the grid centre (the pole), shifted by
/// (`d_row`, `d_col`) cells, as a model-space height field centred on the crop with the
/// curvature drop `z = h − (x² + y²) / 2R`. `None` (with a printed reason) if the file is absent.
fn real_crop(size: usize, d_row: i64, d_col: i64) -> Option<HeightField> {
    let (w, h, z) = read_f32_tiff(&crate::util::shared_lola(GRID_240M)?);
    let px = 240.0;
    let r0 = (h as i64 / 2 - size as i64 / 2 + d_row) as usize;
    let c0 = (w as i64 / 2 - size as i64 / 2 + d_col) as usize;
    let mut hf = HeightField::flat(size, size, px);
    for r in 0..size {
        for c in 0..size {
            let (x, y) = hf.xy_from_row_col(r as f64, c as f64);
            let hgt = z[(r0 + r) * w + (c0 + c)] as f64;
            hf.z_m[r * size + c] = (hgt - (x * x + y * y) / (2.0 * MOON_RADIUS_M)) as f32;
        }
    }
    Some(hf)
}

/// The elevations and azimuths of the acceptance criteria (grid-aligned and not).
const ELEVATIONS_DEG: [f64; 3] = [0.5, 1.5, 5.0];
const AZIMUTHS_DEG: [f64; 6] = [0.0, 37.0, 90.0, 143.0, 210.0, 301.0];

#[test]
fn flat_plane_is_lit_above_and_dark_below_the_horizon() {
    let hf = HeightField::flat(48, 48, 100.0);
    for az in [0.0, 33.0, 90.0, 251.0] {
        let up = light_az_el(az, 0.5);
        let down = light_az_el(az, -0.5);
        for engine in [Engine::Brute, Engine::Dp, Engine::Combined] {
            let lit = engine.hard_mask(&hf, 0.0, up).unwrap();
            assert!(lit.iter().all(|&v| v == MASK_LIT), "{engine:?} az {az}");
            // Only terrain blocks: a ray 0.5° down from 2 m meets the plane 229 m (2.3 cells)
            // out; cells nearer the edge toward the light see past the grid (no terrain there).
            let interior = |i: usize| (4..44).contains(&(i / 48)) && (4..44).contains(&(i % 48));
            let dark = engine.hard_mask(&hf, 2.0, down).unwrap();
            assert!(
                dark.iter()
                    .enumerate()
                    .all(|(i, &v)| !interior(i) || v == MASK_SHADOW),
                "{engine:?} az {az}"
            );
            let f_up = engine
                .visible_fraction(&hf, 0.0, up, SUN_ANGULAR_RADIUS_RAD)
                .unwrap();
            assert!(f_up.iter().all(|&f| f == 1.0), "{engine:?} az {az}");
            let f_down = engine
                .visible_fraction(&hf, 0.0, down, SUN_ANGULAR_RADIUS_RAD)
                .unwrap();
            assert!(
                f_down
                    .iter()
                    .enumerate()
                    .all(|(i, &f)| !interior(i) || f == 0.0),
                "{engine:?} az {az}"
            );
        }
    }
}

#[test]
fn invalid_inputs_are_errors_not_panics() {
    let hf = HeightField::flat(8, 8, 100.0);
    for bad in [
        [0.0, 0.0, 0.0],
        [f64::NAN, 0.0, 1.0],
        [0.0, f64::INFINITY, 0.1],
    ] {
        for engine in [Engine::Brute, Engine::Dp, Engine::Combined] {
            assert!(matches!(
                engine.hard_mask(&hf, 2.0, bad),
                Err(ShadowError::InvalidLight { .. })
            ));
            assert!(matches!(
                engine.visible_fraction(&hf, 2.0, bad, SUN_ANGULAR_RADIUS_RAD),
                Err(ShadowError::InvalidLight { .. })
            ));
        }
    }
    let ok = light_az_el(10.0, 3.0);
    assert!(matches!(
        Engine::Dp.visible_fraction(&hf, 2.0, ok, -0.1),
        Err(ShadowError::InvalidAngularRadius(_))
    ));
    assert!(matches!(
        Engine::Combined.hard_mask(&hf, f64::NAN, ok),
        Err(ShadowError::InvalidObserverHeight(_))
    ));
    assert!(matches!(
        brute::visible_fraction(&hf, 2.0, ok, 0.01, 0),
        Err(ShadowError::InvalidParameter { .. })
    ));
    // A light at the zenith is valid: nothing blocks it.
    for engine in [Engine::Brute, Engine::Combined, Engine::Dp] {
        let m = engine.hard_mask(&hf, 0.0, [0.0, 0.0, 1.0]).unwrap();
        assert!(m.iter().all(|&v| v == MASK_LIT));
    }
}

/// A north-south wall of height `h` on a flat plane; shadow length along a row = h·sin(az)/tan(el).
fn wall_field(height_m: f32) -> HeightField {
    let mut hf = HeightField::flat(40, 96, 100.0);
    for r in 0..40 {
        for c in 70..74 {
            hf.z_m[r * 96 + c] = height_m;
        }
    }
    hf
}

/// Length (cells) of the shadow run just west of the wall in row `row`.
fn shadow_run(mask: &[u8], row: usize) -> usize {
    (0..70)
        .rev()
        .take_while(|&c| mask[row * 96 + c] == MASK_SHADOW)
        .count()
}

#[test]
fn wall_shadow_length_matches_h_over_tan_el() {
    let h = 37.0;
    let hf = wall_field(h as f32);
    for (az, el) in [(90.0, 2.0), (90.0, 0.5), (120.0, 2.0), (63.0, 1.0)] {
        let l = light_az_el(az, el);
        let expected = h * f64::sin(f64::to_radians(az)) / (100.0 * f64::to_radians(el).tan());
        for engine in [Engine::Brute, Engine::Combined, Engine::Dp] {
            let mask = engine.hard_mask(&hf, 0.0, l).unwrap();
            for row in [10, 20, 30] {
                let run = shadow_run(&mask, row) as f64;
                assert!(
                    (run - expected).abs() <= 1.0,
                    "{engine:?} az {az} el {el} row {row}: run {run} vs {expected:.2}"
                );
            }
            // The wall's top and everything east of it is lit.
            assert!(
                (70..96).all(|c| mask[20 * 96 + c] == MASK_LIT),
                "{engine:?}"
            );
        }
    }
}

#[test]
fn holes_let_rays_pass() {
    let mut hf = wall_field(37.0);
    for r in 15..25 {
        for c in 70..74 {
            hf.z_m[r * 96 + c] = f32::NAN;
        }
    }
    let l = light_az_el(90.0, 2.0);
    for engine in [Engine::Brute, Engine::Combined, Engine::Dp] {
        let mask = engine.hard_mask(&hf, 0.0, l).unwrap();
        // Through the gap (rows 16..=23, away from the wall ends) the light passes.
        assert_eq!(shadow_run(&mask, 20), 0, "{engine:?}");
        assert_eq!(mask[20 * 96 + 71], MASK_NODATA);
        assert!(shadow_run(&mask, 5) >= 9, "{engine:?}");
    }
}

/// Spherical bowl: rim radius `rim_m` at z = 0 on a flat plane, depth `depth_m`.
struct Bowl {
    rim_m: f64,
    sphere_r_m: f64,
    centre_z_m: f64,
}

impl Bowl {
    fn new(rim_m: f64, depth_m: f64) -> Bowl {
        let sphere_r_m = (rim_m * rim_m + depth_m * depth_m) / (2.0 * depth_m);
        Bowl {
            rim_m,
            sphere_r_m,
            centre_z_m: sphere_r_m - depth_m,
        }
    }
    fn z(&self, x: f64, y: f64) -> f64 {
        let r2 = x * x + y * y;
        if r2 >= self.rim_m * self.rim_m {
            0.0
        } else {
            self.centre_z_m - (self.sphere_r_m * self.sphere_r_m - r2).sqrt()
        }
    }
    /// Closed-form shadow of a point on the bowl: the ray P + sL meets the sphere again at
    /// s = -2 (P - C)·L; the point is shadowed iff that second hit is below the rim plane
    /// (s <= 0 means the surface faces away from the light: also shadowed).
    fn shadowed(&self, x: f64, y: f64, l: [f64; 3]) -> bool {
        if x * x + y * y >= self.rim_m * self.rim_m {
            return false;
        }
        let p = [x, y, self.z(x, y)];
        let pc = [p[0], p[1], p[2] - self.centre_z_m];
        let s = -2.0 * (pc[0] * l[0] + pc[1] * l[1] + pc[2] * l[2]);
        p[2] + s * l[2] < 0.0
    }
}

#[test]
fn spherical_bowl_matches_closed_form_shadow() {
    let n = 128;
    let mut hf = HeightField::flat(n, n, 50.0);
    let bowl = Bowl::new(2000.0, 400.0);
    for r in 0..n {
        for c in 0..n {
            let (x, y) = hf.xy_from_row_col(r as f64, c as f64);
            hf.z_m[r * n + c] = bowl.z(x, y) as f32;
        }
    }
    for (az, el) in [(45.0, 15.0), (200.0, 10.0), (90.0, 8.0), (311.0, 12.0)] {
        let l = light_az_el(az, el);
        let analytic: Vec<u8> = (0..n * n)
            .map(|k| {
                let (x, y) = hf.xy_from_row_col((k / n) as f64, (k % n) as f64);
                if bowl.shadowed(x, y, l) {
                    MASK_SHADOW
                } else {
                    MASK_LIT
                }
            })
            .collect();
        let shadow_cells = analytic.iter().filter(|&&v| v == MASK_SHADOW).count();
        assert!(shadow_cells > 200, "az {az} el {el}: shadow too small");
        for engine in [Engine::Brute, Engine::Combined, Engine::Dp] {
            let mask = engine.hard_mask(&hf, 0.0, l).unwrap();
            let cmp = compare_masks(&analytic, &mask, n, n);
            eprintln!(
                "bowl az {az} el {el} {engine:?}: {:.3}% of {} cells differ ({} near edges)",
                cmp.disagree_percent(),
                cmp.compared,
                cmp.near_edge
            );
            assert_eq!(cmp.disagree, 0, "{engine:?} az {az} el {el}");
        }
    }
}

#[test]
fn smap_and_dp_hard_masks_match_brute_force_on_the_real_grid() {
    let Some(hf) = real_crop(192, 0, 0) else {
        return;
    };
    for el in ELEVATIONS_DEG {
        for az in AZIMUTHS_DEG {
            let l = light_az_el(az, el);
            let reference = penumbra::shadow::Engine::Brute
                .hard_mask(&hf, 2.0, l)
                .unwrap();
            for engine in [Engine::Combined, Engine::Dp] {
                let mask = engine.hard_mask(&hf, 2.0, l).unwrap();
                let cmp = compare_masks(&reference, &mask, hf.rows, hf.cols);
                eprintln!(
                    "real el {el} az {az} {engine:?}: {:.3}% differ of {} ({:.1}% shadow)",
                    cmp.disagree_percent(),
                    cmp.compared,
                    100.0 * cmp.shadow_share
                );
                assert!(
                    cmp.disagree_percent() <= 0.02,
                    "{engine:?} el {el} az {az}: {:.3}%",
                    cmp.disagree_percent()
                );
            }
        }
    }
}

/// Every third cell in both directions (1/9 of the grid) as sample cells, leaving out the
/// border rows/columns: there a disc straddles the grid's edge line, and the sample rays that
/// leave the grid at once are lit by convention while the prism model (one centre ray) cannot
/// see that (brute 0.5 vs DP 0 along an edge row for a light along it).
fn sample_cells(rows: usize, cols: usize) -> Vec<(usize, usize)> {
    (1..rows - 1)
        .step_by(3)
        .flat_map(|r| (1..cols - 1).step_by(3).map(move |c| (r, c)))
        .collect()
}

#[test]
fn dp_and_combined_fractions_match_brute_force_disc_sampling() {
    let Some(hf) = real_crop(96, -20, 30) else {
        return;
    };
    let cells = sample_cells(hf.rows, hf.cols);
    for (el, radius) in [
        (0.5, SUN_ANGULAR_RADIUS_RAD),
        (1.5, SUN_ANGULAR_RADIUS_RAD),
        (5.0, SUN_ANGULAR_RADIUS_RAD),
        (1.5, EARTH_ANGULAR_RADIUS_RAD),
    ] {
        for az in [37.0, 143.0, 270.0] {
            let l = light_az_el(az, el);
            let reference = brute::visible_fraction_at(&hf, 2.0, l, radius, 128, &cells).unwrap();
            let pick = |map: &[f32]| -> Vec<f32> {
                cells.iter().map(|&(r, c)| map[r * hf.cols + c]).collect()
            };
            let dp_map =
                dp::visible_fraction(&hf, 2.0, l, radius, &dp::DpConfig::default()).unwrap();
            let (combined, stats) = dp::soft_combined(&hf, 2.0, l, radius).unwrap();
            for (name, map) in [("dp", &dp_map), ("combined", &combined)] {
                let cmp = compare_fractions(&reference, &pick(map));
                eprintln!(
                    "fraction el {el} r {:.3}° az {az} {name}: mean {:.4} p99 {:.3} max {:.3} \
                     (DP cells {:.1}%)",
                    radius.to_degrees(),
                    cmp.mean_abs,
                    cmp.p99_abs,
                    cmp.max_abs,
                    100.0 * stats.dp_fraction()
                );
                assert!(
                    cmp.mean_abs <= 0.02,
                    "{name} el {el} az {az}: {}",
                    cmp.mean_abs
                );
            }
        }
    }
}

#[test]
fn dp_cost_is_exact_against_the_brute_force_cost() {
    // DP with branch and bound finds the same minimum cost as the exhaustive march, so its
    // fractions equal the exhaustive prism fractions (up to float rounding).
    let n = 80;
    let mut hf = HeightField::flat(n, n, 120.0);
    for r in 0..n {
        for c in 0..n {
            let (x, y) = (r as f64 * 0.37, c as f64 * 0.23);
            hf.z_m[r * n + c] =
                (300.0 * (x.sin() * y.cos()) + 120.0 * (0.5 * x + 1.3 * y).sin()) as f32;
        }
    }
    for (az, el) in [(37.0, 0.5), (143.0, 1.5), (270.0, 5.0), (0.0, 3.0)] {
        let l = light_az_el(az, el);
        let exact =
            brute::visible_fraction_exact_cost(&hf, 2.0, l, SUN_ANGULAR_RADIUS_RAD).unwrap();
        let dp =
            dp::visible_fraction(&hf, 2.0, l, SUN_ANGULAR_RADIUS_RAD, &Default::default()).unwrap();
        let cmp = compare_fractions(&exact, &dp);
        assert!(cmp.max_abs < 1e-4, "az {az} el {el}: max {}", cmp.max_abs);
        let greedy_cfg = dp::DpConfig {
            greedy: true,
            ..Default::default()
        };
        let greedy =
            dp::visible_fraction(&hf, 2.0, l, SUN_ANGULAR_RADIUS_RAD, &greedy_cfg).unwrap();
        let g = compare_fractions(&exact, &greedy);
        eprintln!(
            "greedy (paper) az {az} el {el}: mean {:.4} max {:.3}",
            g.mean_abs, g.max_abs
        );
        // The greedy path can only miss minima: its cost is >= the exact one.
        assert!(
            greedy.iter().zip(&exact).all(|(g, e)| *g >= *e - 1e-5),
            "greedy brighter than exact"
        );
    }
}

/// The accuracy table of docs/shadow.md, printed and asserted (≈ 13 s in release; the bounds
/// are those of docs/VALIDATION.md, over all 18 lights: SMap and DP masks ≤ 0.01 % of cells off
/// the brute-force mask; against 256-sample brute force, DP fractions mean |Δf| ≤ 0.001, p99 ≤
/// 0.02, max ≤ 0.1; combined mean ≤ 0.002, p99 ≤ 0.02 and ≤ 0.01 % of cells off by more than
/// 0.1 (its max is 1: where SMap's limb mask misses, the cell is wholly wrong, as SMap's mask):
/// `cargo test --release --test it shadow_accuracy_table -- --nocapture`
#[test]
fn shadow_accuracy_table() {
    let Some(hf) = real_crop(256, 0, 0) else {
        return;
    };
    let cells = sample_cells(hf.rows, hf.cols);
    let pick =
        |map: &[f32]| -> Vec<f32> { cells.iter().map(|&(r, c)| map[r * hf.cols + c]).collect() };
    println!(
        "| el° | az° | shadow % | SMap Δmask % | DP Δmask % | DP mean/p99 |Δf| (penumbra mean) \
         | combined mean/p99 | uniform 0.5 cell mean/p99 | uniform 1 cell mean/p99 | DP cells % |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    // Worst over the lights: SMap Δmask %, DP Δmask %, DP mean/p99/max, combined mean/p99/max.
    let mut worst = [0.0_f64; 8];
    // Combined: the share of sampled cells off by more than 0.1 (an SMap limb-mask miss makes a
    // cell fully wrong: SMap's own mask error, bounded like it).
    let mut worst_off_pct = 0.0_f64;
    for el in ELEVATIONS_DEG {
        for az in AZIMUTHS_DEG {
            let l = light_az_el(az, el);
            let r = SUN_ANGULAR_RADIUS_RAD;
            let reference = penumbra::shadow::Engine::Brute
                .hard_mask(&hf, 2.0, l)
                .unwrap();
            let smap = Engine::Combined.hard_mask(&hf, 2.0, l).unwrap();
            let dph = Engine::Dp.hard_mask(&hf, 2.0, l).unwrap();
            let cs = compare_masks(&reference, &smap, hf.rows, hf.cols);
            let cd = compare_masks(&reference, &dph, hf.rows, hf.cols);
            let soft = brute::visible_fraction_at(&hf, 2.0, l, r, 256, &cells).unwrap();
            let dp_map = dp::visible_fraction(&hf, 2.0, l, r, &Default::default()).unwrap();
            let (comb, stats) = dp::soft_combined(&hf, 2.0, l, r).unwrap();
            let u05 = brute::visible_fraction_uniform(&hf, 2.0, l, r, 0.5).unwrap();
            let u1 = brute::visible_fraction_uniform(&hf, 2.0, l, r, 1.0).unwrap();
            let f = |m: &[f32]| compare_fractions(&soft, &pick(m));
            let (fd, fc, f05, f1) = (f(&dp_map), f(&comb), f(&u05), f(&u1));
            println!(
                "| {el} | {az} | {:.1} | {:.3} | {:.3} | {:.4}/{:.3} ({:.3}) | {:.4}/{:.3} \
                 | {:.4}/{:.3} | {:.4}/{:.3} | {:.1} |",
                100.0 * cs.shadow_share,
                cs.disagree_percent(),
                cd.disagree_percent(),
                fd.mean_abs,
                fd.p99_abs,
                fd.mean_abs_penumbra,
                fc.mean_abs,
                fc.p99_abs,
                f05.mean_abs,
                f05.p99_abs,
                f1.mean_abs,
                f1.p99_abs,
                100.0 * stats.dp_fraction()
            );
            let picked = pick(&comb);
            let off = soft
                .iter()
                .zip(&picked)
                .filter(|(a, b)| (*a - *b).abs() > 0.1)
                .count();
            worst_off_pct = worst_off_pct.max(100.0 * off as f64 / soft.len() as f64);
            let now = [
                cs.disagree_percent(),
                cd.disagree_percent(),
                fd.mean_abs,
                fd.p99_abs,
                fd.max_abs,
                fc.mean_abs,
                fc.p99_abs,
                fc.max_abs,
            ];
            for (w, v) in worst.iter_mut().zip(now) {
                *w = w.max(v);
            }
        }
    }
    let [smap, dpm, dmean, dp99, dmax, cmean, cp99, cmax] = worst;
    println!(
        "worst of 18 lights: SMap Δmask {smap:.4} %, DP Δmask {dpm:.4} %; DP |Δf| mean {dmean:.5} \
         p99 {dp99:.4} max {dmax:.4}; combined mean {cmean:.5} p99 {cp99:.4} max {cmax:.4}, \
         {worst_off_pct:.4} % of cells off by > 0.1"
    );
    assert!(
        smap <= 0.01 && dpm <= 0.01,
        "masks: SMap {smap} %, DP {dpm} %"
    );
    assert!(
        dmean <= 0.001 && dp99 <= 0.02 && dmax <= 0.1,
        "DP fractions: mean {dmean} p99 {dp99} max {dmax}"
    );
    assert!(
        cmean <= 0.002 && cp99 <= 0.02 && worst_off_pct <= 0.01,
        "combined fractions: mean {cmean} p99 {cp99} max {cmax}, {worst_off_pct} % off by > 0.1"
    );
}

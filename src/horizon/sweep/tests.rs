//! Unit tests of the line sweep's lattice, template and arc helpers.

use super::arc::*;
use super::samples::*;
use super::*;

#[test]
fn small_angle_series_match_the_library() {
    for i in -1000..=1000 {
        let x = 0.3 * i as f64 / 1000.0;
        // The series' first omitted term is x^25 / 25 (3.4e-15 at 0.3).
        assert!((atan_small(x) - x.atan()).abs() < 4e-15, "{x}");
        let y = 2.0 * x;
        let (s, c) = sin_cos_small(y);
        assert!(
            (s - y.sin()).abs() < 1e-15 && (c - y.cos()).abs() < 1e-15,
            "{y}"
        );
    }
    assert_eq!(atan_small(2.0), 2f64.atan());
}

#[test]
fn arc_tracker_matches_the_direct_formulas() {
    let two_r_k0 = 2.0 * MOON_RADIUS_M;
    let l_m = two_r_k0.hypot(200e3);
    let geom = LineGeometry {
        ell: (1.0, 0.0),
        m_hat: (0.0, 1.0),
        d_m: 200e3,
        rho_c: two_r_k0 / l_m,
        l_m,
    };
    let mut arc = ArcTracker::new(&geom);
    let mut t = -450e3;
    while t < 450e3 {
        let (psi, s, c) = arc.at(t);
        let exact = geom.rho_c * 2.0 * (t / l_m).atan();
        assert!((psi - exact).abs() < 1e-15, "{t}");
        assert!((s - exact.sin()).abs() < 1e-15 && (c - exact.cos()).abs() < 1e-15);
        t += 137.0;
    }
}

#[test]
fn ext_gcd_solves_the_key_equation() {
    for (d_row, d_col) in [(0, 1), (-1, 0), (-3, 5), (7, 2), (-12, 5), (1, 1)] {
        let (g, a, b) = ext_gcd(d_row, -d_col);
        assert_eq!(g.abs(), 1);
        let (x0, y0) = (a * g, b * g);
        assert_eq!(x0 * d_row - y0 * d_col, 1, "{d_row} {d_col}");
    }
}

#[test]
fn m_range_is_the_inside_range() {
    for (a, b, n) in [
        (3, 2, 10),
        (3, -2, 10),
        (-5, 3, 10),
        (12, -3, 10),
        (4, 0, 10),
    ] {
        let brute: Vec<i64> = (-50..50)
            .filter(|m| (0..n).contains(&(a + m * b)))
            .collect();
        let (lo, hi) = m_range(a, b, n).unwrap();
        if b == 0 {
            assert!(!brute.is_empty());
            continue;
        }
        assert_eq!((lo, hi), (*brute.first().unwrap(), *brute.last().unwrap()));
    }
}

#[test]
fn template_samples_are_on_the_line() {
    let cols = 100;
    for (d_row, d_col) in [(-5, 12), (3, 7), (0, 1), (-1, 0), (4, 1)] {
        let t = step_template(d_row, d_col, cols);
        let crossings = t.iter().filter(|e| e.crossing).count() as i64;
        // The pixel centre plus the |dc| - 1 column and |dr| - 1 row crossings between.
        assert_eq!(crossings, (d_row.abs() + d_col.abs() - 1).max(1));
        assert_eq!(t.len() as i64, 2 * crossings);
        for e in &t {
            let (row, col) = (e.f * d_row as f64, e.f * d_col as f64);
            if e.crossing {
                let on_col = (col - col.round()).abs() < 1e-12;
                let on_row = (row - row.round()).abs() < 1e-12;
                assert!(on_col || on_row);
            }
            // The weighted cells reproduce the point (row, col) and stay in the step's box.
            let (mut pr, mut pc, mut ws) = (0.0, 0.0, 0.0);
            for k in 0..4 {
                let (r, c) = (
                    e.off[k].div_euclid(cols as isize),
                    e.off[k].rem_euclid(cols as isize),
                );
                let (r, c) = if c > 50 { (r + 1, c - 100) } else { (r, c) };
                assert!(r >= d_row.min(0) as isize && r <= d_row.max(0) as isize);
                assert!(c >= d_col.min(0) as isize && c <= d_col.max(0) as isize);
                pr += e.w[k] * r as f64;
                pc += e.w[k] * c as f64;
                ws += e.w[k];
            }
            assert!((ws - 1.0).abs() < 1e-12);
            assert!(
                (pr - row).abs() < 1e-12 && (pc - col).abs() < 1e-12,
                "{e:?}"
            );
        }
    }
}

#[test]
fn directions_cover_the_requested_azimuths() {
    let dirs = sweep_directions(720, 16, 240.0, 240.0);
    assert!(dirs.len() > 300, "{}", dirs.len());
    let worst = dirs.iter().map(|d| d.target_error_deg).fold(0.0, f64::max);
    // Next to the axes the steps go on to (64, 1): 0.895 deg off the axis, so up to half of that
    // for the targets in between (without them (16, 1) left 3.58 deg: up to 1.79 deg off).
    assert!(worst < 0.9, "{worst}");
    // Gaps between neighbouring directions: 0.9° next to the axes (where the Earth is on a
    // map centred on longitude 0), 1.85° next to the diagonals ((1, 1) and (16, 15)).
    let gaps: Vec<(f64, f64)> = dirs
        .windows(2)
        .map(|w| (w[0].grid_az_deg, w[1].grid_az_deg - w[0].grid_az_deg))
        .collect();
    let near_axis = |a: f64| (a + 10.0).rem_euclid(90.0) < 20.0;
    let axis_gap = gaps
        .iter()
        .filter(|g| near_axis(g.0))
        .fold(0.0_f64, |m, g| m.max(g.1));
    let any_gap = gaps.iter().fold(0.0_f64, |m, g| m.max(g.1));
    assert!(axis_gap < 0.9, "largest gap next to an axis {axis_gap} deg");
    assert!(any_gap < 1.9, "largest gap {any_gap} deg");
    assert!(dirs.iter().any(|d| (d.dcol, d.dnorth) == (1, 64)));
    for d in &dirs {
        let az = grid_az_deg(d.dcol, d.dnorth, 240.0, 240.0);
        assert!((az - d.grid_az_deg).abs() < 1e-12);
    }
}

#[test]
fn psi_is_the_arc_of_the_circle() {
    // A line at distance d from the pole: compare ψ(t) with the arc between the unit vectors.
    let proj = Projection::LOLA_SOUTH_POLAR;
    let up = UnitProjector::new(&proj);
    let Projection::PolarStereographic { k0, radius_m, .. } = proj else {
        unreachable!()
    };
    let two_r_k0 = 2.0 * radius_m * k0;
    for d_m in [0.0, 50e3, 250e3] {
        let l_m = two_r_k0.hypot(d_m);
        let geom = LineGeometry {
            ell: (0.6, 0.8),
            m_hat: (-0.8, 0.6),
            d_m,
            rho_c: two_r_k0 / l_m,
            l_m,
        };
        let (ta, tb) = (-100e3, 350e3);
        let (pa, pb) = (geom.point(ta), geom.point(tb));
        let (ua, ub) = (up.unit_from_xy(pa.0, pa.1), up.unit_from_xy(pb.0, pb.1));
        // Chord of the circle of radius ρc for the arc ψb − ψa.
        let dpsi = geom.psi_rad(tb) - geom.psi_rad(ta);
        let chord = 2.0 * geom.rho_c * (dpsi / (2.0 * geom.rho_c)).sin();
        assert!(((ua - ub).norm() - chord).abs() < 1e-12, "d {d_m}");
    }
}

/// The samples `refine_piece` keeps leave no point of the piece's exact curve (the bilinear
/// quadratic on the sphere, in 3-D) more than the tolerance above the chord between the kept
/// samples: checked by dense evaluation of the curve in the plane of the line, not by the
/// function's own rise formula.
#[test]
fn refined_pieces_stay_within_the_tolerance_of_their_chords() {
    let r_m = MOON_RADIUS_M;
    let plane = |t: f64, h: f64| ((r_m + h) * (t / r_m).sin(), (r_m + h) * (t / r_m).cos());
    let mut kept_fewer = 0;
    for (len_m, ha, hm, hb, tol_m) in [
        (170.0, 0.0, 0.0, 0.0, SAG_TOLERANCE_M),
        (170.0, 10.0, 16.0, 20.0, SAG_TOLERANCE_M),
        (170.0, 10.0, 14.0, 20.0, SAG_TOLERANCE_M),
        (1_800.0, 0.0, 0.0, 0.0, SAG_TOLERANCE_M),
        (1_800.0, 0.0, 0.0, 0.0, sag_tolerance_m(50_000.0)),
        (2_500.0, 300.0, 420.0, 500.0, sag_tolerance_m(20_000.0)),
        (2_500.0, 300.0, 380.0, 500.0, sag_tolerance_m(20_000.0)),
        (1_200.0, -50.0, -40.0, -45.0, sag_tolerance_m(300_000.0)),
    ] {
        let (a, b) = ((1_000.0, ha), (1_000.0 + len_m, hb));
        let mut kept = vec![a];
        refine_piece(a, hm, b, tol_m, |t, h| kept.push((t, h)));
        kept.push(b);
        if kept.len() == 2 {
            kept_fewer += 1;
        }
        // The exact curve: the quadratic through the ends and the midpoint.
        let q = 2.0 * (ha - 2.0 * hm + hb);
        let p = hb - ha - q;
        let mut worst: f64 = 0.0;
        for k in 0..=2000 {
            let u = k as f64 / 2000.0;
            let (t, h) = (a.0 + u * len_m, ha + p * u + q * u * u);
            let (x, y) = plane(t, h);
            let i = kept.partition_point(|s| s.0 <= t).clamp(1, kept.len() - 1);
            let (p0, p1) = (
                plane(kept[i - 1].0, kept[i - 1].1),
                plane(kept[i].0, kept[i].1),
            );
            // Height of the curve point above the chord, along the chord's normal ("up").
            let (dx, dy) = (p1.0 - p0.0, p1.1 - p0.1);
            let above = (dx * (y - p0.1) - dy * (x - p0.0)) / dx.hypot(dy);
            worst = worst.max(above);
        }
        assert!(
            worst <= tol_m * 1.001 + 1e-6,
            "piece {len_m} m ({ha}, {hm}, {hb}): {} samples leave {worst} m above the chords (tolerance {tol_m} m)",
            kept.len()
        );
    }
    // Some pieces need no interior sample at all (the point of the tolerance).
    assert!(kept_fewer >= 3, "{kept_fewer}");
}

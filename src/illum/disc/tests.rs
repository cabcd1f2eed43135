//! Unit tests of the disc visibility integrals.

use super::*;

const SUN_R_DEG: f64 = 0.267;

fn flat(n: usize, el: f64) -> Vec<f64> {
    vec![el; n]
}

/// A rough horizon of `n` samples, `el0 + a sin(k fa) + b cos(k fb)` degrees at sample `k`.
fn rough(n: usize, el0: f64, (a, fa): (f64, f64), (b, fb): (f64, f64)) -> Vec<f64> {
    (0..n)
        .map(|k| el0 + a * (k as f64 * fa).sin() + b * (k as f64 * fb).cos())
        .collect()
}

/// The quadratic law `I(μ)/I(1) = 1 - u1(1-μ) - u2(1-μ)²`.
fn quadratic(u1: f64, u2: f64) -> LimbDarkening {
    LimbDarkening {
        c0: 1.0 - u1 - u2,
        c1: u1 + 2.0 * u2,
        c2: -u2,
    }
}

/// Relative intensity `I(μ)/I(1)` of `limb`.
fn intensity(limb: &LimbDarkening, mu: f64) -> f64 {
    limb.c0 + limb.c1 * mu + limb.c2 * mu * mu
}

fn methods() -> [DiscMethod; 3] {
    [
        DiscMethod::Exact,
        DiscMethod::Segment,
        DiscMethod::MiddleValue,
    ]
}

/// Closed-form visible fraction of a uniform disc under a horizontal line at `d` (deg).
fn segment_oracle(d: f64, r: f64) -> f64 {
    let x = (d / r).clamp(-1.0, 1.0);
    (x.acos() - x * (1.0 - x * x).sqrt()) / std::f64::consts::PI
}

#[test]
fn gauss_legendre_integrates_polynomials_exactly() {
    let (x, w) = gauss_legendre(GL_NODES);
    for k in 0..(2 * GL_NODES) {
        let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
        let want = if k % 2 == 1 {
            0.0
        } else {
            2.0 / (k as f64 + 1.0)
        };
        assert!((got - want).abs() < 1e-13, "k={k}: {got} vs {want}");
    }
}

#[test]
fn interpolation_is_linear_and_periodic() {
    let el = [0.0, 1.0, 2.0, 3.0];
    let h = HorizonProfile::new(&el).unwrap();
    assert_eq!(h.az_step_deg(), 90.0);
    assert!((h.el_at_az_deg(45.0) - 0.5).abs() < 1e-15);
    assert!((h.el_at_az_deg(315.0) - 1.5).abs() < 1e-15);
    assert!((h.el_at_az_deg(-45.0) - 1.5).abs() < 1e-15);
    assert!((h.el_at_az_deg(405.0) - 0.5).abs() < 1e-15);
}

#[test]
fn bad_profiles_are_errors() {
    assert!(matches!(
        HorizonProfile::new(&[]),
        Err(IllumError::EmptyHorizon)
    ));
    assert!(matches!(
        HorizonProfile::new(&[0.0, f64::NAN]),
        Err(IllumError::NonFiniteHorizon { index: 1, .. })
    ));
}

#[test]
fn flat_horizon_full_empty_and_half() {
    let el = flat(1440, 1.5);
    let h = HorizonProfile::new(&el).unwrap();
    for m in methods() {
        for limb in [LimbDarkening::UNIFORM, LimbDarkening::EDDINGTON] {
            let up = Disc {
                az_deg: 123.4,
                el_deg: 1.5 + 0.3,
                radius_deg: SUN_R_DEG,
            };
            let down = Disc {
                el_deg: 1.5 - 0.3,
                ..up
            };
            let half = Disc { el_deg: 1.5, ..up };
            assert_eq!(visible_fraction(&h, &up, m, &limb), 1.0, "{m:?}");
            assert_eq!(visible_fraction(&h, &down, m, &limb), 0.0, "{m:?}");
            let f = visible_fraction(&h, &half, m, &limb);
            // Uniform: closed forms (rounding only). Limb-darkened: Gauss–Legendre error,
            // measured 7e-9 with 8 nodes per piece (Exact), < 1e-12 with 16 (chord path).
            let tol = if limb.is_uniform() { 1e-12 } else { 2e-8 };
            assert!((f - 0.5).abs() < tol, "{m:?} {limb:?}: {f}");
        }
    }
}

#[test]
fn flat_horizon_at_height_d_is_circular_segment() {
    let el = flat(1440, 0.0);
    let h = HorizonProfile::new(&el).unwrap();
    for r in [SUN_R_DEG, 0.95] {
        for i in -10..=10 {
            let d = r * f64::from(i) / 10.0 * 0.999;
            // Centre at -d so the horizon (0°) is at height d above the centre.
            let disc = Disc {
                az_deg: 77.7,
                el_deg: -d,
                radius_deg: r,
            };
            let want = segment_oracle(d, r);
            for m in methods() {
                let got = visible_fraction(&h, &disc, m, &LimbDarkening::UNIFORM);
                assert!(
                    (got - want).abs() < 1e-12,
                    "{m:?} r={r} d={d}: {got} vs {want}"
                );
            }
        }
    }
}

/// A step horizon: height d1 left of the disc centre's azimuth and d2 right of it. With the
/// centre azimuth exactly half-way between two samples, the linear ramp between them is
/// symmetric about the centre and (both heights inside the chord there) gives exactly the
/// area of the ideal step: (segment(d1) + segment(d2)) / 2 by the mirror symmetry of each half.
#[test]
fn step_horizon_exact_matches_closed_form_and_segment_does_not() {
    let n = 36_000; // 0.01° steps
    let step = 360.0 / n as f64;
    let k_step = 18_000; // the ramp between samples k_step-1 and k_step
    let (h1, h2) = (0.25, -0.1); // left, right (deg), relative to el_c = 0; both inside r
    let el: Vec<f64> = (0..n).map(|k| if k < k_step { h1 } else { h2 }).collect();
    let h = HorizonProfile::new(&el).unwrap();
    let r = SUN_R_DEG;
    let disc = Disc {
        az_deg: (k_step as f64 - 0.5) * step,
        el_deg: 0.0,
        radius_deg: r,
    };
    let want = 0.5 * (segment_oracle(h1, r) + segment_oracle(h2, r));
    let exact = visible_fraction(&h, &disc, DiscMethod::Exact, &LimbDarkening::UNIFORM);
    assert!((exact - want).abs() < 1e-12, "exact {exact} vs {want}");
    let seg = visible_fraction(&h, &disc, DiscMethod::Segment, &LimbDarkening::UNIFORM);
    // The segment line joins (-r, h1) and (r, h2): its distance from the centre is
    // ((h1+h2)/2)/sqrt(1+k²), k = (h2-h1)/(2r).
    let k = (h2 - h1) / (2.0 * r);
    let seg_want = segment_oracle(0.5 * (h1 + h2) / (1.0 + k * k).sqrt(), r);
    assert!(
        (seg - seg_want).abs() < 1e-12,
        "segment {seg} vs {seg_want}"
    );
    assert!(
        (seg - exact).abs() > 0.01,
        "the step must separate the methods: exact {exact}, segment {seg}"
    );
}

/// A sloped straight horizon: the segment method is exact (its line is the horizon), the
/// middle value is not; both against the closed form with the tilted line's distance.
#[test]
fn sloped_horizon_segment_is_exact() {
    let n = 1440;
    let slope_deg_per_deg = 0.02;
    // A triangle wave, linear on [0°, 180°]: el = 1 + 0.02 · az there.
    let el: Vec<f64> = (0..n)
        .map(|i| {
            let az = i as f64 * 0.25;
            1.0 + slope_deg_per_deg * if az <= 180.0 { az } else { 360.0 - az }
        })
        .collect();
    let h = HorizonProfile::new(&el).unwrap();
    for r in [SUN_R_DEG, 0.95] {
        let az = 90.1;
        let el_c = h.el_at_az_deg(az) - 0.3 * r;
        let disc = Disc {
            az_deg: az,
            el_deg: el_c,
            radius_deg: r,
        };
        // In tangent coordinates the horizon is y = (h(az) - el_c) + (slope / cos el_c) u.
        let k = slope_deg_per_deg / el_c.to_radians().cos();
        let d = (h.el_at_az_deg(az) - el_c) / (1.0 + k * k).sqrt();
        let want = segment_oracle(d, r);
        let u = LimbDarkening::UNIFORM;
        let exact = visible_fraction(&h, &disc, DiscMethod::Exact, &u);
        let seg = visible_fraction(&h, &disc, DiscMethod::Segment, &u);
        let mid = visible_fraction(&h, &disc, DiscMethod::MiddleValue, &u);
        assert!((exact - want).abs() < 1e-12, "exact {exact} vs {want}");
        assert!((seg - want).abs() < 1e-12, "segment {seg} vs {want}");
        // The middle value ignores the tilt: its error is the 1/sqrt(1+k²) factor only,
        // tiny for a 0.02 slope but not zero.
        assert!((mid - want).abs() > 1e-7, "middle {mid} vs {want}");
    }
}

/// A uniform law through the Gauss–Legendre path agrees with the closed form.
/// (The integrand is then a trigonometric polynomial of low degree in θ on each piece.)
#[test]
fn gauss_legendre_path_matches_closed_form() {
    let el = rough(1440, 1.0, (0.4, 0.37), (0.2, 1.3));
    let h = HorizonProfile::new(&el).unwrap();
    // A "uniform" law written so that is_uniform() is false: c1 μ with c1 = 1e-300.
    let almost = LimbDarkening {
        c0: 1.0,
        c1: 1e-300,
        c2: 0.0,
    };
    let mut max_err: f64 = 0.0;
    for i in 0..400 {
        let disc = Disc {
            az_deg: i as f64 * 0.9,
            el_deg: 0.6 + 0.002 * i as f64,
            radius_deg: if i % 2 == 0 { SUN_R_DEG } else { 0.95 },
        };
        let a = visible_fraction(&h, &disc, DiscMethod::Exact, &LimbDarkening::UNIFORM);
        let b = visible_fraction(&h, &disc, DiscMethod::Exact, &almost);
        max_err = max_err.max((a - b).abs());
    }
    println!("max |closed form - GL{GL_NODES}| = {max_err:e}");
    assert!(max_err < 1e-12, "max |closed form - GL| = {max_err:e}");
}

/// Convergence of the limb-darkened Gauss–Legendre integral: 8 and 16 nodes per piece
/// against 32, over partially covered discs on a rough horizon.
#[test]
fn limb_darkened_gauss_legendre_convergence() {
    let el = rough(1440, 1.0, (0.4, 0.37), (0.2, 1.3));
    let h = HorizonProfile::new(&el).unwrap();
    let (mut err8, mut err16): (f64, f64) = (0.0, 0.0);
    for i in 0..2000 {
        let r = if i % 2 == 0 { SUN_R_DEG } else { 0.95 };
        let az = i as f64 * 0.1791;
        let disc = Disc {
            az_deg: az,
            el_deg: h.el_at_az_deg(az) + r * ((i * 37 % 200) as f64 / 100.0 - 1.0),
            radius_deg: r,
        };
        let limb = LimbDarkening::EDDINGTON;
        let f32_ = visible_fraction_exact(&h, &disc, &limb, 32);
        err8 = err8.max((visible_fraction_exact(&h, &disc, &limb, 8) - f32_).abs());
        err16 = err16.max((visible_fraction_exact(&h, &disc, &limb, 16) - f32_).abs());
    }
    println!("limb-darkened GL: max |n8 - n32| = {err8:e}, max |n16 - n32| = {err16:e}");
    // 8 nodes (the default, GL_NODES) is well below the tangent-plane error (~1e-4).
    assert!(err8 < 2e-6 && err16 < 1e-7, "{err8:e} {err16:e}");
}

/// Brute-force oracle: midpoint quadrature over the disc in polar coordinates.
fn brute_force_fraction(h: &HorizonProfile<'_>, disc: &Disc, limb: &LimbDarkening) -> f64 {
    let (n_rho, n_phi) = (800, 1600);
    let r = disc.radius_deg;
    let cos_el = disc.el_deg.to_radians().cos();
    let (mut vis, mut tot) = (0.0, 0.0);
    for i in 0..n_rho {
        let rho = (i as f64 + 0.5) / n_rho as f64;
        let mu = (1.0 - rho * rho).sqrt();
        let w = intensity(limb, mu) * rho;
        for j in 0..n_phi {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / n_phi as f64;
            let (u, y) = (r * rho * phi.cos(), r * rho * phi.sin());
            tot += w;
            if y > h.el_at_az_deg(disc.az_deg + u / cos_el) - disc.el_deg {
                vis += w;
            }
        }
    }
    vis / tot
}

#[test]
fn limb_darkened_exact_matches_brute_force() {
    let el = rough(1440, 1.0, (0.3, 0.41), (0.25, 2.1));
    let h = HorizonProfile::new(&el).unwrap();
    for (i, limb) in [LimbDarkening::EDDINGTON, LimbDarkening::ALLEN_550NM]
        .iter()
        .enumerate()
    {
        let disc = Disc {
            az_deg: 200.13 + 3.0 * i as f64,
            el_deg: 1.05,
            radius_deg: SUN_R_DEG,
        };
        let got = visible_fraction(&h, &disc, DiscMethod::Exact, limb);
        let want = brute_force_fraction(&h, &disc, limb);
        println!(
            "{limb:?}: exact {got} brute force {want} diff {:e}",
            got - want
        );
        // Brute force: 800×1600 midpoint cells; its own error is ~1e-5 (boundary cells).
        assert!((got - want).abs() < 5e-5, "{limb:?}: {got} vs brute {want}");
        assert!(got > 0.05 && got < 0.95, "a partial case: {got}");
    }
}

#[test]
fn limb_darkening_laws_normalise() {
    let el = flat(360, -5.0);
    let h = HorizonProfile::new(&el).unwrap();
    for limb in [
        LimbDarkening::EDDINGTON,
        LimbDarkening::ALLEN_550NM,
        quadratic(0.47, 0.23),
    ] {
        assert!((intensity(&limb, 1.0) - 1.0).abs() < 1e-12, "I(1) = 1");
        // A chord below the whole disc: the full flux, 1 (the GL path, not an early exit).
        let f = chord_visible_fraction(-0.999_999, &limb);
        assert!((f - 1.0).abs() < 1e-6, "{limb:?}: {f}");
        // Through the exact path with the disc just touching the horizon.
        let disc = Disc {
            az_deg: 10.0,
            el_deg: -5.0 + SUN_R_DEG * 0.999_999,
            radius_deg: SUN_R_DEG,
        };
        let f = visible_fraction(&h, &disc, DiscMethod::Exact, &limb);
        assert!((f - 1.0).abs() < 1e-6, "{limb:?}: {f}");
    }
    let q = quadratic(0.47, 0.23);
    let allen = LimbDarkening::ALLEN_550NM;
    for (a, b) in [(q.c0, allen.c0), (q.c1, allen.c1), (q.c2, allen.c2)] {
        assert!(
            (a - b).abs() < 1e-12,
            "quadratic(0.47, 0.23) = Allen 550 nm"
        );
    }
    // Limb darkening makes a thin top segment dimmer than its area share.
    for d in [0.5, 0.8, 0.95] {
        let ld = chord_visible_fraction(d, &LimbDarkening::EDDINGTON);
        let uni = chord_visible_fraction(d, &LimbDarkening::UNIFORM);
        assert!(ld < uni, "d={d}: {ld} !< {uni}");
    }
}

#[test]
fn point_disc_is_binary() {
    let el = flat(360, 0.0);
    let h = HorizonProfile::new(&el).unwrap();
    let d = Disc {
        az_deg: 0.0,
        el_deg: 0.01,
        radius_deg: 0.0,
    };
    assert_eq!(
        visible_fraction(&h, &d, DiscMethod::Exact, &LimbDarkening::UNIFORM),
        1.0
    );
}

/// The tangent-plane approximation vs the true spherical cap: brute-force quadrature over the
/// cap on the unit sphere, each point's exact (az, el) tested against the horizon.
#[test]
fn tangent_plane_error_vs_sphere() {
    let el = rough(1440, 8.0, (1.5, 0.05), (0.3, 0.7));
    let h = HorizonProfile::new(&el).unwrap();
    for (r, tol) in [(SUN_R_DEG, 2e-4), (1.0, 1e-3)] {
        let disc = Disc {
            az_deg: 101.3,
            el_deg: h.el_at_az_deg(101.3) + 0.2 * r,
            radius_deg: r,
        };
        let tangent = visible_fraction(&h, &disc, DiscMethod::Exact, &LimbDarkening::UNIFORM);
        let sphere = sphere_cap_fraction(&h, &disc);
        println!(
            "r={r}: tangent {tangent} sphere {sphere} diff {:e}",
            tangent - sphere
        );
        assert!(
            (tangent - sphere).abs() < tol,
            "r={r}: tangent {tangent} vs sphere {sphere}"
        );
        assert!(tangent > 0.05 && tangent < 0.95, "partial: {tangent}");
    }
}

fn sphere_cap_fraction(h: &HorizonProfile<'_>, disc: &Disc) -> f64 {
    let (az, el) = (disc.az_deg.to_radians(), disc.el_deg.to_radians());
    // ENU unit vectors: centre direction c, and two tangent directions e1 (az), e2 (el).
    let c = [el.cos() * az.sin(), el.cos() * az.cos(), el.sin()];
    let e1 = [az.cos(), -az.sin(), 0.0];
    let e2 = [-el.sin() * az.sin(), -el.sin() * az.cos(), el.cos()];
    let r = disc.radius_deg.to_radians();
    let (n_rho, n_phi) = (1000, 2000);
    let (mut vis, mut tot) = (0.0, 0.0);
    for i in 0..n_rho {
        let rho = r * (i as f64 + 0.5) / n_rho as f64;
        let w = rho.sin();
        for j in 0..n_phi {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / n_phi as f64;
            let (s, co) = (rho.sin(), rho.cos());
            let p: Vec<f64> = (0..3)
                .map(|k| c[k] * co + s * (phi.cos() * e1[k] + phi.sin() * e2[k]))
                .collect();
            let p_el = p[2].clamp(-1.0, 1.0).asin().to_degrees();
            let p_az = p[0].atan2(p[1]).to_degrees();
            tot += w;
            if p_el > h.el_at_az_deg(p_az) {
                vis += w;
            }
        }
    }
    vis / tot
}

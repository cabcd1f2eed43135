use super::kernel::atan2_deg;
use super::*;

/// A small deterministic generator (xorshift) for test inputs.
fn rng(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn atan2_deg_matches_f64() {
    let mut r = rng(7);
    let mut worst = 0.0_f64;
    for _ in 0..200_000 {
        let (y, x) = (2.0 * r() - 1.0, 2.0 * r() - 1.0);
        let scale = 10f64.powf(8.0 * r() - 2.0);
        let (y, x) = (y * scale, x * scale);
        let got = f64::from(atan2_deg(y as f32, x as f32));
        let want = (y as f32 as f64).atan2(x as f32 as f64).to_degrees();
        let mut d = (got - want).abs();
        if d > 180.0 {
            d = 360.0 - d;
        }
        worst = worst.max(d);
    }
    // The polynomial is good to 2.2e-6°; f32 rounding of the result near ±180° (one ulp of π is
    // 1.4e-5°) dominates.
    assert!(worst < 5e-5, "worst atan2 error {worst:e} deg");
    assert_eq!(atan2_deg(0.0, 0.0), 0.0);
    assert!((atan2_deg(1.0, 0.0) - 90.0).abs() < 1e-5);
    assert!((atan2_deg(0.0, -1.0) - 180.0).abs() < 1e-5);
    assert!((atan2_deg(-1.0, 0.0) + 90.0).abs() < 1e-5);
}

#[test]
fn azimuth_lookup_interpolates_between_non_uniform_bands() {
    let mut r = rng(11);
    // Non-uniform azimuths (gaps 0.2 … 2.2 deg), starting off zero.
    let mut az = Vec::new();
    let mut a = 0.7;
    while a < 359.0 {
        az.push(a);
        a += 0.2 + 2.0 * r();
    }
    let n = az.len();
    let h: Vec<f32> = (0..n).map(|_| (10.0 * r() - 3.0) as f32).collect();
    let mut hh = h.clone();
    hh.push(h[0]);
    let lookup = AzimuthLookup::new(&az).expect("valid azimuths");
    assert_eq!(lookup.n_bands(), n);
    // Brute force: find the segment (with wrap) and interpolate in f64.
    let want = |q: f64| -> f64 {
        let q = q.rem_euclid(360.0);
        for k in 0..n {
            let (a0, a1) = (az[k], if k + 1 < n { az[k + 1] } else { az[0] + 360.0 });
            for qq in [q, q + 360.0] {
                if qq >= a0 && qq < a1 {
                    let w = (qq - a0) / (a1 - a0);
                    return f64::from(h[k]) * (1.0 - w) + f64::from(h[(k + 1) % n]) * w;
                }
            }
        }
        unreachable!("every azimuth is in a segment")
    };
    let mut worst = 0.0_f64;
    for _ in 0..100_000 {
        let q = 1000.0 * r() - 500.0;
        let got = f64::from(lookup.horizon_deg(&hh, q as f32));
        worst = worst.max((got - want(f64::from(q as f32))).abs());
    }
    // f32 azimuths (an ulp of 360° is 3e-5°) times horizon slopes of up to 50 deg/deg here.
    assert!(worst < 3e-3, "worst lookup error {worst:e} deg");
    // At the bands themselves, the band values.
    for (k, &a) in az.iter().enumerate() {
        let got = lookup.horizon_deg(&hh, a as f32);
        assert!((got - h[k]).abs() < 1e-3, "band {k}: {got} vs {}", h[k]);
    }
    assert!(AzimuthLookup::new(&[10.0, 5.0]).is_none());
    assert!(AzimuthLookup::new(&[10.0, 360.0]).is_none());
    assert!(AzimuthLookup::new(&[10.0]).is_none());
}

#[test]
fn chord_table_matches_the_strip_integral() {
    for limb in [LimbDarkening::UNIFORM, LimbDarkening::EDDINGTON] {
        let table = ChordTable::new(&limb);
        let mut worst = 0.0_f64;
        for i in 0..=20_000 {
            let x = -1.1 + 2.2 * f64::from(i) / 20_000.0;
            let want = crate::illum::chord_visible_fraction(x, &limb);
            let got = f64::from(table.fraction(x as f32));
            let want_at_f32 = crate::illum::chord_visible_fraction(f64::from(x as f32), &limb);
            worst = worst.max((got - want_at_f32).abs().min((got - want).abs()));
        }
        assert!(worst < 1e-5, "{limb:?}: worst table error {worst:e}");
        assert_eq!(table.fraction(1.0), 0.0);
        assert_eq!(table.fraction(-1.0), 1.0);
    }
}

//! The turning Earth: ground stations' positions in J2000 (GCRS axes) at UTC epochs.
//!
//! `r_gcrs = C2T(t)ᵀ · r_itrs`, `C2T = R3(GST) · NPB`, the equinox-based form of IERS Conventions
//! 2010 ch. 5: `NPB` from the IAU 2006 Fukushima–Williams precession angles (frame bias included)
//! and the IAU 2000B nutation (McCarthy & Luzum 2003, 77 luni-solar terms; 1 mas), `GST` the IAU
//! 2006 Greenwich mean sidereal time plus the equation of the equinoxes `Δψ cos ε_A`. UT1 is taken
//! equal to UTC (|UT1 − UTC| < 0.9 s: ≤ 0.0038° of Earth rotation) and polar motion is left out
//! (≤ 0.5″); a station's elevation of a target is then good to ≈ 0.004°, which
//! `python/tests/test_stations.py` checks against astropy (IAU 2006/2000A with IERS UT1 and polar
//! motion). Station coordinates are geodetic on WGS84. Conventions: `docs/comms.md`.

use hifitime::Epoch;
use nalgebra::{Matrix3, Vector3};

/// WGS84 equatorial radius, metres.
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);
/// 0.1 microarcsecond in radians (the unit of the nutation table).
const U2R: f64 = ARCSEC / 1e7;

/// Position (m) in the ITRS of a point at geodetic latitude / east longitude (deg) and height
/// above the WGS84 ellipsoid (m).
pub fn itrs_from_geodetic_m(lat_deg: f64, lon_deg: f64, height_m: f64) -> Vector3<f64> {
    let (sl, cl) = lat_deg.to_radians().sin_cos();
    let (so, co) = lon_deg.to_radians().sin_cos();
    let e2 = WGS84_F * (2.0 - WGS84_F);
    let n = WGS84_A_M / (1.0 - e2 * sl * sl).sqrt();
    Vector3::new(
        (n + height_m) * cl * co,
        (n + height_m) * cl * so,
        (n * (1.0 - e2) + height_m) * sl,
    )
}

/// The ellipsoid's outward normal (the local "up") at geodetic latitude / east longitude (deg),
/// ITRS.
pub fn itrs_up(lat_deg: f64, lon_deg: f64) -> Vector3<f64> {
    let (sl, cl) = lat_deg.to_radians().sin_cos();
    let (so, co) = lon_deg.to_radians().sin_cos();
    Vector3::new(cl * co, cl * so, sl)
}

/// Passive rotation about x by `a` (SOFA `Rx`).
fn rx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, s, 0.0, -s, c)
}

/// Passive rotation about z by `a` (SOFA `Rz`).
fn rz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Horner evaluation of `Σ c_i t^i`, arcseconds → radians.
fn poly_arcsec(c: &[f64], t: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ci| acc * t + ci) * ARCSEC
}

/// IAU 2006 Fukushima–Williams angles `(γ̄, φ̄, ψ̄, ε_A)`, radians, at `t` Julian centuries of TT
/// since J2000 (IERS Conventions 2010, eqs. 5.39–5.40).
fn precession_angles(t: f64) -> (f64, f64, f64, f64) {
    let gamb = poly_arcsec(
        &[
            -0.052928,
            10.556378,
            0.493_204_4,
            -0.000_312_38,
            -0.000_002_788,
            0.000_000_026_0,
        ],
        t,
    );
    let phib = poly_arcsec(
        &[
            84_381.412_819,
            -46.811016,
            0.051_126_8,
            0.000_532_89,
            -0.000_000_440,
            -0.000_000_017_6,
        ],
        t,
    );
    let psib = poly_arcsec(
        &[
            -0.041775,
            5038.481484,
            1.558_417_5,
            -0.000_185_22,
            -0.000_026_452,
            -0.000_000_014_8,
        ],
        t,
    );
    let epsa = poly_arcsec(
        &[
            84_381.406,
            -46.836769,
            -0.000_183_1,
            0.002_003_40,
            -0.000_000_576,
            -0.000_000_043_4,
        ],
        t,
    );
    (gamb, phib, psib, epsa)
}

/// One luni-solar term of IAU 2000B: multipliers of `l, l', F, D, Ω`, then the longitude's
/// `sin`, `t·sin` and `cos` coefficients and the obliquity's `cos`, `t·cos` and `sin`
/// coefficients, in 0.1 µas (and per century).
type NutationTerm = ([i8; 5], [f64; 6]);

/// IAU 2000B luni-solar nutation (McCarthy & Luzum 2003, Celest. Mech. Dyn. Astron. 85, 37,
/// table 1), largest terms first.
#[rustfmt::skip]
const NUTATION_2000B: [NutationTerm; 77] = [
    ([0, 0, 0, 0, 1], [-172_064_161.0, -174_666.0, 33_386.0, 92_052_331.0, 9_086.0, 15_377.0]),
    ([0, 0, 2, -2, 2], [-13_170_906.0, -1_675.0, -13_696.0, 5_730_336.0, -3_015.0, -4_587.0]),
    ([0, 0, 2, 0, 2], [-2_276_413.0, -234.0, 2_796.0, 978_459.0, -485.0, 1_374.0]),
    ([0, 0, 0, 0, 2], [2_074_554.0, 207.0, -698.0, -897_492.0, 470.0, -291.0]),
    ([0, 1, 0, 0, 0], [1_475_877.0, -3_633.0, 11_817.0, 73_871.0, -184.0, -1_924.0]),
    ([0, 1, 2, -2, 2], [-516_821.0, 1_226.0, -524.0, 224_386.0, -677.0, -174.0]),
    ([1, 0, 0, 0, 0], [711_159.0, 73.0, -872.0, -6_750.0, 0.0, 358.0]),
    ([0, 0, 2, 0, 1], [-387_298.0, -367.0, 380.0, 200_728.0, 18.0, 318.0]),
    ([1, 0, 2, 0, 2], [-301_461.0, -36.0, 816.0, 129_025.0, -63.0, 367.0]),
    ([0, -1, 2, -2, 2], [215_829.0, -494.0, 111.0, -95_929.0, 299.0, 132.0]),
    ([0, 0, 2, -2, 1], [128_227.0, 137.0, 181.0, -68_982.0, -9.0, 39.0]),
    ([-1, 0, 2, 0, 2], [123_457.0, 11.0, 19.0, -53_311.0, 32.0, -4.0]),
    ([-1, 0, 0, 2, 0], [156_994.0, 10.0, -168.0, -1_235.0, 0.0, 82.0]),
    ([1, 0, 0, 0, 1], [63_110.0, 63.0, 27.0, -33_228.0, 0.0, -9.0]),
    ([-1, 0, 0, 0, 1], [-57_976.0, -63.0, -189.0, 31_429.0, 0.0, -75.0]),
    ([-1, 0, 2, 2, 2], [-59_641.0, -11.0, 149.0, 25_543.0, -11.0, 66.0]),
    ([1, 0, 2, 0, 1], [-51_613.0, -42.0, 129.0, 26_366.0, 0.0, 78.0]),
    ([-2, 0, 2, 0, 1], [45_893.0, 50.0, 31.0, -24_236.0, -10.0, 20.0]),
    ([0, 0, 0, 2, 0], [63_384.0, 11.0, -150.0, -1_220.0, 0.0, 29.0]),
    ([0, 0, 2, 2, 2], [-38_571.0, -1.0, 158.0, 16_452.0, -11.0, 68.0]),
    ([0, -2, 2, -2, 2], [32_481.0, 0.0, 0.0, -13_870.0, 0.0, 0.0]),
    ([-2, 0, 0, 2, 0], [-47_722.0, 0.0, -18.0, 477.0, 0.0, -25.0]),
    ([2, 0, 2, 0, 2], [-31_046.0, -1.0, 131.0, 13_238.0, -11.0, 59.0]),
    ([1, 0, 2, -2, 2], [28_593.0, 0.0, -1.0, -12_338.0, 10.0, -3.0]),
    ([-1, 0, 2, 0, 1], [20_441.0, 21.0, 10.0, -10_758.0, 0.0, -3.0]),
    ([2, 0, 0, 0, 0], [29_243.0, 0.0, -74.0, -609.0, 0.0, 13.0]),
    ([0, 0, 2, 0, 0], [25_887.0, 0.0, -66.0, -550.0, 0.0, 11.0]),
    ([0, 1, 0, 0, 1], [-14_053.0, -25.0, 79.0, 8_551.0, -2.0, -45.0]),
    ([-1, 0, 0, 2, 1], [15_164.0, 10.0, 11.0, -8_001.0, 0.0, -1.0]),
    ([0, 2, 2, -2, 2], [-15_794.0, 72.0, -16.0, 6_850.0, -42.0, -5.0]),
    ([0, 0, -2, 2, 0], [21_783.0, 0.0, 13.0, -167.0, 0.0, 13.0]),
    ([1, 0, 0, -2, 1], [-12_873.0, -10.0, -37.0, 6_953.0, 0.0, -14.0]),
    ([0, -1, 0, 0, 1], [-12_654.0, 11.0, 63.0, 6_415.0, 0.0, 26.0]),
    ([-1, 0, 2, 2, 1], [-10_204.0, 0.0, 25.0, 5_222.0, 0.0, 15.0]),
    ([0, 2, 0, 0, 0], [16_707.0, -85.0, -10.0, 168.0, -1.0, 10.0]),
    ([1, 0, 2, 2, 2], [-7_691.0, 0.0, 44.0, 3_268.0, 0.0, 19.0]),
    ([-2, 0, 2, 0, 0], [-11_024.0, 0.0, -14.0, 104.0, 0.0, 2.0]),
    ([0, 1, 2, 0, 2], [7_566.0, -21.0, -11.0, -3_250.0, 0.0, -5.0]),
    ([0, 0, 2, 2, 1], [-6_637.0, -11.0, 25.0, 3_353.0, 0.0, 14.0]),
    ([0, -1, 2, 0, 2], [-7_141.0, 21.0, 8.0, 3_070.0, 0.0, 4.0]),
    ([0, 0, 0, 2, 1], [-6_302.0, -11.0, 2.0, 3_272.0, 0.0, 4.0]),
    ([1, 0, 2, -2, 1], [5_800.0, 10.0, 2.0, -3_045.0, 0.0, -1.0]),
    ([2, 0, 2, -2, 2], [6_443.0, 0.0, -7.0, -2_768.0, 0.0, -4.0]),
    ([-2, 0, 0, 2, 1], [-5_774.0, -11.0, -15.0, 3_041.0, 0.0, -5.0]),
    ([2, 0, 2, 0, 1], [-5_350.0, 0.0, 21.0, 2_695.0, 0.0, 12.0]),
    ([0, -1, 2, -2, 1], [-4_752.0, -11.0, -3.0, 2_719.0, 0.0, -3.0]),
    ([0, 0, 0, -2, 1], [-4_940.0, -11.0, -21.0, 2_720.0, 0.0, -9.0]),
    ([-1, -1, 0, 2, 0], [7_350.0, 0.0, -8.0, -51.0, 0.0, 4.0]),
    ([2, 0, 0, -2, 1], [4_065.0, 0.0, 6.0, -2_206.0, 0.0, 1.0]),
    ([1, 0, 0, 2, 0], [6_579.0, 0.0, -24.0, -199.0, 0.0, 2.0]),
    ([0, 1, 2, -2, 1], [3_579.0, 0.0, 5.0, -1_900.0, 0.0, 1.0]),
    ([1, -1, 0, 0, 0], [4_725.0, 0.0, -6.0, -41.0, 0.0, 3.0]),
    ([-2, 0, 2, 0, 2], [-3_075.0, 0.0, -2.0, 1_313.0, 0.0, -1.0]),
    ([3, 0, 2, 0, 2], [-2_904.0, 0.0, 15.0, 1_233.0, 0.0, 7.0]),
    ([0, -1, 0, 2, 0], [4_348.0, 0.0, -10.0, -81.0, 0.0, 2.0]),
    ([1, -1, 2, 0, 2], [-2_878.0, 0.0, 8.0, 1_232.0, 0.0, 4.0]),
    ([0, 0, 0, 1, 0], [-4_230.0, 0.0, 5.0, -20.0, 0.0, -2.0]),
    ([-1, -1, 2, 2, 2], [-2_819.0, 0.0, 7.0, 1_207.0, 0.0, 3.0]),
    ([-1, 0, 2, 0, 0], [-4_056.0, 0.0, 5.0, 40.0, 0.0, -2.0]),
    ([0, -1, 2, 2, 2], [-2_647.0, 0.0, 11.0, 1_129.0, 0.0, 5.0]),
    ([-2, 0, 0, 0, 1], [-2_294.0, 0.0, -10.0, 1_266.0, 0.0, -4.0]),
    ([1, 1, 2, 0, 2], [2_481.0, 0.0, -7.0, -1_062.0, 0.0, -3.0]),
    ([2, 0, 0, 0, 1], [2_179.0, 0.0, -2.0, -1_129.0, 0.0, -2.0]),
    ([-1, 1, 0, 1, 0], [3_276.0, 0.0, 1.0, -9.0, 0.0, 0.0]),
    ([1, 1, 0, 0, 0], [-3_389.0, 0.0, 5.0, 35.0, 0.0, -2.0]),
    ([1, 0, 2, 0, 0], [3_339.0, 0.0, -13.0, -107.0, 0.0, 1.0]),
    ([-1, 0, 2, -2, 1], [-1_987.0, 0.0, -6.0, 1_073.0, 0.0, -2.0]),
    ([1, 0, 0, 0, 2], [-1_981.0, 0.0, 0.0, 854.0, 0.0, 0.0]),
    ([-1, 0, 0, 1, 0], [4_026.0, 0.0, -353.0, -553.0, 0.0, -139.0]),
    ([0, 0, 2, 1, 2], [1_660.0, 0.0, -5.0, -710.0, 0.0, -2.0]),
    ([-1, 0, 2, 4, 2], [-1_521.0, 0.0, 9.0, 647.0, 0.0, 4.0]),
    ([-1, 1, 0, 1, 1], [1_314.0, 0.0, 0.0, -700.0, 0.0, 0.0]),
    ([0, -2, 2, -2, 1], [-1_283.0, 0.0, 0.0, 672.0, 0.0, 0.0]),
    ([1, 0, 2, 2, 1], [-1_331.0, 0.0, 8.0, 663.0, 0.0, 4.0]),
    ([-2, 0, 2, 2, 2], [1_383.0, 0.0, -2.0, -594.0, 0.0, -2.0]),
    ([-1, 0, 0, 0, 2], [1_405.0, 0.0, 4.0, -610.0, 0.0, 2.0]),
    ([1, 1, 2, -2, 2], [1_290.0, 0.0, 0.0, -556.0, 0.0, 0.0]),
];

/// Nutation in longitude and obliquity `(Δψ, Δε)`, radians, IAU 2000B, at `t` Julian centuries
/// of TT since J2000.
pub fn nutation_2000b(t: f64) -> (f64, f64) {
    let turn = 1_296_000.0; // arcseconds in a turn
    let arg = |a0: f64, a1: f64| ((a0 + a1 * t) % turn) * ARCSEC;
    // Delaunay arguments (Simon et al. 1994): l, l', F, D, Ω.
    let fundamental = [
        arg(485_868.249_036, 1_717_915_923.217_8),
        arg(1_287_104.793_05, 129_596_581.048_1),
        arg(335_779.526_232, 1_739_527_262.847_8),
        arg(1_072_260.703_69, 1_602_961_601.209_0),
        arg(450_160.398_036, -6_962_890.543_1),
    ];
    let (mut dpsi, mut deps) = (0.0, 0.0);
    for (mult, c) in NUTATION_2000B.iter().rev() {
        let a: f64 = mult
            .iter()
            .zip(fundamental)
            .map(|(&m, f)| f64::from(m) * f)
            .sum();
        let (s, co) = a.sin_cos();
        dpsi += (c[0] + c[1] * t) * s + c[2] * co;
        deps += (c[3] + c[4] * t) * co + c[5] * s;
    }
    // Fixed offsets in lieu of the planetary terms (-0.135 mas, +0.388 mas).
    let mas = ARCSEC / 1000.0;
    (dpsi * U2R - 0.135 * mas, deps * U2R + 0.388 * mas)
}

/// Julian centuries of TT since J2000 at `epoch`.
fn tt_centuries(epoch: Epoch) -> f64 {
    (epoch.to_jde_tt_days() - 2_451_545.0) / 36_525.0
}

/// The Earth rotation angle (IAU 2000), radians, with UT1 = UTC.
fn earth_rotation_angle(epoch: Epoch) -> f64 {
    let du = epoch.to_jde_utc_days() - 2_451_545.0;
    let frac = du.rem_euclid(1.0);
    (std::f64::consts::TAU * (frac + 0.779_057_273_264 + 0.002_737_811_911_354_48 * du))
        .rem_euclid(std::f64::consts::TAU)
}

/// The rotation ITRS → GCRS (J2000 axes) at `epoch` (UTC), polar motion left out, UT1 = UTC
/// (see the module docs).
pub fn gcrs_from_itrs(epoch: Epoch) -> Matrix3<f64> {
    let t = tt_centuries(epoch);
    let (gamb, phib, psib, epsa) = precession_angles(t);
    let (dpsi, deps) = nutation_2000b(t);
    let npb = rx(-(epsa + deps)) * rz(-(psib + dpsi)) * rx(phib) * rz(gamb);
    let gmst = earth_rotation_angle(epoch)
        + poly_arcsec(
            &[
                0.014506,
                4612.156534,
                1.391_581_7,
                -0.000_000_44,
                -0.000_029_956,
                -0.000_000_036_8,
            ],
            t,
        );
    let gst = gmst + dpsi * epsa.cos();
    (rz(gst) * npb).transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geodetic_round_numbers() {
        // On the equator at Greenwich: x = a + h.
        let p = itrs_from_geodetic_m(0.0, 0.0, 100.0);
        assert!((p.x - (WGS84_A_M + 100.0)).abs() < 1e-6 && p.y.abs() < 1e-6);
        // At the pole: z = b + h with b = a (1 - f).
        let p = itrs_from_geodetic_m(90.0, 0.0, 0.0);
        assert!((p.z - WGS84_A_M * (1.0 - WGS84_F)).abs() < 1e-6, "{}", p.z);
    }

    #[test]
    fn nutation_is_dominated_by_the_node_term() {
        // |Δψ| ≤ 17.3″ + the rest (< 1.5″), |Δε| ≤ 9.2″ + 0.6″ (Seidelmann 1992, table 3.222.1).
        for k in 0..200 {
            let t = -0.5 + k as f64 * 0.005;
            let (dpsi, deps) = nutation_2000b(t);
            assert!(
                dpsi.abs() / ARCSEC < 19.0 && deps.abs() / ARCSEC < 10.3,
                "t {t}"
            );
        }
    }

    #[test]
    fn the_pole_of_date_precesses_about_fifty_arcseconds_a_year() {
        // The CIP's z axis in GCRS at J2000 + 10 y is ≈ 10 × 20.0″ from the GCRS pole (precession
        // in declination, ≈ 20.04″/y) give or take the nutation (≤ 10″).
        let e = Epoch::from_gregorian_utc_at_noon(2010, 1, 1);
        let z = gcrs_from_itrs(e) * Vector3::z();
        let tilt_arcsec = z.z.clamp(-1.0, 1.0).acos() / ARCSEC;
        assert!((tilt_arcsec - 200.4).abs() < 12.0, "{tilt_arcsec}");
    }
}

//! The arc `ψ(t)` of a straight polar-stereographic map line on its circle, and its sine and
//! cosine, cheaply and exactly (see the module docs of [`super`]).

/// A line of one direction, in map coordinates `p(t) = d m̂ + t ℓ`.
#[derive(Debug, Clone, Copy)]
pub(super) struct LineGeometry {
    pub(super) ell: (f64, f64),
    pub(super) m_hat: (f64, f64),
    pub(super) d_m: f64,
    /// `ρc` and `L` of the module docs.
    pub(super) rho_c: f64,
    pub(super) l_m: f64,
}

impl LineGeometry {
    pub(super) fn point(&self, t_m: f64) -> (f64, f64) {
        (
            self.d_m * self.m_hat.0 + t_m * self.ell.0,
            self.d_m * self.m_hat.1 + t_m * self.ell.1,
        )
    }

    pub(super) fn psi_rad(&self, t_m: f64) -> f64 {
        self.rho_c * 2.0 * atan_small(t_m / self.l_m)
    }

    /// `dψ/dt` (rad per map metre) and `d²ψ/dt²` at `t_m`.
    pub(super) fn psi_derivatives(&self, t_m: f64) -> (f64, f64) {
        let tau = t_m / self.l_m;
        let g = 1.0 / (1.0 + tau * tau);
        let d1 = 2.0 * self.rho_c * g / self.l_m;
        (d1, -2.0 * tau * g * d1 / self.l_m)
    }
}

/// `ψ(t)` and its `(sin, cos)` along a line, for `t` visited in order: exact at an anchor, and
/// from there by the angle-difference formulas `atan τ − atan τa = atan((τ − τa) / (1 + τ τa))`
/// and a rotation by the small difference `δ` (short series: `|δ| < 2e-3` rad, errors below
/// 1e-18), re-anchored every [`ANCHOR_SPAN_M`]. A few multiply-adds per sample instead of the
/// long dependency chains of `atan` and `sin_cos`.
pub(super) struct ArcTracker<'g> {
    geom: &'g LineGeometry,
    /// `1 / L` and `2 ρc`.
    inv_l: f64,
    two_rho_c: f64,
    t_a: f64,
    tau_a: f64,
    psi_a: f64,
    sin_a: f64,
    cos_a: f64,
}

/// Largest |t − anchor| (map metres) before re-anchoring.
pub(super) const ANCHOR_SPAN_M: f64 = 6_000.0;

impl<'g> ArcTracker<'g> {
    pub(super) fn new(geom: &'g LineGeometry) -> Self {
        let mut a = ArcTracker {
            geom,
            inv_l: 1.0 / geom.l_m,
            two_rho_c: 2.0 * geom.rho_c,
            t_a: f64::NAN,
            tau_a: 0.0,
            psi_a: 0.0,
            sin_a: 0.0,
            cos_a: 1.0,
        };
        a.anchor(0.0);
        a
    }

    fn anchor(&mut self, t_m: f64) {
        self.t_a = t_m;
        self.tau_a = t_m * self.inv_l;
        self.psi_a = self.geom.psi_rad(t_m);
        (self.sin_a, self.cos_a) = sin_cos_small(self.psi_a);
    }

    /// `(ψ, sin ψ, cos ψ)` at `t_m`.
    #[inline]
    pub(super) fn at(&mut self, t_m: f64) -> (f64, f64, f64) {
        if (t_m - self.t_a).abs() > ANCHOR_SPAN_M {
            self.anchor(t_m);
        }
        // Multiplications by constant reciprocals: a division costs several multiply-adds.
        let tau = t_m * self.inv_l;
        let x = (tau - self.tau_a) / (1.0 + tau * self.tau_a);
        let x2 = x * x;
        let atan_x = x * (1.0 - x2 * (1.0 / 3.0 - x2 * (1.0 / 5.0 - x2 * (1.0 / 7.0))));
        let d = self.two_rho_c * atan_x;
        let d2 = d * d;
        let sin_d = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0)));
        let cos_d = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
        (
            self.psi_a + d,
            self.sin_a * cos_d + self.cos_a * sin_d,
            self.cos_a * cos_d - self.sin_a * sin_d,
        )
    }
}

/// `atan(x)`: its Taylor series for `|x| <= 0.3` (error < 4e-15; `t / L` stays below 0.27 on a
/// ±457 km far field), the library function beyond.
#[inline]
pub(super) fn atan_small(x: f64) -> f64 {
    if x.abs() > 0.3 {
        return x.atan();
    }
    let x2 = x * x;
    x * ATAN_COEFFS.iter().rev().fold(0.0, |acc, &c| acc * x2 + c)
}

/// `(sin x, cos x)`: Taylor series for `|x| <= 0.6` (error < 1e-16), the library beyond.
#[inline]
pub(super) fn sin_cos_small(x: f64) -> (f64, f64) {
    if x.abs() > 0.6 {
        return x.sin_cos();
    }
    let x2 = x * x;
    let s = SIN_COEFFS.iter().rev().fold(0.0, |acc, &c| acc * x2 + c);
    let c = COS_COEFFS.iter().rev().fold(0.0, |acc, &c| acc * x2 + c);
    (x * s, c)
}

/// `(-1)^k / (2k + 1)`.
pub(super) const ATAN_COEFFS: [f64; 12] = {
    let mut a = [0.0; 12];
    let mut k = 0;
    while k < 12 {
        a[k] = if k % 2 == 0 { 1.0 } else { -1.0 } / (2 * k + 1) as f64;
        k += 1;
    }
    a
};

/// `(-1)^k / (2k + 1)!` and `(-1)^k / (2k)!`.
pub(super) const SIN_COEFFS: [f64; 11] = series_coeffs(1);
pub(super) const COS_COEFFS: [f64; 11] = series_coeffs(0);

pub(super) const fn series_coeffs(offset: usize) -> [f64; 11] {
    let mut a = [0.0; 11];
    let mut k = 0;
    while k < 11 {
        let mut f = 1.0;
        let mut i = 2;
        while i <= 2 * k + offset {
            f *= i as f64;
            i += 1;
        }
        a[k] = if k % 2 == 0 { 1.0 } else { -1.0 } / f;
        k += 1;
    }
    a
}

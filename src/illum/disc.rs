//! Visible fraction of a disc (the Sun or the Earth) above a terrain horizon profile.
//!
//! The horizon is a profile of elevations (deg) at uniformly spaced azimuths from 0° (clockwise
//! from north), linear between samples and periodic ([`HorizonProfile`]); the disc has its
//! centre at (`az_deg`, `el_deg`) and angular radius `radius_deg` ([`Disc`]). Every method works
//! in the sky's tangent plane at the disc centre:
//!
//! ```text
//!        y = el - el_c                 ^ y (deg)
//!        x = (az - az_c) cos(el_c)     |   .-'''-.      top(u)    =  sqrt(r² - u²)
//!                                      | /         \    bottom(u) = -sqrt(r² - u²)
//!   horizon g(u) = h(az_c + u/cos el_c) - el_c     |    visible(u) = clamp(top - max(g, bottom))
//!                                      +-----u-----+--> x (deg)
//! ```
//!
//! [`DiscMethod::Exact`] integrates `visible(u)` over `u` in closed form, piece by piece of the
//! interpolated horizon (exact up to rounding; limb darkening by Gauss–Legendre per piece, see
//! [`LimbDarkening`]); [`DiscMethod::Segment`] is the circular segment of paper 001 (eqs. 6–7),
//! [`DiscMethod::MiddleValue`] Max's (1988) middle value. Derivations, the tangent plane's own
//! error and the fast methods' measured errors: `docs/illum.md`, "Disc visibility".

use std::sync::OnceLock;

use super::IllumError;

/// A horizon profile: horizon elevations (deg) at `len` uniformly spaced azimuths
/// `az_deg = i · 360/len`, `i = 0..len`, azimuth clockwise from north. Linearly interpolated
/// between samples, periodic in azimuth.
#[derive(Debug, Clone, Copy)]
pub struct HorizonProfile<'a> {
    el_deg: &'a [f64],
    az_step_deg: f64,
}

impl<'a> HorizonProfile<'a> {
    /// Wraps horizon elevations (deg); errors if the slice is empty or has a non-finite value.
    pub fn new(el_deg: &'a [f64]) -> Result<Self, IllumError> {
        if el_deg.is_empty() {
            return Err(IllumError::EmptyHorizon);
        }
        if let Some(index) = el_deg.iter().position(|e| !e.is_finite()) {
            return Err(IllumError::NonFiniteHorizon {
                index,
                value: el_deg[index],
            });
        }
        let az_step_deg = 360.0 / el_deg.len() as f64;
        Ok(Self {
            el_deg,
            az_step_deg,
        })
    }

    /// The horizon elevations (deg), one per azimuth sample.
    pub fn el_deg(&self) -> &'a [f64] {
        self.el_deg
    }

    /// Azimuth spacing of the samples (deg).
    pub fn az_step_deg(&self) -> f64 {
        self.az_step_deg
    }

    /// Elevation of the sample with (possibly negative or ≥ len) index `k`, taken modulo len.
    fn sample_el_deg(&self, k: i64) -> f64 {
        let i = k.rem_euclid(self.el_deg.len() as i64) as usize;
        self.el_deg[i]
    }

    /// Horizon elevation (deg) at any azimuth (deg, any real value; taken modulo 360), by linear
    /// interpolation between the two neighbouring samples.
    pub fn el_at_az_deg(&self, az_deg: f64) -> f64 {
        let t = az_deg.rem_euclid(360.0) / self.az_step_deg;
        let k = t.floor();
        let frac = t - k;
        let k = k as i64;
        self.sample_el_deg(k) * (1.0 - frac) + self.sample_el_deg(k + 1) * frac
    }
}

/// A disc on the sky: centre azimuth and elevation and angular radius, all in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disc {
    /// Azimuth of the centre, degrees clockwise from north.
    pub az_deg: f64,
    /// Elevation of the centre above the local horizontal plane, degrees.
    pub el_deg: f64,
    /// Angular radius, degrees (the Sun ≈ 0.267° at 1 au, the Earth ≈ 0.95° from the Moon).
    pub radius_deg: f64,
}

/// Method used to compute the visible fraction of a disc. See the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DiscMethod {
    /// Exact integral over vertical strips of the disc (the reference).
    #[default]
    Exact,
    /// Circular segment under the straight line through the horizon at the disc's two azimuth
    /// edges (Fritsch et al., paper 001, eqs. 6–7): the fast path.
    Segment,
    /// Horizontal line at the horizon height of the centre azimuth (Max 1988; paper 001 eq. 5).
    MiddleValue,
}

/// Radial intensity law of a disc, `I(μ)/I(1) = c0 + c1 μ + c2 μ²`, where `μ = cos` of the
/// angle between the line of sight and the surface normal, `μ = sqrt(1 - ρ²/r²)` at angular
/// distance `ρ` from the disc centre.
///
/// The standard quadratic law `I(μ)/I(1) = 1 - u1(1-μ) - u2(1-μ)²` is `c0 = 1-u1-u2`,
/// `c1 = u1+2u2`, `c2 = -u2`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LimbDarkening {
    /// Constant term.
    pub c0: f64,
    /// Coefficient of μ.
    pub c1: f64,
    /// Coefficient of μ².
    pub c2: f64,
}

impl LimbDarkening {
    /// A uniformly bright disc (no limb darkening); also right for the Earth's disc here.
    pub const UNIFORM: Self = Self {
        c0: 1.0,
        c1: 0.0,
        c2: 0.0,
    };
    /// Eddington's grey-atmosphere law `I(μ)/I(1) = (2 + 3μ)/5` (linear law, u1 = 0.6), the
    /// textbook approximation of the Sun's limb darkening in total (bolometric) light, i.e. for
    /// total solar irradiance (e.g. Mihalas 1978, *Stellar Atmospheres*, 2nd ed., §3-3).
    pub const EDDINGTON: Self = Self {
        c0: 0.4,
        c1: 0.6,
        c2: 0.0,
    };
    /// The Sun at 550 nm (visible band): `I(μ)/I(1) = 0.30 + 0.93 μ - 0.23 μ²`, from Cox (ed.),
    /// *Allen's Astrophysical Quantities*, 4th ed., 2000, §14.7 (quadratic law u1 = 0.47,
    /// u2 = 0.23).
    pub const ALLEN_550NM: Self = Self {
        c0: 0.30,
        c1: 0.93,
        c2: -0.23,
    };

    /// Mean relative intensity over the disc, `(1/π) ∫∫_{unit disc} I dA = c0 + 2c1/3 + c2/2`.
    fn disc_mean_intensity(&self) -> f64 {
        self.c0 + 2.0 * self.c1 / 3.0 + self.c2 / 2.0
    }

    /// True for the uniform law (then the exact method uses the closed-form strip integral).
    pub fn is_uniform(&self) -> bool {
        self.c1 == 0.0 && self.c2 == 0.0
    }
}

impl Default for LimbDarkening {
    fn default() -> Self {
        Self::UNIFORM
    }
}

/// Visible fraction (0..=1) of `disc` above `horizon` by `method`, weighted by the intensity law
/// `limb` (flux fraction; [`LimbDarkening::UNIFORM`] gives the area fraction).
///
/// A disc with a non-positive or non-finite radius is treated as a point: 1 if its centre is
/// above the horizon, else 0.
pub fn visible_fraction(
    horizon: &HorizonProfile<'_>,
    disc: &Disc,
    method: DiscMethod,
    limb: &LimbDarkening,
) -> f64 {
    let r = disc.radius_deg;
    if !(r > 0.0 && r.is_finite()) {
        return if disc.el_deg > horizon.el_at_az_deg(disc.az_deg) {
            1.0
        } else {
            0.0
        };
    }
    match method {
        DiscMethod::Exact => visible_fraction_exact(horizon, disc, limb, GL_NODES),
        DiscMethod::Segment => {
            let half_span_az_deg = az_half_span_deg(disc);
            let left = horizon.el_at_az_deg(disc.az_deg - half_span_az_deg) - disc.el_deg;
            let right = horizon.el_at_az_deg(disc.az_deg + half_span_az_deg) - disc.el_deg;
            // Line through L = (-r, left) and R = (r, right): y = m + k u. Its signed distance
            // from the centre C = (0, 0) is the apothem d of eq. 6 (positive: line above C).
            let m = 0.5 * (left + right);
            let k = (right - left) / (2.0 * r);
            let d = m / (1.0 + k * k).sqrt();
            chord_visible_fraction(d / r, limb)
        }
        DiscMethod::MiddleValue => {
            let d = horizon.el_at_az_deg(disc.az_deg) - disc.el_deg;
            chord_visible_fraction(d / r, limb)
        }
    }
}

/// Fraction of a disc (radius 1) above a straight chord at signed distance `d` from the centre
/// (positive: chord above the centre), weighted by `limb`. Uniform disc: the circular-segment
/// area of paper 001 eq. 6, `(acos d - d sqrt(1-d²))/π`.
pub fn chord_visible_fraction(d: f64, limb: &LimbDarkening) -> f64 {
    if d >= 1.0 {
        return 0.0;
    }
    if d <= -1.0 {
        return 1.0;
    }
    if limb.is_uniform() {
        return (d.acos() - d * (1.0 - d * d).sqrt()) / std::f64::consts::PI;
    }
    // Limb-darkened: the same strip integral as the exact method, for a flat horizon at d
    // (the law is rotationally symmetric, so a tilted chord is equivalent to a horizontal one).
    let x_cross = (1.0 - d * d).sqrt();
    let flux = weighted_piece(1.0, -1.0, -x_cross, d, 0.0, limb, 16)
        + weighted_piece(1.0, -x_cross, x_cross, d, 0.0, limb, 16)
        + weighted_piece(1.0, x_cross, 1.0, d, 0.0, limb, 16);
    (flux / (std::f64::consts::PI * limb.disc_mean_intensity())).clamp(0.0, 1.0)
}

/// Half-width of the disc in azimuth (deg): `r / cos(el_c)`, capped at 180°.
fn az_half_span_deg(disc: &Disc) -> f64 {
    let cos_el = disc.el_deg.to_radians().cos();
    let r = disc.radius_deg;
    if cos_el * 180.0 <= r {
        180.0
    } else {
        r / cos_el
    }
}

/// The exact strip integral (see the module docs).
fn visible_fraction_exact(
    horizon: &HorizonProfile<'_>,
    disc: &Disc,
    limb: &LimbDarkening,
    gl_nodes: usize,
) -> f64 {
    let r = disc.radius_deg;
    let half_span_az_deg = az_half_span_deg(disc);
    // u per degree of azimuth (so that u runs over [-r, r] across the azimuth span).
    let u_per_az = r / half_span_az_deg;
    let step = horizon.az_step_deg();
    let az_lo = disc.az_deg - half_span_az_deg;
    let az_hi = disc.az_deg + half_span_az_deg;
    // Sample indices strictly inside (az_lo, az_hi).
    let (k_first, k_last) = (
        (az_lo / step).floor() as i64 + 1,
        (az_hi / step).ceil() as i64 - 1,
    );
    // The polyline g(u): the two ends plus the samples in between.
    let point = |k: i64| -> (f64, f64) {
        let az = k as f64 * step;
        (
            ((az - disc.az_deg) * u_per_az).clamp(-r, r),
            horizon.sample_el_deg(k) - disc.el_deg,
        )
    };
    let start = (-r, horizon.el_at_az_deg(az_lo) - disc.el_deg);
    let end = (r, horizon.el_at_az_deg(az_hi) - disc.el_deg);

    // Quick exits: horizon everywhere above the disc top / below the disc bottom.
    let (mut g_min, mut g_max) = (start.1.min(end.1), start.1.max(end.1));
    for k in k_first..=k_last {
        let g = point(k).1;
        g_min = g_min.min(g);
        g_max = g_max.max(g);
    }
    if g_max <= -r {
        return 1.0;
    }
    if g_min >= r {
        return 0.0;
    }

    let mut total = 0.0;
    let mut prev = start;
    for k in (k_first..=k_last).map(point).chain(std::iter::once(end)) {
        if k.0 > prev.0 {
            total += line_piece(r, prev, k, limb, gl_nodes);
        }
        prev = k;
    }
    let norm = std::f64::consts::PI * r * r * limb.disc_mean_intensity();
    (total / norm).clamp(0.0, 1.0)
}

/// Visible fraction of a **uniform** disc of radius `r` above a horizon polyline given directly:
/// `points` are `(u, g)` with `u` across the disc from `−r` to `r` (increasing) and `g` the
/// horizon minus the centre's elevation, in the same unit as `r`. The exact strip integral of
/// [`DiscMethod::Exact`] (closed forms), for callers whose horizon samples are not uniform in
/// azimuth (the whole-grid statistics' bands).
pub fn polyline_visible_fraction_uniform(points: &[(f64, f64)], r: f64) -> f64 {
    if !(r > 0.0 && r.is_finite()) || points.len() < 2 {
        return f64::NAN;
    }
    let mut total = 0.0;
    for w in points.windows(2) {
        if w[1].0 > w[0].0 {
            total += line_piece(r, w[0], w[1], &LimbDarkening::UNIFORM, 0);
        }
    }
    (total / (std::f64::consts::PI * r * r)).clamp(0.0, 1.0)
}

/// Integral over `u ∈ [p0.0, p1.0]` of the (weighted) visible strip length under the horizon
/// line through `p0` and `p1`, split where the line crosses the rim `u² + y² = r²`.
fn line_piece(
    r: f64,
    p0: (f64, f64),
    p1: (f64, f64),
    limb: &LimbDarkening,
    gl_nodes: usize,
) -> f64 {
    let (u0, g0) = p0;
    let (u1, g1) = p1;
    let b = (g1 - g0) / (u1 - u0);
    let a = g0 - b * u0;
    // Rim crossings: (1 + b²) u² + 2ab u + (a² - r²) = 0.
    let qa = 1.0 + b * b;
    let qb = 2.0 * a * b;
    let qc = a * a - r * r;
    let disc = qb * qb - 4.0 * qa * qc;
    let mut cuts = [u0, u1, u1, u1];
    let mut n = 1;
    if disc > 0.0 {
        let sq = disc.sqrt();
        // Numerically stable roots.
        let q = -0.5 * (qb + qb.signum() * sq);
        let (mut x1, mut x2) = if q != 0.0 {
            (q / qa, qc / q)
        } else {
            (-sq / (2.0 * qa), sq / (2.0 * qa))
        };
        if x1 > x2 {
            std::mem::swap(&mut x1, &mut x2);
        }
        for x in [x1, x2] {
            if x > u0 && x < u1 {
                cuts[n] = x;
                n += 1;
            }
        }
    }
    cuts[n] = u1;
    n += 1;
    let mut sum = 0.0;
    for w in cuts[..n].windows(2) {
        if w[1] > w[0] {
            sum += if limb.is_uniform() {
                uniform_piece(r, w[0], w[1], a, b)
            } else {
                weighted_piece(r, w[0], w[1], a, b, limb, gl_nodes)
            };
        }
    }
    sum
}

/// `∫ sqrt(r² - u²) du` antiderivative.
fn half_chord_antiderivative(r: f64, u: f64) -> f64 {
    let x = (u / r).clamp(-1.0, 1.0);
    0.5 * (u * (r * r - u * u).max(0.0).sqrt() + r * r * x.asin())
}

/// Closed-form visible area over `[u0, u1]` under the line `g = a + b u`, which does not cross
/// the rim inside the interval (so one regime holds throughout).
fn uniform_piece(r: f64, u0: f64, u1: f64, a: f64, b: f64) -> f64 {
    let um = 0.5 * (u0 + u1);
    let s_m = (r * r - um * um).max(0.0).sqrt();
    let g_m = a + b * um;
    let int_s = half_chord_antiderivative(r, u1) - half_chord_antiderivative(r, u0);
    if g_m >= s_m {
        0.0
    } else if g_m <= -s_m {
        2.0 * int_s
    } else {
        let int_g = a * (u1 - u0) + 0.5 * b * (u1 * u1 - u0 * u0);
        int_s - int_g
    }
}

/// Gauss–Legendre nodes and weights on [-1, 1] (Newton iteration on P_n; Golub-Welsch-free).
pub(crate) fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for j in 2..=n {
                let jf = j as f64;
                let p2 = ((2.0 * jf - 1.0) * x * p1 - (jf - 1.0) * p0) / jf;
                p0 = p1;
                p1 = p2;
            }
            dp = nf * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        nodes[i] = x;
        weights[i] = 2.0 / ((1.0 - x * x) * dp * dp);
    }
    (nodes, weights)
}

/// Number of Gauss–Legendre nodes per piece for the limb-darkened integral.
const GL_NODES: usize = 8;

/// Cached Gauss–Legendre rule with `n` nodes (`n` ∈ {8, 16, 32}; other values fall back to 16).
fn gl_rule(n: usize) -> &'static (Vec<f64>, Vec<f64>) {
    static GL8: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    static GL16: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    static GL32: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    match n {
        8 => GL8.get_or_init(|| gauss_legendre(8)),
        32 => GL32.get_or_init(|| gauss_legendre(32)),
        _ => GL16.get_or_init(|| gauss_legendre(16)),
    }
}

/// Limb-darkened visible flux over `[u0, u1]` under the line `g = a + b u` (in units of
/// `I(1) · deg²`): Gauss–Legendre in `θ = asin(u/r)` of the closed-form strip integral.
fn weighted_piece(
    r: f64,
    u0: f64,
    u1: f64,
    a: f64,
    b: f64,
    limb: &LimbDarkening,
    gl_nodes: usize,
) -> f64 {
    let t0 = (u0 / r).clamp(-1.0, 1.0).asin();
    let t1 = (u1 / r).clamp(-1.0, 1.0).asin();
    let (half, mid) = (0.5 * (t1 - t0), 0.5 * (t1 + t0));
    let (nodes, weights) = gl_rule(gl_nodes);
    let mut sum = 0.0;
    for (x, w) in nodes.iter().zip(weights) {
        let t = mid + half * x;
        let (sin_t, cos_t) = t.sin_cos();
        let u = r * sin_t;
        let s = r * cos_t;
        let g = a + b * u;
        if g >= s {
            continue;
        }
        let y0 = g.max(-s);
        sum += w * strip_flux(r, s, y0, s, limb) * r * cos_t;
    }
    sum * half
}

/// `∫_{y0}^{y1} I(μ(y)) dy` along a strip of half-height `s`, with `μ = sqrt(s² - y²)/r`.
fn strip_flux(r: f64, s: f64, y0: f64, y1: f64, limb: &LimbDarkening) -> f64 {
    let len = y1 - y0;
    let mut flux = limb.c0 * len;
    if s > 0.0 {
        let f1 = |y: f64| {
            let x = (y / s).clamp(-1.0, 1.0);
            0.5 * (y * (s * s - y * y).max(0.0).sqrt() + s * s * x.asin())
        };
        flux += limb.c1 / r * (f1(y1) - f1(y0));
        let f2 = |y: f64| s * s * y - y * y * y / 3.0;
        flux += limb.c2 / (r * r) * (f2(y1) - f2(y0));
    }
    flux
}

#[cfg(test)]
mod tests;

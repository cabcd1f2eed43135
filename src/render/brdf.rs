//! Surface photometry of the renderer: a Lambert BRDF and the Hapke (2012) bidirectional
//! reflectance model with the lunar parameters of Sato et al. (2014, JGR Planets 119:1775).
//!
//! [`Brdf::per_sr`] returns `f` in 1/sr with reflected radiance `L = f · E_normal · cos_i`
//! (`i` incidence, `e` emission, `g` phase angle); Hapke's bidirectional reflectance is
//! `r = f · cos_i` and the radiance factor `I/F = pi · r`. The model (Sato et al. eqs. 1–12):
//!
//! ```text
//! r(i,e,g) = K w/(4 pi) mu0e/(mu0e + mue) [p(g) (1 + B_S0 B_S(g)) + M(mu0e, mue)]
//!            [1 + B_C0 B_C(g)] S(i,e,psi)
//! p(g)     = (1+c)/2 (1-b^2)/(1 - 2b cos g + b^2)^1.5 + (1-c)/2 (1-b^2)/(1 + 2b cos g + b^2)^1.5
//! B_S(g)   = 1 / (1 + tan(g/2)/h_S)                                  (SHOE)
//! B_C(g)   = (1 + (1 - exp(-z))/z) / (2 (1 + z)^2),  z = tan(g/2)/h_C  (CBOE)
//! M        = H(mu0e/K) H(mue/K) - 1                                  (IMSA)
//! H(x)     ~ [1 - w x (r0 + (1 - 2 r0 x)/2 ln((1+x)/x))]^-1,  r0 = (1-sqrt(1-w))/(1+sqrt(1-w))
//! ```
//!
//! `S`, `mu0e`, `mue`: the macroscopic roughness correction (Hapke 1984, both branches), so
//! `f(i, e) = f(e, i)`. References, the `H` approximation and the parameters' provenance:
//! `docs/render.md`, "Hapke BRDF", and [`HapkeParams::MOON_643NM`].

use std::f64::consts::PI;

/// Parameters of the Hapke (2012) model (Sato et al. 2014 notation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HapkeParams {
    /// Single-scattering albedo `w`, in [0, 1).
    pub w: f64,
    /// Double Henyey-Greenstein lobe width `b`, in [0, 1).
    pub b: f64,
    /// Double Henyey-Greenstein backscatter weight `c`, in [-1, 1] (`c > 0`: backscattering).
    pub c: f64,
    /// Shadow-hiding opposition effect (SHOE) amplitude `B_S0`.
    pub bs0: f64,
    /// SHOE angular width `h_S`.
    pub hs: f64,
    /// Coherent-backscatter opposition effect (CBOE) amplitude `B_C0`.
    pub bc0: f64,
    /// CBOE angular width `h_C` (unused when `bc0 == 0`).
    pub hc: f64,
    /// Mean macroscopic slope angle `theta_bar`, degrees (0 = smooth surface).
    pub theta_bar_deg: f64,
    /// Porosity factor `K` (>= 1; 1 = porosity effect off).
    pub k: f64,
}

impl HapkeParams {
    /// Representative whole-Moon parameters for the LROC WAC 643 nm band after Sato et al. (2014):
    /// `K = 1`, `B_C0 = 0` (`h_C` unused) and `theta_bar = 23.657 deg` are the constants they fixed
    /// for the whole Moon (also the constant bands 4, 5, 8, 9 of the archived WAC Hapke parameter
    /// maps, PDS `WAC_HAPKEPARAMMAP`); `w = 0.32, b = 0.23, c = 0.70, B_S0 = 1.8, h_S = 0.07` are
    /// typical values of their 643 nm maps. CAVEAT: the paper's tables are not in
    /// `shared/papers/`; these five numbers were NOT checked against them (docs/render.md lists
    /// the resulting normal albedo and I/F as a plausibility check).
    pub const MOON_643NM: HapkeParams = HapkeParams {
        w: 0.32,
        b: 0.23,
        c: 0.70,
        bs0: 1.8,
        hs: 0.07,
        bc0: 0.0,
        hc: 1.0,
        theta_bar_deg: 23.657,
        k: 1.0,
    };

    /// The same parameters on a smooth surface (`theta_bar = 0`).
    pub fn smooth(self) -> Self {
        HapkeParams {
            theta_bar_deg: 0.0,
            ..self
        }
    }
}

/// A surface BRDF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Brdf {
    /// Lambert: `f = albedo / pi`.
    Lambert {
        /// Lambert (hemispherical) albedo, in [0, 1].
        albedo: f64,
    },
    /// Hapke (2012) with the given parameters.
    Hapke(HapkeParams),
}

impl Default for Brdf {
    /// Hapke with [`HapkeParams::MOON_643NM`].
    fn default() -> Self {
        Brdf::Hapke(HapkeParams::MOON_643NM)
    }
}

impl Brdf {
    /// The BRDF in 1/sr (`L = f * E_normal * cos_i`); 0 when the light or the viewer is below
    /// the surface (`cos_i <= 0` or `cos_e <= 0`).
    pub fn per_sr(&self, cos_i: f64, cos_e: f64, cos_g: f64) -> f64 {
        if !(cos_i > 0.0 && cos_e > 0.0) {
            return 0.0;
        }
        match self {
            Brdf::Lambert { albedo } => albedo / PI,
            Brdf::Hapke(p) => hapke_r_per_sr(p, cos_i, cos_e, cos_g) / cos_i.min(1.0),
        }
    }
}

/// Hapke's (2002, eq. 13) approximation of Chandrasekhar's H-function for isotropic scatterers
/// of single-scattering albedo `w`, at `x >= 0`.
pub fn hapke_h(x: f64, w: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gamma = (1.0 - w).max(0.0).sqrt();
    let r0 = (1.0 - gamma) / (1.0 + gamma);
    1.0 / (1.0 - w * x * (r0 + (1.0 - 2.0 * r0 * x) / 2.0 * ((1.0 + x) / x).ln()))
}

/// The double Henyey-Greenstein phase function `p(g)` (Sato et al. 2014 eq. 3).
pub fn double_hg(b: f64, c: f64, cos_g: f64) -> f64 {
    let b2 = b * b;
    (1.0 + c) / 2.0 * (1.0 - b2) / (1.0 - 2.0 * b * cos_g + b2).powf(1.5)
        + (1.0 - c) / 2.0 * (1.0 - b2) / (1.0 + 2.0 * b * cos_g + b2).powf(1.5)
}

/// Hapke's bidirectional reflectance `r(i, e, g)` in 1/sr (radiance / irradiance normal to the
/// beam), with `cos_i, cos_e > 0`. See the module doc for the equations.
pub fn hapke_r_per_sr(p: &HapkeParams, cos_i: f64, cos_e: f64, cos_g: f64) -> f64 {
    let cos_i = cos_i.min(1.0);
    let cos_e = cos_e.min(1.0);
    let cos_g = cos_g.clamp(-1.0, 1.0);
    let g = cos_g.acos();
    let tan_half_g = (g / 2.0).tan();
    let phase = double_hg(p.b, p.c, cos_g);
    let b_s = if p.hs > 0.0 {
        1.0 / (1.0 + tan_half_g / p.hs)
    } else {
        0.0
    };
    let b_c = if p.bc0 == 0.0 || p.hc <= 0.0 {
        0.0
    } else if tan_half_g < 1e-12 {
        1.0
    } else {
        let z = tan_half_g / p.hc;
        (1.0 + (1.0 - (-z).exp()) / z) / (2.0 * (1.0 + z) * (1.0 + z))
    };
    let (mu0e, mue, s) = roughness(p.theta_bar_deg, cos_i, cos_e, cos_g);
    let m = hapke_h(mu0e / p.k, p.w) * hapke_h(mue / p.k, p.w) - 1.0;
    p.k * p.w / (4.0 * PI) * mu0e / (mu0e + mue)
        * (phase * (1.0 + p.bs0 * b_s) + m)
        * (1.0 + p.bc0 * b_c)
        * s
}

/// Hapke's (1984) macroscopic roughness: effective cosines `(mu0e, mue)` and the shadowing
/// function `S` for mean slope `theta_bar_deg` (eq. 46-50 of Hapke 1984; Hapke 2012 ch. 12.4).
/// A smooth surface (`theta_bar <= 0`) gives `(cos_i, cos_e, 1)`.
fn roughness(theta_bar_deg: f64, cos_i: f64, cos_e: f64, cos_g: f64) -> (f64, f64, f64) {
    if theta_bar_deg <= 0.0 {
        return (cos_i, cos_e, 1.0);
    }
    let tan_t = theta_bar_deg.to_radians().tan();
    let chi = 1.0 / (1.0 + PI * tan_t * tan_t).sqrt();
    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
    let sin_e = (1.0 - cos_e * cos_e).max(0.0).sqrt();
    // Azimuth psi between the planes of incidence and emission.
    let (cos_psi, psi) = if sin_i * sin_e < 1e-12 {
        (1.0, 0.0)
    } else {
        let c = ((cos_g - cos_i * cos_e) / (sin_i * sin_e)).clamp(-1.0, 1.0);
        (c, c.acos())
    };
    // E1(y) = exp(-2/pi cot(theta) cot(y)), E2(y) = exp(-1/pi cot^2(theta) cot^2(y)).
    let e1 = |sin_y: f64, cos_y: f64| {
        if sin_y < 1e-12 {
            0.0
        } else {
            (-2.0 / PI / tan_t * cos_y / sin_y).exp()
        }
    };
    let e2 = |sin_y: f64, cos_y: f64| {
        if sin_y < 1e-12 {
            0.0
        } else {
            let cot = cos_y / sin_y / tan_t;
            (-cot * cot / PI).exp()
        }
    };
    let (e1i, e2i, e1e, e2e) = (
        e1(sin_i, cos_i),
        e2(sin_i, cos_i),
        e1(sin_e, cos_e),
        e2(sin_e, cos_e),
    );
    let eta_i = chi * (cos_i + sin_i * tan_t * e2i / (2.0 - e1i));
    let eta_e = chi * (cos_e + sin_e * tan_t * e2e / (2.0 - e1e));
    let f_psi = if psi >= PI - 1e-12 {
        0.0
    } else {
        (-2.0 * (psi / 2.0).tan()).exp()
    };
    let s2 = (psi / 2.0).sin().powi(2);
    let (mu0e, mue, q) = if cos_i >= cos_e {
        // i <= e
        let den = 2.0 - e1e - psi / PI * e1i;
        (
            chi * (cos_i + sin_i * tan_t * (cos_psi * e2e + s2 * e2i) / den),
            chi * (cos_e + sin_e * tan_t * (e2e - s2 * e2i) / den),
            cos_i / eta_i,
        )
    } else {
        let den = 2.0 - e1i - psi / PI * e1e;
        (
            chi * (cos_i + sin_i * tan_t * (e2i - s2 * e2e) / den),
            chi * (cos_e + sin_e * tan_t * (cos_psi * e2i + s2 * e2e) / den),
            cos_e / eta_e,
        )
    };
    let s = mue / eta_e * cos_i / eta_i * chi / (1.0 - f_psi + f_psi * chi * q);
    (mu0e, mue, s)
}

// Surface BRDF of the renderer (composed before render.wgsl, src/gpu/shaders.rs). CPU twin:
// `Brdf::per_sr` / `hapke_r_per_sr` in src/render/brdf.rs (same equations, same order):
// `brdf_per_sr` returns f (1/sr) with radiance L = f * E_normal * cos_i.
// model 0: Lambert, f = albedo / pi. model 1: Hapke (2012) as in Sato et al. (2014), JGR Planets
// 119:1775, with their whole-Moon constants K = 1, B_C0 = 0, theta_bar = 23.657 deg and the
// 643 nm values of HapkeParams::MOON_643NM (w, b, c, B_S0, h_S; keep in sync).
//
// Precision budget (f32): every term is O(1); the largest relative error comes from acos(cos_g)
// near g = 0 (|dg| ~ 3e-4 rad at cos_g = 1 - 6e-8), which moves B_S(g) by < 0.5 % (h_S = 0.07).

const BRDF_PI: f32 = 3.14159265358979;
const HAPKE_W: f32 = 0.32;
const HAPKE_B: f32 = 0.23;
const HAPKE_C: f32 = 0.70;
const HAPKE_BS0: f32 = 1.8;
const HAPKE_HS: f32 = 0.07;
// tan(23.657 deg)
const HAPKE_TAN_THETA: f32 = 0.438074;

// Hapke (2002) eq. 13 approximation of the H-function (K = 1).
fn hapke_h(x: f32, w: f32) -> f32 {
    if (x <= 0.0) {
        return 1.0;
    }
    let gamma = sqrt(max(1.0 - w, 0.0));
    let r0 = (1.0 - gamma) / (1.0 + gamma);
    return 1.0 / (1.0 - w * x * (r0 + (1.0 - 2.0 * r0 * x) * 0.5 * log((1.0 + x) / x)));
}

fn hapke_e1(sin_y: f32, cos_y: f32) -> f32 {
    if (sin_y < 1e-6) {
        return 0.0;
    }
    return exp(-2.0 / BRDF_PI / HAPKE_TAN_THETA * cos_y / sin_y);
}

fn hapke_e2(sin_y: f32, cos_y: f32) -> f32 {
    if (sin_y < 1e-6) {
        return 0.0;
    }
    let cot = cos_y / sin_y / HAPKE_TAN_THETA;
    return exp(-cot * cot / BRDF_PI);
}

// Bidirectional reflectance r (1/sr) of the Hapke model, cos_i, cos_e in (0, 1].
fn hapke_r_per_sr(cos_i: f32, cos_e: f32, cos_g_in: f32) -> f32 {
    let cos_g = clamp(cos_g_in, -1.0, 1.0);
    let g = acos(cos_g);
    let tan_half_g = tan(g * 0.5);
    let b2 = HAPKE_B * HAPKE_B;
    let phase = (1.0 + HAPKE_C) * 0.5 * (1.0 - b2) / pow(1.0 - 2.0 * HAPKE_B * cos_g + b2, 1.5)
        + (1.0 - HAPKE_C) * 0.5 * (1.0 - b2) / pow(1.0 + 2.0 * HAPKE_B * cos_g + b2, 1.5);
    let b_s = 1.0 / (1.0 + tan_half_g / HAPKE_HS);

    // Macroscopic roughness (Hapke 1984 eq. 46-50).
    let tan_t = HAPKE_TAN_THETA;
    let chi = 1.0 / sqrt(1.0 + BRDF_PI * tan_t * tan_t);
    let sin_i = sqrt(max(1.0 - cos_i * cos_i, 0.0));
    let sin_e = sqrt(max(1.0 - cos_e * cos_e, 0.0));
    var cos_psi = 1.0;
    var psi = 0.0;
    if (sin_i * sin_e >= 1e-6) {
        cos_psi = clamp((cos_g - cos_i * cos_e) / (sin_i * sin_e), -1.0, 1.0);
        psi = acos(cos_psi);
    }
    let e1i = hapke_e1(sin_i, cos_i);
    let e2i = hapke_e2(sin_i, cos_i);
    let e1e = hapke_e1(sin_e, cos_e);
    let e2e = hapke_e2(sin_e, cos_e);
    let eta_i = chi * (cos_i + sin_i * tan_t * e2i / (2.0 - e1i));
    let eta_e = chi * (cos_e + sin_e * tan_t * e2e / (2.0 - e1e));
    var f_psi = 0.0;
    if (psi < BRDF_PI - 1e-6) {
        f_psi = exp(-2.0 * tan(psi * 0.5));
    }
    let s2 = sin(psi * 0.5) * sin(psi * 0.5);
    var mu0e: f32;
    var mue: f32;
    var q: f32;
    if (cos_i >= cos_e) {
        let den = 2.0 - e1e - psi / BRDF_PI * e1i;
        mu0e = chi * (cos_i + sin_i * tan_t * (cos_psi * e2e + s2 * e2i) / den);
        mue = chi * (cos_e + sin_e * tan_t * (e2e - s2 * e2i) / den);
        q = cos_i / eta_i;
    } else {
        let den = 2.0 - e1i - psi / BRDF_PI * e1e;
        mu0e = chi * (cos_i + sin_i * tan_t * (e2i - s2 * e2e) / den);
        mue = chi * (cos_e + sin_e * tan_t * (cos_psi * e2i + s2 * e2e) / den);
        q = cos_e / eta_e;
    }
    let s = mue / eta_e * cos_i / eta_i * chi / (1.0 - f_psi + f_psi * chi * q);
    let m = hapke_h(mu0e, HAPKE_W) * hapke_h(mue, HAPKE_W) - 1.0;
    return HAPKE_W / (4.0 * BRDF_PI) * mu0e / (mu0e + mue) * (phase * (1.0 + HAPKE_BS0 * b_s) + m) * s;
}

// The BRDF (1/sr): model 0 Lambert (albedo / pi), 1 Hapke; 0 when cos_i <= 0 or cos_e <= 0.
fn brdf_per_sr(model: u32, cos_i: f32, cos_e: f32, cos_g: f32, albedo: f32) -> f32 {
    if (cos_i <= 0.0 || cos_e <= 0.0) {
        return 0.0;
    }
    if (model == 0u) {
        return albedo / BRDF_PI;
    }
    let ci = min(cos_i, 1.0);
    return hapke_r_per_sr(ci, min(cos_e, 1.0), cos_g) / ci;
}

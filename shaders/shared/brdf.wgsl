// Surface photometry shared by the render kernel (prepended with `// requires: shared/brdf.wgsl`).
// This version implements only Lambert: brdf = albedo / pi for every model (model 1 = Hapke
// falls back to Lambert here; the Hapke version replaces this file). Radiance of one light:
// L = brdf_per_sr(model, cos_i, cos_e, cos_g, albedo) * E_normal * cos_i.

const BRDF_PI: f32 = 3.14159265358979;

// BRDF (1/sr) for incidence cosine cos_i, emission cosine cos_e and phase-angle cosine cos_g.
fn brdf_per_sr(model: u32, cos_i: f32, cos_e: f32, cos_g: f32, albedo: f32) -> f32 {
    return albedo / BRDF_PI;
}

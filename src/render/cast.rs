//! View-ray casting through the model-space height field: the hierarchical caster of paper 000
//! ("pure mipmap casting", after Tevs et al.'s maximum mipmaps) and the uniform-stepping caster,
//! kept for comparison.
//!
//! Both work in grid units: `u` = fractional column, `v` = fractional row (cell centres at
//! integers, `v` grows southwards), `z` in metres, and `t` metres along the unit model-space
//! direction. The surface is the renderer's: bilinear between cell centres, constant over the
//! half-cell border (`u in [-0.5, cols - 0.5]`, `v in [-0.5, rows - 0.5]`, as `render::bilinear`
//! clamps).
//!
//! [`TraceMethod::MaxMipmap`] walks [`crate::shadow::dp::MaxMipmap`] without a stack (up a level
//! past a texel the ray clears, down otherwise) and at level 0 solves the patch's quadratic in
//! `t` ([`PATCH_BISECTIONS`] halvings of its first crossing piece): the first hit on the bilinear
//! surface, never missed. [`TraceMethod::Uniform`] takes steps of `step_cells` cells and refines
//! the first crossing by [`UNIFORM_BISECTIONS`]; it misses features thinner than a step.
//! [`image_error`] compares two images. The traversal, its edge cases and the measured errors:
//! `docs/render.md`, "Ray casting and the GPU path".

use nalgebra::Vector3;

use super::{Sample, bilinear, slab};
use crate::shadow::dp::MaxMipmap;
use crate::terrain::HeightField;

/// Default step of the uniform caster, cells (the first-cut renderer's half cell).
pub const DEFAULT_UNIFORM_STEP_CELLS: f64 = 0.5;

/// Bisections refining a uniform-stepping crossing (the first cut's 30).
pub const UNIFORM_BISECTIONS: usize = 30;

/// Bisections of the monotone piece of a patch that holds the hit.
pub const PATCH_BISECTIONS: usize = 50;

/// Nudge (cells) that puts a point on a texel boundary into the texel ahead of the ray.
const BOUNDARY_NUDGE_CELLS: f64 = 1e-9;

/// How view rays find the terrain.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum TraceMethod {
    /// Hierarchical casting through the maximum mipmap, exact hit on the bilinear patch.
    #[default]
    MaxMipmap,
    /// Uniform steps of `step_cells` cells and bisection of the first crossing.
    Uniform {
        /// Horizontal step, cells.
        step_cells: f64,
    },
}

/// The maximum-mipmap pyramid flattened into one array (level 0 first), the layout the GPU path
/// uploads.
#[derive(Debug, Clone)]
pub struct FlatPyramid {
    /// Per level: (rows, cols, offset of the level's first texel in `texels`).
    pub levels: Vec<(usize, usize, usize)>,
    /// All texels, level after level, each level row-major; `-inf` where all inputs are holes.
    pub texels: Vec<f32>,
}

impl FlatPyramid {
    /// Builds the pyramid of `hf` with [`MaxMipmap::new`].
    pub fn new(hf: &HeightField) -> Self {
        let mip = MaxMipmap::new(hf);
        let mut levels = Vec::with_capacity(mip.n_levels());
        let mut texels = Vec::new();
        for m in 0..mip.n_levels() {
            let (r, c, v) = mip.level(m).expect("level below n_levels");
            levels.push((r, c, texels.len()));
            texels.extend_from_slice(v);
        }
        FlatPyramid { levels, texels }
    }

    /// Texel of level `m` at (i, j), indices clamped into the level.
    #[inline]
    pub fn texel(&self, m: usize, i: i64, j: i64) -> f32 {
        let (r, c, off) = self.levels[m];
        let i = i.clamp(0, r as i64 - 1) as usize;
        let j = j.clamp(0, c as i64 - 1) as usize;
        self.texels[off + i * c + j]
    }
}

/// A ray in grid units: `u(t) = ou + t du`, `v(t) = ov + t dv`, `z(t) = oz + t dz`.
#[derive(Debug, Clone, Copy)]
struct GridRay {
    o: Vector3<f64>,
    d: Vector3<f64>,
}

impl GridRay {
    fn new(hf: &HeightField, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Self {
        GridRay {
            o: Vector3::new(
                (origin.x - hf.x_left_m) / hf.px_m - 0.5,
                (hf.y_top_m - origin.y) / hf.px_m - 0.5,
                origin.z,
            ),
            d: Vector3::new(dir.x / hf.px_m, -dir.y / hf.px_m, dir.z),
        }
    }

    #[inline]
    fn at(&self, t: f64) -> Vector3<f64> {
        self.o + t * self.d
    }
}

/// Index of the texel of size `size` holding coordinate `x`, a point on a boundary counting for
/// the texel ahead of the ray (direction `dx`).
#[inline]
fn texel_index(x: f64, dx: f64, size: f64) -> i64 {
    let nudged = if dx > 0.0 {
        x + BOUNDARY_NUDGE_CELLS
    } else if dx < 0.0 {
        x - BOUNDARY_NUDGE_CELLS
    } else {
        x
    };
    (nudged / size).floor() as i64
}

/// Ray parameter at which coordinate `o + t d` leaves texel `k` of size `size`.
#[inline]
fn texel_exit(o: f64, d: f64, k: i64, size: f64) -> f64 {
    if d > 0.0 {
        ((k + 1) as f64 * size - o) / d
    } else if d < 0.0 {
        (k as f64 * size - o) / d
    } else {
        f64::INFINITY
    }
}

/// Ray casters over one height field (the pyramid is built once).
#[derive(Debug, Clone)]
pub struct RayCaster<'a> {
    hf: &'a HeightField,
    pyramid: FlatPyramid,
    z_min_m: f64,
    z_max_m: f64,
}

impl<'a> RayCaster<'a> {
    /// Builds the maximum mipmap of `hf` and its height range.
    pub fn new(hf: &'a HeightField) -> Self {
        let (z_min_m, z_max_m) = hf
            .z_m
            .iter()
            .filter(|z| !z.is_nan())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &z| {
                (lo.min(f64::from(z)), hi.max(f64::from(z)))
            });
        RayCaster {
            hf,
            pyramid: FlatPyramid::new(hf),
            z_min_m,
            z_max_m,
        }
    }

    /// The height field.
    pub fn height_field(&self) -> &'a HeightField {
        self.hf
    }

    /// The flattened pyramid.
    pub fn pyramid(&self) -> &FlatPyramid {
        &self.pyramid
    }

    /// Lowest and highest terrain heights, m (`inf`, `-inf` for an all-hole field).
    pub fn z_range_m(&self) -> (f64, f64) {
        (self.z_min_m, self.z_max_m)
    }

    /// First terrain hit of `origin + t * dir` (t >= 0) by `method`: model point, or `None`.
    pub fn cast(
        &self,
        origin: &Vector3<f64>,
        dir: &Vector3<f64>,
        method: TraceMethod,
    ) -> Option<Vector3<f64>> {
        match method {
            TraceMethod::MaxMipmap => self.cast_mipmap(origin, dir),
            TraceMethod::Uniform { step_cells } => self.cast_uniform(origin, dir, step_cells),
        }
    }

    /// The `t` interval of the ray inside the grid's box (z within the height range +- 1 m).
    fn clip(&self, ray: &GridRay) -> Option<(f64, f64)> {
        let hf = self.hf;
        slab(
            &ray.o,
            &ray.d,
            [-0.5, -0.5, self.z_min_m - 1.0],
            [
                hf.cols as f64 - 0.5,
                hf.rows as f64 - 0.5,
                self.z_max_m + 1.0,
            ],
        )
    }

    /// Max-mipmap casting (module docs): the exact first hit on the bilinear surface.
    fn cast_mipmap(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Option<Vector3<f64>> {
        let ray = GridRay::new(self.hf, origin, dir);
        let (t_in, t_out) = self.clip(&ray)?;
        let top = self.pyramid.levels.len() - 1;
        let speed = ray.d.x.abs().max(ray.d.y.abs());
        let min_dt = if speed > 0.0 {
            BOUNDARY_NUDGE_CELLS / speed
        } else {
            0.0
        };
        let mut t = t_in.max(0.0);
        let mut level = top;
        // A texel is entered at most a few times per level; the cap only guards against a bug.
        let mut budget = 64 * (self.hf.rows + self.hf.cols + 16) * (top + 1);
        while t < t_out && budget > 0 {
            budget -= 1;
            let p = ray.at(t);
            let size = (1_u64 << level) as f64;
            let j = texel_index(p.x, ray.d.x, size);
            let i = texel_index(p.y, ray.d.y, size);
            let t_exit = texel_exit(ray.o.x, ray.d.x, j, size)
                .min(texel_exit(ray.o.y, ray.d.y, i, size))
                .min(t_out)
                .max(t + min_dt);
            let z_low = p.z.min(ray.o.z + t_exit * ray.d.z);
            if z_low > f64::from(self.pyramid.texel(level, i, j)) {
                t = t_exit;
                level = (level + 1).min(top);
            } else if level > 0 {
                level -= 1;
            } else if let Some(t_hit) = self.patch_hit(&ray, i, j, t, t_exit) {
                return Some(origin + t_hit * dir);
            } else {
                t = t_exit;
                level = 1.min(top);
            }
        }
        None
    }

    /// Exact first crossing of the ray with the bilinear patch of dual cell (i, j) on
    /// `[ta, tb]` (module docs); `None` if the ray stays above it or a corner is a hole.
    fn patch_hit(&self, ray: &GridRay, i: i64, j: i64, ta: f64, tb: f64) -> Option<f64> {
        let hf = self.hf;
        let zc = |r: i64, c: i64| {
            let r = r.clamp(0, hf.rows as i64 - 1) as usize;
            let c = c.clamp(0, hf.cols as i64 - 1) as usize;
            f64::from(hf.z_m[r * hf.cols + c])
        };
        let (z00, z01, z10, z11) = (zc(i, j), zc(i, j + 1), zc(i + 1, j), zc(i + 1, j + 1));
        if z00.is_nan() || z01.is_nan() || z10.is_nan() || z11.is_nan() {
            return None;
        }
        let (a, b, c) = (z01 - z00, z10 - z00, z00 - z01 - z10 + z11);
        let start = ray.at(ta);
        let (pu, pv) = (start.x - j as f64, start.y - i as f64);
        let (qu, qv) = (ray.d.x, ray.d.y);
        // f(s) = ray height - surface height at t = ta + s.
        let f = |s: f64| {
            let fu = (pu + qu * s).clamp(0.0, 1.0);
            let fv = (pv + qv * s).clamp(0.0, 1.0);
            start.z + ray.d.z * s - (z00 + a * fu + b * fv + c * fu * fv)
        };
        let len = tb - ta;
        // f(s) = A s^2 + B s + C: the vertex splits [0, len] into monotone pieces.
        let qa = -c * qu * qv;
        let qb = ray.d.z - (a * qu + b * qv + c * (pu * qv + qu * pv));
        let mut cuts = [0.0, len, len];
        if qa != 0.0 {
            let s_v = -qb / (2.0 * qa);
            if s_v > 0.0 && s_v < len {
                cuts = [0.0, s_v, len];
            }
        }
        if f(0.0) <= 0.0 {
            return Some(ta);
        }
        for piece in cuts.windows(2) {
            let (lo, hi) = (piece[0], piece[1]);
            if hi > lo && f(hi) <= 0.0 {
                let (mut lo, mut hi) = (lo, hi);
                for _ in 0..PATCH_BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    if f(mid) <= 0.0 {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Some(ta + hi);
            }
        }
        None
    }

    /// Uniform stepping (module docs) with a horizontal step of `step_cells` cells.
    fn cast_uniform(
        &self,
        origin: &Vector3<f64>,
        dir: &Vector3<f64>,
        step_cells: f64,
    ) -> Option<Vector3<f64>> {
        let hf = self.hf;
        let ray = GridRay::new(hf, origin, dir);
        let (t_in, t_out) = self.clip(&ray)?;
        let horiz = dir.x.hypot(dir.y).max(0.05);
        let dt = step_cells * hf.px_m / horiz;
        let above = |t: f64| -> Option<bool> {
            let p = origin + t * dir;
            bilinear(hf, &hf.z_m, p.x, p.y, false).map(|z| p.z > z)
        };
        let mut t_prev = t_in.max(0.0);
        let mut prev = above(t_prev);
        if prev == Some(false) {
            return Some(origin + t_prev * dir);
        }
        let mut t = t_prev;
        while t < t_out {
            t = (t + dt).min(t_out);
            let now = above(t);
            if prev == Some(true) && now == Some(false) {
                let (mut lo, mut hi) = (t_prev, t);
                for _ in 0..UNIFORM_BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    if above(mid) == Some(false) {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Some(origin + hi * dir);
            }
            if now.is_some() {
                prev = now;
                t_prev = t;
            }
        }
        None
    }
}

/// Error of an image against a reference image of the same scene and size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageError {
    /// Mean over all pixels of `|L - L_ref| / L_p99`, where `L` is the terrain radiance (0 for
    /// sky and discs) and `L_p99` the 99th percentile of the reference's lit terrain radiance
    /// (the tone map's scale).
    pub mean_rel: f64,
    /// Largest per-pixel `|L - L_ref| / L_p99`.
    pub max_rel: f64,
    /// Pixels that are terrain in one image and not in the other.
    pub class_mismatch: usize,
    /// Pixels compared.
    pub pixels: usize,
}

/// [`ImageError`] of `img` against `reference` (same length).
pub fn image_error(img: &[Sample], reference: &[Sample]) -> ImageError {
    assert_eq!(img.len(), reference.len(), "images of different sizes");
    let l = |s: &Sample| match s {
        Sample::Terrain { radiance_w_m2_sr } => Some(f64::from(*radiance_w_m2_sr)),
        _ => None,
    };
    let scale = super::terrain_radiance_p99(reference).unwrap_or(2.0);
    let (mut sum, mut max, mut mismatch) = (0.0, 0.0_f64, 0);
    for (a, b) in img.iter().zip(reference) {
        let (la, lb) = (l(a), l(b));
        if la.is_some() != lb.is_some() {
            mismatch += 1;
        }
        let e = (la.unwrap_or(0.0) - lb.unwrap_or(0.0)).abs() / scale;
        sum += e;
        max = max.max(e);
    }
    ImageError {
        mean_rel: sum / img.len().max(1) as f64,
        max_rel: max,
        class_mismatch: mismatch,
        pixels: img.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random-ish bumpy field: the mipmap caster's hit lies on the bilinear surface and no
    /// uniform sample at 1/64 cell finds an earlier crossing.
    #[test]
    fn mipmap_hit_is_on_the_surface_and_first() {
        let mut hf = HeightField::flat(40, 50, 10.0);
        for r in 0..hf.rows {
            for c in 0..hf.cols {
                let (x, y) = (c as f64, r as f64);
                hf.z_m[r * hf.cols + c] =
                    (8.0 * (0.7 * x).sin() * (0.45 * y).cos() + 0.3 * x) as f32;
            }
        }
        let caster = RayCaster::new(&hf);
        let mut hits = 0;
        for k in 0..400 {
            let az = k as f64 * 0.37;
            let el = -0.02 - 0.3 * ((k * 7 % 13) as f64 / 13.0);
            let origin = Vector3::new(-240.0 + (k % 20) as f64 * 20.0, 190.0, 30.0);
            let dir =
                Vector3::new(az.sin() * el.cos(), -az.cos().abs() * el.cos(), el.sin()).normalize();
            let hit = caster.cast_mipmap(&origin, &dir);
            let fine = caster.cast_uniform(&origin, &dir, 1.0 / 64.0);
            match (hit, fine) {
                (Some(p), Some(q)) => {
                    hits += 1;
                    let z = bilinear(&hf, &hf.z_m, p.x, p.y, false).unwrap();
                    assert!((p.z - z).abs() < 1e-6, "hit {p:?} off the surface {z}");
                    let (tp, tq) = ((p - origin).norm(), (q - origin).norm());
                    // The fine stepper can only find the same or a later crossing.
                    assert!(tp <= tq + 1e-6, "mipmap hit {tp} after uniform hit {tq}");
                }
                (None, Some(q)) => panic!("mipmap missed a hit at {q:?}"),
                _ => {}
            }
        }
        assert!(hits > 100, "only {hits} hits");
    }
}

//! Brute-force shadow rays: the reference engine, and the uniform-stepping baseline.
//!
//! A ray from the observer toward the light is marched in centre coordinates (integer `row`/`col`
//! are cell centres) by a DDA that visits **every** crossing with the lines `col = k` and
//! `row = k`, in order of distance. At a crossing of `col = k` at fractional row `r` the terrain
//! is the linear interpolation between centres `(floor r, k)` and `(floor r + 1, k)` (likewise for
//! row lines): the bilinear surface between centres, exactly where it is linear. A crossing with a
//! hole among its two centres is no terrain. The ray is blocked where the surface is strictly
//! above it, and lit once it leaves the grid or rises above the grid's highest cell (an early
//! exit every engine shares).
//!
//! Soft shadows sample the disc with `n` directions spread uniformly over the spherical cap (a
//! Vogel spiral: radius `sqrt((i + 1/2) / n)` of the cap area, golden-angle turns; uniform disc).
//! `exact_cost` gives the minimum shadow cost `J* = min Δh / t` over every crossing of the
//! centre ray (what the DP engine searches for); `uniform_cost` is the uniform-stepping baseline
//! of papers 000/003, sampling at a constant step. Conventions: `docs/shadow.md`.

use nalgebra::Vector3;

use super::{
    LightDir, Observer, Observers, Result, ShadowError, check_observer_height, check_radius,
    fraction_from_cost, map_cells, map_observers, max_height_m, unit_light,
};
use crate::terrain::HeightField;

/// Default number of disc sample directions of [`visible_fraction`].
pub const DEFAULT_DISC_SAMPLES: usize = 64;

/// Height of the surface on the line `col = k` at fractional row `r` (or on a row line with the
/// roles swapped): linear between the two neighbouring centres; `None` for a hole.
#[inline]
pub(crate) fn line_height(
    hf: &HeightField,
    along_row_line: bool,
    k: isize,
    frac_pos: f64,
) -> Option<f64> {
    let i = frac_pos.floor();
    let f = frac_pos - i;
    let i = i as isize;
    let (a, b) = if along_row_line {
        // Row line `row = k`, position along columns.
        (hf.z_at(k, i), hf.z_at(k, i + 1))
    } else {
        (hf.z_at(i, k), hf.z_at(i + 1, k))
    };
    match (a, b) {
        (Some(a), Some(b)) => Some(a as f64 + f * (b as f64 - a as f64)),
        (Some(a), None) if f == 0.0 => Some(a as f64),
        _ => None,
    }
}

/// Visits, in order, every crossing of the ray with the centre lines of the grid, calling
/// `visit(s, z_surface)` with `s` the horizontal distance in cells (`> 0`) and the surface height
/// (`None` for holes). Stops when `visit` returns `false` or the ray leaves the grid.
#[inline]
pub(crate) fn march<F>(hf: &HeightField, obs: &Observer, dir: &LightDir, mut visit: F)
where
    F: FnMut(f64, Option<f64>) -> bool,
{
    if dir.hor == 0.0 {
        return;
    }
    // Crossing positions may miss the grid's edge lines by a rounding error.
    const TOL: f64 = 1e-9;
    let (r0, c0) = (obs.row, obs.col);
    let max_r = (hf.rows - 1) as f64;
    let max_c = (hf.cols - 1) as f64;
    let step_c = dir.dcol.signum();
    let step_r = dir.drow.signum();
    let mut next_c = if dir.dcol > 0.0 {
        c0.floor() + 1.0
    } else {
        c0.ceil() - 1.0
    };
    let mut next_r = if dir.drow > 0.0 {
        r0.floor() + 1.0
    } else {
        r0.ceil() - 1.0
    };
    let s_of = |next: f64, start: f64, d: f64| {
        if d == 0.0 {
            f64::INFINITY
        } else {
            (next - start) / d
        }
    };
    let mut s_c = s_of(next_c, c0, dir.dcol);
    let mut s_r = s_of(next_r, r0, dir.drow);
    loop {
        let (s, z) = if s_c <= s_r {
            let s = s_c;
            let r = r0 + s * dir.drow;
            if !(0.0..=max_c).contains(&next_c) || !(-TOL..=max_r + TOL).contains(&r) {
                return;
            }
            let z = line_height(hf, false, next_c as isize, r.clamp(0.0, max_r));
            next_c += step_c;
            s_c = s_of(next_c, c0, dir.dcol);
            (s, z)
        } else {
            let s = s_r;
            let c = c0 + s * dir.dcol;
            if !(0.0..=max_r).contains(&next_r) || !(-TOL..=max_c + TOL).contains(&c) {
                return;
            }
            let z = line_height(hf, true, next_r as isize, c.clamp(0.0, max_c));
            next_r += step_r;
            s_r = s_of(next_r, r0, dir.drow);
            (s, z)
        };
        if !visit(s, z) {
            return;
        }
    }
}

/// Whether the ray from `obs` toward `dir` is blocked (see the module docs); crossings nearer
/// than `min_s_cells` (horizontal, cells) are not sampled ([`super::Observers::Points`]).
#[inline]
pub(crate) fn ray_blocked(
    hf: &HeightField,
    obs: &Observer,
    dir: &LightDir,
    z_max_m: f64,
    min_s_cells: f64,
) -> bool {
    if dir.hor == 0.0 {
        // Straight down meets the observer's own ground; straight up meets nothing.
        return dir.unit.z < 0.0;
    }
    let rise_per_cell = dir.tan_el * hf.px_m;
    let mut blocked = false;
    march(hf, obs, dir, |s, z| {
        let h_ray = obs.z_m + s * rise_per_cell;
        // Above every terrain height and not descending: nothing further can block. (A
        // descending ray above the terrain comes down again: no early exit.)
        if h_ray > z_max_m && rise_per_cell >= 0.0 {
            return false;
        }
        if s < min_s_cells {
            return true;
        }
        if let Some(z) = z
            && z > h_ray
        {
            blocked = true;
            return false;
        }
        true
    });
    blocked
}

/// Exact minimum shadow cost `J* = min Δh/t` (dimensionless, `tan` units) over every crossing
/// of the centre ray; `+inf` when the ray meets no terrain. Exact pruning: beyond distance `t`
/// no sample can have a cost below `tan(el) - (z_max - z0) / t`.
pub(crate) fn exact_cost(hf: &HeightField, obs: &Observer, dir: &LightDir, z_max_m: f64) -> f64 {
    let px = hf.px_m;
    let mut best = f64::INFINITY;
    march(hf, obs, dir, |s, z| {
        let t_m = s * px;
        if let Some(z) = z {
            let cost = (obs.z_m + t_m * dir.tan_el - z) / t_m;
            best = best.min(cost);
        }
        cost_lower_bound(dir.tan_el, z_max_m - obs.z_m, t_m) < best
    });
    best
}

/// Lower bound of the cost `(z_obs + t' tan e - z) / t'` of every sample beyond distance `t_m`
/// with `z <= z_max`: `tan e - dz / t'` with `dz = z_max - z_obs`. For `dz > 0` it grows with `t'`
/// (the bound at `t_m`); for `dz <= 0` (the observer above all terrain) it falls toward `tan e`.
#[inline]
pub(crate) fn cost_lower_bound(tan_el: f64, dz_m: f64, t_m: f64) -> f64 {
    if dz_m > 0.0 {
        tan_el - dz_m / t_m
    } else {
        tan_el
    }
}

/// Bilinear surface height at fractional (row, col) between the four surrounding centres;
/// `None` outside the grid or when one of the centres with non-zero weight is a hole.
#[inline]
pub(crate) fn bilinear(hf: &HeightField, row: f64, col: f64) -> Option<f64> {
    // Positions computed along a ray may miss the grid's edge lines by a rounding error.
    const TOL: f64 = 1e-9;
    let (max_r, max_c) = ((hf.rows - 1) as f64, (hf.cols - 1) as f64);
    if row < -TOL || col < -TOL || row > max_r + TOL || col > max_c + TOL {
        return None;
    }
    let (row, col) = (row.clamp(0.0, max_r), col.clamp(0.0, max_c));
    let r = (row.floor() as isize).min(hf.rows as isize - 2).max(0);
    let c = (col.floor() as isize).min(hf.cols as isize - 2).max(0);
    let fr = row - r as f64;
    let fc = col - c as f64;
    let get = |dr: isize, dc: isize, w: f64| -> Option<f64> {
        if w == 0.0 {
            Some(0.0)
        } else {
            hf.z_at(r + dr, c + dc).map(|z| z as f64 * w)
        }
    };
    Some(
        get(0, 0, (1.0 - fr) * (1.0 - fc))?
            + get(0, 1, (1.0 - fr) * fc)?
            + get(1, 0, fr * (1.0 - fc))?
            + get(1, 1, fr * fc)?,
    )
}

/// Minimum shadow cost by **uniform ray stepping** (the baseline of paper 000/003): samples
/// the bilinear surface every `step_cells` cells of horizontal distance along the centre ray.
fn uniform_cost(
    hf: &HeightField,
    obs: &Observer,
    dir: &LightDir,
    z_max_m: f64,
    step_cells: f64,
) -> f64 {
    let px = hf.px_m;
    let mut best = f64::INFINITY;
    if dir.hor == 0.0 {
        return best;
    }
    let mut k = 1.0;
    loop {
        let s = k * step_cells;
        let row = obs.row + s * dir.drow;
        let col = obs.col + s * dir.dcol;
        if row < 0.0 || col < 0.0 || row > (hf.rows - 1) as f64 || col > (hf.cols - 1) as f64 {
            return best;
        }
        let t_m = s * px;
        if let Some(z) = bilinear(hf, row, col) {
            best = best.min((obs.z_m + t_m * dir.tan_el - z) / t_m);
        }
        if cost_lower_bound(dir.tan_el, z_max_m - obs.z_m, t_m) >= best {
            return best;
        }
        k += 1.0;
    }
}

/// `n` unit directions spread uniformly over the spherical cap of angular radius `radius_rad`
/// around `centre` (Vogel spiral; equal cap area per sample).
fn disc_directions(centre: Vector3<f64>, radius_rad: f64, n: usize) -> Vec<Vector3<f64>> {
    let c = centre.normalize();
    let (e1, e2) = crate::frames::perpendicular_pair(&c);
    let golden = std::f64::consts::PI * (3.0 - 5.0_f64.sqrt());
    let one_minus_cos_r = 1.0 - radius_rad.cos();
    (0..n)
        .map(|i| {
            let area = (i as f64 + 0.5) / n as f64;
            let cos_a = 1.0 - area * one_minus_cos_r;
            let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
            let (st, ct) = (i as f64 * golden).sin_cos();
            (c * cos_a + (e1 * ct + e2 * st) * sin_a).normalize()
        })
        .collect()
}

/// Validates the inputs of a disc-sampling computation and returns the sample directions
/// ([`disc_directions`]) ready for marching.
fn disc_sample_dirs(
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    samples: usize,
) -> Result<Vec<LightDir>> {
    check_radius(angular_radius_rad)?;
    if samples == 0 {
        return Err(ShadowError::InvalidParameter {
            name: "samples",
            reason: "must be at least 1",
        });
    }
    let centre = unit_light(light_in_model)?;
    Ok(disc_directions(centre, angular_radius_rad, samples)
        .into_iter()
        .map(LightDir::new)
        .collect())
}

/// Brute-force visible fraction of a uniform disc: the fraction of `samples` directions over the
/// disc (a Vogel spiral, `disc_directions`) whose ray is unblocked. `NaN` for nodata.
pub fn visible_fraction<'a>(
    hf: &HeightField,
    observers: impl Into<Observers<'a>>,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    samples: usize,
) -> Result<Vec<f32>> {
    let observers = observers.into();
    observers.check()?;
    let dirs = disc_sample_dirs(light_in_model, angular_radius_rad, samples)?;
    let z_max = max_height_m(hf);
    let min_s = observers.min_s_cells();
    Ok(map_observers(hf, &observers, f32::NAN, |_, obs| {
        lit_fraction(hf, obs, &dirs, z_max, min_s)
    }))
}

/// The fraction of the rays from `obs` toward `dirs` that are not blocked ([`ray_blocked`]).
fn lit_fraction(
    hf: &HeightField,
    obs: &Observer,
    dirs: &[LightDir],
    z_max_m: f64,
    min_s_cells: f64,
) -> f32 {
    let lit = dirs
        .iter()
        .filter(|d| !ray_blocked(hf, obs, d, z_max_m, min_s_cells))
        .count();
    lit as f32 / dirs.len() as f32
}

/// Brute-force visible fraction at selected cells only (`cells` as (row, col)); same model as
/// [`visible_fraction`]. `NaN` for holes. For accuracy checks on a subset of a large grid.
pub fn visible_fraction_at(
    hf: &HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    samples: usize,
    cells: &[(usize, usize)],
) -> Result<Vec<f32>> {
    use rayon::prelude::*;
    check_observer_height(observer_height_m)?;
    let dirs = disc_sample_dirs(light_in_model, angular_radius_rad, samples)?;
    let z_max = max_height_m(hf);
    Ok(cells
        .par_iter()
        .map(|&(row, col)| {
            if row >= hf.rows || col >= hf.cols {
                return f32::NAN;
            }
            match super::observer_at(hf, row, col, observer_height_m) {
                None => f32::NAN,
                Some(obs) => lit_fraction(hf, &obs, &dirs, z_max, 0.0),
            }
        })
        .collect())
}

/// Visible fraction from the **exact** minimum shadow cost of the centre ray and the prism
/// disc-occlusion model (eq. 6–7 of paper 000/003): what DP approximates, without DP's search
/// error. `NaN` for nodata.
pub fn visible_fraction_exact_cost(
    hf: &HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
) -> Result<Vec<f32>> {
    check_observer_height(observer_height_m)?;
    check_radius(angular_radius_rad)?;
    fraction_from_costs(
        hf,
        observer_height_m,
        light_in_model,
        angular_radius_rad,
        |o, d, z| exact_cost(hf, o, d, z),
    )
}

/// Visible fraction by **uniform ray stepping** along the centre ray (step `step_cells` cells)
/// and the prism disc-occlusion model: the baseline DP is benchmarked against. `NaN` for nodata.
pub fn visible_fraction_uniform(
    hf: &HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    step_cells: f64,
) -> Result<Vec<f32>> {
    check_observer_height(observer_height_m)?;
    check_radius(angular_radius_rad)?;
    if !(step_cells.is_finite() && step_cells > 0.0) {
        return Err(ShadowError::InvalidParameter {
            name: "step_cells",
            reason: "must be finite and > 0",
        });
    }
    fraction_from_costs(
        hf,
        observer_height_m,
        light_in_model,
        angular_radius_rad,
        |o, d, z| uniform_cost(hf, o, d, z, step_cells),
    )
}

/// The prism visible fraction of every cell from its centre ray's shadow cost
/// `cost(observer, light, z_max_m)`. `NaN` for nodata.
fn fraction_from_costs(
    hf: &HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    cost: impl Fn(&Observer, &LightDir, f64) -> f64 + Sync,
) -> Result<Vec<f32>> {
    let dir = LightDir::new(unit_light(light_in_model)?);
    let z_max = max_height_m(hf);
    Ok(map_cells(hf, observer_height_m, f32::NAN, |_, _, obs| {
        fraction_from_cost(cost(obs, &dir, z_max), &dir, angular_radius_rad) as f32
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disc_directions_lie_in_the_cap_and_are_centred() {
        let c = Vector3::new(0.2, 0.9, 0.1).normalize();
        let r = 0.01;
        let dirs = disc_directions(c, r, 256);
        let mut mean = Vector3::zeros();
        for d in &dirs {
            assert!(d.dot(&c).clamp(-1.0, 1.0).acos() <= r * (1.0 + 1e-9));
            mean += d;
        }
        let mean = mean / dirs.len() as f64;
        // The mean direction lies within 2% of the radius of the centre.
        assert!((mean.normalize() - c).norm() < 0.02 * r);
        // Half of the cap area lies within r / sqrt(2) (small-angle): half the samples do too.
        let inner = dirs
            .iter()
            .filter(|d| d.dot(&c).acos() < r / 2.0_f64.sqrt())
            .count();
        assert!((inner as i64 - 128).abs() <= 2, "{inner}");
    }

    #[test]
    fn march_visits_every_line_crossing() {
        let hf = HeightField::flat(20, 20, 10.0);
        let obs = Observer {
            row: 10.0,
            col: 10.0,
            z_m: 0.0,
        };
        let dir = LightDir::new(Vector3::new(3.0, 1.0, 0.1).normalize());
        let mut n = 0;
        let mut last = 0.0;
        march(&hf, &obs, &dir, |s, _| {
            assert!(s >= last);
            last = s;
            n += 1;
            true
        });
        // Toward +x (col) 9 column lines and the rows crossed meanwhile (-y = up in rows):
        // the ray exits at col 19 after s = 9 / (3/sqrt 10); rows crossed: floor(9 / 3) = 3.
        assert_eq!(n, 9 + 3);
    }
}

//! Soft shadows by dynamic programming over maximum mipmaps (papers 000/003, Jung et al.,
//! "Optimally Fast Soft Shadows on Curved Terrain with Dynamic Programming and Maximum
//! Mipmaps"), and the SMap + DP combination [`soft_combined`].
//!
//! **Shadow cost.** One ray toward the disc's centre, `Δh(t)` above the terrain at horizontal
//! distance `t`: `J* = min_t Δh/t = tan(e_c) − tan(e_h)` (paper eq. 2), `e_h` the terrain horizon
//! along the centre azimuth. **Disc occlusion** (the paper's prism assumption, §3.4): a
//! horizontal edge `δ = e_c − e_h` below the centre, `d = δ / r_L` clamped to `[−1, 1]`,
//! `visible = (π − acos d + d·sqrt(1 − d²)) / π` (eq. 7's circular segment), `d` from exact angles.
//!
//! **Maximum mipmap** ([`MaxMipmap`]): level 0 has one texel per dual cell (the square between
//! four cell centres), the largest of its corners (holes ignored), so it bounds the bilinear
//! surface; level `m` is the 2×2 maximum of level `m − 1`. **Search** (Algorithm 1): intervals of
//! `2^N'` cells, each walked from level `N' − 1` by a DDA that visits every texel under the ray;
//! each texel gets a lower bound of the cost, and the search descends by branch and bound
//! ([`DpConfig::greedy`] = true is the paper's single path); at level 0 the exact cost is taken
//! at the brute-force march's crossings. Intervals continue past the paper's `{5, 5, 5}` until the
//! ray leaves the grid or nothing further out can lower the cost. Why each deviation, and what it
//! measures: `docs/shadow.md`, "Deviations from the papers".

use super::brute::{bilinear, line_height};
use super::smap::{SMap, shadowed};
use super::{
    LightDir, Observer, Observers, Result, ShadowError, check_radius, fraction_from_cost,
    limb_direction, map_observers, max_height_m, unit_light,
};
use crate::terrain::HeightField;

/// Parameters of the DP search.
#[derive(Debug, Clone, PartialEq)]
pub struct DpConfig {
    /// `N'` of each concatenated interval (paper: `{5, 5, 5}`); interval `j` covers `2^N'_j`
    /// cells of the ray.
    pub levels: Vec<u32>,
    /// Continue past `levels` (with `N'` growing by one per interval up to 10) until the ray
    /// leaves the grid; `false` stops after the listed intervals like the paper.
    pub extend: bool,
    /// Keep only the paper's single greedy path (see the module docs).
    pub greedy: bool,
}

impl Default for DpConfig {
    fn default() -> Self {
        DpConfig {
            levels: vec![5, 5, 5],
            extend: true,
            greedy: false,
        }
    }
}

/// Maximum mipmap of a height field over its dual cells (see the module docs).
#[derive(Debug, Clone)]
pub struct MaxMipmap {
    /// Per level: (rows, cols, texels row-major; `-inf` where all inputs are holes).
    levels: Vec<(usize, usize, Vec<f32>)>,
}

impl MaxMipmap {
    /// Builds every level down to a single texel.
    pub fn new(hf: &HeightField) -> MaxMipmap {
        let r0 = hf.rows.saturating_sub(1).max(1);
        let c0 = hf.cols.saturating_sub(1).max(1);
        let get = |r: usize, c: usize| -> f32 {
            let r = r.min(hf.rows - 1);
            let c = c.min(hf.cols - 1);
            let z = hf.z_m[r * hf.cols + c];
            if z.is_nan() { f32::NEG_INFINITY } else { z }
        };
        let mut base = vec![f32::NEG_INFINITY; r0 * c0];
        if hf.rows > 0 && hf.cols > 0 {
            for i in 0..r0 {
                for j in 0..c0 {
                    base[i * c0 + j] = get(i, j)
                        .max(get(i + 1, j))
                        .max(get(i, j + 1))
                        .max(get(i + 1, j + 1));
                }
            }
        }
        let mut levels = vec![(r0, c0, base)];
        loop {
            let (r, c, prev) = levels.last().expect("level 0 exists");
            if *r == 1 && *c == 1 {
                break;
            }
            let (nr, nc) = (r.div_ceil(2), c.div_ceil(2));
            let mut next = vec![f32::NEG_INFINITY; nr * nc];
            for i in 0..nr {
                for j in 0..nc {
                    let mut m = f32::NEG_INFINITY;
                    for di in 0..2 {
                        for dj in 0..2 {
                            let (a, b) = (2 * i + di, 2 * j + dj);
                            if a < *r && b < *c {
                                m = m.max(prev[a * c + b]);
                            }
                        }
                    }
                    next[i * nc + j] = m;
                }
            }
            levels.push((nr, nc, next));
        }
        MaxMipmap { levels }
    }

    /// Number of levels.
    pub fn n_levels(&self) -> usize {
        self.levels.len()
    }

    /// Level `m` (0 = the dual cells) as (rows, cols, texels row-major); `None` past the top.
    pub fn level(&self, m: usize) -> Option<(usize, usize, &[f32])> {
        self.levels.get(m).map(|(r, c, v)| (*r, *c, v.as_slice()))
    }

    /// Texel value at level `m`, indices clamped into the level.
    #[inline]
    fn texel(&self, m: usize, i: i64, j: i64) -> f32 {
        let m = m.min(self.levels.len() - 1);
        let (r, c, ref v) = self.levels[m];
        let i = i.clamp(0, r as i64 - 1) as usize;
        let j = j.clamp(0, c as i64 - 1) as usize;
        v[i * c + j]
    }
}

/// Everything one ray search needs.
struct RaySearch<'a> {
    hf: &'a HeightField,
    mip: &'a MaxMipmap,
    obs: &'a Observer,
    dir: &'a LightDir,
    greedy: bool,
    /// Costs at or above this value no longer matter (fully visible / lit).
    cap: f64,
    /// Best exact cost so far.
    best: f64,
    /// Crossings at or before this ray distance (cells) are ignored (the observer's own cell).
    min_s: f64,
}

impl RaySearch<'_> {
    /// Lower bound of the cost over `[s_in, s_out]` (cells) for a texel of maximum `m_z`.
    #[inline]
    fn bound(&self, m_z: f64, s_in: f64, s_out: f64) -> f64 {
        let dz = m_z - self.obs.z_m;
        let t = if dz > 0.0 { s_in } else { s_out } * self.hf.px_m;
        if t <= 0.0 {
            return if dz > 0.0 {
                f64::NEG_INFINITY
            } else {
                self.dir.tan_el
            };
        }
        self.dir.tan_el - dz / t
    }

    /// Exact costs at the ray's crossings with the four centre lines that bound dual cell
    /// (`i`, `j`) (rows `i`, `i + 1`, columns `j`, `j + 1`) inside `[s_in, s_out]` (cells): the
    /// brute-force samples of that cell.
    ///
    /// Each crossing distance is computed as the brute-force march computes it (`(k − p0)/d`)
    /// and the surface there is the line's own interpolation between its two centres
    /// ([`line_height`]). Sampling instead the bilinear surface at `obs + s·d` for the DDA's
    /// `s_in`/`s_out` (what this did before) lost occluders: that position lands ~1e-15 beside
    /// the line, so the bilinear patch on the far side also needs the two centres across the
    /// line (weights ~1e-15) and a hole there (the nodata margin of a resampled DEM) dropped a
    /// valid sample; and an interval cut within 1e-6 of a line was taken for a crossing
    /// (docs/shadow.md, "Dropped line samples next to holes").
    #[inline]
    fn sample_cell(&mut self, i: i64, j: i64, s_in: f64, s_out: f64) {
        // Texel ends can be nudged by the DDA's `eps` (1e-9 at level 0); a crossing found
        // twice (shared by two cells) is harmless.
        const TOL: f64 = 1e-9;
        let (lo, hi) = (s_in - TOL, s_out + TOL);
        if self.dir.dcol != 0.0 {
            self.sample_lines(false, j, lo, hi);
        }
        if self.dir.drow != 0.0 {
            self.sample_lines(true, i, lo, hi);
        }
    }

    /// The crossings of [`Self::sample_cell`] with lines `k0` and `k0 + 1` of one family inside
    /// `[lo, hi]` (cells): column lines (`along_row_line` false; position `p0 + s·d` along
    /// columns, `q0 + s·dq` along rows) or row lines (roles swapped).
    #[inline]
    fn sample_lines(&mut self, along_row_line: bool, k0: i64, lo: f64, hi: f64) {
        const TOL: f64 = 1e-9;
        let (o, dir) = (self.obs, self.dir);
        let (p0, d, q0, dq) = if along_row_line {
            (o.row, dir.drow, o.col, dir.dcol)
        } else {
            (o.col, dir.dcol, o.row, dir.drow)
        };
        let (max_k, max_q) = if along_row_line {
            ((self.hf.rows - 1) as f64, (self.hf.cols - 1) as f64)
        } else {
            ((self.hf.cols - 1) as f64, (self.hf.rows - 1) as f64)
        };
        // Cheap pre-test on positions; the exact distance below is the brute-force march's.
        let (pa, pb) = (p0 + lo * d, p0 + hi * d);
        let (p_min, p_max) = (pa.min(pb) - TOL, pa.max(pb) + TOL);
        for k in [k0, k0 + 1] {
            let kf = k as f64;
            if kf < p_min || kf > p_max || kf < 0.0 || kf > max_k {
                continue;
            }
            let s = (kf - p0) / d;
            if s <= self.min_s || s < lo || s > hi {
                continue;
            }
            // Same edge rule as the brute-force march.
            let q = q0 + s * dq;
            if !(-TOL..=max_q + TOL).contains(&q) {
                continue;
            }
            if let Some(z) = line_height(self.hf, along_row_line, k as isize, q.clamp(0.0, max_q)) {
                let t = s * self.hf.px_m;
                self.best = self.best.min((self.obs.z_m + t * self.dir.tan_el - z) / t);
            }
        }
    }

    /// Visits every level-`m` texel under the ray on `[sa, sb]` (cells), descending as
    /// described in the module docs.
    fn descend(&mut self, m: usize, sa: f64, sb: f64) {
        let size = (1u64 << m) as f64;
        let (dr, dc) = (self.dir.drow, self.dir.dcol);
        // The "3-texel" DDA: every texel the segment touches, with its entry/exit distances.
        let mut cand: [(f64, i64, i64, f64, f64); 16] = [(0.0, 0, 0, 0.0, 0.0); 16];
        let mut n = 0;
        let mut s = sa;
        let eps = 1e-9 * size.max(1.0);
        while s < sb - eps && n < cand.len() {
            let sm = s + eps;
            let r = self.obs.row + sm * dr;
            let c = self.obs.col + sm * dc;
            // Direction-aware texel index: a point exactly on a texel boundary belongs to the
            // texel the ray is moving into (otherwise a ray with a tiny component along that
            // axis would never leave the boundary).
            let index = |p: f64, d: f64| {
                if d < 0.0 {
                    (p / size).ceil() - 1.0
                } else {
                    (p / size).floor()
                }
            };
            let i = index(r, dr);
            let j = index(c, dc);
            let exit_r = if dr > 0.0 {
                ((i + 1.0) * size - self.obs.row) / dr
            } else if dr < 0.0 {
                (i * size - self.obs.row) / dr
            } else {
                f64::INFINITY
            };
            let exit_c = if dc > 0.0 {
                ((j + 1.0) * size - self.obs.col) / dc
            } else if dc < 0.0 {
                (j * size - self.obs.col) / dc
            } else {
                f64::INFINITY
            };
            let s_out = exit_r.min(exit_c).min(sb).max(s + eps);
            let m_z = self.mip.texel(m, i as i64, j as i64);
            if m_z.is_finite() {
                let lb = self.bound(m_z as f64, s, s_out);
                cand[n] = (lb, i as i64, j as i64, s, s_out);
                n += 1;
            }
            s = s_out;
        }
        // A chord through a parent texel (or one interval, two top-level texels long) touches at
        // most 5 texels of this level plus `eps`-long corner pieces; 16 never truncates.
        debug_assert!(s >= sb - eps, "DDA candidate list truncated at level {m}");
        let cand = &mut cand[..n];
        cand.sort_by(|x, y| x.0.total_cmp(&y.0));
        for &(lb, i, j, s_in, s_out) in cand.iter() {
            if lb >= self.best.min(self.cap) {
                break;
            }
            if m == 0 {
                self.sample_cell(i, j, s_in, s_out);
            } else {
                self.descend(m - 1, s_in, s_out);
            }
            if self.greedy {
                break;
            }
        }
    }
}

/// Distance (cells) at which the ray from `obs` leaves the centre-coordinate rectangle.
pub(crate) fn exit_distance(hf: &HeightField, obs: &Observer, dir: &LightDir) -> f64 {
    // Same rounding tolerance as the brute-force march (a ray along an edge line with a
    // 1e-16 component across it must not exit at once).
    const TOL: f64 = 1e-9;
    let lim = |p: f64, d: f64, max: f64| {
        if d > 0.0 {
            (max + TOL - p) / d
        } else if d < 0.0 {
            -(p + TOL) / d
        } else {
            f64::INFINITY
        }
    };
    lim(obs.row, dir.drow, (hf.rows - 1) as f64)
        .min(lim(obs.col, dir.dcol, (hf.cols - 1) as f64))
        .max(0.0)
}

/// What every ray search over one grid shares: the height field, its maximum mipmap, its
/// highest cell (model z, m) and the search parameters.
pub(crate) struct DpScene<'a> {
    pub hf: &'a HeightField,
    pub mip: &'a MaxMipmap,
    pub z_max_m: f64,
    pub cfg: &'a DpConfig,
}

/// `J* = min Δh/t` over the centre ray by Algorithm 1 with interval concatenation; costs at or
/// above `cap` may be reported as any value `>= cap`. Crossings within `min_s_cells` of the
/// observer (ray distance in cells) are ignored and the bilinear surface is sampled at exactly
/// `min_s_cells`: the per-site series engine ([`crate::compute::site_dp`]) skips the observer's own
/// half cell, as the horizon engine does; `0` samples from the observer on.
pub(crate) fn dp_cost_beyond(
    scene: &DpScene,
    obs: &Observer,
    dir: &LightDir,
    cap: f64,
    min_s_cells: f64,
) -> f64 {
    let &DpScene {
        hf,
        mip,
        z_max_m,
        cfg,
    } = scene;
    if dir.hor == 0.0 {
        return f64::INFINITY;
    }
    let s_exit = exit_distance(hf, obs, dir);
    let mut search = RaySearch {
        hf,
        mip,
        obs,
        dir,
        greedy: cfg.greedy,
        cap,
        best: f64::INFINITY,
        min_s: min_s_cells.max(1e-9),
    };
    // The first sample is the surface where the ray leaves the observer's own half cell (as the
    // horizon engine's scan starts there), wherever that falls between centre lines.
    if min_s_cells > 1e-9 && min_s_cells < s_exit {
        let row = obs.row + min_s_cells * dir.drow;
        let col = obs.col + min_s_cells * dir.dcol;
        if let Some(z) = bilinear(hf, row, col) {
            let t = min_s_cells * hf.px_m;
            search.best = (obs.z_m + t * dir.tan_el - z) / t;
        }
    }
    let max_level = mip.n_levels() as u32;
    let mut s0 = 0.0;
    let mut j = 0usize;
    let mut n_prime = cfg.levels.first().copied().unwrap_or(5).max(1);
    while s0 < s_exit {
        if j < cfg.levels.len() {
            n_prime = cfg.levels[j].max(1);
        } else if cfg.extend {
            n_prime = (n_prime + 1).min(10);
        } else {
            break;
        }
        // Exact pruning: nothing beyond s0 can have a cost below this bound.
        if s0 > 0.0 {
            let lb =
                crate::shadow::brute::cost_lower_bound(dir.tan_el, z_max_m - obs.z_m, s0 * hf.px_m);
            if lb >= search.best.min(cap) {
                break;
            }
        }
        // An interval never exceeds two texels of the coarsest level (so the DDA at its top
        // level visits a handful of texels).
        n_prime = n_prime.min(max_level);
        let len = (1u64 << n_prime) as f64;
        let s1 = (s0 + len).min(s_exit);
        let top = (n_prime - 1).min(max_level - 1) as usize;
        search.descend(top, s0, s1);
        s0 += len;
        j += 1;
    }
    search.best
}

/// Cost above which a disc of angular radius `r` is fully visible (`J* ≥ tan(e_c) − tan(e_c −
/// r)`); `0` for `r = 0` (hard shadows only need the sign of `J*`).
pub(crate) fn full_visibility_cap(dir: &LightDir, r: f64) -> f64 {
    let e_low = dir.elevation_rad() - r;
    if e_low <= -std::f64::consts::FRAC_PI_2 + 1e-9 {
        return f64::INFINITY;
    }
    dir.tan_el - e_low.tan()
}

fn check_config(cfg: &DpConfig) -> Result<()> {
    if cfg.levels.iter().any(|&l| l == 0 || l > 24) {
        return Err(ShadowError::InvalidParameter {
            name: "levels",
            reason: "each N' must be in 1..=24",
        });
    }
    if cfg.levels.is_empty() && !cfg.extend {
        return Err(ShadowError::InvalidParameter {
            name: "levels",
            reason: "empty list without extend",
        });
    }
    Ok(())
}

/// DP visible fraction of a uniform disc of angular radius `angular_radius_rad` for every
/// cell (`NaN` for nodata).
pub fn visible_fraction<'a>(
    hf: &HeightField,
    observers: impl Into<Observers<'a>>,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    cfg: &DpConfig,
) -> Result<Vec<f32>> {
    let observers = observers.into();
    observers.check()?;
    check_radius(angular_radius_rad)?;
    check_config(cfg)?;
    let dir = LightDir::new(unit_light(light_in_model)?);
    let mip = MaxMipmap::new(hf);
    let scene = DpScene {
        hf,
        mip: &mip,
        z_max_m: max_height_m(hf),
        cfg,
    };
    let cap = full_visibility_cap(&dir, angular_radius_rad);
    let min_s = observers.min_s_cells();
    Ok(map_observers(hf, &observers, f32::NAN, |_, obs| {
        let j = dp_cost_beyond(&scene, obs, &dir, cap, min_s);
        fraction_from_cost(j, &dir, angular_radius_rad) as f32
    }))
}

/// Statistics of [`soft_combined`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CombinedStats {
    /// Cells with data.
    pub valid_cells: usize,
    /// Cells whose lower limb is lit per SMap (fraction set to 1).
    pub fully_lit: usize,
    /// Cells whose upper limb is shadowed per SMap (fraction set to 0).
    pub fully_dark: usize,
    /// Cells in between, resolved by DP.
    pub dp_cells: usize,
}

impl CombinedStats {
    /// Fraction of valid cells that needed DP.
    pub fn dp_fraction(&self) -> f64 {
        self.dp_cells as f64 / self.valid_cells.max(1) as f64
    }
}

/// The design's combination: SMap hard masks at the light directions of the disc's upper and
/// lower limbs (the centre rotated by ± the angular radius in its vertical plane) classify cells
/// whose lower limb is visible as fully lit (fraction 1) and cells whose upper limb is hidden as
/// fully dark (0); DP runs only for the penumbra cells in between. Returns the fractions (`NaN`
/// for nodata) and the cell counts.
pub fn soft_combined<'a>(
    hf: &HeightField,
    observers: impl Into<Observers<'a>>,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
) -> Result<(Vec<f32>, CombinedStats)> {
    let observers = observers.into();
    observers.check()?;
    check_radius(angular_radius_rad)?;
    let dir = LightDir::new(unit_light(light_in_model)?);
    let upper = LightDir::new(unit_light(limb_direction(&dir, angular_radius_rad, 1.0))?);
    let lower = LightDir::new(unit_light(limb_direction(&dir, angular_radius_rad, -1.0))?);
    let smap_upper = SMap::build(hf, upper);
    let smap_lower = SMap::build(hf, lower);
    let mip = MaxMipmap::new(hf);
    let scene = DpScene {
        hf,
        mip: &mip,
        z_max_m: max_height_m(hf),
        cfg: &DpConfig::default(),
    };
    let cap = full_visibility_cap(&dir, angular_radius_rad);
    // Class codes: 0 dark, 1 lit, 2 DP, 3 nodata.
    let min_s = observers.min_s_cells();
    // SMap samples only the major-axis lines, so near its edges a thin occluder can be missed
    // (a cell wholly wrong). A verdict counts only where the observer's four neighbours one cell
    // away (same height) share it; cells on an SMap edge go to DP.
    let same_all = |smap: Option<&SMap>, limb: &LightDir, obs: &Observer, v: bool| {
        [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)]
            .iter()
            .all(|&(dr, dc)| {
                let near = Observer {
                    row: obs.row + dr,
                    col: obs.col + dc,
                    z_m: obs.z_m,
                };
                shadowed(smap, limb, &near) == v
            })
    };
    let out: Vec<(f32, u8)> = map_observers(hf, &observers, (f32::NAN, 3u8), |_, obs| {
        if !shadowed(smap_lower.as_ref(), &lower, obs)
            && same_all(smap_lower.as_ref(), &lower, obs, false)
        {
            return (1.0, 1);
        }
        if shadowed(smap_upper.as_ref(), &upper, obs)
            && same_all(smap_upper.as_ref(), &upper, obs, true)
        {
            return (0.0, 0);
        }
        let j = dp_cost_beyond(&scene, obs, &dir, cap, min_s);
        let f = fraction_from_cost(j, &dir, angular_radius_rad);
        (f as f32, 2)
    });
    let mut stats = CombinedStats::default();
    let fractions = out
        .iter()
        .map(|&(f, class)| {
            match class {
                0 => stats.fully_dark += 1,
                1 => stats.fully_lit += 1,
                2 => stats.dp_cells += 1,
                _ => {}
            }
            f
        })
        .collect();
    stats.valid_cells = stats.fully_dark + stats.fully_lit + stats.dp_cells;
    Ok((fractions, stats))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mipmap_levels_bound_their_children() {
        let mut hf = HeightField::flat(37, 23, 10.0);
        for (k, z) in hf.z_m.iter_mut().enumerate() {
            *z = ((k * 7919) % 101) as f32;
        }
        hf.z_m[5] = f32::NAN;
        let mip = MaxMipmap::new(&hf);
        assert_eq!(mip.levels[0].0, 36);
        assert_eq!(mip.levels[0].1, 22);
        assert_eq!(mip.levels.last().unwrap().2.len(), 1);
        let top = mip.levels.last().unwrap().2[0];
        let global = hf
            .z_m
            .iter()
            .filter(|z| !z.is_nan())
            .fold(f32::MIN, |a, &b| a.max(b));
        assert_eq!(top, global);
        // Every dual cell's value is the max of its four corners.
        for i in 0..36 {
            for j in 0..22 {
                let corners = [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
                    .map(|(r, c)| hf.z_m[r * 23 + c])
                    .into_iter()
                    .filter(|z| !z.is_nan())
                    .fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(mip.texel(0, i as i64, j as i64), corners);
                let up = mip.texel(3, (i / 8) as i64, (j / 8) as i64);
                assert!(up >= corners);
            }
        }
    }

    /// For every light at (`az_deg`, `el_deg`) and every observer 2 m above a cell of `hf`:
    /// `check(light, its direction, the Sun's cap, (row, col), exact cost, DP cost)`.
    fn compare_costs(
        hf: &HeightField,
        lights_deg: impl IntoIterator<Item = (f64, f64)>,
        mut check: impl FnMut((f64, f64), &LightDir, f64, (usize, usize), f64, f64),
    ) {
        use crate::shadow::brute::exact_cost;
        let mip = MaxMipmap::new(hf);
        let z_max = max_height_m(hf);
        let scene = DpScene {
            hf,
            mip: &mip,
            z_max_m: z_max,
            cfg: &DpConfig::default(),
        };
        for (az_deg, el_deg) in lights_deg {
            let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
            let l = [az.sin() * el.cos(), az.cos() * el.cos(), el.sin()];
            let dir = LightDir::new(unit_light(l).unwrap());
            let cap = full_visibility_cap(&dir, crate::shadow::SUN_ANGULAR_RADIUS_RAD);
            for r in 0..hf.rows {
                for c in 0..hf.cols {
                    let Some(obs) = crate::shadow::observer_at(hf, r, c, 2.0) else {
                        continue;
                    };
                    let e = exact_cost(hf, &obs, &dir, z_max);
                    let d = dp_cost_beyond(&scene, &obs, &dir, cap, 0.0);
                    check((az_deg, el_deg), &dir, cap, (r, c), e, d);
                }
            }
        }
    }

    #[test]
    fn dp_cost_equals_exhaustive_cost_on_rough_terrain() {
        let n = 80;
        let mut hf = HeightField::flat(n, n, 120.0);
        for r in 0..n {
            for c in 0..n {
                let (x, y) = (r as f64 * 0.37, c as f64 * 0.23);
                hf.z_m[r * n + c] =
                    (300.0 * (x.sin() * y.cos()) + 120.0 * (0.5 * x + 1.3 * y).sin()) as f32;
            }
        }
        hf.z_m[40 * n + 40] = f32::NAN;
        let lights = [(37.0, 0.5), (90.0, 1.5), (180.0, 5.0), (301.0, 0.2)];
        compare_costs(&hf, lights, |(az_deg, el_deg), _, cap, (r, c), e, d| {
            // Costs at or above the cap all mean "fully visible".
            assert!(
                (e.min(cap) - d.min(cap)).abs() < 1e-9,
                "az {az_deg} el {el_deg} r {r} c {c}: exact {e} dp {d}"
            );
        });
    }

    /// Regression: next to a nodata margin (as at the edge of a resampled DEM) the DP sampled
    /// the bilinear surface at `obs + s·d`, which lands ~1e-15 beside the centre line; the patch
    /// on the far side needed a hole's weight-1e-15 corner and the sample was dropped, so DP
    /// missed occluders on the margin's first valid line (on the synthetic DEM: 1,925 costs and
    /// 433 fractions wrong of 7.68 M cell-suns; docs/shadow.md). Before the fix this grid gave
    /// 41 costs and 6 fractions wrong of 42,408 cell-suns; now DP equals the brute-force march's
    /// cost to 1e-9 (and the prism fraction to 1e-6) in every cell.
    #[test]
    fn dp_cost_equals_exhaustive_cost_next_to_a_nodata_margin() {
        let n = 48;
        let mut hf = HeightField::flat(n, n, 100.0);
        for r in 0..n {
            for c in 0..n {
                let (x, y) = (r as f64 * 0.41, c as f64 * 0.29);
                // Ridges whose crests reach the margin: occluders on its first valid lines.
                hf.z_m[r * n + c] =
                    (250.0 * (x.sin() * y.cos()) + 150.0 * (0.7 * x - 1.1 * y).sin()) as f32;
                // A ragged margin 2..=4 cells wide on every side.
                let w = 2 + (r + c) % 3;
                if r < w || c < w || r >= n - w || c >= n - w {
                    hf.z_m[r * n + c] = f32::NAN;
                }
            }
        }
        let r_sun = crate::shadow::SUN_ANGULAR_RADIUS_RAD;
        let (mut cells, mut blocked_near_margin) = (0, 0);
        let (mut wrong_costs, mut wrong_fractions) = (0, 0);
        let lights = (0..24).map(|k| (15.0 * k as f64 + 2.5, [0.5f64, 1.5, 4.0][k % 3]));
        compare_costs(&hf, lights, |(az_deg, el_deg), dir, cap, (r, c), e, d| {
            cells += 1;
            let fe = fraction_from_cost(e, dir, r_sun);
            let fd = fraction_from_cost(d, dir, r_sun);
            let bad_cost = (e.min(cap) - d.min(cap)).abs() >= 1e-9;
            let bad_fraction = (fe - fd).abs() >= 1e-6;
            if (bad_cost || bad_fraction) && wrong_costs < 3 {
                eprintln!("az {az_deg} el {el_deg} r {r} c {c}: exact {e} dp {d}");
            }
            wrong_costs += usize::from(bad_cost);
            wrong_fractions += usize::from(bad_fraction);
            blocked_near_margin += usize::from(e < 0.0 && (r.min(c) < 8 || r.max(c) >= n - 8));
        });
        eprintln!(
            "{cells} cell-suns, {blocked_near_margin} blocked within 8 cells of the margin: \
             {wrong_costs} costs (|Δ| ≥ 1e-9) and {wrong_fractions} fractions (|Δ| ≥ 1e-6) wrong"
        );
        // The rays do cross the margin's first lines with occluders on them.
        assert!(cells > 24 * 1500 && blocked_near_margin > 500);
        assert_eq!((wrong_costs, wrong_fractions), (0, 0));
    }
}

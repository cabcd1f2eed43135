//! SMap hard shadows (paper 004, "Real-time terrain shadowing by directional light").
//!
//! Per light the grid is re-indexed into a canonical frame `(u, v)` (one of eight flips and
//! transposes): `v` runs along the grid axis nearest the light's azimuth and decreases toward the
//! light; one step toward it moves `u` by `a = |minor/major| ∈ [0, 1]` and raises the ray by
//! `b = tan(el)·px·sqrt(1 + a²)` (the paper's `Lw`). As in the paper's `IsShadow`, terrain is
//! sampled on the major-axis lines only, linear along `u` (the surface of [`super::brute`], which
//! also samples the minor-axis lines).
//!
//! Beam `n` covers `[s, s + 1]` on line `v`, `s = n + a·(Nv − 1 − v)`, so a ray stays in one
//! beam. A beam's line is Black when its cross-section holds a silhouette point (`h1 > h0 + b`
//! and `h1 > h2 − b`); NextV (paper §6, quad merge) points each beam to the nearest Black line
//! toward the light, and `IsShadow` jumps from Black line to Black line. `HasSilhouette` solves
//! each linear piece exactly where the paper tests five points (which can miss a silhouette), so
//! the skip is provably safe. Proof and what is not implemented: `docs/shadow.md`, "Deviations
//! from the papers".

use rayon::prelude::*;

use super::{LightDir, Observer, max_height_m};
use crate::terrain::HeightField;

/// `NextV` value meaning "no Black line (yet / at all) toward the light".
const NONE: i32 = -1;

/// The SMap of one light direction over one height field.
#[derive(Debug, Clone)]
pub struct SMap {
    /// Whether the major (`v`) axis is the column axis.
    v_is_col: bool,
    /// Whether `v` = `N − 1 − index` (flipped) along the major axis.
    v_flipped: bool,
    /// Whether `u` = `N − 1 − index` along the minor axis.
    u_flipped: bool,
    /// Canonical sizes.
    nu: usize,
    nv: usize,
    /// Minor-axis shift per step toward the light, cells (`0..=1`).
    a: f64,
    /// Ray rise per step toward the light, metres.
    rise_m: f64,
    /// Canonical heights, `v`-major (`z[v * nu + u]`), `NaN` for holes.
    z: Vec<f32>,
    /// Smallest beam index.
    b_min: i64,
    /// Beam-major colours (`true` = Black), `[(b - b_min) * nv + v]`.
    black: Vec<bool>,
    /// Beam-major NextV (`NONE` when there is no Black line toward the light).
    next: Vec<i32>,
    /// Largest terrain height, m.
    z_max_m: f64,
}

impl SMap {
    /// Builds the SMap for `light` (unit, model space) over `hf`. Returns `None` when the light
    /// has no horizontal component (nothing can block a vertical ray over a height field).
    pub(crate) fn build(hf: &HeightField, dir: LightDir) -> Option<SMap> {
        if dir.hor == 0.0 || hf.rows == 0 || hf.cols == 0 {
            return None;
        }
        let v_is_col = dir.dcol.abs() >= dir.drow.abs();
        let (major, minor) = if v_is_col {
            (dir.dcol, dir.drow)
        } else {
            (dir.drow, dir.dcol)
        };
        // v decreases toward the light: flip when the index increases toward the light.
        let v_flipped = major > 0.0;
        // u increases toward the light: flip when the index decreases toward the light.
        let u_flipped = minor < 0.0;
        let a = (minor / major).abs().min(1.0);
        let (nu, nv) = if v_is_col {
            (hf.rows, hf.cols)
        } else {
            (hf.cols, hf.rows)
        };
        let rise_m = dir.tan_el * hf.px_m * (1.0 + a * a).sqrt();
        let mut smap = SMap {
            v_is_col,
            v_flipped,
            u_flipped,
            nu,
            nv,
            a,
            rise_m,
            z: vec![f32::NAN; nu * nv],
            b_min: -((a * (nv as f64 - 1.0)).ceil() as i64) - 1,
            black: Vec::new(),
            next: Vec::new(),
            z_max_m: max_height_m(hf),
        };
        smap.z.par_chunks_mut(nu).enumerate().for_each(|(v, line)| {
            for (u, z) in line.iter_mut().enumerate() {
                let (row, col) = smap_row_col(v_is_col, v_flipped, u_flipped, nu, nv, u, v);
                *z = hf.z_m[row * hf.cols + col];
            }
        });
        let n_beams = (nu as i64 - smap.b_min) as usize;
        // Pass 0: colours (paper §5), parallel over beams.
        let mut black = vec![false; n_beams * nv];
        black.par_chunks_mut(nv).enumerate().for_each(|(ib, col)| {
            let b = ib as i64 + smap.b_min;
            for (v, c) in col.iter_mut().enumerate() {
                *c = smap.has_silhouette(b, v);
            }
        });
        // Pass 1: NextV with the quad-merge log-step search (paper §6 "Optimization").
        let mut next = vec![NONE; n_beams * nv];
        next.par_chunks_mut(nv)
            .zip(black.par_chunks(nv))
            .for_each(|(nx, bl)| find_next_v_quad(bl, nx));
        smap.black = black;
        smap.next = next;
        Some(smap)
    }

    /// Canonical (u, v) of fractional grid (row, col).
    #[inline]
    fn uv_of(&self, row: f64, col: f64) -> (f64, f64) {
        let (minor_i, major_i, n_minor, n_major) = if self.v_is_col {
            (row, col, self.nu, self.nv)
        } else {
            (col, row, self.nu, self.nv)
        };
        let u = if self.u_flipped {
            (n_minor - 1) as f64 - minor_i
        } else {
            minor_i
        };
        let v = if self.v_flipped {
            (n_major - 1) as f64 - major_i
        } else {
            major_i
        };
        (u, v)
    }

    /// Height on line `v` at fractional `u` (linear between neighbours); `None` off the grid
    /// or in a hole.
    #[inline]
    fn line_z(&self, v: i64, u: f64) -> Option<f64> {
        if v < 0 || v >= self.nv as i64 || u < 0.0 || u > (self.nu - 1) as f64 {
            return None;
        }
        let i = (u.floor() as usize).min(self.nu.saturating_sub(2));
        let f = u - i as f64;
        let base = v as usize * self.nu;
        let z0 = self.z[base + i];
        if self.nu == 1 {
            return (!z0.is_nan()).then_some(z0 as f64);
        }
        let z1 = self.z[base + i + 1];
        if z0.is_nan() || (z1.is_nan() && f > 0.0) {
            return None;
        }
        if f == 0.0 {
            return Some(z0 as f64);
        }
        Some(z0 as f64 + f * (z1 as f64 - z0 as f64))
    }

    /// The linear function (value at `p`, value at `q`) of line `v` on the piece `[p, q]`,
    /// which lies within one cell interval (so the cell pair is the one of the midpoint).
    #[inline]
    fn piece(&self, v: i64, p: f64, q: f64) -> Option<(f64, f64)> {
        let m = 0.5 * (p + q);
        if v < 0 || v >= self.nv as i64 || m < 0.0 || m > (self.nu - 1) as f64 {
            return None;
        }
        if self.nu == 1 {
            let z = self.line_z(v, 0.0)?;
            return Some((z, z));
        }
        let i = (m.floor() as usize).min(self.nu - 2);
        let base = v as usize * self.nu;
        let (z0, z1) = (self.z[base + i], self.z[base + i + 1]);
        if z0.is_nan() || z1.is_nan() {
            return None;
        }
        let (z0, z1) = (z0 as f64, z1 as f64);
        let at = |u: f64| z0 + (u - i as f64) * (z1 - z0);
        Some((at(p), at(q)))
    }

    /// `HasSilhouette` (paper §5) for beam `b` on line `v`, solved exactly per linear piece
    /// (see the module docs for the deviation from the paper's five-point test).
    fn has_silhouette(&self, b: i64, v: usize) -> bool {
        let a = self.a;
        let s = b as f64 + a * (self.nv as f64 - 1.0 - v as f64);
        let lo = s.max(0.0);
        let hi = (s + 1.0).min((self.nu - 1) as f64);
        if lo > hi {
            return false;
        }
        // Breakpoints: integers of line v, of line v+1 shifted by +a, of line v-1 shifted by -a.
        let mut cuts = [0.0f64; 8];
        let mut n = 0;
        cuts[n] = lo;
        n += 1;
        for shift in [0.0, a, -a] {
            let mut k = (lo - shift).floor() + 1.0;
            while k + shift < hi && n < cuts.len() - 1 {
                cuts[n] = k + shift;
                n += 1;
                k += 1.0;
            }
        }
        cuts[n] = hi;
        n += 1;
        let cuts = &mut cuts[..n];
        cuts.sort_by(|x, y| x.total_cmp(y));
        let v = v as i64;
        let rise = self.rise_m;
        let check = |p: f64, q: f64| -> bool {
            let Some((h1p, h1q)) = self.piece(v, p, q) else {
                return false;
            };
            // Far neighbour (line v + 1, at u - a) and near neighbour (line v - 1, at u + a).
            let h0 = self.piece(v + 1, p - a, q - a);
            let h2 = self.piece(v - 1, p + a, q + a);
            // Condition 1: f1 = h1 - h0 - rise > 0; condition 2: f2 = h1 - h2 + rise > 0.
            // Each holds on a sub-interval of [0, 1] (piece parameter); intersect them.
            let int1 = match h0 {
                None => Some((0.0, 1.0)),
                Some((h0p, h0q)) => positive_part(h1p - h0p - rise, h1q - h0q - rise),
            };
            let int2 = match h2 {
                None => Some((0.0, 1.0)),
                Some((h2p, h2q)) => positive_part(h1p - h2p + rise, h1q - h2q + rise),
            };
            match (int1, int2) {
                (Some((a1, b1)), Some((a2, b2))) => a1.max(a2) <= b1.min(b2),
                _ => false,
            }
        };
        if n == 2 && cuts[0] == cuts[1] {
            return check(cuts[0], cuts[1]);
        }
        cuts.windows(2).any(|w| w[1] > w[0] && check(w[0], w[1]))
    }

    /// `IsShadow` (paper §8) for the ray of one observer.
    #[inline]
    pub(crate) fn is_shadow(&self, obs: &Observer) -> bool {
        let (u_f, v_f) = self.uv_of(obs.row, obs.col);
        // Advance to the first integral line toward the light (strictly ahead of the observer).
        let v1 = v_f.ceil() - 1.0;
        if v1 < 0.0 {
            return false;
        }
        let u_at = |v: f64| u_f + self.a * (v_f - v);
        let w_at = |v: f64| obs.z_m + (v_f - v) * self.rise_m;
        let b = (u_at(v1) - self.a * (self.nv as f64 - 1.0 - v1)).floor() as i64;
        let ib = (b - self.b_min) as usize;
        let base = ib * self.nv;
        let mut v = v1 as i64;
        // The first sample is always tested (the silhouette argument needs a previous sample).
        let mut first = true;
        loop {
            let vf = v as f64;
            let u = u_at(vf);
            if u > (self.nu - 1) as f64 + 1e-9 || u < -1e-9 {
                return false;
            }
            let w = w_at(vf);
            // Above all terrain and not descending: lit (a descending ray comes down again).
            if w > self.z_max_m && self.rise_m >= 0.0 {
                return false;
            }
            if (first || self.black[base + v as usize])
                && self
                    .line_z(v, u.clamp(0.0, (self.nu - 1) as f64))
                    .is_some_and(|h| h > w)
            {
                return true;
            }
            first = false;
            let nv = self.next[base + v as usize];
            if nv == NONE {
                return false;
            }
            v = nv as i64;
        }
    }
}

/// Row and column of canonical (u, v).
#[inline]
fn smap_row_col(
    v_is_col: bool,
    v_flipped: bool,
    u_flipped: bool,
    nu: usize,
    nv: usize,
    u: usize,
    v: usize,
) -> (usize, usize) {
    let minor = if u_flipped { nu - 1 - u } else { u };
    let major = if v_flipped { nv - 1 - v } else { v };
    if v_is_col {
        (minor, major)
    } else {
        (major, minor)
    }
}

/// Sub-interval of `[0, 1]` where the linear function with end values `fp`, `fq` is `>= 0`
/// (`>=` rather than the paper's `>`: marking more lines Black is always safe).
#[inline]
fn positive_part(fp: f64, fq: f64) -> Option<(f64, f64)> {
    match (fp >= 0.0, fq >= 0.0) {
        (true, true) => Some((0.0, 1.0)),
        (false, false) => None,
        (true, false) => Some((0.0, fp / (fp - fq))),
        (false, true) => Some((fp / (fp - fq), 1.0)),
    }
}

/// `FindNextV` with the quad merge (paper §6, "Optimization"): `next[v]` becomes the largest
/// `v' < v` with `black[v']`, or [`NONE`]. Pass `DIST` merges four blocks of size `DIST` into
/// one of `4·DIST`; passes run for `DIST = 1, 4, 16, …` (log₄ N passes).
fn find_next_v_quad(black: &[bool], next: &mut [i32]) {
    let n = black.len();
    next.fill(NONE);
    let mut dist = 1usize;
    while dist < n {
        for v in 0..n {
            if next[v] != NONE {
                continue;
            }
            let min_lookup = (v - v % (dist * 4)) as i64;
            let mut lookup = (v - v % dist) as i64 - 1;
            while lookup >= min_lookup && next[v] == NONE {
                let l = lookup as usize;
                next[v] = if black[l] { l as i32 } else { next[l] };
                lookup -= dist as i64;
            }
        }
        dist *= 4;
    }
}

/// Whether `obs` is in the shadow of `smap` (built for `dir`); without a map (a vertical light)
/// a light from below is shadowed.
pub(crate) fn shadowed(smap: Option<&SMap>, dir: &LightDir, obs: &Observer) -> bool {
    match smap {
        Some(s) => s.is_shadow(obs),
        None => dir.unit.z < 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quad_merge_matches_linear_scan() {
        // Deterministic pseudo-random patterns of several lengths and densities.
        let mut state = 12345u64;
        for n in [1usize, 2, 3, 4, 5, 15, 16, 17, 63, 64, 65, 200, 1000] {
            for density in [0.0, 0.02, 0.3, 1.0] {
                let black: Vec<bool> = (0..n)
                    .map(|_| {
                        state = state
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        ((state >> 33) as f64 / (1u64 << 31) as f64) < density
                    })
                    .collect();
                let mut next = vec![0; n];
                find_next_v_quad(&black, &mut next);
                for (v, &got) in next.iter().enumerate() {
                    let expected = (0..v).rev().find(|&w| black[w]).map_or(NONE, |w| w as i32);
                    assert_eq!(got, expected, "n={n} density={density} v={v}");
                }
            }
        }
    }

    #[test]
    fn positive_part_roots() {
        assert_eq!(positive_part(1.0, -1.0), Some((0.0, 0.5)));
        assert_eq!(positive_part(-3.0, 1.0), Some((0.75, 1.0)));
        assert_eq!(positive_part(-1.0, -1.0), None);
    }
}

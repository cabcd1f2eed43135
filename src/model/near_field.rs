//! The near field of a one-light map on the DEM's own lattice.
//!
//! The per-light engines march the model grid, a resampling of every layer onto a regular grid
//! in the map centre's tangent plane. Away from the centre its cells drift off the DEM's pixel
//! centres (the projection's scale change and the tilt of the vertical), and a bilinear surface
//! resampled bilinearly loses a sharp crest: 0.03 px of drift on a crater wall lowered a crest
//! one pixel from an observer by 1.1 m, its horizon by 0.25° (a pixel of the SPICE DSK test lit
//! 26 % where the Sun is wholly hidden; docs/shadow.md, "The near field"). So within
//! [`NEAR_FIELD_CELLS`] of each pixel the rays march the DEM's own lattice instead: the exact
//! model-space position of every pixel centre ([`MapGrid`] keeps them), bilinear between them,
//! sampled at each crossing of a lattice line, in the middle of each patch piece and at the
//! tangent point of its height profile (as the per-site horizon scan samples; the terrain within
//! [`crate::shadow::OWN_HALF_PIXEL_CELLS`] left out, as there). The engines then march the model
//! grid only beyond it, and the shadow cost of a ray is the smaller of the two.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::MapGrid;
use crate::shadow::{LightDir, OWN_HALF_PIXEL_CELLS, Observer, fraction_from_cost, unit_light};

/// How far (DEM pixels) the rays march the DEM's own lattice before the model grid takes over.
/// The resampling's height error (≈ slope × drift, a metre on a steep wall) then subtends at most
/// ≈ 1 m / (16 × 240 m) ≈ 0.015° on the 240 m LOLA grid, against 0.25° at one pixel.
pub const NEAR_FIELD_CELLS: f64 = 16.0;

impl MapGrid {
    /// The shadow cost `J = min (z_obs + t·tan e − z) / t` (model space; `t` the horizontal
    /// distance toward the light) of the DEM's own surface within [`NEAR_FIELD_CELLS`] of each
    /// observer, per DEM pixel (`+∞` where nothing is sampled: nodata, a light at the zenith).
    /// `observers` are [`MapGrid::pixel_observers`]; the cost is the one the DP engine minimises,
    /// so a disc's fraction follows from the smaller of this and the engine's.
    pub fn near_field_costs(
        &self,
        observers: &[Option<Observer>],
        light_in_model: [f64; 3],
    ) -> anyhow::Result<Vec<f64>> {
        let dir = LightDir::new(unit_light(light_in_model)?);
        let g = self.dem.grid;
        let (rows, cols) = (g.rows, g.cols);
        Ok((0..rows * cols)
            .into_par_iter()
            .map(|i| {
                let (Some(obs), Some(_)) = (observers.get(i).copied().flatten(), self.surface(i))
                else {
                    return f64::INFINITY;
                };
                if dir.hor == 0.0 {
                    return f64::INFINITY;
                }
                self.near_cost_at(i / cols, i % cols, &obs, &dir)
                    .unwrap_or(f64::INFINITY)
            })
            .collect())
    }

    /// The visible fraction of a disc of angular radius `angular_radius_rad` toward
    /// `light_in_model` left by the near field alone ([`MapGrid::near_field_costs`], the DP
    /// engine's prism occlusion; radius 0: 1 lit, 0 dark), per DEM pixel (1 where nothing is
    /// sampled).
    pub fn near_field_fractions(
        &self,
        observers: &[Option<Observer>],
        light_in_model: [f64; 3],
        angular_radius_rad: f64,
    ) -> anyhow::Result<Vec<f32>> {
        let dir = LightDir::new(unit_light(light_in_model)?);
        Ok(self
            .near_field_costs(observers, light_in_model)?
            .into_par_iter()
            .map(|j| {
                if !j.is_finite() {
                    1.0
                } else if angular_radius_rad > 0.0 {
                    fraction_from_cost(j, &dir, angular_radius_rad) as f32
                } else if j < 0.0 {
                    0.0
                } else {
                    1.0
                }
            })
            .collect())
    }

    /// Per DEM pixel, the smaller of `beyond` (the fractions from the model grid beyond the near
    /// field, e.g. [`MapGrid::pixel_points_beyond_near_field`]; `NaN` for nodata stays) and the
    /// near field's ([`MapGrid::near_field_fractions`]): a ray's cost is the smaller of the two
    /// and the fraction is monotone in it. The one place the two parts meet, for every backend.
    pub fn with_near_field(
        &self,
        beyond: &[f32],
        observers: &[Option<Observer>],
        light_in_model: [f64; 3],
        angular_radius_rad: f64,
    ) -> anyhow::Result<Vec<f32>> {
        let near = self.near_field_fractions(observers, light_in_model, angular_radius_rad)?;
        Ok(beyond
            .iter()
            .zip(&near)
            .map(|(&b, &n)| if b.is_nan() { b } else { b.min(n) })
            .collect())
    }

    /// The model-space surface point of DEM pixel `i` (row-major), `None` for nodata.
    fn surface(&self, i: usize) -> Option<&Vector3<f64>> {
        self.surface_in_model.get(i).and_then(|p| p.as_ref())
    }

    fn point(&self, r: i64, c: i64) -> Option<&Vector3<f64>> {
        let g = self.dem.grid;
        if r < 0 || c < 0 || r as usize >= g.rows || c as usize >= g.cols {
            return None;
        }
        self.surface(r as usize * g.cols + c as usize)
    }

    /// The near-field cost of pixel (`r0`, `c0`) for observer `obs`; `None` when no sample.
    fn near_cost_at(&self, r0: usize, c0: usize, obs: &Observer, dir: &LightDir) -> Option<f64> {
        let (ri, ci) = (r0 as i64, c0 as i64);
        let p0 = *self.point(ri, ci)?;
        // The observer in model space (its row/col are the model grid's).
        let (ox, oy) = self.hf.xy_from_row_col(obs.row, obs.col);
        let o = Vector3::new(ox, oy, obs.z_m);
        // The lattice's local axes in model metres (central differences where both sides exist).
        let axis = |dr: i64, dc: i64| -> Option<Vector3<f64>> {
            match (self.point(ri + dr, ci + dc), self.point(ri - dr, ci - dc)) {
                (Some(a), Some(b)) => Some((a - b) / 2.0),
                (Some(a), None) => Some(a - p0),
                (None, Some(b)) => Some(p0 - b),
                (None, None) => None,
            }
        };
        let (ec, er) = (axis(0, 1)?, axis(1, 0)?);
        // The light's horizontal direction in lattice steps: solve [ec er] (dc, dr) = u.
        let (ux, uy) = (dir.unit.x / dir.hor, dir.unit.y / dir.hor);
        let det = ec.x * er.y - er.x * ec.y;
        if det.abs() < 1e-9 {
            return None;
        }
        // A lattice point, or one step past the DEM's edge: the edge pixel's height carried half
        // a pixel further (the DEM covers its pixels' areas, as the per-site scan reads it),
        // placed along the lattice axes with the sphere's drop only.
        let (rows, cols) = (self.dem.grid.rows as i64, self.dem.grid.cols as i64);
        let pt = |r: i64, c: i64| -> Option<Vector3<f64>> {
            let (rc, cc) = (r.clamp(0, rows - 1), c.clamp(0, cols - 1));
            let (sr, sc) = ((r - rc) as f64, (c - cc) as f64);
            if sr.abs() > 1.0 || sc.abs() > 1.0 {
                return None;
            }
            let e = *self.point(rc, cc)?;
            if sr == 0.0 && sc == 0.0 {
                return Some(e);
            }
            let (dx, dy) = (sc * ec.x + sr * er.x, sc * ec.y + sr * er.y);
            let dz = -(e.x * dx + e.y * dy) / crate::MOON_RADIUS_M;
            Some(Vector3::new(e.x + dx, e.y + dy, e.z + dz))
        };
        let (r_lo, r_hi) = (-0.5, rows as f64 - 0.5);
        let (c_lo, c_hi) = (-0.5, cols as f64 - 0.5);
        let (mut dc, mut dr) = ((ux * er.y - er.x * uy) / det, (ec.x * uy - ux * ec.y) / det);
        let norm = dc.hypot(dr);
        (dc, dr) = (dc / norm, dr / norm);
        // The pixel's own position in the lattice is its centre: (r0, c0).
        let (rs, cs) = (r0 as f64, c0 as f64);
        let at = |s: f64| (rs + s * dr, cs + s * dc);
        // Crossings with the lattice lines up to NEAR_FIELD_CELLS, in order.
        // At most 2 ends, 2 × 17 line crossings and 4 edges: a fixed buffer (no allocation per
        // pixel).
        let mut buf = [0.0_f64; 48];
        buf[0] = OWN_HALF_PIXEL_CELLS;
        buf[1] = NEAR_FIELD_CELLS;
        let mut n = 2;
        let mut push = |s: f64| {
            if n < buf.len() {
                buf[n] = s;
                n += 1;
            }
        };
        let lines = |p0: f64, d: f64, push: &mut dyn FnMut(f64)| {
            if d.abs() < 1e-12 {
                return;
            }
            let (a, b) = (p0, p0 + NEAR_FIELD_CELLS * d);
            let (lo, hi) = (a.min(b).ceil() as i64, a.max(b).floor() as i64);
            for k in lo..=hi {
                let s = (k as f64 - p0) / d;
                if s > OWN_HALF_PIXEL_CELLS && s < NEAR_FIELD_CELLS {
                    push(s);
                }
            }
        };
        lines(rs, dr, &mut push);
        lines(cs, dc, &mut push);
        // The DEM's outer edge (half a pixel past the last centres) ends the near field.
        for (p0, d, lo, hi) in [(rs, dr, r_lo, r_hi), (cs, dc, c_lo, c_hi)] {
            for edge in [lo, hi] {
                if d.abs() > 1e-12 {
                    let s = (edge - p0) / d;
                    if s > OWN_HALF_PIXEL_CELLS && s < NEAR_FIELD_CELLS {
                        push(s);
                    }
                }
            }
        }
        let cuts = &mut buf[..n];
        cuts.sort_unstable_by(f64::total_cmp);
        let mut best = f64::INFINITY;
        let tan_el = dir.tan_el;
        let mut offer = |p: &Vector3<f64>| {
            let t = (p.x - o.x) * ux + (p.y - o.y) * uy;
            if t > 0.0 {
                best = best.min((o.z + t * tan_el - p.z) / t);
            }
        };
        for w in cuts.windows(2) {
            let (sa, sb) = (w[0], w[1]);
            if sb - sa < 1e-12 {
                continue;
            }
            // The patch holding the piece: its four corners (a hole or the DEM's edge ends the
            // near field there; what lies beyond is the model grid's).
            let (rm, cm) = at(0.5 * (sa + sb));
            if rm < r_lo || rm > r_hi || cm < c_lo || cm > c_hi {
                break;
            }
            let (i, j) = (rm.floor() as i64, cm.floor() as i64);
            let (Some(z00), Some(z01), Some(z10), Some(z11)) =
                (pt(i, j), pt(i, j + 1), pt(i + 1, j), pt(i + 1, j + 1))
            else {
                break;
            };
            let surf = |s: f64| {
                let (r, c) = at(s);
                let (fr, fc) = (
                    (r - i as f64).clamp(0.0, 1.0),
                    (c - j as f64).clamp(0.0, 1.0),
                );
                (1.0 - fr) * ((1.0 - fc) * z00 + fc * z01) + fr * ((1.0 - fc) * z10 + fc * z11)
            };
            let (pa, pm, pb) = (surf(sa), surf(0.5 * (sa + sb)), surf(sb));
            offer(&pa);
            offer(&pm);
            offer(&pb);
            // The tangent point of the piece's (quadratic) height profile, as the DP engine's
            // cost is least where h(s) − z_obs = C·s² (t taken as linear in s over the piece).
            let q = 2.0 * (pa.z - 2.0 * pm.z + pb.z);
            if q < 0.0 {
                let len = sb - sa;
                let p = pb.z - pa.z - q;
                let c = q / (len * len);
                let b = p / len - 2.0 * c * sa;
                let a = pa.z - b * sa - c * sa * sa;
                let ratio = (a - o.z) / c;
                if ratio > 0.0 {
                    let s_star = ratio.sqrt();
                    if s_star > sa && s_star < sb {
                        offer(&surf(s_star));
                    }
                }
            }
        }
        best.is_finite().then_some(best)
    }
}

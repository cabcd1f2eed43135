//! Synthetic terrain: a deterministic (seeded) south-polar DEM for demos, and tiny analytic DEMs
//! with closed-form answers for tests.
//!
//! The synthetic DEM ([`south_polar_dem`]) is a south-polar stereographic grid centred on the
//! pole, built from:
//! - craters with a size-frequency distribution `N(>D) ∝ D⁻²` (near lunar equilibrium), each a
//!   parabolic bowl with a raised rim and ejecta decaying as `r⁻³`; depth/diameter and rim
//!   heights follow Pike (1977): simple craters `d = 0.196 D`, rim `0.036 D`; complex craters
//!   (`D > 15 km`) `d = 1.044 D^0.301`, rim `0.236 D^0.399` (km) with a flat floor; a large young
//!   "Shackleton-like" crater (d/D = 0.2) near the pole; younger craters overprint older ones;
//! - a ridge (Gaussian cross-section, tapering ends) and a massif (a broad mound);
//! - fractal roughness: fBm of a hash-based value noise (6 octaves, gain 0.5).
//!
//! The flat DEM ([`flat`]) and any DEM of a closed-form height function ([`dem_from_fn`],
//! [`square_dem_at`]) sit on the same kind of grid.

use rayon::prelude::*;

use super::error::{DemError, Result};
use super::grid::{Dem, GridGeometry, Projection};

/// Parameters of the synthetic south-polar DEM.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthParams {
    /// Grid size, pixels (square).
    pub size_px: usize,
    /// Pixel size, metres.
    pub px_m: f64,
    /// Seed of the pseudo-random generator (same seed, same DEM, on every platform).
    pub seed: u64,
}

impl Default for SynthParams {
    /// 400 x 400 pixels of 100 m (40 km square around the pole), seed 1.
    fn default() -> Self {
        SynthParams {
            size_px: 400,
            px_m: 100.0,
            seed: 1,
        }
    }
}

/// A square south-polar stereographic grid of `n` x `n` cells of `px_m`, centred on the pole.
fn polar_grid(rows: usize, cols: usize, px_m: f64) -> GridGeometry {
    GridGeometry {
        rows,
        cols,
        x_left_m: -(cols as f64) * px_m / 2.0,
        y_top_m: rows as f64 * px_m / 2.0,
        px_x_m: px_m,
        px_y_m: px_m,
    }
}

/// A DEM of `rows` x `cols` cells of `px_m` on a south-polar stereographic grid centred on the
/// pole, with heights `f(x_m, y_m)` at the cell centres.
pub fn dem_from_fn(
    rows: usize,
    cols: usize,
    px_m: f64,
    name: &str,
    f: impl Fn(f64, f64) -> f64 + Sync,
) -> Dem {
    dem_on_grid(polar_grid(rows, cols, px_m), name, f)
}

/// A square south polar stereographic DEM of `n` x `n` cells of `px_m` centred on map point
/// (`cx_m`, `cy_m`), heights `f(x_m, y_m)` at the cell centres.
pub fn square_dem_at(
    n: usize,
    px_m: f64,
    (cx_m, cy_m): (f64, f64),
    name: &str,
    f: impl Fn(f64, f64) -> f64 + Sync,
) -> Dem {
    let mut grid = polar_grid(n, n, px_m);
    grid.x_left_m += cx_m;
    grid.y_top_m += cy_m;
    dem_on_grid(grid, name, f)
}

/// A DEM on `grid` (south polar stereographic) with heights `f(x_m, y_m)` at the cell centres.
fn dem_on_grid(grid: GridGeometry, name: &str, f: impl Fn(f64, f64) -> f64 + Sync) -> Dem {
    let (rows, cols) = (grid.rows, grid.cols);
    let mut heights_m = vec![0.0_f32; rows * cols];
    heights_m
        .par_chunks_mut(cols.max(1))
        .enumerate()
        .for_each(|(row, out)| {
            for (col, h) in out.iter_mut().enumerate() {
                let (x, y) = grid.xy_from_row_col(row as f64, col as f64);
                *h = f(x, y) as f32;
            }
        });
    Dem {
        grid,
        projection: Projection::LOLA_SOUTH_POLAR,
        heights_m,
        name: name.into(),
    }
}

/// A flat DEM at `height_m` everywhere.
pub fn flat(rows: usize, cols: usize, px_m: f64, height_m: f64) -> Dem {
    dem_from_fn(rows, cols, px_m, "synth:flat", |_, _| height_m)
}

// ------------------------------------------------------------------------------------------------
// Pseudo-random numbers and noise
// ------------------------------------------------------------------------------------------------

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny, portable, well-mixed generator.
#[derive(Debug, Clone)]
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.0)
    }
    /// Uniform in `[0, 1)`.
    fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// SplitMix64's finaliser.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of a lattice point to `[-1, 1]`.
fn lattice_value(ix: i64, iy: i64, salt: u64) -> f64 {
    let h = mix64(
        (ix as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (iy as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ salt,
    );
    (h >> 11) as f64 * (2.0 / (1u64 << 53) as f64) - 1.0
}

/// Value noise: lattice values blended with the quintic fade `6t⁵ − 15t⁴ + 10t³` (Perlin 2002),
/// so the surface is C² smooth. Range `[-1, 1]`.
fn value_noise(x: f64, y: f64, salt: u64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (u, v) = (fade(x - fx), fade(y - fy));
    let a = lattice_value(ix, iy, salt);
    let b = lattice_value(ix + 1, iy, salt);
    let c = lattice_value(ix, iy + 1, salt);
    let d = lattice_value(ix + 1, iy + 1, salt);
    let top = a + (b - a) * u;
    let bottom = c + (d - c) * u;
    top + (bottom - top) * v
}

/// Fractional Brownian motion: `octaves` of a value noise, each at twice the frequency and
/// `gain` times the amplitude of the previous one.
pub fn fbm(x: f64, y: f64, octaves: u32, gain: f64, salt: u64) -> f64 {
    let (mut sum, mut amp, mut freq) = (0.0, 1.0, 1.0);
    for o in 0..octaves {
        sum += amp * value_noise(x * freq, y * freq, salt.wrapping_add(u64::from(o) * 7919));
        amp *= gain;
        freq *= 2.0;
    }
    sum
}

// ------------------------------------------------------------------------------------------------
// The synthetic south-polar DEM
// ------------------------------------------------------------------------------------------------

/// One crater of the synthetic DEM.
#[derive(Debug, Clone, Copy)]
struct Crater {
    x_m: f64,
    y_m: f64,
    diameter_m: f64,
    depth_m: f64,
    rim_m: f64,
    /// Floor radius as a fraction of the rim radius (0 for simple bowls).
    floor_frac: f64,
}

impl Crater {
    fn from_pike(x_m: f64, y_m: f64, diameter_m: f64) -> Self {
        let d_km = diameter_m / 1000.0;
        let (depth_km, rim_km, floor_frac) = if d_km < 15.0 {
            (0.196 * d_km, 0.036 * d_km, 0.0)
        } else {
            (1.044 * d_km.powf(0.301), 0.236 * d_km.powf(0.399), 0.4)
        };
        Crater {
            x_m,
            y_m,
            diameter_m,
            depth_m: depth_km * 1000.0,
            rim_m: rim_km * 1000.0,
            floor_frac,
        }
    }

    /// Outer reach of the ejecta blanket, in rim radii.
    const REACH: f64 = 3.0;

    /// Applies the crater to the old surface height `h_old` at distance `r_m`: inside, the bowl
    /// replaces the old terrain (progressively towards the centre); outside, the rim/ejecta adds.
    fn apply(&self, r_m: f64, h_old: f64) -> f64 {
        let rc = self.diameter_m / 2.0;
        let q = r_m / rc;
        if q >= Self::REACH {
            return h_old;
        }
        if q >= 1.0 {
            let cut = Self::REACH.powi(-3);
            return h_old + self.rim_m * (q.powi(-3) - cut) / (1.0 - cut);
        }
        let floor = self.rim_m - self.depth_m;
        let t = ((q - self.floor_frac) / (1.0 - self.floor_frac)).max(0.0);
        let bowl = floor + self.depth_m * t * t;
        // Old terrain survives on the upper walls only (weight q⁴).
        let w = q.powi(4);
        bowl + w * h_old
    }
}

/// The seeded synthetic south-polar DEM (see the module docs). Errors for an empty or absurd
/// size (more than 16384 pixels a side) or a non-positive pixel size.
pub fn south_polar_dem(params: &SynthParams) -> Result<Dem> {
    let n = params.size_px;
    if n == 0 || n > 16_384 || !(params.px_m > 0.0 && params.px_m.is_finite()) {
        return Err(DemError::InvalidParameter(format!(
            "synthetic DEM of {n} px at {} m (need 1..=16384 px and a positive pixel size)",
            params.px_m
        )));
    }
    let extent_m = n as f64 * params.px_m;
    let mut rng = SplitMix64(params.seed ^ 0x5EED_0F7E_44A1);
    let seed_salt = rng.next_u64();

    // Ridge: through the domain at a seeded angle, passing beside the pole.
    let ridge_angle = rng.next_f64() * std::f64::consts::PI;
    let (ridge_dx, ridge_dy) = (ridge_angle.cos(), ridge_angle.sin());
    let ridge_offset_m = (0.15 + 0.1 * rng.next_f64()) * extent_m;
    let ridge_height_m = 1200.0;
    let ridge_sigma_m = 0.05 * extent_m;
    // Massif: a broad mound in one quadrant.
    let massif_angle = rng.next_f64() * std::f64::consts::TAU;
    let massif_r_m = 0.3 * extent_m;
    let (massif_x_m, massif_y_m) = (
        massif_r_m * massif_angle.cos(),
        massif_r_m * massif_angle.sin(),
    );
    let massif_height_m = 2500.0;
    let massif_sigma_m = 0.12 * extent_m;
    let noise_wavelength_m = extent_m / 3.0;
    let roughness_m = 150.0;

    let base = dem_from_fn(n, n, params.px_m, "synth:south-polar", |x, y| {
        // Signed distance across the ridge and position along it.
        let across = -x * ridge_dy + y * ridge_dx - ridge_offset_m;
        let along = x * ridge_dx + y * ridge_dy;
        let taper = (-(along / (0.45 * extent_m)).powi(4)).exp();
        let ridge = ridge_height_m
            * taper
            * (-(across * across) / (2.0 * ridge_sigma_m * ridge_sigma_m)).exp();
        let (mx, my) = (x - massif_x_m, y - massif_y_m);
        let massif = massif_height_m
            * (-(mx * mx + my * my) / (2.0 * massif_sigma_m * massif_sigma_m)).exp()
            * (1.0 + 0.25 * value_noise(mx / massif_sigma_m, my / massif_sigma_m, seed_salt));
        let rough = roughness_m
            * fbm(
                x / noise_wavelength_m,
                y / noise_wavelength_m,
                6,
                0.5,
                seed_salt,
            );
        ridge + massif + rough
    });

    // Craters, N(>D) = 0.05 A / D² between 4 px and 0.25 of the extent, plus the polar crater.
    let d_min_m = 4.0 * params.px_m;
    let d_max_m = 0.25 * extent_m;
    let area_m2 = extent_m * extent_m * 1.44; // include a 10 % margin around the grid
    let count = ((0.05 * area_m2 / (d_min_m * d_min_m)) as usize).min(5000);
    let mut craters: Vec<Crater> = (0..count)
        .map(|_| {
            let u = rng.next_f64().max(1e-12);
            let d = (d_min_m / u.sqrt()).min(d_max_m);
            let x = (rng.next_f64() - 0.5) * 1.2 * extent_m;
            let y = (rng.next_f64() - 0.5) * 1.2 * extent_m;
            Crater::from_pike(x, y, d)
        })
        .collect();
    // Largest first ≈ oldest first; the young polar crater goes in after the old large ones.
    craters.sort_by(|a, b| b.diameter_m.total_cmp(&a.diameter_m));
    let polar_d_m = 0.4 * extent_m;
    let polar = Crater {
        x_m: (rng.next_f64() - 0.5) * 0.1 * extent_m,
        y_m: (rng.next_f64() - 0.5) * 0.1 * extent_m,
        diameter_m: polar_d_m,
        depth_m: 0.2 * polar_d_m,
        rim_m: 0.036 * polar_d_m,
        floor_frac: 0.0,
    };
    let insert_at = craters
        .iter()
        .position(|c| c.diameter_m < 0.1 * extent_m)
        .unwrap_or(craters.len());
    craters.insert(insert_at, polar);

    let mut dem = base;
    apply_craters(&mut dem, &craters);
    Ok(dem)
}

/// Overprints `craters` on `dem` in order (later craters over earlier ones).
fn apply_craters(dem: &mut Dem, craters: &[Crater]) {
    let grid = dem.grid;
    let (rows, cols) = (grid.rows, grid.cols);
    for c in craters {
        let reach_m = Crater::REACH * c.diameter_m / 2.0;
        let (r0, c0) = grid.row_col_from_xy(c.x_m - reach_m, c.y_m + reach_m);
        let (r1, c1) = grid.row_col_from_xy(c.x_m + reach_m, c.y_m - reach_m);
        let row_lo = r0.floor().max(0.0) as usize;
        let row_hi = (r1.ceil().max(-1.0) + 1.0).min(rows as f64) as usize;
        let col_lo = c0.floor().max(0.0) as usize;
        let col_hi = (c1.ceil().max(-1.0) + 1.0).min(cols as f64) as usize;
        if row_lo >= row_hi || col_lo >= col_hi {
            continue;
        }
        dem.heights_m[row_lo * cols..row_hi * cols]
            .par_chunks_mut(cols)
            .enumerate()
            .for_each(|(i, out)| {
                let row = row_lo + i;
                for (col, h) in out.iter_mut().enumerate().take(col_hi).skip(col_lo) {
                    let (x, y) = grid.xy_from_row_col(row as f64, col as f64);
                    let r = (x - c.x_m).hypot(y - c.y_m);
                    *h = c.apply(r, f64::from(*h)) as f32;
                }
            });
    }
}

/// Pixel size of the far-field layer, in pixels of the near one.
pub const FAR_FIELD_PX_FACTOR: f64 = 10.0;

/// Smallest half-width of the far-field layer, metres: rays leaving it are then at least
/// `R (1 − cos p)` ≈ 11.5 km above the sphere for a level observer, so no ray toward the Sun
/// (at most ≈ 1.9° below the horizontal at the pole) leaves it below the sphere.
pub const FAR_FIELD_HALF_WIDTH_M: f64 = 200_000.0;

/// The far-field layer of the synthetic DEM `near` (made by [`south_polar_dem`] with
/// `params`): a south-polar grid of [`FAR_FIELD_PX_FACTOR`] times the near pixel, reaching at
/// least [`FAR_FIELD_HALF_WIDTH_M`] from the pole (and 4 near extents), generated like the near
/// one at its own scale (fBm roughness and a crater population of `N(>D) ∝ D⁻²` from 4 of its
/// pixels to 30 km, Pike profiles), equal to the near DEM over the near DEM's extent and
/// blended into it across a 10 km band, so that rays leave the near layer into terrain, not
/// into the void, and there is no cliff at its edge.
pub fn south_polar_far_field(near: &Dem, params: &SynthParams) -> Result<Dem> {
    let px_m = FAR_FIELD_PX_FACTOR * params.px_m;
    let near_half_m = params.size_px as f64 * params.px_m / 2.0;
    let half_m = FAR_FIELD_HALF_WIDTH_M.max(4.0 * near_half_m);
    let n = ((2.0 * half_m / px_m).ceil() as usize).clamp(16, 4096);
    let extent_m = n as f64 * px_m;
    let mut rng = SplitMix64(params.seed ^ 0xFA2F_1E1D_7A11);
    let salt = rng.next_u64();
    let mut far = dem_from_fn(n, n, px_m, "synth:south-polar-far", |x, y| {
        400.0 * fbm(x / (extent_m / 6.0), y / (extent_m / 6.0), 6, 0.5, salt)
    });
    let d_min_m = 4.0 * px_m;
    let d_max_m = 30_000.0f64.max(2.0 * d_min_m);
    let area_m2 = extent_m * extent_m;
    let count = ((0.05 * area_m2 / (d_min_m * d_min_m)) as usize).min(3000);
    let mut craters: Vec<Crater> = (0..count)
        .map(|_| {
            let u = rng.next_f64().max(1e-12);
            let d = (d_min_m / u.sqrt()).min(d_max_m);
            let x = (rng.next_f64() - 0.5) * extent_m;
            let y = (rng.next_f64() - 0.5) * extent_m;
            Crater::from_pike(x, y, d)
        })
        .collect();
    craters.sort_by(|a, b| b.diameter_m.total_cmp(&a.diameter_m));
    apply_craters(&mut far, &craters);

    // The near DEM over its own extent; outside, its edge blended into the far terrain.
    let blend_m = 10_000.0;
    let inner_m = near_half_m - params.px_m / 2.0;
    let grid = far.grid;
    far.heights_m
        .par_chunks_mut(n)
        .enumerate()
        .for_each(|(row, out)| {
            for (col, h) in out.iter_mut().enumerate() {
                let (x, y) = grid.xy_from_row_col(row as f64, col as f64);
                let (cx, cy) = (x.clamp(-inner_m, inner_m), y.clamp(-inner_m, inner_m));
                let Some(edge) = near.height_at_xy_m(cx, cy) else {
                    continue;
                };
                let d = (x - cx).hypot(y - cy);
                let t = (d / blend_m).clamp(0.0, 1.0);
                let w = t * t * (3.0 - 2.0 * t);
                *h = ((1.0 - w) * edge + w * f64::from(*h)) as f32;
            }
        });
    Ok(far)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_dem_is_deterministic_and_plausible() {
        let p = SynthParams {
            size_px: 128,
            px_m: 200.0,
            seed: 7,
        };
        let a = south_polar_dem(&p).unwrap();
        let b = south_polar_dem(&p).unwrap();
        assert_eq!(a.heights_m, b.heights_m, "same seed, same DEM");
        let c = south_polar_dem(&SynthParams { seed: 8, ..p }).unwrap();
        assert_ne!(a.heights_m, c.heights_m, "another seed, another DEM");
        let (lo, hi) = a
            .heights_m
            .iter()
            .fold((f32::MAX, f32::MIN), |(lo, hi), &h| (lo.min(h), hi.max(h)));
        let relief_m = f64::from(hi - lo);
        assert!((2000.0..12000.0).contains(&relief_m), "relief {relief_m} m");
        assert!(a.heights_m.iter().all(|h| h.is_finite()));
        // The young polar crater: the centre region is well below the mean.
        let mean = a.heights_m.iter().map(|&h| f64::from(h)).sum::<f64>() / (128.0 * 128.0);
        let centre = a.height_at_xy_m(0.0, 0.0).unwrap();
        assert!(centre < mean - 1000.0, "centre {centre} m, mean {mean} m");
    }

    #[test]
    fn value_noise_is_bounded_and_continuous() {
        let mut max_jump: f64 = 0.0;
        let mut prev = value_noise(0.0, 0.3, 1);
        for k in 1..10_000 {
            let v = value_noise(f64::from(k) * 1e-3, 0.3, 1);
            assert!((-1.0..=1.0).contains(&v));
            max_jump = max_jump.max((v - prev).abs());
            prev = v;
        }
        // Max slope of the quintic-faded lattice is 15/8 * 2 = 3.75 per unit; step is 1e-3.
        assert!(max_jump < 4e-3, "{max_jump}");
    }

    #[test]
    fn flat_fixture() {
        let f = flat(3, 3, 10.0, 5.0);
        assert_eq!(f.cell_height_m(1, 1), Some(5.0));
        assert_eq!(f.grid.xy_from_row_col(1.0, 1.0), (0.0, 0.0));
    }
}

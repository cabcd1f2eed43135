//! CPU twins of the GPU kernels in `shaders/`: same names, same inputs and outputs, written in f32
//! to be compared line by line with the WGSL (vello `vello_shaders/src/cpu.rs` idea).
//!
//! They are the parity oracle of the GPU backend (tests/it/gpu.rs) and the CPU fallback of the
//! GPU sweep. They are *not* the f64 reference engines of this module's siblings: the twins
//! reproduce the GPU's arithmetic (f32 heights relative to a local origin, f32 light vectors),
//! so that a GPU-vs-twin difference can only come from the GPU (rounding, FMA contraction) or
//! from a bug, never from a different algorithm.
//!
//! Ray model (shared by every kernel, see `shaders/shared/march.wgsl`): an observer stands
//! `observer_height_m` above the cell centre along the radial direction; the ray towards the light
//! is walked with a 2-D DDA over the lattice of cell centres and compared, at each lattice-line
//! crossing, with the linear interpolation of the two lattice heights on that line (the bilinear
//! surface restricted to the line). A ray that leaves the lattice is lit; holes are stored as
//! [`HOLE_Z_M`], far below any ray, so rays pass over them.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::{FAR_CELLS, HOLE_TEST_M, HOLE_Z_M, LIT, NODATA, NODATA_FRACTION, SHADOW};
use crate::MOON_RADIUS_M;
use crate::terrain::HeightField;

/// A light whose horizontal component is below this goes straight up or down.
pub(crate) const MIN_HORIZ: f32 = 1.0e-7;

/// Why a height field cannot be marched.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MarchGridError {
    /// The lattice of cell centres needs at least 2 × 2 cells for bilinear interpolation.
    #[error("the grid is {rows} × {cols} cells; the shadow march needs at least 2 × 2")]
    TooSmall {
        /// Rows of the grid.
        rows: usize,
        /// Columns of the grid.
        cols: usize,
    },
    /// Row and column indices must fit the GPU's 32-bit integers (and f32 cell units exactly).
    #[error("the grid is {rows} × {cols} cells; at most 16,777,216 per side")]
    TooLarge {
        /// Rows of the grid.
        rows: usize,
        /// Columns of the grid.
        cols: usize,
    },
    /// The observer height must be finite and not negative.
    #[error("observer height {observer_height_m} m is not a finite, non-negative number")]
    BadObserverHeight {
        /// The height given, metres.
        observer_height_m: f64,
    },
}

/// A height field prepared for the march kernels, exactly as the GPU sees it (the twin of the
/// uniform `GridParams` plus the `heights` buffer of `shaders/shared/march.wgsl`).
#[derive(Debug, Clone)]
pub struct MarchGrid {
    /// Number of rows.
    pub rows: u32,
    /// Number of columns.
    pub cols: u32,
    /// Cell size, metres.
    pub px_m: f32,
    /// Observer height above the surface along the radial direction, metres.
    pub observer_height_m: f32,
    /// Model x of the centre of cell (0, 0), metres (for the radial direction only).
    pub x0_m: f32,
    /// Model y of the centre of cell (0, 0), metres (for the radial direction only).
    pub y0_m: f32,
    /// Highest height of the grid relative to `z_ref_m`, metres.
    pub z_max_m: f32,
    /// `z_ref_m` + the Moon's radius, metres.
    pub z_ref_plus_radius_m: f32,
    /// The local height origin subtracted from every height, metres (f64, CPU only).
    pub z_ref_m: f64,
    /// Heights relative to `z_ref_m`, row-major, holes as [`HOLE_Z_M`].
    pub heights_m: Vec<f32>,
}

impl MarchGrid {
    /// Prepares `hf` for the march: heights relative to the midpoint of their range (so that
    /// f32 keeps ≤ 1 mm resolution over ±8 km of relief), holes as [`HOLE_Z_M`].
    pub fn from_height_field(
        hf: &HeightField,
        observer_height_m: f64,
    ) -> Result<Self, MarchGridError> {
        if hf.rows < 2 || hf.cols < 2 {
            return Err(MarchGridError::TooSmall {
                rows: hf.rows,
                cols: hf.cols,
            });
        }
        const MAX_SIDE: usize = 1 << 24;
        if hf.rows > MAX_SIDE || hf.cols > MAX_SIDE {
            return Err(MarchGridError::TooLarge {
                rows: hf.rows,
                cols: hf.cols,
            });
        }
        if !(observer_height_m.is_finite() && observer_height_m >= 0.0) {
            return Err(MarchGridError::BadObserverHeight { observer_height_m });
        }
        let (z_min, z_max) = hf
            .z_m
            .iter()
            .filter(|z| !z.is_nan())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &z| {
                (lo.min(f64::from(z)), hi.max(f64::from(z)))
            });
        let z_ref_m = if z_min.is_finite() {
            0.5 * (z_min + z_max)
        } else {
            0.0
        };
        let heights_m = hf
            .z_m
            .iter()
            .map(|&z| {
                if z.is_nan() {
                    HOLE_Z_M
                } else {
                    (f64::from(z) - z_ref_m) as f32
                }
            })
            .collect();
        let (x0_m, y0_m) = hf.xy_from_row_col(0.0, 0.0);
        Ok(MarchGrid {
            rows: hf.rows as u32,
            cols: hf.cols as u32,
            px_m: hf.px_m as f32,
            observer_height_m: observer_height_m as f32,
            x0_m: x0_m as f32,
            y0_m: y0_m as f32,
            z_max_m: if z_min.is_finite() {
                (z_max - z_ref_m) as f32
            } else {
                HOLE_Z_M
            },
            z_ref_plus_radius_m: (z_ref_m + MOON_RADIUS_M) as f32,
            z_ref_m,
            heights_m,
        })
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.rows as usize * self.cols as usize
    }

    #[inline]
    pub(crate) fn height_at(&self, row: i32, col: i32) -> f32 {
        self.heights_m[row as usize * self.cols as usize + col as usize]
    }
}

/// A model-space light direction reduced to the f32 `vec4` the GPU reads (normalised in f64
/// first; `w` = 0). This is the only place where the light loses precision (~6e-8 rad).
pub fn light_to_f32(light_in_model: &Vector3<f64>) -> [f32; 4] {
    let l = light_in_model.normalize();
    [l.x as f32, l.y as f32, l.z as f32, 0.0]
}

/// `n` directions spread uniformly over a disc of angular radius `radius_rad` around
/// `centre_in_model` (Fibonacci/Vogel spiral: radius √((k + ½)/n), golden-angle steps), as f32
/// `vec4`s for the soft kernel. Uniform disc: no limb darkening.
pub fn sun_disc_directions(
    centre_in_model: &Vector3<f64>,
    radius_rad: f64,
    n: usize,
) -> Vec<[f32; 4]> {
    let c = centre_in_model.normalize();
    // Any vector not parallel to c gives the tangent basis (e1, e2).
    let helper = if c.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let e1 = c.cross(&helper).normalize();
    let e2 = c.cross(&e1);
    let golden_angle_rad = std::f64::consts::PI * (3.0 - 5.0_f64.sqrt());
    let tan_radius = radius_rad.tan();
    (0..n)
        .map(|k| {
            let r = ((k as f64 + 0.5) / n as f64).sqrt() * tan_radius;
            let (s, co) = (k as f64 * golden_angle_rad).sin_cos();
            light_to_f32(&(c + r * (co * e1 + s * e2)))
        })
        .collect()
}

/// Twin of `DdaAxis` and `dda_axis` in `shaders/shared/march.wgsl`: one axis of the 2-D DDA,
/// the next lattice line, the step to the line after it, and the ray parameter `t` (cells of
/// horizontal travel) to reach it and between two lines.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DdaAxis {
    line: i32,
    step: i32,
    t_max: f32,
    t_delta: f32,
}

impl DdaAxis {
    fn new(p0: f32, d: f32) -> Self {
        let mut a = DdaAxis {
            line: 0,
            step: 0,
            t_max: FAR_CELLS,
            t_delta: FAR_CELLS,
        };
        if d > 0.0 {
            a.line = p0.floor() as i32 + 1;
            a.step = 1;
            a.t_delta = 1.0 / d;
            a.t_max = (a.line as f32 - p0) * a.t_delta;
        } else if d < 0.0 {
            a.line = p0.ceil() as i32 - 1;
            a.step = -1;
            a.t_delta = -1.0 / d;
            a.t_max = (p0 - a.line as f32) * a.t_delta;
        }
        a
    }
}

/// Twin of `Dda`, `dda_start` and `dda_next` in `shaders/shared/march.wgsl`: the DDA of the
/// horizontal ray `(u0, v0) + t (du, dv)` in grid units (direction unit) over the lattice lines.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Dda {
    u: DdaAxis,
    v: DdaAxis,
    u0: f32,
    v0: f32,
    du: f32,
    dv: f32,
}

impl Dda {
    /// `dda_start`: the DDA before its first crossing.
    pub(crate) fn start(u0: f32, v0: f32, du: f32, dv: f32) -> Self {
        Dda {
            u: DdaAxis::new(u0, du),
            v: DdaAxis::new(v0, dv),
            u0,
            v0,
            du,
            dv,
        }
    }

    /// `dda_next`: advances to the next crossing with a lattice line and returns its `t` (cells)
    /// and the surface height there, or `None` (WGSL: `inside = false`) once the ray has left
    /// the lattice by more than `edge_tol_cells` (a crossing within it is clamped onto the edge).
    pub(crate) fn next(&mut self, grid: &MarchGrid, edge_tol_cells: f32) -> Option<(f32, f32)> {
        let rows = grid.rows as i32;
        let cols = grid.cols as i32;
        let t;
        let z_surf;
        if self.u.t_max < self.v.t_max {
            t = self.u.t_max;
            let line_u = self.u.line;
            if line_u < 0 || line_u > cols - 1 {
                return None;
            }
            let v = self.v0 + t * self.dv;
            if v < -edge_tol_cells || v > (rows - 1) as f32 + edge_tol_cells {
                return None;
            }
            let vc = v.clamp(0.0, (rows - 1) as f32);
            let r0 = (vc.floor() as i32).min(rows - 2);
            let w = vc - r0 as f32;
            z_surf = grid.height_at(r0, line_u) * (1.0 - w) + grid.height_at(r0 + 1, line_u) * w;
            self.u.t_max += self.u.t_delta;
            self.u.line = line_u + self.u.step;
        } else {
            t = self.v.t_max;
            let line_v = self.v.line;
            if line_v < 0 || line_v > rows - 1 {
                return None;
            }
            let u = self.u0 + t * self.du;
            if u < -edge_tol_cells || u > (cols - 1) as f32 + edge_tol_cells {
                return None;
            }
            let uc = u.clamp(0.0, (cols - 1) as f32);
            let c0 = (uc.floor() as i32).min(cols - 2);
            let w = uc - c0 as f32;
            z_surf = grid.height_at(line_v, c0) * (1.0 - w) + grid.height_at(line_v, c0 + 1) * w;
            self.v.t_max += self.v.t_delta;
            self.v.line = line_v + self.v.step;
        }
        Some((t, z_surf))
    }
}

/// Twin of `march_hard` in `shaders/shared/march.wgsl`: [`LIT`], [`SHADOW`] or [`NODATA`] for
/// cell (row, col) and the light direction `light` (model space, unit).
pub fn march_hard(grid: &MarchGrid, row: u32, col: u32, light: [f32; 3]) -> u32 {
    let z_cell = grid.heights_m[(row * grid.cols + col) as usize];
    if z_cell < HOLE_TEST_M {
        return NODATA;
    }
    let x_m = grid.x0_m + col as f32 * grid.px_m;
    let y_m = grid.y0_m - row as f32 * grid.px_m;
    let up = normalize3([x_m, y_m, z_cell + grid.z_ref_plus_radius_m]);
    let u0 = col as f32 + grid.observer_height_m * up[0] / grid.px_m;
    let v0 = row as f32 - grid.observer_height_m * up[1] / grid.px_m;
    let z0 = z_cell + grid.observer_height_m * up[2];
    let horiz_len = (light[0] * light[0] + light[1] * light[1]).sqrt();
    if horiz_len < MIN_HORIZ {
        return if light[2] > 0.0 { LIT } else { SHADOW };
    }
    let du = light[0] / horiz_len;
    let dv = -light[1] / horiz_len;
    let rise_m_per_cell = light[2] / horiz_len * grid.px_m;
    let mut dda = Dda::start(u0, v0, du, dv);
    let max_steps = grid.rows as i32 + grid.cols as i32 + 4;
    for _ in 0..max_steps {
        let Some((t, z_surf)) = dda.next(grid, 0.0) else {
            return LIT;
        };
        let z_ray = z0 + t * rise_m_per_cell;
        if z_ray > grid.z_max_m && rise_m_per_cell >= 0.0 {
            return LIT;
        }
        if z_surf > z_ray {
            return SHADOW;
        }
    }
    LIT
}

pub(crate) fn normalize3(v: [f32; 3]) -> [f32; 3] {
    let inv_len = 1.0 / (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] * inv_len, v[1] * inv_len, v[2] * inv_len]
}

/// Which rows a dispatch covers (the twin of `StepParams` in `shaders/shared/march.wgsl`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowBand {
    /// First row of the band.
    pub row0: u32,
    /// Number of rows of the band.
    pub rows: u32,
}

impl RowBand {
    /// The whole grid as one band.
    pub fn whole(grid: &MarchGrid) -> Self {
        RowBand {
            row0: 0,
            rows: grid.rows,
        }
    }
}

/// Twin of `shaders/shadow_march.wgsl`: the hard-shadow band (row-major, band-relative) for
/// `lights[light_index]`: [`LIT`], [`SHADOW`] or [`NODATA`] per cell. Rayon over rows.
pub fn shadow_march(
    grid: &MarchGrid,
    lights: &[[f32; 4]],
    light_index: u32,
    band: RowBand,
) -> Vec<u32> {
    let l = lights[light_index as usize];
    let light = [l[0], l[1], l[2]];
    let cols = grid.cols as usize;
    let mut out = vec![NODATA; band.rows as usize * cols];
    out.par_chunks_mut(cols)
        .enumerate()
        .for_each(|(band_row, out_row)| {
            for (col, o) in out_row.iter_mut().enumerate() {
                *o = march_hard(grid, band.row0 + band_row as u32, col as u32, light);
            }
        });
    out
}

/// Twin of `shaders/shadow_march_soft.wgsl`: per cell of the band, the fraction of the
/// directions in `lights` that are lit, or [`NODATA_FRACTION`] for a hole. Rayon over rows.
pub fn shadow_march_soft(grid: &MarchGrid, lights: &[[f32; 4]], band: RowBand) -> Vec<f32> {
    let cols = grid.cols as usize;
    let n = lights.len() as u32;
    let mut out = vec![NODATA_FRACTION; band.rows as usize * cols];
    out.par_chunks_mut(cols)
        .enumerate()
        .for_each(|(band_row, out_row)| {
            let row = band.row0 + band_row as u32;
            'cell: for (col, o) in out_row.iter_mut().enumerate() {
                let mut lit = 0_u32;
                for l in lights {
                    let state = march_hard(grid, row, col as u32, [l[0], l[1], l[2]]);
                    if state == NODATA {
                        *o = NODATA_FRACTION;
                        continue 'cell;
                    }
                    lit += state;
                }
                *o = lit as f32 / n as f32;
            }
        });
    out
}

/// Running per-cell statistics of an epoch sweep (the twin of `CellStats` in
/// `shaders/sweep_accumulate.wgsl`). Counts are in epochs.
// Keep in sync with shaders/sweep_accumulate.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CellStats {
    /// Number of epochs at which the cell was lit.
    pub lit_epochs: u32,
    /// Length of the dark run that is still going on at the last epoch folded in.
    pub dark_run_epochs: u32,
    /// Longest run of consecutive dark epochs.
    pub longest_dark_run_epochs: u32,
    /// 1 if the cell was lit at least once, else 0 (never lit = permanently shadowed).
    pub ever_lit: u32,
}
const _: () = assert!(size_of::<CellStats>() == 16);

/// Twin of `shaders/sweep_accumulate.wgsl` for one cell: folds one epoch's hard-shadow `state`
/// into `stats` (holes leave it untouched).
pub fn sweep_accumulate(state: u32, stats: &mut CellStats) {
    if state == NODATA {
        return;
    }
    if state == LIT {
        stats.lit_epochs += 1;
        stats.dark_run_epochs = 0;
        stats.ever_lit = 1;
    } else {
        stats.dark_run_epochs += 1;
        stats.longest_dark_run_epochs = stats.longest_dark_run_epochs.max(stats.dark_run_epochs);
    }
}

/// CPU twin of the whole GPU epoch sweep: for every cell of `band`, march towards each light of
/// `lights` in order (one per epoch) and fold the result with [`sweep_accumulate`]. Rayon over
/// cells; the epoch loop is inner so each cell's runs are sequential in time.
pub fn sweep_stats(grid: &MarchGrid, lights: &[[f32; 4]], band: RowBand) -> Vec<CellStats> {
    let cols = grid.cols as usize;
    let mut stats = vec![CellStats::default(); band.rows as usize * cols];
    stats
        .par_chunks_mut(cols)
        .enumerate()
        .for_each(|(band_row, stats_row)| {
            let row = band.row0 + band_row as u32;
            for (col, s) in stats_row.iter_mut().enumerate() {
                for l in lights {
                    let state = march_hard(grid, row, col as u32, [l[0], l[1], l[2]]);
                    sweep_accumulate(state, s);
                }
            }
        });
    stats
}

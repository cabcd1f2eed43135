//! The f32 grid every grid kernel reads ([`MarchGrid`]: heights relative to a local origin, as
//! the GPU sees them), the light reduced to f32 ([`light_to_f32`]), the band of rows a dispatch
//! covers ([`RowBand`]), and the twin of the 2-D DDA of `shaders/shared/march.wgsl` (`Dda`,
//! used by the Fourier build).
//!
//! Ray model (`shaders/shared/march.wgsl`): an observer stands `observer_height_m` above the cell
//! centre along the radial direction; the ray towards the light is walked with a 2-D DDA over the
//! lattice of cell centres and compared, at each lattice-line crossing, with the linear
//! interpolation of the two lattice heights on that line (the bilinear surface restricted to the
//! line). Holes are stored as [`HOLE_Z_M`], far below any ray, so rays pass over them.

use nalgebra::Vector3;

use super::{FAR_CELLS, HOLE_Z_M};
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

/// A height field prepared for the grid kernels, exactly as the GPU sees it (the twin of the
/// uniform `GridParams` plus the `heights` buffer of `shaders/shared/march.wgsl` and `DpGridParams`
/// of `shaders/shared/dp.wgsl`).
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

pub(crate) fn normalize3(v: [f32; 3]) -> [f32; 3] {
    let inv_len = 1.0 / (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] * inv_len, v[1] * inv_len, v[2] * inv_len]
}

/// Which rows a dispatch covers (the band fields of `DpStep` in `shaders/shared/dp.wgsl`).
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

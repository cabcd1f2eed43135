//! CPU twins of the GPU kernels in `shaders/`, all in one place (vello `vello_shaders/src/cpu/`):
//! one file per shader family, each function named as the WGSL entry point it mirrors, written
//! in f32 to be compared line by line with the WGSL.
//!
//! They are the parity oracle of the GPU backend (tests/it/gpu/), *not* the f64 reference
//! engines of [`crate::shadow`] and [`crate::horizon`]: they reproduce the GPU's arithmetic (f32
//! heights relative to a local origin, f32 light vectors), so that a GPU-vs-twin difference can
//! only come from the GPU (rounding, FMA contraction) or from a bug. The sentinels the kernels
//! share are defined here once. `render.wgsl` has no twin here: its CPU counterpart is the f64
//! renderer ([`crate::render`]).
//!
//! | file | shaders |
//! |---|---|
//! | [`march`] | `shared/march.wgsl` (the grid and the DDA of `fourier_build.wgsl`) |
//! | [`dp`] | `shared/dp.wgsl`, `dp_visible.wgsl`, `dp_sweep.wgsl`, `dp_sites.wgsl`, `dp_points.wgsl`, `dp_points_sweep.wgsl` |
//! | [`dp_tiles`] | `shared/dp_tile.wgsl`, `dp_tile_cost.wgsl`, `dp_tile_fraction.wgsl`, `dp_tile_sweep_cost.wgsl`, `dp_tile_sweep_accumulate.wgsl` |
//! | [`fourier`] | `fourier_build.wgsl`, `fourier_eval.wgsl` |
//! | [`horizon_scan`] | `horizon_scan.wgsl` |
//! | [`horizon_stats`] | `horizon_stats.wgsl` |
//! | [`line_sweep`] | `line_sweep.wgsl` |

pub mod dp;
pub mod dp_tiles;
pub mod fourier;
pub mod horizon_scan;
pub mod horizon_stats;
pub mod line_sweep;
pub mod march;

pub use dp::*;
pub use march::*;

/// Output of the visible-fraction kernels for a hole.
pub const NODATA_FRACTION: f32 = -1.0;
/// A hard-mask fraction (1 / 0, `NaN` nodata) as a mask byte.
pub fn mask_of_fraction(f: f32) -> u8 {
    if f.is_nan() {
        crate::shadow::MASK_NODATA
    } else if f > 0.5 {
        crate::shadow::MASK_LIT
    } else {
        crate::shadow::MASK_SHADOW
    }
}

/// A soft-shadow kernel output as a fraction: `NaN` for a hole
/// ([`NODATA_FRACTION`], -1), else clamped to [0, 1] (f32 rounding
/// leaves a few lit-edge cells at -1e-7, which a `< 0` hole test would turn into holes).
pub fn fraction_from_gpu(f: f32) -> f32 {
    if f < NODATA_FRACTION + 0.5 {
        f32::NAN
    } else {
        f.clamp(0.0, 1.0)
    }
}

/// Height stored for a hole (NaN never goes to the GPU: WGSL has no NaN guarantees).
pub const HOLE_Z_M: f32 = -1.0e30;
/// Heights below this are holes.
pub(crate) const HOLE_TEST_M: f32 = -1.0e29;
/// "Never" for the DDA ray parameter, cells.
pub(crate) const FAR_CELLS: f32 = 1.0e30;
/// Value written for every coefficient of a hole cell by the Fourier build kernel.
pub const HOLE_COEFF: f32 = HOLE_Z_M;
/// "No sample" for the horizon scan's heights and best tangent.
pub const NO_SAMPLE: f32 = HOLE_Z_M;

/// The kernels' nodata-aware bilinear height at fractional (`row`, `col`) of a `rows` × `cols`
/// layer whose cells `cell(row, col)` reads (holes below [`HOLE_TEST_M`], [`NO_SAMPLE`] outside):
/// [`NO_SAMPLE`] outside the outer cell edges, when the nearest centre is a hole, or with no valid
/// corner; else the weighted mean of the valid corners (as `Dem::height_at_row_col`). The twin of
/// `height_at` in horizon_scan.wgsl and line_sweep.wgsl.
pub(crate) fn bilinear_with_holes(
    rows: u32,
    cols: u32,
    row: f32,
    col: f32,
    cell: impl Fn(i32, i32) -> f32,
) -> f32 {
    let (n_rows, n_cols) = (rows as f32, cols as f32);
    if !(row >= -0.5 && col >= -0.5 && row <= n_rows - 0.5 && col <= n_cols - 0.5) {
        return NO_SAMPLE;
    }
    let r = row.clamp(0.0, n_rows - 1.0);
    let c = col.clamp(0.0, n_cols - 1.0);
    let r0 = (r.floor() as i32).min(rows as i32 - 2).max(0);
    let c0 = (c.floor() as i32).min(cols as i32 - 2).max(0);
    let fr = r - r0 as f32;
    let fc = c - c0 as f32;
    let rn = (row + 0.5).floor().clamp(0.0, n_rows - 1.0) as i32;
    let cn = (col + 0.5).floor().clamp(0.0, n_cols - 1.0) as i32;
    if cell(rn, cn) < HOLE_TEST_M {
        return NO_SAMPLE;
    }
    let mut sum = 0.0;
    let mut wsum = 0.0;
    for dr in 0..2 {
        let wr = if dr == 1 { fr } else { 1.0 - fr };
        for dc in 0..2 {
            let w = wr * if dc == 1 { fc } else { 1.0 - fc };
            if w <= 0.0 {
                continue;
            }
            let h = cell(r0 + dr, c0 + dc);
            if h >= HOLE_TEST_M {
                sum += w * h;
                wsum += w;
            }
        }
    }
    if wsum > 0.0 {
        return sum / wsum;
    }
    NO_SAMPLE
}

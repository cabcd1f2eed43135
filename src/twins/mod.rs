//! CPU twins of the GPU kernels in `shaders/`, all in one place (vello `vello_shaders/src/cpu/`):
//! one file per shader family, each function named as the WGSL entry point it mirrors, written
//! in f32 to be compared line by line with the WGSL.
//!
//! They are the parity oracle of the GPU backend (tests/it/gpu*.rs) and the CPU fallback of the
//! GPU sweep. They are *not* the f64 reference engines of [`crate::shadow`] and
//! [`crate::horizon`]: the twins reproduce the GPU's arithmetic (f32 heights relative to a local
//! origin, f32 light vectors), so that a GPU-vs-twin difference can only come from the GPU
//! (rounding, FMA contraction) or from a bug, never from a different algorithm.
//!
//! | file | shaders |
//! |---|---|
//! | [`march`] | `shared/march.wgsl`, `shadow_march.wgsl`, `shadow_march_soft.wgsl`, `sweep_accumulate.wgsl` |
//! | [`dp`] | `shared/dp.wgsl`, `dp_visible.wgsl`, `dp_sweep.wgsl`, `dp_sites.wgsl` |
//! | [`dp_tiles`] | `dp_tile_cost.wgsl`, `dp_tile_fraction.wgsl`, `dp_tile_sweep_cost.wgsl`, `dp_tile_sweep_accumulate.wgsl` |
//! | [`fourier`] | `fourier_build.wgsl`, `fourier_eval.wgsl` |
//! | [`horizon_scan`] | `horizon_scan.wgsl` |
//! | [`line_sweep`] | `line_sweep.wgsl` |
//!
//! The sentinels the kernels share (hole markers, "lit"/"shadow" codes) are defined here once.

pub mod dp;
pub mod dp_tiles;
pub mod fourier;
pub mod horizon_scan;
pub mod line_sweep;
pub mod march;

pub use dp::*;
pub use march::*;

/// Output of the hard-shadow kernels: the cell is lit.
pub const LIT: u32 = 1;
/// Output of the hard-shadow kernels: the cell is in shadow.
pub const SHADOW: u32 = 0;
/// Output of the hard-shadow kernels: the cell is a hole (no terrain).
pub const NODATA: u32 = 255;
/// Output of the soft-shadow kernel for a hole.
pub const NODATA_FRACTION: f32 = -1.0;
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

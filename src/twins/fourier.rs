//! CPU twins (f32, line by line) of `shaders/fourier_build.wgsl` and `shaders/fourier_eval.wgsl`,
//! the GPU build and evaluation of the Fourier horizon maps of [`super::fourier`] (paper 001),
//! plus the host-side data layout both sides share: the uniforms [`FourierBuildParams`] and
//! [`FourierEvalParams`], the `(sin, cos)` table of [`azimuth_table`], the packed f16
//! coefficients of [`pack_coeffs`], and the conversion of the kernel's f32 output into a
//! [`HorizonMap`] identical in layout to the CPU engine's ([`horizon_map_from_f32`]).
//!
//! As with every twin, a GPU-vs-twin difference can only come from GPU rounding (atan,
//! FMA contraction) or a bug; a twin-vs-engine difference comes from f32 against f64 (heights
//! relative to the grid's `z_ref`, cell-unit positions, the azimuth directions rounded to f32).
//!
//! **Build** (one invocation per cell): for each azimuth `θ_n = 2πn/N` the horizontal ray is
//! marched over every crossing with the lines joining cell centres (the DDA of
//! `shaders/shared/march.wgsl`, the brute-force engine's surface), keeping the largest
//! `(z − z_obs) / t` from the bare sphere's horizon up ([`sphere_floor_tan`]), until the grid edge, the distance
//! limit, or `(z_max − z_obs) / t ≤ best`; `α_n = atan(best)` is folded straight into the DFT sums
//! `acc_k += α_n (cos kθ_n, −sin kθ_n)` with the twiddles read from the same `(sin, cos)` table at
//! index `k n mod N`. The azimuths of a build are split into dispatches of `az_count`; the partial
//! sums are kept in the output between dispatches; the last one applies the weights `1/N`, `2/N`.

use bytemuck::{Pod, Zeroable};
use half::f16;
use rayon::prelude::*;

pub use super::HOLE_COEFF;
use super::march::{Dda, MarchGrid, normalize3};
use super::{HOLE_TEST_M, NODATA_FRACTION};
use crate::shadow::ShadowError;
use crate::shadow::fourier::{HorizonMap, HorizonMapMeta, az_el, half_span_rad};

/// A crossing this close outside the lattice (cells) is clamped onto its edge line, as the CPU
/// engine's march does within 1e-9 (f64): a ray along an edge row or column must sample it.
const EDGE_TOL_CELLS: f32 = 1.0e-3;
/// Largest number of complex coefficients the build kernel accumulates (`2K ≤ 64` partial sums).
pub const MAX_GPU_COEFFS: usize = 32;
/// The packed `Re X_0` of a hole in the evaluation kernel's input: `f16::MIN` (−65504).
const HOLE_PACKED_RE: f16 = f16::MIN;
/// `Re X_0` below this is a hole (a real one is an angle in [−π/2, π/2]).
const FE_HOLE_TEST: f32 = -60000.0;

/// The build kernel's uniform. Keep in sync with `FourierBuildParams` in
/// `shaders/fourier_build.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FourierBuildParams {
    /// First row of the band.
    pub band_row0: u32,
    /// Rows of the band.
    pub band_rows: u32,
    /// Number of azimuths of the whole build (`N`).
    pub n_az: u32,
    /// First azimuth of this dispatch.
    pub az0: u32,
    /// Azimuths of this dispatch.
    pub az_count: u32,
    /// Complex coefficients kept (`K ≤` [`MAX_GPU_COEFFS`]).
    pub n_coeffs: u32,
    /// Crossings farther than this (cells of horizontal travel) are not sampled.
    pub max_distance_cells: f32,
    /// 1 when this dispatch holds the last azimuths (the weights are applied), else 0.
    pub last: u32,
}
const _: () = assert!(size_of::<FourierBuildParams>() == 32);

/// `(sin, cos)` of `2πm/N` for `m = 0 … N−1`, computed in f64 and rounded to f32: the azimuth
/// directions (east, north components) and the DFT twiddles (index `k n mod N`) of the build.
pub fn azimuth_table(n_az: usize) -> Vec<[f32; 2]> {
    (0..n_az)
        .map(|m| {
            let (s, c) = (std::f64::consts::TAU * m as f64 / n_az as f64).sin_cos();
            [s as f32, c as f32]
        })
        .collect()
}

/// Twin of `fb_sphere_floor_tan` in `shaders/fourier_build.wgsl`: the start value of
/// [`horizon_tan`], the bare sphere's horizon (the dip `sqrt(2h/R)` below the observer's local
/// horizontal, `h` its height above the sphere) as `tan` above the model x/y plane; see
/// [`crate::shadow::fourier`] for why Fourier profiles have this floor.
pub fn sphere_floor_tan(
    grid: &MarchGrid,
    x_m: f32,
    y_m: f32,
    z0: f32,
    up: [f32; 3],
    sc: [f32; 2],
) -> f32 {
    const R: f32 = crate::MOON_RADIUS_M as f32;
    let tan_local = -(up[0] * sc[0] + up[1] * sc[1]) / up[2];
    let h = z0 + (grid.z_ref_plus_radius_m - R) + (x_m * x_m + y_m * y_m) / (2.0 * R);
    let dip = (2.0 * h.max(0.0) / R).sqrt();
    (tan_local.atan() - dip).tan()
}

/// Twin of `horizon_tan` in `shaders/fourier_build.wgsl`: the largest `tan` of the terrain's
/// elevation along the horizontal ray from `(u0, v0, z0)` in grid direction `(du, dv)`, at least
/// `start_tan`, within `max_distance_cells` (the shader's `grid` and `fb` are its globals).
pub fn horizon_tan(
    (grid, max_distance_cells): (&MarchGrid, f32),
    (u0, v0, z0): (f32, f32, f32),
    (du, dv): (f32, f32),
    start_tan: f32,
) -> f32 {
    let mut best = start_tan;
    let mut dda = Dda::start(u0, v0, du, dv);
    let max_steps = grid.rows as i32 + grid.cols as i32 + 4;
    for _ in 0..max_steps {
        let Some((t, z_surf)) = dda.next(grid, EDGE_TOL_CELLS) else {
            return best;
        };
        if t > max_distance_cells {
            return best;
        }
        let t_m = t * grid.px_m;
        best = best.max((z_surf - z0) / t_m);
        // Beyond t no sample rises above (z_max - z0) / t' (t' >= t): the bound at t when the
        // top is above the observer, else 0 (approached as t' grows).
        if ((grid.z_max_m - z0) / t_m).max(0.0) <= best {
            return best;
        }
    }
    best
}

/// Twin of one invocation of `fourier_build`: updates `acc` (the cell's `2K` values of the band
/// output: partial sums, or the weighted coefficients after the last dispatch).
pub fn fourier_build_cell(
    grid: &MarchGrid,
    sincos: &[[f32; 2]],
    fb: &FourierBuildParams,
    row: u32,
    col: u32,
    acc: &mut [f32],
) {
    let per = 2 * fb.n_coeffs as usize;
    let z_cell = grid.heights_m[(row * grid.cols + col) as usize];
    if z_cell < HOLE_TEST_M {
        acc[..per].fill(HOLE_COEFF);
        return;
    }
    let x_m = grid.x0_m + col as f32 * grid.px_m;
    let y_m = grid.y0_m - row as f32 * grid.px_m;
    let up = normalize3([x_m, y_m, z_cell + grid.z_ref_plus_radius_m]);
    let u0 = (col as f32 + grid.observer_height_m * up[0] / grid.px_m)
        .clamp(0.0, (grid.cols - 1) as f32);
    let v0 = (row as f32 - grid.observer_height_m * up[1] / grid.px_m)
        .clamp(0.0, (grid.rows - 1) as f32);
    let z0 = z_cell + grid.observer_height_m * up[2];
    if fb.az0 == 0 {
        acc[..per].fill(0.0);
    }
    for a in 0..fb.az_count {
        let n = fb.az0 + a;
        let sc = sincos[n as usize];
        let alpha = horizon_tan(
            (grid, fb.max_distance_cells),
            (u0, v0, z0),
            (sc[0], -sc[1]),
            sphere_floor_tan(grid, x_m, y_m, z0, up, sc),
        )
        .atan();
        let mut m = 0_u32;
        for k in 0..fb.n_coeffs as usize {
            let tw = sincos[m as usize];
            acc[2 * k] += alpha * tw[1];
            acc[2 * k + 1] -= alpha * tw[0];
            m += n;
            if m >= fb.n_az {
                m -= fb.n_az;
            }
        }
    }
    if fb.last == 1 {
        let w0 = 1.0 / fb.n_az as f32;
        let w = 2.0 / fb.n_az as f32;
        acc[0] *= w0;
        acc[1] *= w0;
        for v in &mut acc[2..per] {
            *v *= w;
        }
    }
}

/// Twin of one dispatch of `shaders/fourier_build.wgsl` over the band of `fb`: `band_out` holds
/// `band_rows × cols × 2K` values (band-relative), read and written. Rayon over rows.
pub fn fourier_build(
    grid: &MarchGrid,
    sincos: &[[f32; 2]],
    fb: &FourierBuildParams,
    band_out: &mut [f32],
) {
    let per = 2 * fb.n_coeffs as usize;
    let cols = grid.cols as usize;
    band_out
        .par_chunks_mut(cols * per)
        .take(fb.band_rows as usize)
        .enumerate()
        .for_each(|(band_row, line)| {
            let row = fb.band_row0 + band_row as u32;
            for (col, acc) in line.chunks_exact_mut(per).enumerate() {
                fourier_build_cell(grid, sincos, fb, row, col as u32, acc);
            }
        });
}

/// The dispatches of a build over `rows_per_band`-row bands and `az_per_dispatch`-azimuth chunks,
/// in execution order (band by band, azimuth chunks in order), as the GPU runner issues them.
pub fn build_dispatches(
    rows: u32,
    n_az: u32,
    n_coeffs: u32,
    max_distance_cells: usize,
    rows_per_band: u32,
    az_per_dispatch: u32,
) -> Vec<FourierBuildParams> {
    let mut out = Vec::new();
    let (rows_per_band, az_per_dispatch) = (rows_per_band.max(1), az_per_dispatch.max(1));
    let mut row0 = 0;
    while row0 < rows {
        let band_rows = rows_per_band.min(rows - row0);
        let mut az0 = 0;
        while az0 < n_az {
            let az_count = az_per_dispatch.min(n_az - az0);
            out.push(FourierBuildParams {
                band_row0: row0,
                band_rows,
                n_az,
                az0,
                az_count,
                n_coeffs,
                max_distance_cells: max_distance_cells as f32,
                last: u32::from(az0 + az_count == n_az),
            });
            az0 += az_count;
        }
        row0 += band_rows;
    }
    out
}

/// The whole build on the twin (one band, one dispatch: the result does not depend on the
/// banding): `rows × cols × 2K` f32 values, [`HOLE_COEFF`] for holes.
pub fn build_coeffs_twin(grid: &MarchGrid, n_az: usize, n_coeffs: usize, max_d: usize) -> Vec<f32> {
    let sincos = azimuth_table(n_az);
    let mut out = vec![0.0; grid.cells() * 2 * n_coeffs];
    for fb in build_dispatches(
        grid.rows,
        n_az as u32,
        n_coeffs as u32,
        max_d,
        grid.rows,
        n_az as u32,
    ) {
        fourier_build(grid, &sincos, &fb, &mut out);
    }
    out
}

/// A [`HorizonMap`] from the build kernel's f32 output (row-major, `2K` per cell): each value
/// rounded to f16 as the CPU engine stores it; [`HOLE_COEFF`] becomes NaN.
pub fn horizon_map_from_f32(meta: HorizonMapMeta, values: &[f32]) -> HorizonMap {
    let coeffs = values
        .iter()
        .map(|&v| {
            if v < HOLE_TEST_M {
                f16::NAN
            } else {
                f16::from_f32(v)
            }
        })
        .collect();
    HorizonMap { meta, coeffs }
}

/// The evaluation kernel's uniform. Keep in sync with `FourierEvalParams` in
/// `shaders/fourier_eval.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FourierEvalParams {
    /// Rows of the map.
    pub rows: u32,
    /// Columns of the map.
    pub cols: u32,
    /// Complex coefficients per cell.
    pub n_coeffs: u32,
    /// First row of the band.
    pub band_row0: u32,
    /// Rows of the band.
    pub band_rows: u32,
    /// Padding.
    pub _pad: [u32; 3],
    /// `(cos, sin)` of the light's azimuth.
    pub mid: [f32; 2],
    /// `(cos, sin)` of the disc's left edge azimuth.
    pub left: [f32; 2],
    /// `(cos, sin)` of the disc's right edge azimuth.
    pub right: [f32; 2],
    /// The light's elevation above the model x/y plane, radians.
    pub el_rad: f32,
    /// The disc's angular radius, radians (0: hard mask).
    pub radius_rad: f32,
}
const _: () = assert!(size_of::<FourierEvalParams>() == 64);

impl FourierEvalParams {
    /// The uniform for a map with metadata `meta` and a disc of angular radius `angular_radius_rad` centred on
    /// `light_in_model`: azimuth, elevation and edge azimuths in f64 as the CPU engine's
    /// `visible_fraction`, then (cos, sin) rounded to f32. Band fields are zero (the runner sets
    /// them).
    pub fn new(
        meta: &HorizonMapMeta,
        light_in_model: [f64; 3],
        angular_radius_rad: f64,
    ) -> Result<Self, ShadowError> {
        crate::shadow::check_radius(angular_radius_rad)?;
        let l = crate::shadow::unit_light(light_in_model)?;
        let (az, el) = az_el(&l);
        let half_span = half_span_rad(el, angular_radius_rad);
        let cs = |a: f64| [a.cos() as f32, a.sin() as f32];
        Ok(FourierEvalParams {
            rows: meta.rows as u32,
            cols: meta.cols as u32,
            n_coeffs: meta.n_coeffs as u32,
            band_row0: 0,
            band_rows: 0,
            _pad: [0; 3],
            mid: cs(az),
            left: cs(az - half_span),
            right: cs(az + half_span),
            el_rad: el as f32,
            radius_rad: angular_radius_rad as f32,
        })
    }
}

/// The coefficients of `map` as the evaluation kernel reads them: one u32 per complex
/// coefficient, `Re` in the low and `Im` in the high 16 bits (the f16 bit patterns); a hole
/// has `Re X_0` = `f16::MIN` and zeros elsewhere.
pub fn pack_coeffs(map: &HorizonMap) -> Vec<u32> {
    let nk = map.meta.n_coeffs;
    let mut out = Vec::with_capacity(map.coeffs.len() / 2);
    for cell in map.coeffs.chunks_exact(2 * nk) {
        if cell[0].is_nan() {
            out.push(u32::from(HOLE_PACKED_RE.to_bits()));
            out.extend(std::iter::repeat_n(0, nk - 1));
            continue;
        }
        out.extend(
            cell.chunks_exact(2)
                .map(|p| u32::from(p[0].to_bits()) | (u32::from(p[1].to_bits()) << 16)),
        );
    }
    out
}

/// Twin of WGSL `unpack2x16float`.
fn unpack2x16float(v: u32) -> [f32; 2] {
    [
        f16::from_bits(v as u16).to_f32(),
        f16::from_bits((v >> 16) as u16).to_f32(),
    ]
}

/// Twin of `fe_series`: paper 001 eq. 3 at the azimuth whose `(cos, sin)` is `cs`, the
/// `cos kθ`, `sin kθ` by the rotation recurrence.
pub fn fe_series(coeffs: &[u32], base: usize, n_coeffs: u32, cs: [f32; 2]) -> f32 {
    let (mut c, mut s, mut sum) = (1.0_f32, 0.0_f32, 0.0_f32);
    for k in 0..n_coeffs as usize {
        let x = unpack2x16float(coeffs[base + k]);
        sum += x[0] * c - x[1] * s;
        let c_next = c * cs[0] - s * cs[1];
        s = s * cs[0] + c * cs[1];
        c = c_next;
    }
    sum
}

/// Twin of one invocation of `fourier_eval`: the visible fraction (radius 0: 1 / 0) of cell
/// `cell` of the band whose packed coefficients are `coeffs`, or [`NODATA_FRACTION`] for a hole.
pub fn fourier_eval_cell(coeffs: &[u32], fe: &FourierEvalParams, cell: usize) -> f32 {
    let base = cell * fe.n_coeffs as usize;
    if unpack2x16float(coeffs[base])[0] < FE_HOLE_TEST {
        return NODATA_FRACTION;
    }
    let mid = fe_series(coeffs, base, fe.n_coeffs, fe.mid);
    let r = fe.radius_rad;
    if r <= 0.0 {
        return if fe.el_rad > mid { 1.0 } else { 0.0 };
    }
    let left = fe_series(coeffs, base, fe.n_coeffs, fe.left) - fe.el_rad;
    let right = fe_series(coeffs, base, fe.n_coeffs, fe.right) - fe.el_rad;
    let m = 0.5 * (left + right);
    let k = (right - left) / (2.0 * r);
    let d = m / (1.0 + k * k).sqrt();
    let x = d / r;
    if x <= -1.0 {
        1.0
    } else if x < 1.0 {
        (x.acos() - x * (1.0 - x * x).sqrt()) / std::f32::consts::PI
    } else {
        0.0
    }
}

/// Twin of `shaders/fourier_eval.wgsl` over a whole map (one band): per cell the visible
/// fraction or the 1 / 0 hard test (radius 0), [`NODATA_FRACTION`] for holes. Rayon over rows.
pub fn fourier_eval(map: &HorizonMap, fe: &FourierEvalParams) -> Vec<f32> {
    let coeffs = pack_coeffs(map);
    let cols = map.meta.cols.max(1);
    let mut out = vec![NODATA_FRACTION; map.meta.rows * map.meta.cols];
    out.par_chunks_mut(cols)
        .enumerate()
        .for_each(|(row, line)| {
            for (col, o) in line.iter_mut().enumerate() {
                *o = fourier_eval_cell(&coeffs, fe, row * map.meta.cols + col);
            }
        });
    out
}

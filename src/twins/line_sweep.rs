//! CPU twin of `shaders/line_sweep.wgsl`: the looks of the whole-grid line sweep
//! ([`crate::horizon::HorizonSweep`]) in f32, one invocation per (line, look), and the packing of
//! the CPU sweep's lines for it.
//!
//! **Split of the work.** The CPU builds each line's samples exactly as its own sweep does
//! ([`HorizonSweep::with_line`]: the finest layer's crossings with concave refinement, every
//! coarser layer beyond) and packs them here ([`LineBatch`]); the kernel does what the CPU
//! profile spends most of its time on — the upper convex hull of the samples passed (Graham's
//! scan, O(1) amortised per sample), the tangent from every observer (binary search) and the
//! observer's own half-pixel piece (two bilinear reads of the finest layer). A line's hull lives
//! in its own slice of one storage buffer, as long as the line has samples, so it can never
//! overflow.
//!
//! The kernel writes `(tan el, Δψ)` pairs ([`NO_SAMPLE`] where the look sees no terrain);
//! [`to_band_values`] turns them into the CPU sweep's `(elevation °, distance m)`.
//! [`sweep_batched`] drives a whole sweep through either the twin or the GPU runner
//! (`crate::gpu::line_sweep`) and hands out bands as [`HorizonSweep::run`] does. The precision
//! budget (f32) is on [`line_sweep`].

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::HOLE_TEST_M;
pub use super::{HOLE_Z_M, NO_SAMPLE};
use crate::MOON_RADIUS_M;
use crate::horizon::{HorizonSweep, SweepBand, SweepScratch, SweptLine};

/// Invocations per workgroup. Keep in sync with shaders/line_sweep.wgsl.
pub const WORKGROUP_SIZE: u32 = 64;
/// Bit of [`LineRecord::looks`]: the forward look (toward increasing `t`) is wanted.
pub const LOOK_FORWARD: u32 = 1;
/// Bit of [`LineRecord::looks`]: the backward look is wanted.
pub const LOOK_BACKWARD: u32 = 2;
/// Most hull vertices the tangent climbs from the binary search's vertex (see
/// [`line_sweep`]). Keep in sync with the WGSL.
pub const CLIMB_STEPS: usize = 64;
/// Samples of a line closer than this along it (map metres; the f32 spacing of the hull frame
/// is ≤ 0.06 m) are packed as one
/// ([`LineBatch::push_line`]).
pub const SAME_T_M: f64 = 0.05;
/// Lines built on the CPU per parallel chunk of [`sweep_batched`].
pub const CHUNK_LINES: usize = 256;

/// The kernel's uniform. Keep in sync with `Params` in shaders/line_sweep.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
pub struct LineSweepParams {
    /// Lines in the batch.
    pub n_lines: u32,
    /// Samples in the batch (the stride between the two looks' hull slices).
    pub n_samples: u32,
    /// Rows and columns of the finest layer.
    pub rows: u32,
    /// Columns of the finest layer.
    pub cols: u32,
    /// Cell width and height of the finest layer, metres.
    pub px_x_m: f32,
    /// Cell height of the finest layer, metres.
    pub px_y_m: f32,
    /// Half a pixel as a ground angle, radians ([`HorizonSweep::theta_min_rad`]).
    pub theta_min_rad: f32,
    /// Observer height above the ground, metres.
    pub observer_height_m: f32,
    /// The finest layer's pixel size, metres (the observer's own piece when no sample is passed).
    pub px_m: f32,
    /// Workgroups along x of the dispatch (invocation id = x + y · groups_x · 64).
    pub groups_x: u32,
    /// Rows of the first coarser layer, stored in the heights after the finest layer (0: none).
    pub coarse_rows: u32,
    /// Columns of the first coarser layer.
    pub coarse_cols: u32,
    /// The coarser layer's fractional row at the finest layer's row 0.
    pub coarse_row0: f32,
    /// The coarser layer's fractional column at the finest layer's column 0.
    pub coarse_col0: f32,
    /// Coarser rows per finest row.
    pub coarse_row_scale: f32,
    /// Coarser columns per finest column.
    pub coarse_col_scale: f32,
}
const _: () = assert!(size_of::<LineSweepParams>() == 64);

/// One line of a batch. Keep in sync with `Line` in shaders/line_sweep.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
pub struct LineRecord {
    /// First sample of the line in the batch's samples, and their count.
    pub sample_start: u32,
    /// Samples of the line.
    pub sample_count: u32,
    /// First observer of the line in the batch's observers, and their count.
    pub obs_start: u32,
    /// Observers of the line.
    pub obs_count: u32,
    /// `L` of the line, metres.
    pub l_m: f32,
    /// `1 / (2 ρc)`.
    pub inv_two_rho_c: f32,
    /// Map direction of increasing `t`.
    pub ell_x: f32,
    /// Map direction of increasing `t`, y component.
    pub ell_y: f32,
    /// [`LOOK_FORWARD`] | [`LOOK_BACKWARD`]: the looks wanted.
    pub looks: u32,
    /// Padding.
    pub _pad: [u32; 3],
}
const _: () = assert!(size_of::<LineRecord>() == 48);

/// One sample. Keep in sync with `Sample` in shaders/line_sweep.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
pub struct SampleRecord {
    /// Hull frame `r sin ψ`, metres.
    pub x_m: f32,
    /// Hull frame `r cos ψ − R`, metres.
    pub y_m: f32,
    /// `ψ = psi_hi + psi_lo`, radians (`psi_hi` the f32 nearest to ψ).
    pub psi_hi: f32,
    /// The remainder of ψ.
    pub psi_lo: f32,
    /// Height above the sphere, metres.
    pub h_m: f32,
}
const _: () = assert!(size_of::<SampleRecord>() == 20);

/// One observer. Keep in sync with `Observer` in shaders/line_sweep.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
pub struct ObserverRecord {
    /// Index of the observer's sample within its line.
    pub sample: u32,
    /// Row-major pixel index on the finest layer.
    pub pixel: u32,
}

/// The terrain the kernel reads for the observers' own pieces (the finest layer, then the first
/// coarser one: at the grid's edge a piece reaches past the finest layer) and the
/// batch-independent uniform fields.
///
/// The f64 sweep falls back to every coarser layer in turn; the kernel reads only the first.
/// They differ only where that layer has a hole just outside the finest layer.
pub struct SweepGrid {
    /// Uniform fields that do not depend on the batch.
    pub params: LineSweepParams,
    /// The finest layer's heights, row-major, then the first coarser layer's; holes as
    /// [`HOLE_Z_M`].
    pub heights_m: Vec<f32>,
}

impl SweepGrid {
    /// The finest and first coarser layers of `sweep`'s stack and the parameters.
    pub fn new(sweep: &HorizonSweep) -> Self {
        let dem = sweep.grid_dem();
        let g = &dem.grid;
        let as_stored = |h: &f32| if h.is_finite() { *h } else { HOLE_Z_M };
        let mut params = LineSweepParams {
            rows: g.rows as u32,
            cols: g.cols as u32,
            px_x_m: g.px_x_m as f32,
            px_y_m: g.px_y_m as f32,
            theta_min_rad: sweep.theta_min_rad() as f32,
            observer_height_m: sweep.params().observer_height_m as f32,
            px_m: dem.px_m() as f32,
            ..LineSweepParams::default()
        };
        let mut heights_m: Vec<f32> = dem.heights_m.iter().map(as_stored).collect();
        // All layers share the map projection (checked by `HorizonSweep::new`), so a coarser
        // layer's (row, col) is affine in the finest layer's, without rotation.
        if let Some(coarse) = sweep.stack().layers.get(1) {
            let c = &coarse.grid;
            let (x0, y0) = g.xy_from_row_col(0.0, 0.0);
            let (row0, col0) = c.row_col_from_xy(x0, y0);
            params.coarse_rows = c.rows as u32;
            params.coarse_cols = c.cols as u32;
            params.coarse_row0 = row0 as f32;
            params.coarse_col0 = col0 as f32;
            params.coarse_row_scale = (g.px_y_m / c.px_y_m) as f32;
            params.coarse_col_scale = (g.px_x_m / c.px_x_m) as f32;
            heights_m.extend(coarse.heights_m.iter().map(as_stored));
        }
        SweepGrid { params, heights_m }
    }
}

/// A batch of packed lines (the kernel's storage buffers).
#[derive(Debug, Default, Clone)]
pub struct LineBatch {
    /// The lines.
    pub lines: Vec<LineRecord>,
    /// Every line's samples, line after line.
    pub samples: Vec<SampleRecord>,
    /// Every line's observers in the kept rows, line after line.
    pub observers: Vec<ObserverRecord>,
}

impl LineBatch {
    /// Packs `line` with the looks `looks`, keeping the observers whose pixel is in `kept`.
    /// Samples at the same `t` (to [`SAME_T_M`]: a layer's edge value and the next layer's
    /// first value, a piece end read twice) become one, the highest: on one radial line the
    /// highest point has the highest elevation from every observer, so no horizon changes (5 cm
    /// apart: by less than the slope times 5 cm over the distance), and the f32 hull never holds
    /// nearly coincident vertices, whose edge directions rounding decides.
    pub fn push_line(&mut self, line: &SweptLine<'_>, looks: u32, kept: &std::ops::Range<usize>) {
        if !line.observers.iter().any(|o| kept.contains(&o.pixel)) {
            return;
        }
        let sample_start = self.samples.len() as u32;
        let mut index_of = Vec::with_capacity(line.samples.len());
        let mut last_t = f64::NEG_INFINITY;
        let mut last_r = f64::NEG_INFINITY;
        for s in line.samples {
            let same = s.t_m - last_t <= SAME_T_M;
            if !same || s.r_m > last_r {
                let psi_hi = s.psi_rad as f32;
                let rec = SampleRecord {
                    x_m: s.x_m as f32,
                    y_m: (s.y_m - MOON_RADIUS_M) as f32,
                    psi_hi,
                    psi_lo: (s.psi_rad - f64::from(psi_hi)) as f32,
                    h_m: (s.r_m - MOON_RADIUS_M) as f32,
                };
                if same {
                    *self.samples.last_mut().expect("a sample before") = rec;
                } else {
                    self.samples.push(rec);
                }
                last_r = s.r_m;
            }
            if !same {
                last_t = s.t_m;
            }
            index_of.push(self.samples.len() as u32 - 1 - sample_start);
        }
        let obs_start = self.observers.len() as u32;
        self.observers.extend(
            line.observers
                .iter()
                .filter(|o| kept.contains(&o.pixel))
                .map(|o| ObserverRecord {
                    sample: index_of[o.sample],
                    pixel: o.pixel as u32,
                }),
        );
        self.lines.push(LineRecord {
            sample_start,
            sample_count: self.samples.len() as u32 - sample_start,
            obs_start,
            obs_count: self.observers.len() as u32 - obs_start,
            l_m: line.l_m as f32,
            inv_two_rho_c: (0.5 / line.rho_c) as f32,
            ell_x: line.ell.0 as f32,
            ell_y: line.ell.1 as f32,
            looks,
            _pad: [0; 3],
        });
    }

    /// Appends `other`, shifting its indices.
    pub fn append(&mut self, other: &LineBatch) {
        let (s0, o0) = (self.samples.len() as u32, self.observers.len() as u32);
        self.lines.extend(other.lines.iter().map(|l| LineRecord {
            sample_start: l.sample_start + s0,
            obs_start: l.obs_start + o0,
            ..*l
        }));
        self.samples.extend_from_slice(&other.samples);
        self.observers.extend_from_slice(&other.observers);
    }

    /// Empties the batch, keeping its allocations.
    pub fn clear(&mut self) {
        self.lines.clear();
        self.samples.clear();
        self.observers.clear();
    }
}

/// `sin t` by its Taylor series (|t| ≤ 0.6: error < 1e-10). As `sin_series` in the WGSL.
#[inline]
pub fn sin_series(t: f32) -> f32 {
    let t2 = t * t;
    t * (1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))))
}

/// `1 − cos t` by its Taylor series. As `one_minus_cos_series` in the WGSL.
#[inline]
pub fn one_minus_cos_series(t: f32) -> f32 {
    let t2 = t * t;
    t2 / 2.0 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0 * (1.0 - t2 / 90.0))))
}

/// `tan a` for the small `a = ψ / (2 ρc)` (≤ 0.2): three terms (error < 1e-7 relative).
#[inline]
fn tan_series(a: f32) -> f32 {
    let a2 = a * a;
    a * (1.0 + a2 / 3.0 * (1.0 + 0.4 * a2))
}

/// `tan` of the elevation of a terrain point `dpsi` (> 0) ahead of an observer whose eye is
/// `h_eye_m` above the sphere, on the unrolled cone (see the module docs).
#[inline]
fn tan_rel(dpsi: f32, h_p_m: f32, h_eye_m: f32) -> f32 {
    let r_p = MOON_RADIUS_M as f32 + h_p_m;
    let x = r_p * sin_series(dpsi);
    let y = (h_p_m - h_eye_m) - r_p * one_minus_cos_series(dpsi);
    y / x
}

/// Signed `ψ_p − ψ_o` from the hi/lo pairs (the hi difference of nearby arcs is exact).
#[inline]
fn dpsi_of(p: &SampleRecord, o: &SampleRecord) -> f32 {
    (p.psi_hi - o.psi_hi) + (p.psi_lo - o.psi_lo)
}

/// Nodata-aware bilinear height at fractional (row, col) of the layer stored from
/// `heights[0]` with `rows` × `cols` cells (`layer_height` of line_sweep.wgsl).
fn layer_height(heights: &[f32], rows: u32, cols: u32, row: f32, col: f32) -> f32 {
    super::bilinear_with_holes(rows, cols, row, col, |r, c| {
        if r < 0 || c < 0 || r >= rows as i32 || c >= cols as i32 {
            return NO_SAMPLE;
        }
        heights[r as usize * cols as usize + c as usize]
    })
}

/// The stack's height at fractional (row, col) of the finest layer: the finest layer's, else
/// (outside it or in a hole) the first coarser layer's (`height_at` of line_sweep.wgsl).
fn height_at(params: &LineSweepParams, heights: &[f32], row: f32, col: f32) -> f32 {
    let fine_len = params.rows as usize * params.cols as usize;
    let h = layer_height(&heights[..fine_len], params.rows, params.cols, row, col);
    if h >= HOLE_TEST_M || params.coarse_rows == 0 {
        return h;
    }
    layer_height(
        &heights[fine_len..],
        params.coarse_rows,
        params.coarse_cols,
        params.coarse_row0 + row * params.coarse_row_scale,
        params.coarse_col0 + col * params.coarse_col_scale,
    )
}

/// One hull vertex: `(x, y)` in the (mirrored) hull frame and the sample index.
#[derive(Debug, Clone, Copy, Default)]
struct Vertex {
    x: f32,
    y: f32,
    sample: u32,
}

/// The kernel twin: `out[2 · observer + look]` = `(tan el, Δψ rad)` for every line and wanted
/// look of `batch` (look 0 forward, 1 backward; unwanted looks stay `[0, 0]`).
///
/// **Precision (f32).** Absolute radii have an f32 spacing of 0.125 m (0.015° at 240 m), so
/// nothing here is an absolute radius:
/// - the hull is kept in a line-local frame `x = r sin ψ`, `y = r cos ψ − R = h cos ψ − 2 R
///   sin²(ψ/2)` (the CPU's frame shifted by the constant `R`, so every orientation test is the
///   same; coordinates rounded from f64, spacing ≤ 0.03 m within ±500 km of the line's foot). It
///   only decides *which* sample is the tangent;
/// - elevations are evaluated relative to the observer on the unrolled cone: with
///   `Δψ = ψ_p − ψ_o` (ψ stored as an f32 pair `hi + lo`, so that the difference of two nearby
///   arcs is exact), `x′ = r_p sin Δψ`, `y′ = (h_p − h_o − h_obs) − r_p (1 − cos Δψ)`, heights
///   differenced directly, sine and `1 − cos` as Taylor series (WGSL only promises 2⁻¹¹ absolute
///   error for its built-ins). The CPU sweep evaluates the same tangent vertex in exact 3-D; the
///   unrolled cone differs from it by at most ≈ 7e-5 rad (0.004°, the CPU's `NEAR_TIE_RAD`
///   comment), exactly 0 on lines through the pole;
/// - the observer's own piece: the CPU reads the surface at `t_start = t(ψ_o ± θ_min)` and at
///   the midpoint in `t` between it and the first sample passed; here the same two points are
///   placed from the observer's pixel centre with `dt/dψ` at the observer (linear over at most
///   two pixels: ≤ 5 mm off on the map) and the midpoint is taken in `ψ` (the same point to
///   ≈ 1 mm).
pub fn line_sweep(grid: &SweepGrid, batch: &LineBatch) -> Vec<[f32; 2]> {
    let params = LineSweepParams {
        n_lines: batch.lines.len() as u32,
        n_samples: batch.samples.len() as u32,
        ..grid.params
    };
    let mut out = vec![[0.0_f32; 2]; 2 * batch.observers.len()];
    // Lines own disjoint observer ranges: split the output by line.
    let mut slices: Vec<(&LineRecord, &mut [[f32; 2]])> = Vec::with_capacity(batch.lines.len());
    let mut rest = out.as_mut_slice();
    let mut at = 0usize;
    for line in &batch.lines {
        let start = 2 * line.obs_start as usize;
        let (_, tail) = rest.split_at_mut(start - at);
        let (mine, tail) = tail.split_at_mut(2 * line.obs_count as usize);
        slices.push((line, mine));
        rest = tail;
        at = start + 2 * line.obs_count as usize;
    }
    slices
        .into_par_iter()
        .for_each_init(Vec::new, |hull, (line, out)| {
            for look in 0..2 {
                if line.looks & (1 << look) != 0 {
                    look_line(&params, &grid.heights_m, batch, line, look, hull, out);
                }
            }
        });
    out
}

/// One (line, look) invocation; `out` holds the line's observers' outputs. Line by line with
/// `line_sweep` in shaders/line_sweep.wgsl.
fn look_line(
    params: &LineSweepParams,
    heights: &[f32],
    batch: &LineBatch,
    line: &LineRecord,
    look: u32,
    hull: &mut Vec<Vertex>,
    out: &mut [[f32; 2]],
) {
    let forward = look == 0;
    let sign: f32 = if forward { 1.0 } else { -1.0 };
    let n = line.sample_count;
    let samples = &batch.samples[line.sample_start as usize..][..n as usize];
    let th = params.theta_min_rad;
    let h_obs = params.observer_height_m;
    hull.clear();
    let mut next = 0u32;
    for k in 0..line.obs_count {
        let kk = if forward { line.obs_count - 1 - k } else { k };
        let ob = batch.observers[(line.obs_start + kk) as usize];
        let so = samples[ob.sample as usize];
        // Every sample at least half a pixel ahead joins the hull.
        while next < n {
            let qi = if forward { n - 1 - next } else { next };
            let q = samples[qi as usize];
            if sign * dpsi_of(&q, &so) < th {
                break;
            }
            let (qx, qy) = (sign * q.x_m, q.y_m);
            while let [.., c, b] = hull.as_slice() {
                let cross = (b.x - qx) * (c.y - b.y) - (b.y - qy) * (c.x - b.x);
                if cross >= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(Vertex {
                x: qx,
                y: qy,
                sample: qi,
            });
            next += 1;
        }
        let h_eye = so.h_m + h_obs;
        let mut best_tan = NO_SAMPLE;
        let mut best_dpsi = 0.0_f32;
        let mut offer = |tan: f32, dpsi: f32| {
            if tan > best_tan {
                best_tan = tan;
                best_dpsi = dpsi;
            }
        };
        // The observer's own piece: half a pixel out, and midway to the first sample passed.
        let tau_o = tan_series(so.psi_hi * line.inv_two_rho_c);
        let dt_dpsi = line.l_m * (1.0 + tau_o * tau_o) * line.inv_two_rho_c;
        let dpsi_first = if next > 0 {
            let fi = if forward { n - next } else { next - 1 };
            sign * dpsi_of(&samples[fi as usize], &so)
        } else {
            th + params.px_m / dt_dpsi
        };
        let row_o = (ob.pixel / params.cols) as f32;
        let col_o = (ob.pixel % params.cols) as f32;
        for j in 0..2 {
            let dpsi = if j == 0 { th } else { 0.5 * (th + dpsi_first) };
            let dt = sign * dpsi * dt_dpsi;
            let row = row_o - dt * line.ell_y / params.px_y_m;
            let col = col_o + dt * line.ell_x / params.px_x_m;
            let h = height_at(params, heights, row, col);
            if h >= HOLE_TEST_M {
                offer(tan_rel(dpsi, h, h_eye), dpsi);
            }
        }
        let slot = 2 * (kk as usize) + look as usize;
        if hull.is_empty() {
            out[slot] = [best_tan, best_dpsi];
            continue;
        }
        // The tangent from the observer's eye: along the hull (farthest vertex first) the
        // elevations seen from the eye rise to the tangent vertex and fall after it, so a binary
        // search finds it. The search compares the elevations themselves (relative to the
        // observer, precise), not orientations in the f32 hull frame, which rounding decides for
        // nearly coincident vertices; a short climb then corrects a landing that rounding of the
        // hull itself (a vertex kept or dropped by mistake) left beside the best vertex.
        let tan_at = |i: usize| {
            let p = samples[hull[i].sample as usize];
            let dpsi = sign * dpsi_of(&p, &so);
            (tan_rel(dpsi, p.h_m, h_eye), dpsi)
        };
        let (mut lo, mut hi) = (0usize, hull.len() - 1);
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if tan_at(mid - 1).0 > tan_at(mid).0 {
                hi = mid - 1;
            } else {
                lo = mid;
            }
        }
        let mut cur = tan_at(lo);
        let farther = if lo > 0 {
            tan_at(lo - 1)
        } else {
            (NO_SAMPLE, 0.0)
        };
        let nearer = if lo + 1 < hull.len() {
            tan_at(lo + 1)
        } else {
            (NO_SAMPLE, 0.0)
        };
        if farther.0 > cur.0 && farther.0 >= nearer.0 {
            cur = farther;
            let mut i = lo - 1;
            while i > 0 && i + CLIMB_STEPS > lo {
                let t = tan_at(i - 1);
                if t.0 <= cur.0 {
                    break;
                }
                (cur, i) = (t, i - 1);
            }
        } else if nearer.0 > cur.0 {
            cur = nearer;
            let mut i = lo + 1;
            while i + 1 < hull.len() && i < lo + CLIMB_STEPS {
                let t = tan_at(i + 1);
                if t.0 <= cur.0 {
                    break;
                }
                (cur, i) = (t, i + 1);
            }
        }
        offer(cur.0, cur.1);
        out[slot] = [best_tan, best_dpsi];
    }
}

/// A kernel output as the CPU sweep's band values: `(elevation deg, distance m)`; `(−90, NaN)`
/// where the look sees no terrain.
pub fn to_band_values(o: [f32; 2]) -> (f32, f32) {
    if o[0] < HOLE_TEST_M {
        return (-90.0, f32::NAN);
    }
    (
        f64::from(o[0]).atan().to_degrees() as f32,
        (f64::from(o[1]) * MOON_RADIUS_M) as f32,
    )
}

/// Packs lines `keys` of one canonical direction in parallel.
fn pack_chunk(
    sweep: &HorizonSweep,
    canonical: (i32, i32),
    keys: std::ops::Range<i64>,
    looks: u32,
) -> LineBatch {
    let cols = sweep.grid_dem().grid.cols;
    let rows = sweep.rows();
    let kept = rows.start * cols..rows.end * cols;
    keys.into_par_iter()
        .fold(
            || (SweepScratch::default(), LineBatch::default()),
            |(mut scratch, mut batch), key| {
                sweep.with_line(canonical, key, &mut scratch, |line| {
                    batch.push_line(&line, looks, &kept)
                });
                (scratch, batch)
            },
        )
        .map(|(_, b)| b)
        .reduce(LineBatch::default, |mut a, b| {
            a.append(&b);
            a
        })
}

/// The whole sweep with the looks run by `run_batch` (the twin [`line_sweep`] or the GPU),
/// in batches of at most `max_samples` samples: bands handed to `sink` as
/// [`HorizonSweep::run`] does (the same band order and layout).
///
/// Packing and looks overlap: a scoped thread builds and packs the lines of the next batch (on
/// rayon's pool) while this thread runs the current one and scatters its looks into the bands;
/// the batches, their order and so the outputs are those of packing and running in turn. At
/// most two batches are alive at once (a rendezvous channel: the packer waits until the last
/// batch is taken). When `run_batch` or `sink` fails, the packer stops at its next hand-over.
pub fn sweep_batched<E>(
    sweep: &HorizonSweep,
    max_samples: usize,
    mut run_batch: impl FnMut(&LineBatch) -> Result<Vec<[f32; 2]>, E>,
    mut sink: impl FnMut(SweepBand<'_>) -> Result<(), E>,
    mut progress: impl FnMut(usize),
) -> Result<(), E> {
    let cols = sweep.grid_dem().grid.cols;
    let rows = sweep.rows();
    let first_px = rows.start * cols;
    let n_px = rows.len() * cols;
    let directions = sweep.line_directions();
    std::thread::scope(|scope| {
        // (direction, a batch of its lines or none, whether it is the direction's last).
        let (tx, rx) = std::sync::mpsc::sync_channel::<(usize, Option<LineBatch>, bool)>(0);
        let packer_directions = &directions;
        scope.spawn(move || {
            for (d, &(canonical, forward, backward)) in packer_directions.iter().enumerate() {
                let looks = if forward.is_some() { LOOK_FORWARD } else { 0 }
                    | if backward.is_some() { LOOK_BACKWARD } else { 0 };
                let mut batch = LineBatch::default();
                let keys = sweep.line_keys(canonical);
                let mut k = *keys.start();
                while k <= *keys.end() {
                    let k_end = (k + CHUNK_LINES as i64).min(*keys.end() + 1);
                    let chunk = pack_chunk(sweep, canonical, k..k_end, looks);
                    if !batch.samples.is_empty()
                        && batch.samples.len() + chunk.samples.len() > max_samples
                    {
                        let full = std::mem::take(&mut batch);
                        if tx.send((d, Some(full), false)).is_err() {
                            return;
                        }
                    }
                    batch.append(&chunk);
                    k = k_end;
                }
                let last = (!batch.lines.is_empty()).then_some(batch);
                if tx.send((d, last, true)).is_err() {
                    return;
                }
            }
        });
        let mut done = 0;
        // Band values: [forward, backward] × (elevation, distance).
        let new_bands = || -> [(Vec<f32>, Vec<f32>); 2] {
            [
                (vec![f32::NAN; n_px], vec![f32::NAN; n_px]),
                (vec![f32::NAN; n_px], vec![f32::NAN; n_px]),
            ]
        };
        let mut bands = new_bands();
        // Returning drops `rx`, which stops the packer at its next `send`.
        for (d, batch, last) in rx {
            if let Some(batch) = batch {
                let out = run_batch(&batch)?;
                for line in &batch.lines {
                    for k in 0..line.obs_count as usize {
                        let oi = line.obs_start as usize + k;
                        let px = batch.observers[oi].pixel as usize - first_px;
                        for (look, band) in bands.iter_mut().enumerate() {
                            if line.looks & (1 << look) != 0 {
                                let (el_deg, dist_m) = to_band_values(out[2 * oi + look]);
                                band.0[px] = el_deg;
                                band.1[px] = dist_m;
                            }
                        }
                    }
                }
            }
            if last {
                let (_, forward, backward) = directions[d];
                for (look, band) in [forward, backward].into_iter().enumerate() {
                    let Some(index) = band else { continue };
                    let (el, dist) = &bands[look];
                    sink(SweepBand {
                        index,
                        direction: sweep.directions()[index],
                        rows: rows.clone(),
                        elevation_deg: el,
                        distance_m: dist,
                    })?;
                    done += 1;
                    progress(done);
                }
                bands = new_bands();
            }
        }
        Ok(())
    })
}

/// Largest batch of [`sweep_twin`], samples (as lavapipe's, 128 MiB / 32 B).
pub const TWIN_BATCH_SAMPLES: usize = 1 << 22;

/// The whole sweep through the twin: [`sweep_batched`] with [`line_sweep`] (the GPU
/// kernel's arithmetic on the CPU; the parity oracle of the GPU runner).
pub fn sweep_twin<E>(
    sweep: &HorizonSweep,
    sink: impl FnMut(SweepBand<'_>) -> Result<(), E>,
    progress: impl FnMut(usize),
) -> Result<(), E> {
    let grid = SweepGrid::new(sweep);
    sweep_batched(
        sweep,
        TWIN_BATCH_SAMPLES,
        |batch| Ok(line_sweep(&grid, batch)),
        sink,
        progress,
    )
}

//! CPU twin of `shaders/horizon_stats.wgsl`: the horizons engine's per-cell epoch loop
//! ([`crate::horizon::statistics`]) in f32, one invocation per cell over a batch of epochs, with
//! the statistics kept in a [`KernelAcc`] per cell between batches.
//!
//! Per epoch and body: the body's centre relative to the cell's observer in the cell's (map +x,
//! map +y, up) frame; its elevation; a disc entirely above the cell's highest horizon (1) or
//! below its lowest (0) needs nothing more; the others take their grid azimuth, the horizon
//! between the two neighbouring bands, and the visible fraction: the circular segment under the
//! horizon's chord across the disc (the Sun, flux-weighted through its chord table) or, for the
//! Earth (uniform), the horizon polyline across the disc: see `polyline_fraction`. Then the statistics in time order, as the CPU engine.
//! `atan2` is the engine's polynomial ([`atan2_deg`]), written out in the WGSL too, so both
//! sides round alike.

use std::sync::Arc;

use rayon::prelude::*;

use crate::horizon::HorizonError;
use crate::horizon::statistics::{
    CellKernel, EPOCH_CHUNK, KernelAcc, KernelCell, KernelEpoch, KernelShared, atan2_deg,
};

/// Invocations per workgroup (one cell each).
pub const WORKGROUP_SIZE: u32 = 64;
/// Most bands inside one disc's span that the polyline takes (the CPU engine's bound).
pub const MAX_POLY_POINTS: usize = 64;

/// The kernel's uniform block (48 B).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct HorizonStatsParams {
    /// Cells of this dispatch.
    pub n_cells: u32,
    /// Horizon values per cell (`n_bands + 1`).
    pub stride: u32,
    /// Bands.
    pub n_bands: u32,
    /// Bins of the azimuth index.
    pub n_index: u32,
    /// First epoch of the batch (a multiple of [`EPOCH_CHUNK`]).
    pub epoch_begin: u32,
    /// One past the batch's last epoch.
    pub epoch_end: u32,
    /// Workgroups along x (the grid is 2-D past the per-dimension limit).
    pub groups_x: u32,
    /// Intervals of each chord table.
    pub chord_bins: u32,
    /// The first band's grid azimuth, degrees.
    pub a0_deg: f32,
    /// Index bins per degree.
    pub bins_per_deg: f32,
    /// "Visible" above this fraction.
    pub visible_min: f32,
    /// "Full" from this fraction.
    pub full_min: f32,
}

impl HorizonStatsParams {
    /// The parameters of `shared` for `n_cells` cells over epochs `begin..end`.
    pub fn new(shared: &KernelShared, n_cells: usize, begin: usize, end: usize) -> Self {
        HorizonStatsParams {
            n_cells: n_cells as u32,
            stride: shared.n_bands() as u32 + 1,
            n_bands: shared.n_bands() as u32,
            n_index: shared.index.len() as u32,
            epoch_begin: begin as u32,
            epoch_end: end as u32,
            groups_x: 0,
            chord_bins: shared.chord_sun.len() as u32 - 1,
            a0_deg: shared.a0_deg,
            bins_per_deg: shared.bins_per_deg,
            visible_min: shared.visible_min,
            full_min: shared.full_min,
        }
    }
}

/// The tables in the kernel's one `f32` storage array: `rel_deg` (n + 1), `inv_width` (n),
/// `band_az_deg` (n), the Sun's chord table, the Earth's (`chord_bins + 1` each).
pub fn packed_tables(shared: &KernelShared) -> Vec<f32> {
    let mut t = Vec::with_capacity(
        3 * shared.n_bands() + 1 + shared.chord_sun.len() + shared.chord_earth.len(),
    );
    t.extend_from_slice(&shared.rel_deg);
    t.extend_from_slice(&shared.inv_width);
    t.extend_from_slice(&shared.band_az_deg);
    t.extend_from_slice(&shared.chord_sun);
    t.extend_from_slice(&shared.chord_earth);
    t
}

/// The tables as the kernel reads them.
struct Tables<'a> {
    p: &'a HorizonStatsParams,
    t: &'a [f32],
    index: &'a [u32],
}

impl Tables<'_> {
    fn rel(&self, k: usize) -> f32 {
        self.t[k]
    }
    fn inv_width(&self, k: usize) -> f32 {
        self.t[self.p.n_bands as usize + 1 + k]
    }
    fn band_az(&self, k: usize) -> f32 {
        self.t[2 * self.p.n_bands as usize + 1 + k]
    }
    fn chord(&self, earth: bool, x: f32) -> f32 {
        let bins = self.p.chord_bins as usize;
        let base = 3 * self.p.n_bands as usize + 1 + usize::from(earth) * (bins + 1);
        let t = (x.clamp(-1.0, 1.0) + 1.0) * (bins as f32 * 0.5);
        let i = (t as i32).clamp(0, bins as i32 - 1) as usize;
        let f = t - i as f32;
        let (a, b) = (self.t[base + i], self.t[base + i + 1]);
        a + f * (b - a)
    }
    /// The band segment holding grid azimuth `az_deg` and the azimuth relative to the first
    /// band in [0, 360) (`AzimuthLookup::segment`).
    fn segment(&self, az_deg: f32) -> (usize, f32) {
        let r0 = az_deg - self.p.a0_deg;
        let r = r0 - 360.0 * (r0 * (1.0 / 360.0)).floor();
        let last = self.p.n_index as i32 - 1;
        let j = ((r * self.p.bins_per_deg) as i32).clamp(0, last) as usize;
        let k0 = self.index[j] as usize;
        let k = (k0 + usize::from(r >= self.rel(k0 + 1))).min(self.p.n_bands as usize - 1);
        (k, r)
    }
    fn horizon(&self, h: &[f32], az_deg: f32) -> f32 {
        let (k, r) = self.segment(az_deg);
        let w = (r - self.rel(k)) * self.inv_width(k);
        h[k] + w * (h[k + 1] - h[k])
    }
}

/// `∫ √(r² − u²) du` (twin of `half_chord_integral`).
fn half_chord_integral(r: f32, u: f32) -> f32 {
    let x = (u / r).clamp(-1.0, 1.0);
    0.5 * (u * (r * r - u * u).max(0.0).sqrt() + r * r * x.asin())
}

/// Visible area over `[u0, u1]` under `g = a + b u`, one regime throughout (twin of
/// `uniform_piece`; `crate::illum`'s f64 `uniform_piece`).
fn uniform_piece(r: f32, u0: f32, u1: f32, a: f32, b: f32) -> f32 {
    let um = 0.5 * (u0 + u1);
    let s_m = (r * r - um * um).max(0.0).sqrt();
    let g_m = a + b * um;
    let int_s = half_chord_integral(r, u1) - half_chord_integral(r, u0);
    if g_m >= s_m {
        0.0
    } else if g_m <= -s_m {
        2.0 * int_s
    } else {
        int_s - (a * (u1 - u0) + 0.5 * b * (u1 * u1 - u0 * u0))
    }
}

/// The visible area under the horizon line through `p0`, `p1`, split where it crosses the
/// rim (twin of `line_piece`).
fn line_piece(r: f32, p0: (f32, f32), p1: (f32, f32)) -> f32 {
    let (u0, g0) = p0;
    let (u1, g1) = p1;
    let b = (g1 - g0) / (u1 - u0);
    let a = g0 - b * u0;
    let qa = 1.0 + b * b;
    let qb = 2.0 * a * b;
    let qc = a * a - r * r;
    let disc = qb * qb - 4.0 * qa * qc;
    let mut cuts = [u0, u1, u1, u1];
    let mut n = 1;
    if disc > 0.0 {
        let sq = disc.sqrt();
        let q = -0.5 * (qb + if qb < 0.0 { -sq } else { sq });
        let (mut x1, mut x2) = if q != 0.0 {
            (q / qa, qc / q)
        } else {
            (-sq / (2.0 * qa), sq / (2.0 * qa))
        };
        if x1 > x2 {
            std::mem::swap(&mut x1, &mut x2);
        }
        for x in [x1, x2] {
            if x > u0 && x < u1 {
                cuts[n] = x;
                n += 1;
            }
        }
    }
    cuts[n] = u1;
    n += 1;
    let mut sum = 0.0;
    for i in 0..n - 1 {
        if cuts[i + 1] > cuts[i] {
            sum += uniform_piece(r, cuts[i], cuts[i + 1], a, b);
        }
    }
    sum
}

#[allow(
    clippy::needless_range_loop,
    reason = "indexed as the WGSL it mirrors (the points, then the disc's right edge)"
)]
/// A disc's visible fraction above the horizon polyline (twin of `polyline_fraction`): the
/// chord's segment where the polyline stays within 1 % of the radius of the chord, 0 or 1 where
/// no part of the disc is above (below) the polyline, the segment in between, except for the
/// Earth (uniform) near 0 and 1, where the exact strip integral decides (the CPU engine's
/// `kernel::polyline_fraction`, in f64 there). Only the Earth takes it (the Sun the segment
/// alone, as the CPU engine's partial epochs); `earth` picks the chord table and the integral.
fn polyline_fraction(
    tb: &Tables,
    h: &[f32],
    (el, az, r, half_span): (f32, f32, f32, f32),
    earth: bool,
) -> f32 {
    let from = az - half_span;
    let left = tb.horizon(h, from) - el;
    let right = tb.horizon(h, az + half_span) - el;
    let slope = (right - left) / (2.0 * r);
    let m = 0.5 * (left + right);
    let segment = tb.chord(earth, m / (1.0 + slope * slope).sqrt() / r);
    let mut points = [(0.0_f32, 0.0_f32); MAX_POLY_POINTS];
    let mut n = 0;
    let nb = tb.p.n_bands as usize;
    let (k0, _) = tb.segment(from);
    let u_per_deg = r / half_span;
    let mut k = (k0 + 1) % nb;
    while n < MAX_POLY_POINTS {
        let x = tb.band_az(k) - from;
        let d = x - 360.0 * (x * (1.0 / 360.0)).floor();
        if d >= 2.0 * half_span || k == k0 {
            break;
        }
        points[n] = (-r + d * u_per_deg, h[k] - el);
        n += 1;
        k = (k + 1) % nb;
    }
    let mut off_chord = 0.0_f32;
    for &(u, g) in &points[..n] {
        off_chord = off_chord.max((g - (left + slope * (u + r))).abs());
    }
    if off_chord <= 0.01 * r {
        return segment;
    }
    let (mut some_visible, mut some_hidden) = (false, false);
    let mut prev = (-r, left);
    for i in 0..=n {
        let (u, g) = if i < n { points[i] } else { (r, right) };
        if u > prev.0 {
            let b = (g - prev.1) / (u - prev.0);
            let a = prev.1 - b * prev.0;
            let q = (1.0 + b * b).sqrt();
            let ut = (-b * r / q).clamp(prev.0, u);
            some_visible |= (r * r - ut * ut).max(0.0).sqrt() - (a + b * ut) > 0.0;
            let ub = (b * r / q).clamp(prev.0, u);
            some_hidden |= a + b * ub + (r * r - ub * ub).max(0.0).sqrt() > 0.0;
        }
        prev = (u, g);
    }
    if !some_visible {
        return 0.0;
    }
    if !some_hidden {
        return 1.0;
    }
    if !earth || (0.02..=0.98).contains(&segment) {
        return segment;
    }
    let mut total = 0.0;
    let mut prev = (-r, left);
    for i in 0..=n {
        let p = if i < n { points[i] } else { (r, right) };
        if p.0 > prev.0 {
            total += line_piece(r, prev, p);
        }
        prev = p;
    }
    (total / (std::f32::consts::PI * r * r)).clamp(0.0, 1.0)
}

/// A body seen from a cell: sine and cosine of its elevation, and its fraction visible.
struct Seen {
    sin_el: f32,
    cos_el: f32,
    fraction: f32,
}

/// Twin of `body_at`: the body at `pos_km` (from the Moon's centre), angular radius `r`.
fn body_at(
    tb: &Tables,
    cell: &KernelCell,
    h: &[f32],
    pos_km: [f32; 3],
    r: f32,
    earth: bool,
) -> Seen {
    let dot = |a: [f32; 3]| a[0] * pos_km[0] + a[1] * pos_km[1] + a[2] * pos_km[2];
    let vz = dot(cell.up) - cell.r_obs_km;
    let vx = dot(cell.grid_east);
    let vy = dot(cell.grid_north);
    let hxy = (vx * vx + vy * vy).sqrt();
    let inv_len = 1.0 / (hxy * hxy + vz * vz).sqrt();
    let (sin_el, cos_el) = (vz * inv_len, hxy * inv_len);
    let el = atan2_deg(vz, hxy);
    let fraction = if el - r >= cell.h_max_deg {
        1.0
    } else if el + r <= cell.h_min_deg {
        0.0
    } else {
        let a = atan2_deg(vx, vy);
        let az = if a < 0.0 { a + 360.0 } else { a };
        let half_span = if cos_el > 1e-3 {
            (r / cos_el).min(180.0)
        } else {
            180.0
        };
        if earth && half_span < 90.0 {
            polyline_fraction(tb, h, (el, az, r, half_span), earth)
        } else {
            let left = tb.horizon(h, az - half_span) - el;
            let right = tb.horizon(h, az + half_span) - el;
            let m = 0.5 * (left + right);
            let k = (right - left) / (2.0 * r);
            tb.chord(earth, m / (1.0 + k * k).sqrt() / r)
        }
    };
    Seen {
        sin_el,
        cos_el,
        fraction,
    }
}

/// Twin of the entry point `horizon_stats`: cell `cell` (horizon `h`, `stride` values) over the
/// batch's epochs, updating `acc`.
pub fn horizon_stats(
    params: &HorizonStatsParams,
    tables: &[f32],
    index: &[u32],
    epochs: &[KernelEpoch],
    cell: &KernelCell,
    h: &[f32],
    acc: &mut KernelAcc,
) {
    let tb = Tables {
        p: params,
        t: tables,
        index,
    };
    let mut s = *acc;
    let (mut sum, mut irr_h, mut irr_t) = (0.0_f32, 0.0_f32, 0.0_f32);
    for j in params.epoch_begin..params.epoch_end {
        let e = &epochs[j as usize];
        let sun = body_at(&tb, cell, h, e.sun_km, e.sun_radius_deg, false);
        let earth = body_at(&tb, cell, h, e.earth_km, e.earth_radius_deg, true);
        let (fs, fe) = (sun.fraction, earth.fraction);
        let sun_up = fs > params.visible_min;
        let earth_up = fe > params.visible_min;
        sum += fs;
        let flux = e.sun_normal_w_m2 * fs;
        irr_h += flux * sun.sin_el.max(0.0);
        irr_t += flux * sun.cos_el;
        s.sun_visible += u32::from(sun_up);
        s.sun_full += u32::from(fs >= params.full_min);
        s.earth_visible += u32::from(earth_up);
        s.sun_and_earth += u32::from(sun_up && earth_up);
        s.dark_run = if sun_up { 0 } else { s.dark_run + 1 };
        s.dark_max = s.dark_max.max(s.dark_run);
        s.earth_hidden_run = if earth_up { 0 } else { s.earth_hidden_run + 1 };
        s.earth_hidden_max = s.earth_hidden_max.max(s.earth_hidden_run);
        s.low_lit += u32::from(sun_up && sun.sin_el < cell.sin_dip_bound);
        // The chunk's f32 sums into the totals at each chunk's end (the batch ends on one).
        if (j + 1) % EPOCH_CHUNK as u32 == 0 || j + 1 == params.epoch_end {
            s.sun_fraction_sum += sum;
            s.irradiance_horizontal_sum += irr_h;
            s.irradiance_tracking_sum += irr_t;
            (sum, irr_h, irr_t) = (0.0, 0.0, 0.0);
        }
    }
    *acc = s;
}

/// Epochs per batch of the twin and the GPU (a multiple of [`EPOCH_CHUNK`]).
pub const EPOCHS_PER_BATCH: usize = 8 * EPOCH_CHUNK;

/// The twin as a [`CellKernel`]: cells in parallel (rayon), epochs in the GPU's batches.
#[derive(Debug, Default)]
pub struct TwinKernel {
    shared: Option<(Arc<KernelShared>, Vec<f32>)>,
}

impl CellKernel for TwinKernel {
    fn begin(&mut self, shared: Arc<KernelShared>) -> Result<(), HorizonError> {
        let tables = packed_tables(&shared);
        self.shared = Some((shared, tables));
        Ok(())
    }

    fn run(
        &mut self,
        cells: &[KernelCell],
        horizons: &[f32],
    ) -> Result<Vec<KernelAcc>, HorizonError> {
        let (shared, tables) = self
            .shared
            .as_ref()
            .ok_or_else(|| HorizonError::Kernel("the twin ran before begin".into()))?;
        let stride = shared.n_bands() + 1;
        let mut acc = vec![KernelAcc::default(); cells.len()];
        let n = shared.epochs.len();
        for begin in (0..n).step_by(EPOCHS_PER_BATCH) {
            let params = HorizonStatsParams::new(
                shared,
                cells.len(),
                begin,
                (begin + EPOCHS_PER_BATCH).min(n),
            );
            acc.par_iter_mut()
                .zip(cells.par_iter().zip(horizons.par_chunks(stride)))
                .for_each(|(a, (c, h))| {
                    horizon_stats(&params, tables, &shared.index, &shared.epochs, c, h, a)
                });
        }
        Ok(acc)
    }

    fn name(&self) -> String {
        "cpu twin of horizon_stats.wgsl".into()
    }
}

//! The per-cell loop over epochs: each body's direction at the cell (its own frame, the Earth's
//! parallax included), the horizon at its grid azimuth, the visible fraction of its disc, and the
//! statistics. f32 geometry (errors ≈ 1e-5°, far below the horizons' 0.01° quantisation), f64
//! sums.
//!
//! Passes over a chunk of epochs per cell, so that the expensive part vectorises:
//! 0. with the shared sector tables: blocks of [`BLOCK`] (32) epochs decided whole for a body
//!    ([`super::sectors::block_decision`]) get its fraction 0 or 1 at once;
//! 1. the other epochs: the shared classification, or geometry (branch-free: three dot
//!    products, two square roots, two `atan2`s per body) against per-cell sector bounds
//!    (widened by the largest disc half-span);
//! 2. fractions: the epochs neither decides get the circular segment under the horizon's chord
//!    across the disc (the Earth: the polyline itself);
//! 3. the statistics, in time order: a block decided whole for both bodies at once (its sums in
//!    the epoch-by-epoch order, so bit for bit), the others with their sums epoch by epoch and
//!    their counts and runs from bit masks of the block's epochs ([`count_mask`]).

#![allow(
    clippy::needless_range_loop,
    reason = "indexed loops over several equal-length arrays are what autovectorises here"
)]

use super::lookup::{AzimuthLookup, ChordTable, atan2_deg};
use super::sectors::{
    BLOCK, BLOCK_BOUNDS, BlockSpan, BodySectors, Entry, MapFrame, SECTORS as PSI_SECTORS,
    block_decision,
};
use crate::illum::polyline_visible_fraction_uniform;

/// Epochs per chunk (the chunk's arrays stay in L1 while a task's cells run over it).
pub(super) const CHUNK: usize = 512;
// Whole blocks per chunk, counted in `u32` bit masks.
const _: () = assert!(CHUNK.is_multiple_of(BLOCK) && BLOCK <= 32);
/// Azimuth sectors of the per-cell horizon bounds (one set per body).
pub(super) const BOUND_SECTORS: usize = 128;
/// Largest half-span in azimuth of the Sun's disc the Sun's sector bounds cover, degrees (each
/// sector's bounds take in the horizon this far beyond its edges): `0.272° / cos(el)` up to 39°
/// of elevation.
pub(super) const SUN_MARGIN_DEG: f32 = 0.35;
/// The same for the Earth's disc: `0.95–1.0° / cos(el)` up to 20° of elevation.
pub(super) const EARTH_MARGIN_DEG: f32 = 1.1;

/// The epochs in the kernel's units, one array per quantity: body centres relative to the Moon's
/// centre in `MOON_ME`, km; angular radii, degrees; the Sun's normal irradiance (whole disc),
/// W/m².
#[derive(Debug, Clone, Default)]
pub(super) struct Epochs {
    pub sun: [Vec<f32>; 3],
    pub sun_radius_deg: Vec<f32>,
    pub sun_normal_w_m2: Vec<f32>,
    pub earth: [Vec<f32>; 3],
    pub earth_radius_deg: Vec<f32>,
    /// The bodies in the grid centre's frame, for the shared sector classification.
    pub sun_sectors: BodySectors,
    pub earth_sectors: BodySectors,
    /// Per block of [`BLOCK`] epochs from the first, bit `j`: a station sees the DEM at epoch
    /// `j` of the block (direct-to-Earth statistics); empty without a link.
    pub link_bits: Vec<u32>,
    /// A panel and its load (the power statistics); `None` without.
    pub power: Option<PowerSoa>,
}

/// A panel and its load per epoch, in the kernel's units.
#[derive(Debug, Clone, Default)]
pub(super) struct PowerSoa {
    /// The panel's incidence factor: 0 `cos el` (vertical, tracking the Sun's azimuth), 1
    /// `max(sin el, 0)` (horizontal), 2 one (two-axis).
    pub panel: u8,
    /// Watts per W/m² of normal irradiance on the disc's visible part: area × efficiency ×
    /// (1 − degradation).
    pub scale: Vec<f32>,
    /// Energy the load draws over the sample's step, Wh, while any part of the Sun is visible.
    pub day_wh: Vec<f32>,
    /// The same while the Sun is entirely hidden.
    pub night_wh: Vec<f32>,
    /// Hours per sample.
    pub step_h: f32,
}

/// [`PowerSoa`] over one chunk of epochs.
#[derive(Clone, Copy)]
struct PowerChunk<'a> {
    panel: u8,
    scale: &'a [f32],
    day_wh: &'a [f32],
    night_wh: &'a [f32],
    step_h: f32,
}

/// A cell's panel and battery over a chunk: the power's sum (W, the chunk's in f32), the
/// battery's deficit below full and its largest, Wh.
struct Battery {
    power_sum_w: f32,
    deficit_wh: f64,
    max_deficit_wh: f64,
}

/// The power statistics of a cell over the chunk's epochs, once its Sun fractions are known
/// (and, wherever the Sun is visible, its elevation): each epoch's power and net energy at
/// block by block (vectorised; a block with the Sun hidden throughout takes the night load at
/// once), the battery's deficit in time order ([`drain`]).
#[inline(always)]
fn power_chunk(pw: &PowerChunk<'_>, sun_w: &[f32], sun: &Seen, b: &mut Battery) {
    let n = sun_w.len().min(CHUNK);
    let mut net = [0.0_f32; BLOCK];
    let mut p = [0.0_f32; BLOCK];
    let mut j0 = 0;
    while j0 < n {
        let j1 = (j0 + BLOCK).min(n);
        let m = j1 - j0;
        let f = &sun.fraction[j0..j1];
        let night = &pw.night_wh[j0..j1];
        if f.iter().fold(0_u32, |a, &x| a | u32::from(x > 0.0)) == 0 {
            // The Sun hidden throughout: no power, the night load.
            drain(night, &mut b.deficit_wh, &mut b.max_deficit_wh);
            j0 = j1;
            continue;
        }
        let (scale, w, day) = (&pw.scale[j0..j1], &sun_w[j0..j1], &pw.day_wh[j0..j1]);
        let (sin_el, cos_el) = (&sun.sin_el[j0..j1], &sun.cos_el[j0..j1]);
        // One loop per panel, so that each vectorises; where the Sun is hidden the elevation
        // may be stale, so the power is selected, not multiplied by a zero.
        macro_rules! each {
            ($g:expr) => {
                for i in 0..m {
                    let v = scale[i] * (w[i] * f[i]) * $g(sin_el[i], cos_el[i]);
                    p[i] = if f[i] > 0.0 { v } else { 0.0 };
                }
            };
        }
        match pw.panel {
            0 => each!(|_: f32, c: f32| c),
            1 => each!(|s: f32, _: f32| s.max(0.0)),
            _ => each!(|_: f32, _: f32| 1.0_f32),
        }
        for i in 0..m {
            let load = if f[i] > 0.0 { day[i] } else { night[i] };
            net[i] = load - p[i] * pw.step_h;
        }
        b.power_sum_w += sum8(&p[..m]);
        drain(&net[..m], &mut b.deficit_wh, &mut b.max_deficit_wh);
        j0 = j1;
    }
}

/// The sum of `x` in eight partial sums (so that it vectorises instead of one chain of
/// dependent additions).
#[inline(always)]
fn sum8(x: &[f32]) -> f32 {
    let mut lanes = [0.0_f32; 8];
    let mut chunks = x.chunks_exact(8);
    for c in &mut chunks {
        for k in 0..8 {
            lanes[k] += c[k];
        }
    }
    lanes.iter().sum::<f32>() + chunks.remainder().iter().sum::<f32>()
}

/// The battery's deficit below full (Wh) through a block of epochs short of the load by `net`
/// each (`D ← max(0, D + net)`, the largest `D` kept): at once when every `net` has one sign
/// (a surplus only drains the deficit toward 0, a shortfall only adds to it), epoch by epoch
/// otherwise.
#[inline(always)]
fn drain(net: &[f32], deficit: &mut f64, max_deficit: &mut f64) {
    let (mut surplus, mut short) = ([0_u32; 8], [0_u32; 8]);
    let mut chunks = net.chunks_exact(8);
    for c in &mut chunks {
        for k in 0..8 {
            surplus[k] |= u32::from(c[k] < 0.0);
            short[k] |= u32::from(c[k] > 0.0);
        }
    }
    for &x in chunks.remainder() {
        surplus[0] |= u32::from(x < 0.0);
        short[0] |= u32::from(x > 0.0);
    }
    let any_surplus = surplus.iter().any(|&x| x != 0);
    let any_short = short.iter().any(|&x| x != 0);
    let sum = sum8(net);
    if !any_short {
        *deficit = (*deficit + f64::from(sum)).max(0.0);
    } else if !any_surplus {
        *deficit += f64::from(sum);
        *max_deficit = max_deficit.max(*deficit);
    } else {
        for &x in net {
            *deficit = (*deficit + f64::from(x)).max(0.0);
            *max_deficit = max_deficit.max(*deficit);
        }
    }
}

impl Epochs {
    pub fn len(&self) -> usize {
        self.sun_radius_deg.len()
    }
}

/// What one cell needs: its frame (radial up and the map's +x, +y directions on the sphere, all
/// unit vectors in `MOON_ME`), the observer's distance from the Moon's centre and where its rays
/// leave the DEM.
#[derive(Debug, Clone, Copy)]
pub(super) struct CellGeom {
    pub up: [f32; 3],
    /// Map +x ("grid east") in the tangent plane.
    pub grid_east: [f32; 3],
    /// Map +y ("grid north") in the tangent plane.
    pub grid_north: [f32; 3],
    /// Observer's distance from the Moon's centre, km.
    pub r_obs_km: f32,
    /// `up · U₀`, the grid centre's up (the shared sector classification).
    pub up_ref: f32,
    /// The cell's frame in f64, to build its sector tables (`up`, `grid_east` and `grid_north`
    /// above are its f32 copies for the per-epoch geometry).
    pub frame: MapFrame,
    /// Where the cell's rays leave the outermost layer (the below-sphere count).
    pub beyond: super::BeyondDem,
    /// Whether the Sun and the Earth are seen at all, always whole, or sometimes cut, by bounds
    /// over every epoch (so that most crater floors skip the Sun and most far slopes the Earth).
    pub sun: Reach,
    pub earth: Reach,
}

/// What bounds over every epoch say of a body at a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Reach {
    /// Entirely below the horizon at every epoch.
    Never,
    /// Entirely above the horizon at every epoch.
    Always,
    /// Epoch by epoch.
    Varies,
}

/// Running statistics of one cell.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct CellAcc {
    pub sun_fraction_sum: f64,
    pub irradiance_horizontal_sum: f64,
    pub irradiance_tracking_sum: f64,
    pub sun_visible: u32,
    pub sun_full: u32,
    pub earth_visible: u32,
    pub sun_and_earth: u32,
    pub dark_run: u32,
    pub dark_max: u32,
    pub earth_hidden_run: u32,
    pub earth_hidden_max: u32,
    pub dte: u32,
    pub dte_off_run: u32,
    pub dte_off_max: u32,
    pub below_sphere: u32,
    /// Sum of the panel's power over the epochs, W.
    pub power_sum_w: f64,
    /// The battery's deficit below full now and its largest so far, Wh (the required
    /// capacity: [`crate::illum::power`]).
    pub deficit_wh: f64,
    pub max_deficit_wh: f64,
}

/// Thresholds of the statistics.
#[derive(Debug, Clone, Copy)]
pub(super) struct Thresholds {
    pub visible_min: f32,
    pub full_min: f32,
}

/// A body's direction over a chunk, per epoch.
pub(super) struct Seen {
    pub el_deg: [f32; CHUNK],
    pub az_deg: [f32; CHUNK],
    pub sin_el: [f32; CHUNK],
    pub cos_el: [f32; CHUNK],
    pub fraction: [f32; CHUNK],
}

impl Default for Scratch {
    fn default() -> Self {
        Scratch {
            sun: Box::default(),
            earth: Box::default(),
            partial: Box::new([0; CHUNK]),
            undecided: Box::new([false; CHUNK]),
        }
    }
}

impl Default for Seen {
    fn default() -> Self {
        Seen {
            el_deg: [0.0; CHUNK],
            az_deg: [0.0; CHUNK],
            sin_el: [0.0; CHUNK],
            cos_el: [0.0; CHUNK],
            fraction: [0.0; CHUNK],
        }
    }
}

#[inline(always)]
fn dot(a: [f32; 3], x: f32, y: f32, z: f32) -> f32 {
    a[0] * x + a[1] * y + a[2] * z
}

/// The body at `(bx, by, bz)` (km from the Moon's centre) from `cell`: `(vz, hxy, 1 / |v|, vx,
/// vy)` of the vector from the observer, in the cell's (grid east, grid north, up) frame.
#[inline(always)]
fn local(cell: &CellGeom, bx: f32, by: f32, bz: f32) -> (f32, f32, f32, f32, f32) {
    let vz = dot(cell.up, bx, by, bz) - cell.r_obs_km;
    let vx = dot(cell.grid_east, bx, by, bz);
    let vy = dot(cell.grid_north, bx, by, bz);
    let hxy = (vx * vx + vy * vy).sqrt();
    let inv_len = 1.0 / (hxy * hxy + vz * vz).sqrt();
    (vz, hxy, inv_len, vx, vy)
}

/// Elevation and grid azimuth (degrees, azimuth in [0, 360)) from [`local`]'s values.
#[inline(always)]
fn el_az_deg(vz: f32, hxy: f32, vx: f32, vy: f32) -> (f32, f32) {
    let a = atan2_deg(vx, vy);
    (atan2_deg(vz, hxy), if a < 0.0 { a + 360.0 } else { a })
}

/// Pass 1: the direction of the body at `pos` (km, relative to the Moon's centre) from `cell`
/// for the epochs `span` of the chunk.
#[inline(always)]
fn geometry_span(cell: &CellGeom, pos: [&[f32]; 3], span: std::ops::Range<usize>, out: &mut Seen) {
    let (a, b) = (span.start, span.end.min(CHUNK).min(pos[0].len()));
    let (px, py, pz) = (&pos[0][a..b], &pos[1][a..b], &pos[2][a..b]);
    let (el, az) = (&mut out.el_deg[a..b], &mut out.az_deg[a..b]);
    let (sin_el, cos_el) = (&mut out.sin_el[a..b], &mut out.cos_el[a..b]);
    for j in 0..b - a {
        let (vz, hxy, inv_len, vx, vy) = local(cell, px[j], py[j], pz[j]);
        sin_el[j] = vz * inv_len;
        cos_el[j] = hxy * inv_len;
        (el[j], az[j]) = el_az_deg(vz, hxy, vx, vy);
    }
}

/// [`geometry_span`]'s sine and cosine of the elevation only (the irradiance needs them
/// wherever the Sun may light the cell; the angles are only needed where a disc is cut).
#[inline(always)]
fn geometry_sin_cos_span(
    cell: &CellGeom,
    pos: [&[f32]; 3],
    span: std::ops::Range<usize>,
    out: &mut Seen,
) {
    let (a, b) = (span.start, span.end.min(CHUNK).min(pos[0].len()));
    let (px, py, pz) = (&pos[0][a..b], &pos[1][a..b], &pos[2][a..b]);
    let (sin_el, cos_el) = (&mut out.sin_el[a..b], &mut out.cos_el[a..b]);
    for j in 0..b - a {
        let (vz, hxy, inv_len, _, _) = local(cell, px[j], py[j], pz[j]);
        sin_el[j] = vz * inv_len;
        cos_el[j] = hxy * inv_len;
    }
}

/// [`geometry_span`] at epoch `j` of the chunk only.
#[inline(always)]
fn geometry_at(cell: &CellGeom, pos: [&[f32]; 3], j: usize, out: &mut Seen) {
    let (vz, hxy, inv_len, vx, vy) = local(cell, pos[0][j], pos[1][j], pos[2][j]);
    out.sin_el[j] = vz * inv_len;
    out.cos_el[j] = hxy * inv_len;
    (out.el_deg[j], out.az_deg[j]) = el_az_deg(vz, hxy, vx, vy);
}

/// Pass 1 from the shared sector classification ([`super::sectors`]) over the epochs
/// `from .. from + sector.len()` of the chunk: a disc decided full (or visible) or dark for
/// every `ψ` of its sector gets 1 or 0 without any geometry; the other epochs are flagged in
/// `undecided` and appended to `partial` from `count` (the new count returned).
#[inline(always)]
fn classify_sectors(
    table: &[Entry],
    up_ref: f32,
    (sector, cos_e, sin_e): (&[u16], &[f32], &[f32]),
    from: usize,
    fraction: &mut [f32; CHUNK],
    (undecided, partial): (&mut [bool; CHUNK], &mut [u16; CHUNK]),
    mut count: usize,
) -> usize {
    let n = sector.len().min(CHUNK - from);
    let (sector, cos_e, sin_e) = (&sector[..n], &cos_e[..n], &sin_e[..n]);
    let table = &table[..PSI_SECTORS];
    let (fraction, undecided) = (
        &mut fraction[from..from + n],
        &mut undecided[from..from + n],
    );
    // Without a dependence between epochs (so that it pipelines), then the list.
    for j in 0..n {
        let [a_lo, s_hi, a_hi, s_lo] = table[usize::from(sector[j]) % PSI_SECTORS];
        let cs = up_ref * sin_e[j];
        let full = cos_e[j] * a_lo + cs >= s_hi;
        let dark = cos_e[j] * a_hi + cs <= s_lo;
        fraction[j] = if full { 1.0 } else { 0.0 };
        undecided[j] = !(full | dark);
    }
    for (j, &u) in undecided.iter().enumerate() {
        if u {
            partial[count] = (from + j) as u16;
            count += 1;
        }
    }
    count
}

/// Pass 2 by the per-cell bounds: a branch-free classification of the directions in `seen`
/// against the cell's sector bounds (a disc entirely above or below the horizon of its sector is
/// 1 or 0), listing the other epochs in `partial` (their count returned).
#[inline(always)]
fn classify_bounds(
    bounds: &[[f32; 2]],
    margin_deg: f32,
    radius_deg: &[f32],
    seen: &mut Seen,
    partial: &mut [u16; CHUNK],
) -> usize {
    let n = radius_deg.len().min(CHUNK);
    let sector_per_deg = BOUND_SECTORS as f32 / 360.0;
    let bounds = &bounds[..BOUND_SECTORS];
    let mut count = 0;
    for j in 0..n {
        let (el, az, r) = (seen.el_deg[j], seen.az_deg[j], radius_deg[j]);
        let s = ((az * sector_per_deg) as usize).min(BOUND_SECTORS - 1);
        let [lo, hi] = bounds[s];
        // Within the sector bounds only while the disc's half-span fits the margin.
        let fits = r <= margin_deg * seen.cos_el[j];
        let full = fits & (el - r >= hi);
        let dark = fits & (el + r <= lo);
        seen.fraction[j] = if full { 1.0 } else { 0.0 };
        partial[count] = j as u16;
        count += usize::from(!(full | dark));
    }
    count
}

/// The visible fraction of a disc of `radius_deg` (per epoch) above the cell's horizon `h`
/// (`n + 1` band values) at the `partial` epochs of `seen` (directions known there): the
/// circular segment under the horizon's chord across the disc, or for `exact_uniform` the
/// polyline itself ([`polyline_fraction`]).
#[inline(always)]
fn partial_fractions(
    h: &[f32],
    lookup: &AzimuthLookup,
    chord: &ChordTable,
    exact_uniform: bool,
    radius_deg: &[f32],
    seen: &mut Seen,
    partial: &[u16],
) {
    for &j in partial {
        let j = usize::from(j);
        let (el, az, r) = (seen.el_deg[j], seen.az_deg[j], radius_deg[j]);
        let cos_el = seen.cos_el[j];
        let half_span = if cos_el > 1e-3 {
            (r / cos_el).min(180.0)
        } else {
            180.0
        };
        if exact_uniform && half_span < 90.0 {
            seen.fraction[j] = polyline_fraction(h, lookup, el, az, r, half_span, chord);
            continue;
        }
        // Circular segment under the straight line through the horizon at the disc's two
        // azimuth edges (paper 001 eqs. 6–7), flux-weighted with the limb law.
        let left = lookup.horizon_deg(h, az - half_span) - el;
        let right = lookup.horizon_deg(h, az + half_span) - el;
        let m = 0.5 * (left + right);
        let k = (right - left) / (2.0 * r);
        let d = m / (1.0 + k * k).sqrt();
        seen.fraction[j] = chord.fraction(d / r);
    }
}

/// The visible fraction of a uniform disc (centre `el`, `az`, radius `r`, half-span in azimuth
/// `half_span`, degrees) above the horizon polyline itself: the disc's two edges and every band
/// inside its span, integrated exactly ([`polyline_visible_fraction_uniform`]; the segment's
/// straight chord would miss a notch of the horizon inside a wide disc such as the Earth's).
pub(super) fn polyline_fraction(
    h: &[f32],
    lookup: &AzimuthLookup,
    el: f32,
    az: f32,
    r: f32,
    half_span: f32,
    chord: &ChordTable,
) -> f32 {
    const MAX_POINTS: usize = 64;
    let from = az - half_span;
    let left = lookup.horizon_deg(h, from) - el;
    let right = lookup.horizon_deg(h, az + half_span) - el;
    // The circular segment under the chord through the polyline's ends.
    let slope = (right - left) / (2.0 * r);
    let m = 0.5 * (left + right);
    let segment = chord.fraction(m / (1.0 + slope * slope).sqrt() / r);
    // The bands strictly inside the span, as (u, g).
    let mut points = [(0.0_f32, 0.0_f32); MAX_POINTS];
    let mut n = 0;
    let band_az = lookup.band_az_deg();
    let nb = band_az.len();
    let (k0, _) = lookup.segment(from);
    let u_per_deg = r / half_span;
    let mut k = (k0 + 1) % nb;
    while n < MAX_POINTS {
        // Degrees from the disc's left edge, in [0, 360): `from` may be below 0 or past 360
        // (a disc across grid azimuth 0).
        let d = (band_az[k] - from).rem_euclid(360.0);
        if d >= 2.0 * half_span || k == k0 {
            break;
        }
        points[n] = (-r + d * u_per_deg, h[k] - el);
        n += 1;
        k = (k + 1) % nb;
    }
    // Within 1 % of the radius of the chord, the segment is the polyline's fraction.
    let off_chord = points[..n]
        .iter()
        .map(|&(u, g)| (g - (left + slope * (u + r))).abs())
        .fold(0.0_f32, f32::max);
    if off_chord <= 0.01 * r {
        return segment;
    }
    // Does the polyline leave any of the disc above it (and any below)? On each piece `g = a +
    // b u` the top arc minus `g` and `g` plus the bottom arc are concave, with their maxima at
    // `u = ∓ b r / √(1 + b²)` (clamped to the piece): a disc wholly hidden or wholly visible is
    // told exactly, without the integral.
    let mut some_visible = false;
    let mut some_hidden = false;
    let mut prev = (-r, left);
    for &(u, g) in points[..n].iter().chain(std::iter::once(&(r, right))) {
        if u > prev.0 {
            let b = (g - prev.1) / (u - prev.0);
            let a = prev.1 - b * prev.0;
            let q = (1.0 + b * b).sqrt();
            let arc = |x: f32| (r * r - x * x).max(0.0).sqrt();
            let ut = (-b * r / q).clamp(prev.0, u);
            some_visible |= arc(ut) - (a + b * ut) > 0.0;
            let ub = (b * r / q).clamp(prev.0, u);
            some_hidden |= a + b * ub + arc(ub) > 0.0;
        }
        prev = (u, g);
    }
    if !some_visible {
        return 0.0;
    }
    if !some_hidden {
        return 1.0;
    }
    // Partly visible: the segment in mid-range (a bend of the horizon changes the fraction by a
    // little there), the exact integral near 0 and 1, where the thresholds are.
    if (0.02..=0.98).contains(&segment) {
        return segment;
    }
    let mut poly = [(0.0_f64, 0.0_f64); MAX_POINTS + 2];
    let r64 = f64::from(r);
    poly[0] = (-r64, f64::from(left));
    for (p, &(u, g)) in poly[1..].iter_mut().zip(&points[..n]) {
        *p = (f64::from(u), f64::from(g));
    }
    poly[n + 1] = (r64, f64::from(right));
    polyline_visible_fraction_uniform(&poly[..n + 2], r64) as f32
}

/// Appends to `out` the horizon bounds of each of the [`BOUND_SECTORS`] azimuth sectors of a cell (with
/// `margin_deg` on both sides) from its `n + 1` band values at `lookup`'s azimuths.
pub(super) fn sector_bounds(
    h: &[f32],
    band_az_deg: &[f32],
    margin_deg: f32,
    out: &mut Vec<[f32; 2]>,
) {
    let base = out.len();
    out.resize(base + BOUND_SECTORS, [f32::INFINITY, f32::NEG_INFINITY]);
    let out = &mut out[base..];
    let width = 360.0 / BOUND_SECTORS as f32;
    let n = band_az_deg.len();
    for (k, &a) in band_az_deg.iter().enumerate() {
        // The band and the segment to the next one: the horizon on [a, a_next] lies between
        // their values. Sectors whose widened span meets the segment take both.
        let a_next = if k + 1 < n {
            band_az_deg[k + 1]
        } else {
            band_az_deg[0] + 360.0
        };
        let (v0, v1) = (h[k], h[k + 1]);
        let (lo, hi) = (v0.min(v1), v0.max(v1));
        // Band azimuths are in [0, 360): shift by a whole turn so that truncation floors.
        let first = ((a - margin_deg + 360.0) / width) as i64 - BOUND_SECTORS as i64;
        let last = ((a_next + margin_deg + 360.0) / width) as i64 - BOUND_SECTORS as i64;
        for s in first..=last {
            let b = &mut out[s.rem_euclid(BOUND_SECTORS as i64) as usize];
            b[0] = b[0].min(lo);
            b[1] = b[1].max(hi);
        }
    }
}

/// Counts `len` consecutive epochs in which a body is visible (`up`) or hidden throughout: the
/// epochs it is visible, the run of hidden epochs up to now and the longest such run
/// (branch-free, so that the epoch-by-epoch loop keeps its selects).
#[inline(always)]
fn count_epochs(up: bool, len: u32, visible: &mut u32, hidden_run: &mut u32, longest: &mut u32) {
    *visible += len * u32::from(up);
    *hidden_run = if up { 0 } else { *hidden_run + len };
    *longest = (*longest).max(*hidden_run);
}

/// [`count_epochs`] over `len ≤ 32` consecutive epochs at once: bit `i` of `up` tells whether
/// the body is visible at the `i`-th. The same counts as epoch by epoch: the hidden run before
/// the first visible epoch extends the current run, the runs between visible epochs stand
/// alone, the run after the last one is the new current run.
#[inline(always)]
fn count_mask(up: u32, len: u32, visible: &mut u32, hidden_run: &mut u32, longest: &mut u32) {
    debug_assert!((1..=32).contains(&len));
    let valid = u32::MAX >> (32 - len);
    let up = up & valid;
    *visible += up.count_ones();
    if up == 0 {
        *hidden_run += len;
        *longest = (*longest).max(*hidden_run);
        return;
    }
    let (first, last) = (up.trailing_zeros(), 31 - up.leading_zeros());
    *longest = (*longest).max(*hidden_run + first);
    // Hidden epochs between the first and the last visible one: the longest run of ones.
    let mut inner = !up & valid & (u32::MAX >> (31 - last)) & (u32::MAX << first);
    let mut run = 0;
    while inner != 0 {
        inner &= inner >> 1;
        run += 1;
    }
    *hidden_run = len - 1 - last;
    *longest = (*longest).max(run).max(*hidden_run);
}

/// Per-thread buffers of a chunk.
pub(super) struct Scratch {
    sun: Box<Seen>,
    earth: Box<Seen>,
    partial: Box<[u16; CHUNK]>,
    undecided: Box<[bool; CHUNK]>,
}

/// Runs the task's `cells` (each with its `stride = n + 1` horizon values and 2 ×
/// [`BOUND_SECTORS`] bounds, the Sun's then the Earth's) over epochs `range` (in time order),
/// updating `acc`.
#[inline(always)]
fn run_cells(task: RunCells<'_>) {
    let RunCells {
        cells,
        horizons,
        bounds,
        tables,
        block_bounds,
        stride,
        epochs,
        range,
        lookup,
        chord_sun,
        chord_earth,
        th,
        edges,
        scratch,
        acc,
    } = task;
    let Scratch {
        sun,
        earth,
        partial,
        undecided,
    } = scratch;
    fn sl(v: &[Vec<f32>; 3], range: std::ops::Range<usize>) -> [&[f32]; 3] {
        [&v[0][range.clone()], &v[1][range.clone()], &v[2][range]]
    }
    fn sectors_of(
        s: &BodySectors,
        range: std::ops::Range<usize>,
    ) -> Option<(&[u16], &[f32], &[f32])> {
        s.enabled.then(|| {
            (
                &s.sector[range.clone()],
                &s.cos_e[range.clone()],
                &s.sin_e[range],
            )
        })
    }
    let (sun_pos, earth_pos) = (
        sl(&epochs.sun, range.clone()),
        sl(&epochs.earth, range.clone()),
    );
    let sun_r = &epochs.sun_radius_deg[range.clone()];
    let earth_r = &epochs.earth_radius_deg[range.clone()];
    let sun_w = &epochs.sun_normal_w_m2[range.clone()];
    let n = sun_r.len();
    // Tables of both bodies per cell, or none (the per-cell path for every epoch).
    let per_cell = if tables.is_empty() {
        0
    } else {
        2 * PSI_SECTORS
    };
    let sectors = [
        sectors_of(&epochs.sun_sectors, range.clone()).filter(|_| per_cell > 0),
        sectors_of(&epochs.earth_sectors, range.clone()).filter(|_| per_cell > 0),
    ];
    // Blocks of BLOCK epochs from the chunk's start (chunks start at multiples of CHUNK).
    debug_assert_eq!(range.start % BLOCK, 0);
    let n_blocks = n.div_ceil(BLOCK);
    fn block_range(s: &BodySectors, first: usize, count: usize) -> &[BlockSpan] {
        s.blocks.get(first..first + count).unwrap_or(&[])
    }
    let blocks = [
        block_range(&epochs.sun_sectors, range.start / BLOCK, n_blocks),
        block_range(&epochs.earth_sectors, range.start / BLOCK, n_blocks),
    ];
    let link = (!epochs.link_bits.is_empty())
        .then(|| &epochs.link_bits[range.start / BLOCK..range.start / BLOCK + n_blocks]);
    let power = epochs.power.as_ref().map(|p| PowerChunk {
        panel: p.panel,
        scale: &p.scale[range.clone()],
        day_wh: &p.day_wh[range.clone()],
        night_wh: &p.night_wh[range.clone()],
        step_h: p.step_h,
    });
    // Per body and block: decided whole (full or visible: true; dark: false), or epoch by epoch.
    let mut decided = [[None::<bool>; CHUNK / BLOCK]; 2];
    for (i, ((cell, h), a)) in cells
        .iter()
        .zip(horizons.chunks_exact(stride))
        .zip(acc.iter_mut())
        .enumerate()
    {
        let table = if per_cell > 0 {
            &tables[i * per_cell..(i + 1) * per_cell]
        } else {
            &[][..]
        };
        // Per-cell bounds (absent when both bodies have tables).
        let (b_sun, b_earth) = if bounds.is_empty() {
            (&[][..], &[][..])
        } else {
            bounds[i * 2 * BOUND_SECTORS..(i + 1) * 2 * BOUND_SECTORS].split_at(BOUND_SECTORS)
        };
        // The Earth's disc is uniform and wide (1.9°): its partial epochs get the exact strip
        // integral over the horizon polyline; the Sun's (limb-darkened, 0.53°) the segment.
        for (body, reach, pos, radius, chord, exact, (b, margin), seen) in [
            (
                0,
                cell.sun,
                sun_pos,
                sun_r,
                chord_sun,
                false,
                (b_sun, SUN_MARGIN_DEG),
                &mut **sun,
            ),
            (
                1,
                cell.earth,
                earth_pos,
                earth_r,
                chord_earth,
                true,
                (b_earth, EARTH_MARGIN_DEG),
                &mut **earth,
            ),
        ] {
            // Only the Sun's elevation is needed at every epoch it may light (irradiance).
            let is_sun = body == 0;
            decided[body][..n_blocks].fill(None);
            match reach {
                Reach::Never => {
                    seen.fraction[..n].fill(0.0);
                    decided[body][..n_blocks].fill(Some(false));
                }
                Reach::Always => {
                    if is_sun {
                        geometry_sin_cos_span(cell, pos, 0..n, seen);
                    }
                    seen.fraction[..n].fill(1.0);
                    decided[body][..n_blocks].fill(Some(true));
                }
                Reach::Varies => {
                    let count = if let Some(sec) = sectors[body] {
                        let t = &table[body * PSI_SECTORS..(body + 1) * PSI_SECTORS];
                        let bb = &block_bounds[(2 * i + body) * BLOCK_BOUNDS..][..BLOCK_BOUNDS];
                        // Whole blocks first; the epochs of the others one by one.
                        let mut count = 0;
                        for k in 0..n_blocks {
                            let (j0, j1) = (k * BLOCK, ((k + 1) * BLOCK).min(n));
                            decided[body][k] = blocks[body]
                                .get(k)
                                .and_then(|span| block_decision(bb, cell.up_ref, span));
                            if let Some(v) = decided[body][k] {
                                seen.fraction[j0..j1].fill(if v { 1.0 } else { 0.0 });
                                // The Sun's elevation where it lights the cell (irradiance;
                                // a dark block adds nothing).
                                if is_sun && v {
                                    geometry_sin_cos_span(cell, pos, j0..j1, seen);
                                }
                                continue;
                            }
                            let (sector, cos_e, sin_e) = sec;
                            let before = count;
                            count = classify_sectors(
                                t,
                                cell.up_ref,
                                (&sector[j0..j1], &cos_e[j0..j1], &sin_e[j0..j1]),
                                j0,
                                &mut seen.fraction,
                                (undecided, partial),
                                count,
                            );
                            // The directions of the epochs left: the whole block in SIMD lanes
                            // when it has a few, else one by one.
                            if count - before >= 2 {
                                geometry_span(cell, pos, j0..j1, seen);
                            } else {
                                if is_sun {
                                    geometry_sin_cos_span(cell, pos, j0..j1, seen);
                                }
                                for &j in &partial[before..count] {
                                    geometry_at(cell, pos, usize::from(j), seen);
                                }
                            }
                        }
                        count
                    } else {
                        geometry_span(cell, pos, 0..n, seen);
                        classify_bounds(b, margin, radius, seen, partial)
                    };
                    partial_fractions(h, lookup, chord, exact, radius, seen, &partial[..count]);
                }
            }
        }
        let mut s = *a;
        let mut sum = 0.0_f32;
        let (mut irr_h, mut irr_t) = (0.0_f32, 0.0_f32);
        let mut battery = Battery {
            power_sum_w: 0.0,
            deficit_wh: s.deficit_wh,
            max_deficit_wh: s.max_deficit_wh,
        };
        let bound = cell.beyond.sin_dip_bound();
        for k in 0..n_blocks {
            let (j0, j1) = (k * BLOCK, ((k + 1) * BLOCK).min(n));
            // A block decided whole for both bodies: its statistics at once, its sums in the
            // same order as epoch by epoch (bit for bit) — unless a lit Sun may be below the
            // observer's geometric horizon (the below-sphere check, epoch by epoch).
            if let (Some(sun_whole), Some(earth_whole)) = (decided[0][k], decided[1][k])
                && !(sun_whole && sun.sin_el[j0..j1].iter().any(|&x| x < bound))
            {
                let len = (j1 - j0) as u32;
                let (fs, fe) = (
                    f32::from(u8::from(sun_whole)),
                    f32::from(u8::from(earth_whole)),
                );
                let (sun_up, earth_up) = (fs > th.visible_min, fe > th.visible_min);
                if fs != 0.0 {
                    // (Adding the zeros of a dark Sun changes no sum.)
                    for j in j0..j1 {
                        sum += fs;
                        let flux = sun_w[j] * fs;
                        irr_h += flux * sun.sin_el[j].max(0.0);
                        irr_t += flux * sun.cos_el[j];
                    }
                }
                count_epochs(
                    sun_up,
                    len,
                    &mut s.sun_visible,
                    &mut s.dark_run,
                    &mut s.dark_max,
                );
                s.sun_full += len * u32::from(fs >= th.full_min);
                count_epochs(
                    earth_up,
                    len,
                    &mut s.earth_visible,
                    &mut s.earth_hidden_run,
                    &mut s.earth_hidden_max,
                );
                s.sun_and_earth += len * u32::from(sun_up && earth_up);
                if let Some(l) = link {
                    let up = if earth_up { l[k] } else { 0 };
                    count_mask(up, len, &mut s.dte, &mut s.dte_off_run, &mut s.dte_off_max);
                }
                continue;
            }
            // Epoch by epoch: the sums in time order, the rest as bit masks of the block's
            // epochs (bit `j − j0`), counted at once (as `count_epochs` would epoch by epoch).
            let (mut sun_up, mut earth_up, mut full, mut low) = (0_u32, 0_u32, 0_u32, 0_u32);
            for j in j0..j1 {
                let (fs, fe) = (sun.fraction[j], earth.fraction[j]);
                sum += fs;
                let flux = sun_w[j] * fs;
                irr_h += flux * sun.sin_el[j].max(0.0);
                irr_t += flux * sun.cos_el[j];
                let bit = (j - j0) as u32;
                sun_up |= u32::from(fs > th.visible_min) << bit;
                earth_up |= u32::from(fe > th.visible_min) << bit;
                full |= u32::from(fs >= th.full_min) << bit;
                low |= u32::from(sun.sin_el[j] < bound) << bit;
            }
            let len = (j1 - j0) as u32;
            count_mask(
                sun_up,
                len,
                &mut s.sun_visible,
                &mut s.dark_run,
                &mut s.dark_max,
            );
            s.sun_full += full.count_ones();
            count_mask(
                earth_up,
                len,
                &mut s.earth_visible,
                &mut s.earth_hidden_run,
                &mut s.earth_hidden_max,
            );
            s.sun_and_earth += (sun_up & earth_up).count_ones();
            if let Some(l) = link {
                count_mask(
                    earth_up & l[k],
                    len,
                    &mut s.dte,
                    &mut s.dte_off_run,
                    &mut s.dte_off_max,
                );
            }
            // Lit from below the local horizontal, and below the observer's geometric horizon
            // on the sphere (its sine, with room for f32): the ray may meet the sphere.
            let mut maybe_below = sun_up & low;
            while maybe_below != 0 {
                let j = j0 + maybe_below.trailing_zeros() as usize;
                maybe_below &= maybe_below - 1;
                let (vz, hxy, _, vx, vy) = local(cell, sun_pos[0][j], sun_pos[1][j], sun_pos[2][j]);
                let (el, az) = el_az_deg(vz, hxy, vx, vy);
                if el < 0.0
                    && cell.beyond.may_meet_sphere(el)
                    && cell.beyond.meets_sphere(edges, az, el)
                {
                    s.below_sphere += 1;
                }
            }
        }
        if let Some(pw) = &power {
            power_chunk(pw, sun_w, sun, &mut battery);
        }
        // Chunk sums in f32 (≤ CHUNK terms), the running totals in f64.
        s.sun_fraction_sum += f64::from(sum);
        s.irradiance_horizontal_sum += f64::from(irr_h);
        s.irradiance_tracking_sum += f64::from(irr_t);
        s.power_sum_w += f64::from(battery.power_sum_w);
        (s.deficit_wh, s.max_deficit_wh) = (battery.deficit_wh, battery.max_deficit_wh);
        *a = s;
    }
}

/// [`run_cells`] as a `pulp` SIMD task: the kernel is inlined into a function compiled for the
/// best instruction set of the CPU (AVX2 + FMA, AVX-512 or the baseline), chosen at run time,
/// and autovectorised there.
pub(super) struct RunCells<'a> {
    pub cells: &'a [CellGeom],
    pub horizons: &'a [f32],
    pub bounds: &'a [[f32; 2]],
    pub tables: &'a [Entry],
    /// Per cell, the Sun's then the Earth's block decision values (`sectors::BLOCK_BOUNDS`
    /// each; with the tables).
    pub block_bounds: &'a [f32],
    pub stride: usize,
    pub epochs: &'a Epochs,
    pub range: std::ops::Range<usize>,
    pub lookup: &'a AzimuthLookup,
    pub chord_sun: &'a ChordTable,
    pub chord_earth: &'a ChordTable,
    pub th: Thresholds,
    pub edges: &'a super::Edges,
    pub scratch: &'a mut Scratch,
    pub acc: &'a mut [CellAcc],
}

impl pulp::WithSimd for RunCells<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        run_cells(self);
    }
}

#[cfg(test)]
mod tests {
    use super::{count_epochs, count_mask, drain};

    /// A block drained at once equals the epoch-by-epoch recursion `D ← max(0, D + x)`.
    #[test]
    fn drain_equals_epoch_by_epoch() {
        let blocks: [&[f32]; 5] = [
            &[-3.0, -1.0, -0.5, -7.0],
            &[2.0, 0.0, 4.5, 1.0],
            &[2.0, -5.0, 4.5, -1.0, 3.0],
            &[0.0, 0.0],
            &[-1.0, 6.0, -2.0],
        ];
        for start in [0.0, 2.5, 10.0] {
            for net in blocks {
                let (mut d, mut m) = (start, start + 1.0);
                drain(net, &mut d, &mut m);
                let (mut wd, mut wm) = (start, start + 1.0_f64);
                for &x in net {
                    wd = (wd + f64::from(x)).max(0.0);
                    wm = wm.max(wd);
                }
                assert!(
                    (d - wd).abs() < 1e-9 && (m - wm).abs() < 1e-9,
                    "{net:?} from {start}"
                );
            }
        }
    }

    /// Every 12-epoch pattern (and blocks of 1, 16 and 32 epochs from a small generator), from
    /// several running states: the counts at once equal the epoch-by-epoch counts.
    #[test]
    fn count_mask_equals_epoch_by_epoch() {
        let mut state = 0x2545_f491_u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let mut cases: Vec<(u32, u32)> = (0..1 << 12).map(|m| (m, 12)).collect();
        for len in [1, 2, 16, 31, 32] {
            cases.extend((0..500).map(|_| (next(), len)));
            cases.extend([(0, len), (u32::MAX, len), (1, len), (1 << (len - 1), len)]);
        }
        for (mask, len) in cases {
            for (run0, longest0) in [(0, 0), (3, 3), (5, 40), (100, 100)] {
                let mut want = (0_u32, run0, longest0);
                for bit in 0..len {
                    let up = mask >> bit & 1 == 1;
                    count_epochs(up, 1, &mut want.0, &mut want.1, &mut want.2);
                }
                let mut got = (0_u32, run0, longest0);
                count_mask(mask, len, &mut got.0, &mut got.1, &mut got.2);
                assert_eq!(
                    got, want,
                    "mask {mask:#b}, {len} epochs, from {run0}/{longest0}"
                );
            }
        }
    }
}

//! The per-cell loop over epochs: each body's direction at the cell (its own frame, the Earth's
//! parallax included), the horizon at its grid azimuth, the visible fraction of its disc, and the
//! statistics. f32 geometry (errors ≈ 1e-5°, far below the horizons' 0.01° quantisation), f64
//! sums.
//!
//! Three passes over a chunk of epochs per cell, so that the expensive part vectorises:
//! 1. geometry (branch-free: three dot products, two square roots, two `atan2`s per body);
//! 2. fractions: a disc entirely above or below the horizon of its azimuth sector (bounds per
//!    cell and sector, widened by the largest disc half-span) needs no lookup; the others get the
//!    circular segment under the horizon's chord across the disc;
//! 3. the statistics, in time order.

#![allow(
    clippy::needless_range_loop,
    reason = "indexed loops over several equal-length arrays are what autovectorises here"
)]

use super::lookup::{AzimuthLookup, ChordTable};
use crate::illum::polyline_visible_fraction_uniform;

/// Epochs per chunk (the chunk's arrays stay in L1 while a task's cells run over it).
pub(super) const CHUNK: usize = 512;
/// Azimuth sectors of the per-cell horizon bounds (one set per body).
pub(super) const SECTORS: usize = 128;
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
    pub below_sphere: u32,
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

/// `atan(a)` for `a` in [0, 1]: a least-squares minimax polynomial in `a²` (degree 7), error
/// < 4e-8 rad (2.2e-6°; `tests::atan2_deg_matches_f64`).
#[inline(always)]
fn atan_unit(a: f32) -> f32 {
    const C: [f32; 8] = [
        9.999_993_4e-1,
        -3.332_986e-1,
        1.994_656e-1,
        -1.390_860_7e-1,
        9.642_142e-2,
        -5.591_159e-2,
        2.186_245_7e-2,
        -4.054_43e-3,
    ];
    // Plain multiply-adds: `mul_add` is a libm call without the FMA target feature.
    let t = a * a;
    let p = C[7];
    let p = p * t + C[6];
    let p = p * t + C[5];
    let p = p * t + C[4];
    let p = p * t + C[3];
    let p = p * t + C[2];
    let p = p * t + C[1];
    let p = p * t + C[0];
    a * p
}

/// `atan2(y, x)` in degrees, in [−180, 180], branch-free (0 for `(0, 0)`).
#[inline(always)]
pub(super) fn atan2_deg(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let lo = ax.min(ay);
    let hi = ax.max(ay).max(f32::MIN_POSITIVE);
    let r = atan_unit(lo / hi);
    let r = if ay > ax {
        std::f32::consts::FRAC_PI_2 - r
    } else {
        r
    };
    let r = if x < 0.0 { std::f32::consts::PI - r } else { r };
    let r = if y < 0.0 { -r } else { r };
    r * (180.0 / std::f32::consts::PI)
}

#[inline(always)]
fn dot(a: [f32; 3], x: f32, y: f32, z: f32) -> f32 {
    a[0] * x + a[1] * y + a[2] * z
}

/// Pass 1: the direction of the body at `pos` (km, relative to the Moon's centre) from `cell`
/// for epochs `range` of the chunk.
#[inline(always)]
fn geometry(cell: &CellGeom, pos: [&[f32]; 3], out: &mut Seen) {
    let n = pos[0].len().min(CHUNK);
    let (px, py, pz) = (&pos[0][..n], &pos[1][..n], &pos[2][..n]);
    let (el, az) = (&mut out.el_deg[..n], &mut out.az_deg[..n]);
    let (sin_el, cos_el) = (&mut out.sin_el[..n], &mut out.cos_el[..n]);
    let r = cell.r_obs_km;
    for j in 0..n {
        let (bx, by, bz) = (px[j], py[j], pz[j]);
        let vz = dot(cell.up, bx, by, bz) - r;
        let vx = dot(cell.grid_east, bx, by, bz);
        let vy = dot(cell.grid_north, bx, by, bz);
        let hxy = (vx * vx + vy * vy).sqrt();
        let inv_len = 1.0 / (hxy * hxy + vz * vz).sqrt();
        sin_el[j] = vz * inv_len;
        cos_el[j] = hxy * inv_len;
        el[j] = atan2_deg(vz, hxy);
        let a = atan2_deg(vx, vy);
        az[j] = if a < 0.0 { a + 360.0 } else { a };
    }
}

/// Pass 2: the visible fraction of a disc of `radius_deg` (per epoch) for the directions in
/// `seen`, above the cell's horizon `h` (`n + 1` band values) with its sector bounds. First a
/// branch-free classification against the sector bounds (a disc entirely above or below the
/// horizon of its sector is 1 or 0), which lists the other epochs; then the circular segment for
/// those only.
#[inline(always)]
#[allow(clippy::too_many_arguments, reason = "the kernel's inputs")]
fn fractions(
    h: &[f32],
    bounds: &[[f32; 2]],
    margin_deg: f32,
    lookup: &AzimuthLookup,
    chord: &ChordTable,
    exact_uniform: bool,
    radius_deg: &[f32],
    seen: &mut Seen,
    partial: &mut [u16; CHUNK],
) {
    let n = radius_deg.len().min(CHUNK);
    let sector_per_deg = SECTORS as f32 / 360.0;
    let bounds = &bounds[..SECTORS];
    let mut count = 0;
    for j in 0..n {
        let (el, az, r) = (seen.el_deg[j], seen.az_deg[j], radius_deg[j]);
        let s = ((az * sector_per_deg) as usize).min(SECTORS - 1);
        let [lo, hi] = bounds[s];
        // Within the sector bounds only while the disc's half-span fits the margin.
        let fits = r <= margin_deg * seen.cos_el[j];
        let full = fits & (el - r >= hi);
        let dark = fits & (el + r <= lo);
        seen.fraction[j] = if full { 1.0 } else { 0.0 };
        partial[count] = j as u16;
        count += usize::from(!(full | dark));
    }
    for &j in &partial[..count] {
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
        let mut d = band_az[k] - from;
        if d < 0.0 {
            d += 360.0;
        }
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

/// Appends to `out` the horizon bounds of each of the [`SECTORS`] azimuth sectors of a cell (with
/// `margin_deg` on both sides) from its `n + 1` band values at `lookup`'s azimuths.
pub(super) fn sector_bounds(
    h: &[f32],
    band_az_deg: &[f32],
    margin_deg: f32,
    out: &mut Vec<[f32; 2]>,
) {
    let base = out.len();
    out.resize(base + SECTORS, [f32::INFINITY, f32::NEG_INFINITY]);
    let out = &mut out[base..];
    let width = 360.0 / SECTORS as f32;
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
        let first = ((a - margin_deg + 360.0) / width) as i64 - SECTORS as i64;
        let last = ((a_next + margin_deg + 360.0) / width) as i64 - SECTORS as i64;
        for s in first..=last {
            let b = &mut out[s.rem_euclid(SECTORS as i64) as usize];
            b[0] = b[0].min(lo);
            b[1] = b[1].max(hi);
        }
    }
}

/// Per-thread buffers of a chunk.
pub(super) struct Scratch {
    sun: Box<Seen>,
    earth: Box<Seen>,
    partial: Box<[u16; CHUNK]>,
}

/// Runs `cells` (each with its `stride = n + 1` horizon values and 2 × [`SECTORS`] bounds, the
/// Sun's then the Earth's) over
/// epochs `range` (in time order), updating `acc`.
#[allow(
    clippy::too_many_arguments,
    reason = "the kernel's inputs are flat slices for the inner loop"
)]
#[inline(always)]
pub(super) fn run_cells(
    cells: &[CellGeom],
    horizons: &[f32],
    bounds: &[[f32; 2]],
    stride: usize,
    epochs: &Epochs,
    range: std::ops::Range<usize>,
    lookup: &AzimuthLookup,
    chord_sun: &ChordTable,
    chord_earth: &ChordTable,
    th: Thresholds,
    edges: &super::Edges,
    scratch: &mut Scratch,
    acc: &mut [CellAcc],
) {
    let Scratch {
        sun,
        earth,
        partial,
    } = scratch;
    fn sl(v: &[Vec<f32>; 3], range: std::ops::Range<usize>) -> [&[f32]; 3] {
        [&v[0][range.clone()], &v[1][range.clone()], &v[2][range]]
    }
    let (sun_pos, earth_pos) = (
        sl(&epochs.sun, range.clone()),
        sl(&epochs.earth, range.clone()),
    );
    let sun_r = &epochs.sun_radius_deg[range.clone()];
    let earth_r = &epochs.earth_radius_deg[range.clone()];
    let sun_w = &epochs.sun_normal_w_m2[range.clone()];
    let n = sun_r.len();
    for (((cell, h), b), a) in cells
        .iter()
        .zip(horizons.chunks_exact(stride))
        .zip(bounds.chunks_exact(2 * SECTORS))
        .zip(acc.iter_mut())
    {
        // The Earth's disc is uniform and wide (1.9°): its partial epochs get the exact strip
        // integral over the horizon polyline; the Sun's (limb-darkened, 0.53°) the segment.
        let (b_sun, b_earth) = b.split_at(SECTORS);
        for (reach, pos, radius, chord, exact, (b, margin), seen) in [
            (
                cell.sun,
                sun_pos,
                sun_r,
                chord_sun,
                false,
                (b_sun, SUN_MARGIN_DEG),
                &mut **sun,
            ),
            (
                cell.earth,
                earth_pos,
                earth_r,
                chord_earth,
                true,
                (b_earth, EARTH_MARGIN_DEG),
                &mut **earth,
            ),
        ] {
            match reach {
                // The Sun's elevation still feeds the irradiance and the below-sphere count.
                Reach::Never => seen.fraction[..n].fill(0.0),
                Reach::Always => {
                    geometry(cell, pos, seen);
                    seen.fraction[..n].fill(1.0);
                }
                Reach::Varies => {
                    geometry(cell, pos, seen);
                    fractions(h, b, margin, lookup, chord, exact, radius, seen, partial);
                }
            }
        }
        let mut s = *a;
        let mut sum = 0.0_f32;
        let (mut irr_h, mut irr_t) = (0.0_f32, 0.0_f32);
        for j in 0..n {
            let (fs, fe) = (sun.fraction[j], earth.fraction[j]);
            let sun_up = fs > th.visible_min;
            let earth_up = fe > th.visible_min;
            sum += fs;
            let flux = sun_w[j] * fs;
            irr_h += flux * sun.sin_el[j].max(0.0);
            irr_t += flux * sun.cos_el[j];
            s.sun_visible += u32::from(sun_up);
            s.sun_full += u32::from(fs >= th.full_min);
            s.earth_visible += u32::from(earth_up);
            s.sun_and_earth += u32::from(sun_up && earth_up);
            s.dark_run = if sun_up { 0 } else { s.dark_run + 1 };
            s.dark_max = s.dark_max.max(s.dark_run);
            s.earth_hidden_run = if earth_up { 0 } else { s.earth_hidden_run + 1 };
            s.earth_hidden_max = s.earth_hidden_max.max(s.earth_hidden_run);
            if sun_up
                && sun.el_deg[j] < 0.0
                && cell.beyond.may_meet_sphere(sun.el_deg[j])
                && cell
                    .beyond
                    .meets_sphere(edges, sun.az_deg[j], sun.el_deg[j])
            {
                s.below_sphere += 1;
            }
        }
        // Chunk sums in f32 (≤ CHUNK terms), the running totals in f64.
        s.sun_fraction_sum += f64::from(sum);
        s.irradiance_horizontal_sum += f64::from(irr_h);
        s.irradiance_tracking_sum += f64::from(irr_t);
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
        run_cells(
            self.cells,
            self.horizons,
            self.bounds,
            self.stride,
            self.epochs,
            self.range,
            self.lookup,
            self.chord_sun,
            self.chord_earth,
            self.th,
            self.edges,
            self.scratch,
            self.acc,
        );
    }
}

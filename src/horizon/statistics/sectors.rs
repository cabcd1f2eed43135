//! Classification of epochs shared by every cell: most epochs need no per-cell geometry.
//!
//! Each body's direction `d` (unit, from the Moon's centre, `MOON_ME`) is written once per epoch
//! in the frame of the grid centre: its azimuth `ψ` (from the centre's map +y, clockwise) picks
//! one of [`SECTORS`] sectors, and `cos e`, `sin e` of its elevation `e` there are kept. At a
//! cell of radial `u`, with `a = u·E₀`, `b = u·N₀`, `c = u·U₀` (the centre's map east, north, up):
//!
//! ```text
//! sin el_geo = d·u = cos e (a sin ψ + b cos ψ) + c sin e          (exact)
//! el_geo − el_topo = asin(ρ cos el_topo),  ρ = r_obs / |body|       (exact: the parallax)
//! ```
//!
//! So per cell and sector two conservative thresholds on `cos e · A + c sin e` decide, with two
//! multiply-adds per epoch, "full" (the Sun) or "visible" (the Earth) or "dark"; a disc on the
//! horizon takes the exact per-cell path. The same bounds over [`BLOCK`] consecutive epochs
//! ([`BlockSpan`], [`append_block_bounds`], [`block_decision`]) decide whole blocks. Neither
//! changes a result (`statistics::tests::sector_tables_change_nothing`,
//! `tests::block_decisions_agree_with_every_epoch`). Thresholds, margins and the block bounds:
//! `docs/horizon.md`, "Shared epoch classification".

use nalgebra::Vector3;

use super::EpochBodies;
use super::lookup::{AzimuthLookup, atan2_deg};

/// The visible-only rule's cap: the part of a disc above the chord at `CAP_HEIGHT` radii over
/// its centre, `CAP_HALF_WIDTH = √(1 − 0.9²)` radii either side, is 1.87 % of the disc.
const CAP_HEIGHT: f32 = 0.9;
const CAP_HALF_WIDTH: f32 = 0.436;
/// The largest "visible" threshold (fraction of the disc) the visible-only rule serves.
pub(super) const VISIBLE_ONLY_MAX_FRACTION: f64 = 0.01;

/// Azimuth sectors of the shared classification (1° each: at 0.5° the tables cost more than
/// the 7 % fewer undecided epochs of the Sun save over a year hourly).
pub(super) const SECTORS: usize = 360;
/// Margin of every threshold, degrees (f32 geometry and lookups are good to ≈ 1e-5°).
const MARGIN_DEG: f32 = 1e-4;
/// Margin of the cell's azimuths at the sector's corners, degrees (the f32 `atan2`).
const AZ_MARGIN_DEG: f32 = 1e-3;
/// Cells whose elevations of a body can exceed this (degrees) take the exact path for it: the
/// corner azimuths assume the body stays well away from the cell's zenith.
const MAX_ELEVATION_DEG: f64 = 60.0;

/// A sector entry: `[a_lo, s_hi, a_hi, s_lo]`. The disc is full (or visible) when
/// `cos e · a_lo + c sin e ≥ s_hi`, dark when `cos e · a_hi + c sin e ≤ s_lo`.
pub(super) type Entry = [f32; 4];

/// An entry that decides nothing (every epoch of the sector takes the exact path).
const UNDECIDED: Entry = [0.0, f32::INFINITY, 0.0, f32::NEG_INFINITY];

/// Radial up and the map's +x ("grid east") and +y ("grid north") directions on the sphere at a
/// map point, unit vectors in `MOON_ME` (the grid centre's is the reference of the shared
/// classification).
#[derive(Debug, Clone, Copy)]
pub(super) struct MapFrame {
    pub east: Vector3<f64>,
    pub north: Vector3<f64>,
    pub up: Vector3<f64>,
}

/// One body's epochs in the reference frame, and the bounds of its path.
#[derive(Debug, Clone, Default)]
pub(super) struct BodySectors {
    /// Whether the tables are used for this body (its path stays within
    /// [`MAX_ELEVATION_DEG`] of the centre's horizontal).
    pub enabled: bool,
    /// Per epoch: the sector of `ψ`, `cos e`, `sin e`.
    pub sector: Vec<u16>,
    pub cos_e: Vec<f32>,
    pub sin_e: Vec<f32>,
    /// Per block of [`BLOCK`] epochs (from the first epoch): the sectors and the range of `sin e`
    /// the body covers over it ([`BlockSpan`]).
    pub blocks: Vec<BlockSpan>,
    /// The range of `cos e` over every epoch (its f32 values).
    pub cos_e_range: [f32; 2],
    /// Runs of consecutive sectors some epoch falls in (the others need no entry).
    runs: Vec<std::ops::Range<usize>>,
    e_min_rad: f64,
    e_max_rad: f64,
    dist_min_km: f64,
    dist_max_km: f64,
    radius_max_deg: f64,
}

/// Epochs per block of the block decisions ([`BlockSpan`]; a divisor of the kernel's chunk,
/// at most 32: the kernel counts a block's epochs in `u32` bit masks). 32 rather than 16: half
/// the decisions per cell, and hourly the Sun's blocks are decided about as often (crop of the
/// LOLA grid, 2025–2027 hourly: 1.06× faster, outputs identical).
pub(super) const BLOCK: usize = 32;
/// The most sectors a block may cover and still be decided whole (the Sun covers ≈ 17 in 32 h
/// at the poles, ≈ 33 at a 2-hour step; the Earth 1 to 3).
pub(super) const BLOCK_MAX_SECTORS: usize = 40;

/// What a block of [`BLOCK`] consecutive epochs covers of a body's path: the sectors
/// `first .. first + count` (cyclic; `count` 0 when more than [`BLOCK_MAX_SECTORS`]) and the
/// range of `sin e`. A cell's entries over those sectors, with `cos e` (over the whole path)
/// and `c sin e` (over the block) at their least favourable ends, decide every epoch of the
/// block at once ([`block_decision`]): the same thresholds as epoch by epoch, so a block
/// decided whole is decided as each of its epochs would be.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct BlockSpan {
    pub first: u16,
    pub count: u16,
    pub sin_e: [f32; 2],
}

/// Values per body and cell of the block decisions: `F` then `−D` (see
/// [`append_block_bounds`]), each over the [`SECTORS`] sectors and again over the first
/// [`BLOCK_MAX_SECTORS`] (so that a block across sector 0 reads a contiguous run).
pub(super) const BLOCK_BOUNDS: usize = 2 * (SECTORS + BLOCK_MAX_SECTORS);

/// Appends a cell's [`BLOCK_BOUNDS`] values of one body from its [`SECTORS`] `entries`, for a
/// path whose `cos e` stays within `cos_e_range`: per sector `F = min(cos e · a_lo) − s_hi` and
/// `D = s_lo − max(cos e · a_hi)` over that range (`cos e · a` is linear in `cos e`: its ends).
/// An epoch in the sector is full when `F + c sin e ≥ 0`, dark when `D − c sin e ≥ 0`.
#[inline(always)]
fn append_block_bounds(entries: &[Entry], cos_e_range: [f32; 2], out: &mut Vec<f32>) {
    let [ce0, ce1] = cos_e_range;
    let base = out.len();
    out.resize(base + BLOCK_BOUNDS, 0.0);
    let (f, d) = out[base..].split_at_mut(SECTORS + BLOCK_MAX_SECTORS);
    for ((f, d), &[a_lo, s_hi, a_hi, s_lo]) in f.iter_mut().zip(d.iter_mut()).zip(entries) {
        let (p, q) = (ce0 * a_lo, ce1 * a_lo);
        *f = (if p < q { p } else { q }) - s_hi;
        let (p, q) = (ce0 * a_hi, ce1 * a_hi);
        *d = (if p > q { p } else { q }) - s_lo;
    }
    f.copy_within(..BLOCK_MAX_SECTORS, SECTORS);
    d.copy_within(..BLOCK_MAX_SECTORS, SECTORS);
}

/// What a cell's [`BLOCK_BOUNDS`] values `bounds` of a body say of every epoch of `block` at a
/// cell with `c = up_ref`: `Some(true)` full (or visible), `Some(false)` dark, `None` either
/// some epoch is not decided by its entry or the bound is not tight enough. Never decides an
/// epoch otherwise than its entry would (the entries' margins cover the f32 rounding here).
#[inline(always)]
pub(super) fn block_decision(bounds: &[f32], up_ref: f32, block: &BlockSpan) -> Option<bool> {
    let count = usize::from(block.count);
    if count == 0 {
        return None;
    }
    let (cs0, cs1) = (up_ref * block.sin_e[0], up_ref * block.sin_e[1]);
    let (cs_lo, cs_hi) = if cs0 < cs1 { (cs0, cs1) } else { (cs1, cs0) };
    let (f, minus_d) = bounds[..BLOCK_BOUNDS].split_at(SECTORS + BLOCK_MAX_SECTORS);
    let first = usize::from(block.first);
    let (full, minus_dark) = min_max(&f[first..first + count], &minus_d[first..first + count]);
    if full + cs_lo >= 0.0 {
        Some(true)
    } else if -minus_dark - cs_hi >= 0.0 {
        Some(false)
    } else {
        None
    }
}

/// The [`BlockSpan`] of a block's epochs (their sectors and `sin e`).
fn block_span(sector: &[u16], sin_e: &[f32]) -> BlockSpan {
    // The shortest cyclic arc of sectors holding them all: offsets from the first epoch's in
    // (−180, 180] sectors' worth of a turn.
    let k0 = i32::from(sector[0]);
    let n = SECTORS as i32;
    let (mut lo, mut hi) = (0_i32, 0_i32);
    for &k in sector {
        let mut d = (i32::from(k) - k0).rem_euclid(n);
        if d > n / 2 {
            d -= n;
        }
        lo = lo.min(d);
        hi = hi.max(d);
    }
    let count = (hi - lo + 1) as usize;
    BlockSpan {
        first: (k0 + lo).rem_euclid(n) as u16,
        count: if count <= BLOCK_MAX_SECTORS {
            count as u16
        } else {
            0
        },
        sin_e: value_range(sin_e),
    }
}

/// The lowest and highest of `values`.
fn value_range(values: &[f32]) -> [f32; 2] {
    values
        .iter()
        .fold([f32::INFINITY, f32::NEG_INFINITY], |[a, b], &x| {
            [a.min(x), b.max(x)]
        })
}

/// `(sin, cos)` of every sector edge (`SECTORS + 1`).
pub(super) fn edges() -> Vec<(f32, f32)> {
    (0..=SECTORS)
        .map(|k| {
            let (s, c) = (k as f64 * 360.0 / SECTORS as f64).to_radians().sin_cos();
            (s as f32, c as f32)
        })
        .collect()
}

impl BodySectors {
    /// The body at `body(e)` (position relative to the Moon's centre, km, and angular radius,
    /// degrees) for every epoch.
    pub fn new(
        epochs: &[EpochBodies],
        body: impl Fn(&EpochBodies) -> ([f64; 3], f64),
        reference: &MapFrame,
    ) -> Self {
        let mut s = BodySectors {
            enabled: true,
            runs: Vec::new(),
            e_min_rad: f64::INFINITY,
            e_max_rad: f64::NEG_INFINITY,
            dist_min_km: f64::INFINITY,
            dist_max_km: 0.0,
            ..Default::default()
        };
        let mut visited = vec![false; SECTORS];
        for e in epochs {
            let (p, radius_deg) = body(e);
            let p = Vector3::from(p);
            let dist = p.norm();
            let d = p / dist;
            let (x, y, z) = (
                d.dot(&reference.east),
                d.dot(&reference.north),
                d.dot(&reference.up),
            );
            let psi = x.atan2(y).rem_euclid(std::f64::consts::TAU);
            let k = ((psi / std::f64::consts::TAU * SECTORS as f64) as usize).min(SECTORS - 1);
            let e_rad = z.clamp(-1.0, 1.0).asin();
            s.sector.push(k as u16);
            s.cos_e.push(x.hypot(y) as f32);
            s.sin_e.push(z as f32);
            visited[k] = true;
            s.e_min_rad = s.e_min_rad.min(e_rad);
            s.e_max_rad = s.e_max_rad.max(e_rad);
            s.dist_min_km = s.dist_min_km.min(dist);
            s.dist_max_km = s.dist_max_km.max(dist);
            s.radius_max_deg = s.radius_max_deg.max(radius_deg);
        }
        s.blocks = s
            .sector
            .chunks(BLOCK)
            .zip(s.sin_e.chunks(BLOCK))
            .map(|(sec, se)| block_span(sec, se))
            .collect();
        s.cos_e_range = value_range(&s.cos_e);
        let mut k = 0;
        while k < SECTORS {
            if visited[k] {
                let start = k;
                while k < SECTORS && visited[k] {
                    k += 1;
                }
                s.runs.push(start..k);
            }
            k += 1;
        }
        s.enabled = !epochs.is_empty()
            && s.e_min_rad.abs().max(s.e_max_rad.abs()).to_degrees() < MAX_ELEVATION_DEG
            && s.dist_min_km > 0.0;
        s
    }

    /// Appends the [`SECTORS`] entries of `cell`. `visible_only`: the body's statistics need
    /// only whether any part of it is visible (more than a fraction below
    /// [`VISIBLE_ONLY_MAX_FRACTION`]), not whether it is whole. Array passes over the visited
    /// sectors (the first and last vectorise).
    #[inline(always)]
    fn append_entries(
        &self,
        reference: &MapFrame,
        edges: &[(f32, f32)],
        cell: &TableCell,
        visible_only: bool,
        scratch: &mut TableScratch,
        out: &mut Vec<Entry>,
    ) {
        let TableCell {
            frame: &MapFrame { up, east, north },
            r_obs_km,
            ref horizon,
        } = *cell;
        let base = out.len();
        out.resize(base + SECTORS, UNDECIDED);
        let out = &mut out[base..];
        let (a, b) = (up.dot(&reference.east), up.dot(&reference.north));
        let alpha = [
            reference.east.dot(&east) as f32,
            reference.north.dot(&east) as f32,
            reference.up.dot(&east) as f32,
        ];
        let beta = [
            reference.east.dot(&north) as f32,
            reference.north.dot(&north) as f32,
            reference.up.dot(&north) as f32,
        ];
        let rho_max = r_obs_km / self.dist_min_km;
        let rho_min = r_obs_km / self.dist_max_km;
        // Largest |elevation| at the cell: the tilt of its vertical plus the body's range of e,
        // plus the parallax.
        let sin_e_abs = self.e_min_rad.sin().abs().max(self.e_max_rad.sin().abs());
        let el_abs_deg =
            ((a.hypot(b) + sin_e_abs).min(1.0).asin() + rho_max.min(1.0).asin()).to_degrees();
        if !self.enabled || el_abs_deg >= MAX_ELEVATION_DEG {
            return;
        }
        let r = self.radius_max_deg as f32;
        let half_span = (self.radius_max_deg / el_abs_deg.to_radians().cos()) as f32;
        let (ce0, se0) = (self.e_min_rad.cos() as f32, self.e_min_rad.sin() as f32);
        let (ce1, se1) = (self.e_max_rad.cos() as f32, self.e_max_rad.sin() as f32);
        let (a32, b32) = (a as f32, b as f32);
        // A = a sin ψ + b cos ψ = R cos(ψ − ψ*) leaves its edge values by at most
        // R (1 − cos(half a sector)) inside a sector; f32 rounding adds < 3e-7.
        let half_sector = (180.0 / SECTORS as f64).to_radians();
        let a_margin = ((1.0 - half_sector.cos()) * a.hypot(b) * 1.01 + 3e-7) as f32;
        let (rho_max, rho_min) = (rho_max as f32, rho_min as f32);
        let TableScratch {
            az0,
            az1,
            a_edge,
            top,
            bottom,
        } = scratch;
        for run in &self.runs {
            let (k0, k1) = (run.start, run.end);
            // Pass 1, per edge: the cell's grid azimuth of the direction at the body's lowest
            // and highest e (f32: within 5e-5° of f64, covered by AZ_MARGIN_DEG), and A.
            for ((&(s, c), (z0, z1)), ae) in edges[k0..=k1]
                .iter()
                .zip(az0[k0..=k1].iter_mut().zip(az1[k0..=k1].iter_mut()))
                .zip(a_edge[k0..=k1].iter_mut())
            {
                let (x0, x1) = (s * alpha[0] + c * alpha[1], s * beta[0] + c * beta[1]);
                *z0 = atan2_deg(ce0 * x0 + se0 * alpha[2], ce0 * x1 + se0 * beta[2]);
                *z1 = atan2_deg(ce1 * x0 + se1 * alpha[2], ce1 * x1 + se1 * beta[2]);
                *ae = a32 * s + b32 * c;
            }
            // Pass 2, per sector: the azimuths the disc can cover and the horizon over them.
            for k in k0..k1 {
                let base_az = az0[k];
                let unwrap = |x: f32| {
                    let d = x - base_az;
                    let d = if d > 180.0 { d - 360.0 } else { d };
                    base_az + if d < -180.0 { d + 360.0 } else { d }
                };
                let (c1, c2, c3) = (unwrap(az1[k]), unwrap(az0[k + 1]), unwrap(az1[k + 1]));
                let lo = base_az.min(c1).min(c2).min(c3) - AZ_MARGIN_DEG;
                let hi = base_az.max(c1).max(c2).max(c3) + AZ_MARGIN_DEG;
                let (h_lo, h_hi) = horizon.range(lo - half_span, hi + half_span);
                top[k] = if visible_only {
                    // The horizon under the disc's top cap (above the chord at 0.9 r, which
                    // spans ±0.436 r) lower than that chord: at least 1.87 % of the disc is
                    // visible.
                    horizon
                        .range(
                            lo - CAP_HALF_WIDTH * half_span,
                            hi + CAP_HALF_WIDTH * half_span,
                        )
                        .1
                        - CAP_HEIGHT * r
                } else {
                    h_hi + r
                };
                bottom[k] = h_lo - r;
            }
            // Pass 3, per sector: the thresholds on the linear form.
            for (((o, &t), &bt), ae) in out[k0..k1]
                .iter_mut()
                .zip(&top[k0..k1])
                .zip(&bottom[k0..k1])
                .zip(a_edge[k0..=k1].windows(2))
            {
                let s_hi = sin_topo_to_geo(t + MARGIN_DEG, rho_max);
                let s_lo = sin_topo_to_geo(bt - MARGIN_DEG, rho_min);
                *o = [
                    ae[0].min(ae[1]) - a_margin,
                    s_hi,
                    ae[0].max(ae[1]) + a_margin,
                    s_lo,
                ];
            }
        }
    }
}

/// A cell's tables of both bodies (the Sun's then the Earth's) as a `pulp` SIMD task, compiled
/// for the CPU's best instruction set as the kernel is.
pub(super) struct CellTables<'a> {
    /// Each body's path, whether only "any part visible" matters, and whether the cell needs
    /// its table at all (a body it never or always sees needs none: the entries stay undecided).
    pub bodies: [(&'a BodySectors, bool, bool); 2],
    pub reference: &'a MapFrame,
    pub edges: &'a [(f32, f32)],
    /// The cell's own frame.
    pub frame: &'a MapFrame,
    pub r_obs_km: f64,
    /// The cell's horizon: `n + 1` band values at the bands of `lookup`.
    pub h: &'a [f32],
    pub lookup: &'a AzimuthLookup,
    pub scratch: &'a mut TableScratch,
    pub out: &'a mut Vec<Entry>,
    /// The [`BLOCK_BOUNDS`] values of each body ([`append_block_bounds`]).
    pub block_out: &'a mut Vec<f32>,
}

impl pulp::WithSimd for CellTables<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let cell = TableCell {
            frame: self.frame,
            r_obs_km: self.r_obs_km,
            horizon: HorizonPolyline {
                lookup: self.lookup,
                h: self.h,
            },
        };
        for (body, visible_only, needed) in self.bodies {
            let base = self.out.len();
            if needed {
                body.append_entries(
                    self.reference,
                    self.edges,
                    &cell,
                    visible_only,
                    self.scratch,
                    self.out,
                );
            } else {
                self.out.resize(base + SECTORS, UNDECIDED);
            }
            append_block_bounds(&self.out[base..], body.cos_e_range, self.block_out);
        }
    }
}

/// A cell as its sector tables see it: its frame (radial `up`, map `east` and `north` on the
/// sphere), the observer's distance from the Moon's centre (km) and its horizon polyline.
struct TableCell<'a> {
    frame: &'a MapFrame,
    r_obs_km: f64,
    horizon: HorizonPolyline<'a>,
}

/// Per-thread arrays of [`BodySectors::append_entries`] (one value per sector edge).
#[derive(Debug, Clone)]
pub(super) struct TableScratch {
    az0: Vec<f32>,
    az1: Vec<f32>,
    a_edge: Vec<f32>,
    top: Vec<f32>,
    bottom: Vec<f32>,
}

impl Default for TableScratch {
    fn default() -> Self {
        let v = vec![0.0; SECTORS + 1];
        TableScratch {
            az0: v.clone(),
            az1: v.clone(),
            a_edge: v.clone(),
            top: v.clone(),
            bottom: v,
        }
    }
}

/// `sin(t + asin(ρ cos t))` for `t` in degrees (`|t| ≤ 60°`): the sine of the geocentric
/// elevation of a body seen at topocentric elevation `t` from an observer `ρ` body-distances
/// from the Moon's centre. f32 polynomials (error < 2e-7, 1e-5° of elevation, inside the
/// thresholds' 1e-4° margin); `asin(x) ≈ x` underestimates the parallax by `x³/6 < 2e-8` rad
/// for the Earth.
#[inline(always)]
fn sin_topo_to_geo(t_deg: f32, rho: f32) -> f32 {
    let t = t_deg * (std::f32::consts::PI / 180.0);
    let t2 = t * t;
    // Taylor series to t^10 / t^11 (|x| ≤ 1.1: truncation < 3e-9).
    let cos_t = 1.0
        + t2 * (-0.5
            + t2 * (1.0 / 24.0 + t2 * (-1.0 / 720.0 + t2 * (1.0 / 40_320.0 - t2 / 3_628_800.0))));
    let x = t + rho * cos_t;
    let x2 = x * x;
    x * (1.0
        + x2 * (-1.0 / 6.0
            + x2 * (1.0 / 120.0
                + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362_880.0 - x2 / 39_916_800.0)))))
}

/// A cell's horizon polyline: `n + 1` band values `h` at the bands of `lookup` (the last the
/// first again), linear in grid azimuth between bands as the kernel reads it
/// ([`AzimuthLookup::horizon_deg`]).
#[derive(Clone, Copy)]
pub(super) struct HorizonPolyline<'a> {
    pub lookup: &'a AzimuthLookup,
    pub h: &'a [f32],
}

impl HorizonPolyline<'_> {
    /// The lowest and highest horizon over grid azimuths `[from, to]` (degrees, any real
    /// values, `to ≥ from`): the polyline at both ends and the bands strictly between them
    /// (its extremes on a span; the f32 rounding, ≈ 1e-6°, is within the entries' margins).
    /// A span of 90 bands (4° apart) holds one band or none, so this is a few loads.
    #[inline(always)]
    pub fn range(&self, from: f32, to: f32) -> (f32, f32) {
        let h = self.h;
        let n = self.lookup.n_bands();
        if to - from >= 360.0 {
            return min_max(&h[..n], &h[..n]);
        }
        let rel = self.lookup.parts().rel_deg;
        let (k0, r0) = self.lookup.segment(from);
        let start = self.lookup.horizon_in_segment(h, k0, r0);
        let stop = self.lookup.horizon_deg(h, to);
        let (mut lo, mut hi) = (fmin(start, stop), fmax(start, stop));
        // The bands after `from` (unwrapped past the first lap) before `to`.
        let end = r0 + (to - from);
        for k in k0 + 1..k0 + 1 + n {
            let (at, v) = if k <= n {
                (rel[k], h[k])
            } else {
                (rel[k - n] + 360.0, h[k - n])
            };
            if at >= end {
                break;
            }
            lo = fmin(lo, v);
            hi = fmax(hi, v);
        }
        (lo, hi)
    }
}

/// The smaller of two horizon values (never NaN): a plain comparison, which compiles to one
/// `min` instruction (`f32::min`'s NaN rule costs a compare and a blend in a dependent chain).
#[inline(always)]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// The larger of two horizon values (never NaN).
#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// The lowest of `lo` and the highest of `hi` (equal lengths): eight lanes at a time (the last
/// eight overlap the others: min and max do not mind), so that it vectorises.
#[inline(always)]
fn min_max(lo: &[f32], hi: &[f32]) -> (f32, f32) {
    const LANES: usize = 8;
    let n = lo.len().min(hi.len());
    if n < LANES {
        let mut m = (f32::INFINITY, f32::NEG_INFINITY);
        for i in 0..n {
            m = (fmin(lo[i], m.0), fmax(hi[i], m.1));
        }
        return m;
    }
    let load = |v: &[f32], at: usize| -> [f32; LANES] { v[at..at + LANES].try_into().unwrap() };
    let (mut mn, mut mx) = (load(lo, n - LANES), load(hi, n - LANES));
    let mut at = 0;
    while at + LANES < n {
        let (a, b) = (load(lo, at), load(hi, at));
        for i in 0..LANES {
            mn[i] = fmin(a[i], mn[i]);
            mx[i] = fmax(b[i], mx[i]);
        }
        at += LANES;
    }
    // Halving reductions.
    let mut width = LANES / 2;
    while width > 0 {
        for i in 0..width {
            mn[i] = fmin(mn[i], mn[i + width]);
            mx[i] = fmax(mx[i], mx[i + width]);
        }
        width /= 2;
    }
    (mn[0], mx[0])
}

#[cfg(test)]
mod tests {
    use super::super::tests::rng;
    use super::*;

    /// The polyline's range over a span equals the extremes of the horizon sampled densely
    /// over it plus the bands inside it (found in f64, by their unwrapped distance from the
    /// span's start): non-uniform bands, spans across grid azimuth 0, past 360° and whole turns.
    #[test]
    fn polyline_range_matches_dense_samples() {
        let mut uniform = rng(0x2545_F491_4F6C_DD1D_u64);
        for n in [7_usize, 90, 720] {
            // Non-uniform bands: jittered around n even steps.
            let az: Vec<f64> = (0..n)
                .map(|k| (k as f64 + 0.1 + 0.8 * uniform()) * 360.0 / n as f64)
                .collect();
            let lookup = AzimuthLookup::new(&az).unwrap();
            let mut h: Vec<f32> = (0..n).map(|_| (4.0 * uniform() - 1.0) as f32).collect();
            h.push(h[0]);
            let horizon = HorizonPolyline {
                lookup: &lookup,
                h: &h,
            };
            let (mut inside_some, mut whole) = (0, 0);
            for _ in 0..2_000 {
                let from = (720.0 * uniform() - 360.0) as f32;
                let width = if uniform() < 0.05 {
                    360.0 + 10.0 * uniform()
                } else {
                    12.0 * uniform() * uniform()
                } as f32;
                let to = from + width;
                let (lo, hi) = horizon.range(from, to);
                // `strict`: the ends, dense samples and the bands clearly inside; `loose` also
                // the bands within 1e-3° of an end (f32 may put those either side).
                let mut strict = [f32::INFINITY, f32::NEG_INFINITY];
                let mut loose = strict;
                let take = |m: &mut [f32; 2], v: f32| *m = [m[0].min(v), m[1].max(v)];
                if width >= 360.0 {
                    h[..n].iter().for_each(|&v| take(&mut strict, v));
                    whole += 1;
                } else {
                    for i in 0..=64 {
                        take(
                            &mut strict,
                            lookup.horizon_deg(&h, from + width * i as f32 / 64.0),
                        );
                    }
                    loose = strict;
                    for (k, &a) in az.iter().enumerate() {
                        let d = (a - f64::from(from)).rem_euclid(360.0);
                        if d > 1e-3 && d < f64::from(width) - 1e-3 {
                            take(&mut strict, h[k]);
                            inside_some += 1;
                        }
                        if d < f64::from(width) + 1e-3 || d > 360.0 - 1e-3 {
                            take(&mut loose, h[k]);
                        }
                    }
                }
                if width >= 360.0 {
                    loose = strict;
                }
                // Dense samples can only miss the extremes at the bands, which are taken.
                let ok =
                    |got: f32, a: f32, b: f32| got >= a.min(b) - 1e-5 && got <= a.max(b) + 1e-5;
                assert!(
                    ok(lo, strict[0], loose[0]) && ok(hi, strict[1], loose[1]),
                    "n {n}, [{from}, {to}]: ({lo}, {hi}) vs {strict:?} / {loose:?}"
                );
            }
            assert!(inside_some > 100 && whole > 20, "{inside_some} {whole}");
        }
    }

    /// A block decided whole is decided so at each of its epochs by the per-epoch rule (the
    /// kernel's `classify_sectors`), on random entries and paths; and the bound is tight enough
    /// to decide most blocks of a slow path.
    #[test]
    fn block_decisions_agree_with_every_epoch() {
        let mut uniform = rng(0x9E37_79B9_7F4A_7C15_u64);
        let (mut decided, mut blocks) = (0, 0);
        for _ in 0..200 {
            // A cell's entries: A = a sin ψ + b cos ψ over each sector, thresholds about a
            // horizon that wanders by a few degrees.
            let (a, b) = (0.1 * (uniform() - 0.5), 0.1 * (uniform() - 0.5));
            let c = (1.0 - a * a - b * b).sqrt() as f32;
            let mut horizon = 0.02 * (uniform() - 0.5);
            let table: Vec<Entry> = (0..SECTORS)
                .map(|k| {
                    horizon = (horizon + 0.002 * (uniform() - 0.5)).clamp(-0.05, 0.05);
                    let psi = |k: usize| (k as f64 * 360.0 / SECTORS as f64).to_radians();
                    let ends = [psi(k), psi(k + 1)].map(|p| a * p.sin() + b * p.cos());
                    let (a_lo, a_hi) = (ends[0].min(ends[1]), ends[0].max(ends[1]));
                    let half = 0.005 * uniform();
                    [
                        a_lo as f32,
                        (horizon + half) as f32,
                        a_hi as f32,
                        (horizon - half) as f32,
                    ]
                })
                .collect();
            // A path: ψ advancing ≈ 0.55° per epoch, e wandering within ±1°.
            let start = 360.0 * uniform();
            let e0 = 0.03 * (uniform() - 0.5);
            let n = 20 * BLOCK;
            let (mut sector, mut cos_e, mut sin_e) = (vec![], vec![], vec![]);
            for j in 0..n {
                let psi = (start + 0.55 * j as f64).rem_euclid(360.0);
                let e = e0 + 0.005 * ((j as f64) * 0.01).sin();
                sector.push(((psi / 360.0 * SECTORS as f64) as usize).min(SECTORS - 1) as u16);
                cos_e.push(e.cos() as f32);
                sin_e.push(e.sin() as f32);
            }
            let mut bounds = Vec::new();
            append_block_bounds(&table, value_range(&cos_e), &mut bounds);
            for j0 in (0..n).step_by(BLOCK) {
                let r = j0..j0 + BLOCK;
                let span = block_span(&sector[r.clone()], &sin_e[r.clone()]);
                blocks += 1;
                let Some(v) = block_decision(&bounds, c, &span) else {
                    continue;
                };
                decided += 1;
                for j in r {
                    let [a_lo, s_hi, a_hi, s_lo] = table[usize::from(sector[j])];
                    let cs = c * sin_e[j];
                    if v {
                        assert!(cos_e[j] * a_lo + cs >= s_hi, "block full, epoch {j} not");
                    } else {
                        assert!(cos_e[j] * a_hi + cs <= s_lo, "block dark, epoch {j} not");
                    }
                }
            }
        }
        assert!(decided * 2 > blocks, "{decided} of {blocks} blocks decided");
    }
}

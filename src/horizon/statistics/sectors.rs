//! Classification of epochs shared by every cell: most epochs need no per-cell geometry.
//!
//! Each body's direction `d` (unit, from the Moon's centre, `MOON_ME`) is written once per
//! epoch in the frame of the grid centre: the azimuth `ψ` (from the centre's map +y, clockwise)
//! picks one of [`SECTORS`] sectors, and `cos e`, `sin e` (`e` its elevation at the centre) are
//! kept. At a cell of radial `u`, with `a = u·E₀`, `b = u·N₀`, `c = u·U₀` (the centre's map
//! east, north and up):
//!
//! ```text
//! sin el_geo = d·u = cos e (a sin ψ + b cos ψ) + c sin e          (exact)
//! el_geo − el_topo = asin(ρ cos el_topo),  ρ = r_obs / |body|       (exact: the parallax)
//! ```
//!
//! and the body's grid azimuth at the cell is that of `d` (the parallax moves a body along the
//! cell's vertical only). So, per cell and sector, from the azimuths the disc can cover (the
//! sector's corners over the body's range of `e`, plus the disc's half-span) and the horizon
//! polyline over them, two thresholds on the linear form `cos e · A + c sin e` tell, with two
//! multiply-adds per epoch:
//! - **full** (the Sun) or **visible** (the Earth, whose statistics need only "any part
//!   visible": a horizon below the chord 0.9 radii above the disc's centre, over that chord's
//!   width, leaves the cap above it, 1.87 % of the disc, visible) at every `ψ` of the sector, or
//! - **dark**: the disc entirely below the horizon.
//!
//! Every other epoch (a disc on the horizon) takes the exact per-cell path. The thresholds are
//! conservative (the parallax at its largest or smallest, 1e-4° of margin for f32), so the
//! fast path never decides an epoch the exact path would decide otherwise
//! (`tests::sector_tables_change_nothing`).

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
    /// Runs of consecutive sectors some epoch falls in (the others need no entry).
    runs: Vec<std::ops::Range<usize>>,
    e_min_rad: f64,
    e_max_rad: f64,
    dist_min_km: f64,
    dist_max_km: f64,
    radius_max_deg: f64,
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

    /// Appends the [`SECTORS`] entries of a cell (radial `up`, map `east` and `north` on the
    /// sphere, observer at `r_obs_km` from the Moon's centre; horizon bounds per azimuth bin in
    /// `bins`). `visible_only`: the body's statistics need only whether any part of it is
    /// visible (more than a fraction below [`VISIBLE_ONLY_MAX_FRACTION`]), not whether it is
    /// whole. Array passes over the visited sectors (the first and last vectorise).
    #[allow(clippy::too_many_arguments, reason = "a cell's frame and horizon")]
    #[inline(always)]
    pub fn append_entries(
        &self,
        reference: &MapFrame,
        edges: &[(f32, f32)],
        cell: &MapFrame,
        r_obs_km: f64,
        bins: &HorizonBins,
        visible_only: bool,
        scratch: &mut TableScratch,
        out: &mut Vec<Entry>,
    ) {
        let MapFrame { up, east, north } = *cell;
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
                let (h_lo, h_hi) = bins.range(lo - half_span, hi + half_span);
                top[k] = if visible_only {
                    // The horizon under the disc's top cap (above the chord at 0.9 r, which
                    // spans ±0.436 r) lower than that chord: at least 1.87 % of the disc is
                    // visible.
                    bins.range(
                        lo - CAP_HALF_WIDTH * half_span,
                        hi + CAP_HALF_WIDTH * half_span,
                    )
                    .1 - CAP_HEIGHT * r
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
    pub h: &'a [f32],
    pub lookup: &'a AzimuthLookup,
    pub bins: &'a mut HorizonBins,
    pub scratch: &'a mut TableScratch,
    pub out: &'a mut Vec<Entry>,
}

impl pulp::WithSimd for CellTables<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        self.bins.fill(self.h, self.lookup);
        for (body, visible_only, needed) in self.bodies {
            if !needed {
                self.out.resize(self.out.len() + SECTORS, UNDECIDED);
                continue;
            }
            body.append_entries(
                self.reference,
                self.edges,
                self.frame,
                self.r_obs_km,
                self.bins,
                visible_only,
                self.scratch,
                self.out,
            );
        }
    }
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

/// Bins of a cell's horizon polyline over grid azimuth ([`BINS`] of `360 / BINS` degrees): the
/// lowest and highest horizon over each (its two edges and the bands inside), so that the
/// range over any span is a few comparisons.
#[derive(Debug, Clone)]
pub(super) struct HorizonBins {
    lo: Vec<f32>,
    hi: Vec<f32>,
    edge: Vec<f32>,
}

/// Bins of [`HorizonBins`] (0.125° each).
const BINS: usize = 2880;

impl Default for HorizonBins {
    fn default() -> Self {
        HorizonBins {
            lo: vec![0.0; BINS],
            hi: vec![0.0; BINS],
            edge: vec![0.0; BINS + 1],
        }
    }
}

impl HorizonBins {
    /// The bins of the horizon `h` (`n + 1` band values at `lookup`'s bands).
    #[inline(always)]
    pub fn fill(&mut self, h: &[f32], lookup: &AzimuthLookup) {
        lookup.sample_uniform(h, &mut self.edge);
        for i in 0..BINS {
            let (a, b) = (self.edge[i], self.edge[i + 1]);
            self.lo[i] = a.min(b);
            self.hi[i] = a.max(b);
        }
        let per_deg = BINS as f32 / 360.0;
        for (&az, &v) in lookup.band_az_deg().iter().zip(h) {
            let i = ((az * per_deg) as usize).min(BINS - 1);
            self.lo[i] = self.lo[i].min(v);
            self.hi[i] = self.hi[i].max(v);
        }
    }

    /// The lowest and highest horizon over grid azimuths `[from, to]` (degrees, any real
    /// values, `to ≥ from`), taken over whole bins (so a little beyond the span: conservative).
    #[inline(always)]
    pub fn range(&self, from: f32, to: f32) -> (f32, f32) {
        let per_deg = BINS as f32 / 360.0;
        // Floors by truncation of positive values (spans are within a turn or two of 0°).
        let turns = 4 * BINS as i64;
        let first = ((from * per_deg) as f64 + turns as f64) as i64 - turns;
        let last = ((to * per_deg) as f64 + turns as f64) as i64 - turns;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        if last - first >= BINS as i64 {
            for i in 0..BINS {
                lo = lo.min(self.lo[i]);
                hi = hi.max(self.hi[i]);
            }
            return (lo, hi);
        }
        let start = first.rem_euclid(BINS as i64) as usize;
        let count = (last - first + 1) as usize;
        let head = count.min(BINS - start);
        for i in start..start + head {
            lo = lo.min(self.lo[i]);
            hi = hi.max(self.hi[i]);
        }
        for i in 0..count - head {
            lo = lo.min(self.lo[i]);
            hi = hi.max(self.hi[i]);
        }
        (lo, hi)
    }
}

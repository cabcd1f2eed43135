//! Whole-grid horizons by the line sweep (Timonen & Westerholm 2010; Barrett 2011), exact on the
//! DEM's own polar stereographic grid with every layer.
//!
//! A look direction is a coprime integer step `(dcol, dnorth)` (at most [`SweepParams::max_step`]);
//! the straight map lines of that direction through all pixel centres of the finest layer are
//! swept once each, so every observer stands on its line. Samples are the line's crossings with
//! the lines through cell centres (the bilinear surface exactly), then every coarser layer, plus
//! refinement samples where a piece rises above its chord (`samples.rs`); samples no hull can
//! hold are dropped first (`prune.rs`). Requested azimuths are served by the nearest direction
//! ([`HorizonSweep::directions`], [`SweepDirection::target_error_deg`]).
//!
//! A straight line of the polar stereographic map is the image of a circle through the far pole;
//! unrolling the cone from the Moon's centre over that circle keeps distances and every
//! observer's radial, so the sweep keeps a 2-D convex hull (Graham's scan about the Moon's
//! centre) and reads each horizon as the hull's tangent, then re-evaluates the tangent vertex in
//! exact 3-D. Bands are in *grid azimuth* (from map +y, clockwise); add
//! [`grid_convergence_deg`] for the local azimuth. Geometry, tolerances, and how the sweep
//! differs from the per-site scan: `docs/horizon.md`, "Whole-grid horizons: the line sweep".

use rayon::prelude::*;

mod arc;
mod prune;
mod samples;

use arc::{ArcTracker, LineGeometry};
use samples::*;

use super::HorizonError;
use crate::MOON_RADIUS_M;
use crate::frames::enu_from_moon_me;
use crate::terrain::unit_projector::UnitProjector;
use crate::terrain::{Dem, Projection, TerrainStack};

/// Default number of requested azimuths (0.5° apart).
pub const DEFAULT_SWEEP_AZIMUTHS: usize = 720;
/// Default largest step component of a sweep direction (see [`SweepParams::max_step`]).
pub const DEFAULT_MAX_STEP: u32 = 16;

/// Parameters of a whole-grid sweep.
#[derive(Debug, Clone, Copy)]
pub struct SweepParams {
    /// Observer height above the ground (radial), metres (>= 0).
    pub observer_height_m: f64,
    /// Requested azimuths, uniform in grid azimuth from 0 (>= 4).
    pub azimuths: usize,
    /// Largest `|dcol|`, `|dnorth|` of a direction's integer step (1 … 64); next to the grid axes
    /// steps go on to [`AXIS_STEP_FACTOR`] times this. The work per band is about `|dcol| +
    /// |dnorth|` samples per pixel; the directions next to the grid axes are then
    /// `1 / (4 max_step)` rad apart (0.9° for 16), elsewhere denser.
    pub max_step: u32,
}

impl Default for SweepParams {
    fn default() -> Self {
        SweepParams {
            observer_height_m: crate::DEFAULT_OBSERVER_HEIGHT_M,
            azimuths: DEFAULT_SWEEP_AZIMUTHS,
            max_step: DEFAULT_MAX_STEP,
        }
    }
}

/// One band of a sweep: a look direction as an integer grid step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepDirection {
    /// Columns per step (map +x), signed.
    pub dcol: i32,
    /// Map-north cells per step (toward row 0, map +y), signed.
    pub dnorth: i32,
    /// Grid azimuth of the look direction, degrees in [0, 360): from map +y, clockwise.
    pub grid_az_deg: f64,
    /// Largest |grid azimuth − requested azimuth| over the requested azimuths it serves, degrees.
    pub target_error_deg: f64,
}

/// One finished band: the horizon of every pixel of the swept rows of the finest layer toward
/// one direction.
pub struct SweepBand<'b> {
    /// Index into [`HorizonSweep::directions`].
    pub index: usize,
    /// The direction.
    pub direction: SweepDirection,
    /// The rows of the finest layer the band covers ([`HorizonSweep::rows`]: all of them unless
    /// the sweep was restricted with [`HorizonSweep::with_rows`]).
    pub rows: std::ops::Range<usize>,
    /// Horizon elevation above the local horizontal, degrees, row-major on the finest layer's
    /// grid from the first row of `rows`; NaN at nodata pixels, −90 where no terrain lies along
    /// the line.
    pub elevation_deg: &'b [f32],
    /// Ground distance to the horizon point, metres (NaN where there is none).
    pub distance_m: &'b [f32],
}

/// How much longer than `max_step` the steps next to the grid axes may be ([`sweep_directions`]).
pub const AXIS_STEP_FACTOR: u32 = 4;

/// The sweep directions serving `azimuths` requested grid azimuths `360 k / azimuths` with
/// steps up to `max_step` (grid cells `px_x_m` × `px_y_m`), without repeats, sorted by grid
/// azimuth. Next to the grid axes the steps `(±1, ±k)` and `(±k, ±1)` go on to
/// `AXIS_STEP_FACTOR · max_step` (64 for 16): the directions of steps up to `max_step` alone leave
/// a gap of `atan(1 / max_step)` (3.6° for 16) on each side of an axis, and on a polar map whose
/// central meridian faces the Earth the Earth stays within a few degrees of grid north. The
/// extra work is that of a few long steps (≈ +25 % at 720 azimuths).
pub fn sweep_directions(
    azimuths: usize,
    max_step: u32,
    px_x_m: f64,
    px_y_m: f64,
) -> Vec<SweepDirection> {
    let m = max_step as i32;
    let mut candidates: Vec<(i32, i32, f64)> = Vec::new();
    for dc in -m..=m {
        for dn in -m..=m {
            if (dc, dn) != (0, 0) && gcd(dc.unsigned_abs(), dn.unsigned_abs()) == 1 {
                let az = grid_az_deg(dc, dn, px_x_m, px_y_m);
                candidates.push((dc, dn, az));
            }
        }
    }
    for k in (m + 1)..=(m * AXIS_STEP_FACTOR as i32) {
        for (dc, dn) in [
            (1, k),
            (-1, k),
            (1, -k),
            (-1, -k),
            (k, 1),
            (-k, 1),
            (k, -1),
            (-k, -1),
        ] {
            candidates.push((dc, dn, grid_az_deg(dc, dn, px_x_m, px_y_m)));
        }
    }
    let mut chosen: Vec<SweepDirection> = Vec::new();
    for k in 0..azimuths {
        let target = 360.0 * k as f64 / azimuths as f64;
        let (dc, dn, az) = candidates
            .iter()
            .copied()
            .min_by(|a, b| ang_diff(a.2, target).total_cmp(&ang_diff(b.2, target)))
            .expect("candidates are never empty");
        let err = ang_diff(az, target);
        match chosen.iter_mut().find(|d| (d.dcol, d.dnorth) == (dc, dn)) {
            Some(d) => d.target_error_deg = d.target_error_deg.max(err),
            None => chosen.push(SweepDirection {
                dcol: dc,
                dnorth: dn,
                grid_az_deg: az,
                target_error_deg: err,
            }),
        }
    }
    chosen.sort_by(|a, b| a.grid_az_deg.total_cmp(&b.grid_az_deg));
    chosen
}

/// Local azimuth of map +y (grid north) at pixel (row, col) of `dem`, degrees: add it to a grid
/// azimuth to get the azimuth from true north, clockwise (the map is conformal).
pub fn grid_convergence_deg(dem: &Dem, row: f64, col: f64) -> f64 {
    let projector = UnitProjector::new(&dem.projection);
    let (x, y) = dem.grid.xy_from_row_col(row, col);
    let eps_m = 1.0;
    let u = projector.unit_from_xy(x, y);
    let du = projector.unit_from_xy(x, y + eps_m) - projector.unit_from_xy(x, y - eps_m);
    let (lat_deg, lon_deg) = (
        u.z.clamp(-1.0, 1.0).asin().to_degrees(),
        u.y.atan2(u.x).to_degrees(),
    );
    let enu = enu_from_moon_me(lat_deg, lon_deg);
    let east = enu.row(0).transpose().dot(&du);
    let north = enu.row(1).transpose().dot(&du);
    east.atan2(north).to_degrees().rem_euclid(360.0)
}

/// The whole-grid line sweep over a terrain stack; see the module docs.
pub struct HorizonSweep<'a> {
    stack: &'a TerrainStack,
    projector: UnitProjector,
    two_r_k0_m: f64,
    params: SweepParams,
    directions: Vec<SweepDirection>,
    /// The rows of the finest layer whose horizons are kept (all by default).
    rows: std::ops::Range<usize>,
    /// Whether lines drop the samples no look can have on its hull (see [`prune`]).
    drop_hidden: bool,
}

/// One terrain sample along a line.
#[derive(Debug, Clone, Copy)]
pub struct LineSample {
    /// Map distance along the line from its foot, metres.
    pub t_m: f64,
    /// Arc on the unrolled cone, radians (≈ ground angle), 0 at the line's foot.
    pub psi_rad: f64,
    /// Distance from the Moon's centre, metres.
    pub r_m: f64,
    /// Unrolled-cone plane coordinate `r sin ψ`, metres.
    pub x_m: f64,
    /// Unrolled-cone plane coordinate `r cos ψ`, metres.
    pub y_m: f64,
}

/// An observer on a line: its sample (index into the line's samples) and pixel (row-major
/// index on the finest layer).
#[derive(Debug, Clone, Copy)]
pub struct LineObserver {
    /// Index into the line's samples.
    pub sample: usize,
    /// Row-major pixel index on the finest layer.
    pub pixel: usize,
}

/// One line of a sweep direction as the CPU sweep samples it (see [`HorizonSweep::with_line`]):
/// what the GPU kernel of `crate::twins::line_sweep` receives, packed in f32.
#[derive(Debug, Clone, Copy)]
pub struct SweptLine<'s> {
    /// `ρc` of the module docs (the cone's unrolling factor; 1 through the pole).
    pub rho_c: f64,
    /// `L` of the module docs, metres (`ψ = 2 ρc atan(t / L)`).
    pub l_m: f64,
    /// Map direction of increasing `t` (unit vector, map x and y).
    pub ell: (f64, f64),
    /// The samples in increasing `t` (all layers).
    pub samples: &'s [LineSample],
    /// Every pixel centre on the line (kept rows or not), in increasing `t`.
    pub observers: &'s [LineObserver],
}

/// Per-thread buffers of the sweep (reused from line to line).
#[derive(Default)]
pub struct SweepScratch {
    /// The step template of the direction being swept (see [`step_template`]).
    template: Vec<TemplateEntry>,
    template_for: Option<(i32, i32)>,
    raw: Vec<(f64, f64, Option<usize>, bool)>,
    samples: Vec<LineSample>,
    far: Vec<(f64, f64)>,
    /// The t-ranges of the layers already sampled, and [`push_segment_samples`]' piece ends.
    covered: Vec<(f64, f64)>,
    ts: Vec<f64>,
    observers: Vec<LineObserver>,
    hull: Vec<HullVertex>,
    /// Which samples [`prune::drop_hidden_samples`] must keep.
    keep: Vec<bool>,
}

/// A vertex of a look's hull: the sample's plane coordinates (mirrored for the backward look),
/// kept beside its index so that the hull's orientation tests read one array.
#[derive(Debug, Clone, Copy)]
struct HullVertex {
    x_m: f64,
    y_m: f64,
    sample: usize,
}

/// A canonical line direction and the bands it serves forward and backward.
pub type LineDirection = ((i32, i32), Option<usize>, Option<usize>);

/// One look of one observer: `(pixel, elevation deg, distance m)`.
type Look = (u32, f32, f32);

impl<'a> HorizonSweep<'a> {
    /// Checks the stack and the parameters and chooses the directions.
    pub fn new(stack: &'a TerrainStack, params: SweepParams) -> Result<Self, HorizonError> {
        let fine = stack.layers.first().ok_or(HorizonError::NoLayers)?;
        let h = params.observer_height_m;
        if !(h.is_finite() && h >= 0.0) {
            return Err(HorizonError::BadObserverHeight {
                observer_height_m: h,
            });
        }
        if params.azimuths < 4 || params.azimuths > 100_000 {
            return Err(HorizonError::SweepUnsupported {
                reason: format!("{} azimuths (must be 4 … 100000)", params.azimuths),
            });
        }
        if !(1..=64).contains(&params.max_step) {
            return Err(HorizonError::SweepUnsupported {
                reason: format!("max step {} (must be 1 … 64)", params.max_step),
            });
        }
        let Projection::PolarStereographic { k0, radius_m, .. } = fine.projection else {
            return Err(HorizonError::SweepUnsupported {
                reason: format!(
                    "layer {} is not polar stereographic (the sweep follows straight map lines)",
                    fine.name
                ),
            });
        };
        if let Some(other) = stack
            .layers
            .iter()
            .find(|l| l.projection != fine.projection)
        {
            return Err(HorizonError::SweepUnsupported {
                reason: format!(
                    "layer {} has another projection than {} (the sweep needs one map for all layers)",
                    other.name, fine.name
                ),
            });
        }
        let directions = sweep_directions(
            params.azimuths,
            params.max_step,
            fine.grid.px_x_m,
            fine.grid.px_y_m,
        );
        Ok(HorizonSweep {
            stack,
            projector: UnitProjector::new(&fine.projection),
            two_r_k0_m: 2.0 * radius_m * k0,
            params,
            directions,
            rows: 0..fine.grid.rows,
            drop_hidden: true,
        })
    }

    /// The same sweep with every sample kept on its line: by default a line drops, before its
    /// looks, the samples that lie below the chord of their neighbours and so cannot be on any
    /// look's hull (about two thirds of them on the 240 m LOLA grid; see `prune.rs`), which
    /// changes no horizon. For checks of exactly that.
    pub fn keeping_hidden_samples(mut self) -> Self {
        self.drop_hidden = false;
        self
    }

    /// The same sweep keeping only the horizons of the finest layer's `rows` (a shard of a map,
    /// `penumbra map --shard`): the bands cover those rows, lines that do not cross them are not
    /// swept, and each line's walk stops once past them. The horizons are the same values as
    /// the whole sweep's for those rows (each depends on the terrain along its own line only).
    pub fn with_rows(mut self, rows: std::ops::Range<usize>) -> Result<Self, HorizonError> {
        let all = self.grid_dem().grid.rows;
        if rows.start >= rows.end || rows.end > all {
            return Err(HorizonError::SweepUnsupported {
                reason: format!(
                    "rows {}..{} (the finest layer has {all} rows)",
                    rows.start, rows.end
                ),
            });
        }
        self.rows = rows;
        Ok(self)
    }

    /// The rows of the finest layer whose horizons the sweep keeps.
    pub fn rows(&self) -> std::ops::Range<usize> {
        self.rows.clone()
    }

    /// The parameters.
    pub fn params(&self) -> SweepParams {
        self.params
    }

    /// The bands, sorted by grid azimuth.
    pub fn directions(&self) -> &[SweepDirection] {
        &self.directions
    }

    /// The terrain stack swept.
    pub fn stack(&self) -> &'a TerrainStack {
        self.stack
    }

    /// The finest layer: the output grid.
    pub fn grid_dem(&self) -> &'a Dem {
        &self.stack.layers[0]
    }

    /// Sweeps every band and hands each to `sink` as soon as it is done (bands of opposite
    /// directions come in pairs; memory stays a few grids). `progress` is called with the number
    /// of bands finished.
    pub fn run<E>(
        &self,
        mut sink: impl FnMut(SweepBand<'_>) -> Result<(), E>,
        mut progress: impl FnMut(usize),
    ) -> Result<(), E> {
        let cols = self.grid_dem().grid.cols;
        let first_px = self.rows.start * cols;
        let n_px = self.rows.len() * cols;
        let mut done = 0;
        for (canonical, forward, backward) in self.line_directions() {
            let looks = self.sweep_direction(canonical, forward.is_some(), backward.is_some());
            for (band, looks) in [(forward, &looks.0), (backward, &looks.1)] {
                let Some(index) = band else { continue };
                let mut el = vec![f32::NAN; n_px];
                let mut dist = vec![f32::NAN; n_px];
                for &(px, e, d) in looks {
                    el[px as usize - first_px] = e;
                    dist[px as usize - first_px] = d;
                }
                sink(SweepBand {
                    index,
                    direction: self.directions[index],
                    rows: self.rows.clone(),
                    elevation_deg: &el,
                    distance_m: &dist,
                })?;
                done += 1;
                progress(done);
            }
        }
        Ok(())
    }

    /// The horizon of one pixel toward band `index` (the same sweep restricted to that pixel's
    /// line): `(elevation deg, distance m)`, for checks.
    pub fn pixel_horizon(&self, row: usize, col: usize, index: usize) -> Option<(f64, f64)> {
        let dir = self.directions.get(index)?;
        let (canonical, forward) = canonical_of(dir.dcol, dir.dnorth);
        let grid = &self.grid_dem().grid;
        let (d_row, d_col) = (-canonical.1 as i64, canonical.0 as i64);
        let key = col as i64 * d_row - row as i64 * d_col;
        let mut scratch = SweepScratch::default();
        let mut looks = Vec::new();
        if forward {
            self.sweep_line(canonical, key, &mut scratch, Some(&mut looks), None);
        } else {
            self.sweep_line(canonical, key, &mut scratch, None, Some(&mut looks));
        }
        let px = (row * grid.cols + col) as u32;
        looks
            .iter()
            .find(|l| l.0 == px)
            .map(|l| (f64::from(l.1), f64::from(l.2)))
    }

    /// The canonical line directions (`dcol > 0`, or `dcol == 0` and `dnorth > 0`) with the bands
    /// they serve forward (`+step`) and backward (`−step`).
    pub fn line_directions(&self) -> Vec<LineDirection> {
        let mut out: Vec<LineDirection> = Vec::new();
        for (i, d) in self.directions.iter().enumerate() {
            let (canonical, forward) = canonical_of(d.dcol, d.dnorth);
            let entry = match out.iter_mut().find(|e| e.0 == canonical) {
                Some(e) => e,
                None => {
                    out.push((canonical, None, None));
                    out.last_mut().expect("just pushed")
                }
            };
            if forward {
                entry.1 = Some(i);
            } else {
                entry.2 = Some(i);
            }
        }
        out
    }

    /// The keys of the lines of one canonical direction that cross the kept rows (see
    /// [`Self::with_line`]).
    pub fn line_keys(&self, canonical: (i32, i32)) -> std::ops::RangeInclusive<i64> {
        let g = &self.grid_dem().grid;
        let (d_row, d_col) = (-canonical.1 as i64, canonical.0 as i64);
        let key_of = |r: i64, c: i64| c * d_row - r * d_col;
        // Only the lines through the kept rows (a line's key is linear in row and column).
        let (r0, r1) = (self.rows.start as i64, self.rows.end as i64 - 1);
        let corners = [
            key_of(r0, 0),
            key_of(r0, g.cols as i64 - 1),
            key_of(r1, 0),
            key_of(r1, g.cols as i64 - 1),
        ];
        let k0 = *corners.iter().min().expect("four corners");
        let k1 = *corners.iter().max().expect("four corners");
        k0..=k1
    }

    /// The number of samples the CPU looks walk on line `key` of a canonical direction (after
    /// the pruning of `prune.rs` for looks that decide their sets' boundaries in f64, unless
    /// [`Self::keeping_hidden_samples`]); `None` when the line holds no pixel centre with data.
    /// For measurements and checks.
    pub fn looked_sample_count(
        &self,
        canonical: (i32, i32),
        key: i64,
        scratch: &mut SweepScratch,
    ) -> Option<usize> {
        self.build_line(canonical, key, prune::Boundary::F64, scratch)?;
        Some(scratch.samples.len())
    }

    /// Builds line `key` of a canonical direction (from [`Self::line_directions`] and
    /// [`Self::line_keys`]) as the CPU sweep samples it and hands it to `f`; `None` when the line
    /// holds no pixel centre with data. The hidden samples are dropped for looks that decide the
    /// boundaries of their sets in f32 (the GPU kernel and its twin: the samples on either side
    /// of each boundary stay too, so a line holds a few more samples than the CPU looks walk).
    pub fn with_line<R>(
        &self,
        canonical: (i32, i32),
        key: i64,
        scratch: &mut SweepScratch,
        f: impl FnOnce(SweptLine<'_>) -> R,
    ) -> Option<R> {
        let geom = self.build_line(canonical, key, prune::Boundary::F32, scratch)?;
        Some(f(SweptLine {
            rho_c: geom.rho_c,
            l_m: geom.l_m,
            ell: geom.ell,
            samples: &scratch.samples,
            observers: &scratch.observers,
        }))
    }

    /// Half a pixel of the finest layer as a ground angle, radians: terrain closer to an
    /// observer than this is not part of its horizon (as in the per-site scan).
    pub fn theta_min_rad(&self) -> f64 {
        0.5 * self.grid_dem().px_m() / MOON_RADIUS_M
    }

    /// All lines of one canonical direction: the looks forward and backward.
    fn sweep_direction(
        &self,
        canonical: (i32, i32),
        forward: bool,
        backward: bool,
    ) -> (Vec<Look>, Vec<Look>) {
        let keys = self.line_keys(canonical);
        let k0 = *keys.start();
        let n_keys = usize::try_from(keys.end() - k0 + 1).expect("key range fits");
        let chunks: Vec<(Vec<Look>, Vec<Look>)> = (0..n_keys)
            .into_par_iter()
            .with_min_len(16)
            .fold(
                || (SweepScratch::default(), Vec::new(), Vec::new()),
                |(mut scratch, mut f, mut b), i| {
                    let key = k0 + i as i64;
                    self.sweep_line(
                        canonical,
                        key,
                        &mut scratch,
                        forward.then_some(&mut f),
                        backward.then_some(&mut b),
                    );
                    (scratch, f, b)
                },
            )
            .map(|(_, f, b)| (f, b))
            .collect();
        let mut f = Vec::new();
        let mut b = Vec::new();
        for (cf, cb) in chunks {
            f.extend(cf);
            b.extend(cb);
        }
        (f, b)
    }

    /// Sweeps one line (`key = col · d_row − row · d_col`), appending its looks forward and/or
    /// backward to the given outputs.
    fn sweep_line(
        &self,
        canonical: (i32, i32),
        key: i64,
        scratch: &mut SweepScratch,
        forward: Option<&mut Vec<Look>>,
        backward: Option<&mut Vec<Look>>,
    ) {
        let Some(geom) = self.build_line(canonical, key, prune::Boundary::F64, scratch) else {
            return;
        };
        let theta_min_rad = self.theta_min_rad();
        if let Some(out) = forward {
            self.look(&geom, scratch, theta_min_rad, 1.0, out);
        }
        if let Some(out) = backward {
            self.look(&geom, scratch, theta_min_rad, -1.0, out);
        }
    }

    /// Fills `scratch.samples` (sorted by `t`) and `scratch.observers` for one line; `None` when
    /// the line holds no pixel centre.
    fn build_line(
        &self,
        canonical: (i32, i32),
        key: i64,
        boundary: prune::Boundary,
        scratch: &mut SweepScratch,
    ) -> Option<LineGeometry> {
        let fine = self.grid_dem();
        let g = &fine.grid;
        let (rows, cols) = (g.rows as i64, g.cols as i64);
        let (d_row, d_col) = (-canonical.1 as i64, canonical.0 as i64);
        // A pixel of key 1: x0 d_row − y0 d_col = 1 (col x0, row y0).
        let (gcd, a, b) = ext_gcd(d_row, -d_col);
        debug_assert_eq!(gcd.abs(), 1);
        let (x0, y0) = (a * gcd * key, b * gcd * key);
        // Pixels (row, col) = (y0 + m d_row, x0 + m d_col) inside the grid.
        let (m0, m1) = {
            let (lo_c, hi_c) = m_range(x0, d_col, cols)?;
            let (lo_r, hi_r) = m_range(y0, d_row, rows)?;
            (lo_c.max(lo_r), hi_c.min(hi_r))
        };
        if m0 > m1 {
            return None;
        }
        let (r_start, c_start) = (y0 + m0 * d_row, x0 + m0 * d_col);
        // Map geometry of the line.
        let (px_x, px_y) = (g.px_x_m, g.px_y_m);
        let v = (f64::from(canonical.0) * px_x, f64::from(canonical.1) * px_y);
        let step_m = v.0.hypot(v.1);
        let ell = (v.0 / step_m, v.1 / step_m);
        let m_hat = (-ell.1, ell.0);
        let p0 = g.xy_from_row_col(r_start as f64, c_start as f64);
        let d_m = p0.0 * m_hat.0 + p0.1 * m_hat.1;
        let t0_m = p0.0 * ell.0 + p0.1 * ell.1;
        let l_m = self.two_r_k0_m.hypot(d_m);
        let geom = LineGeometry {
            ell,
            m_hat,
            d_m,
            rho_c: self.two_r_k0_m / l_m,
            l_m,
        };

        // Fine samples: a template of crossings per step.
        if scratch.template_for != Some(canonical) {
            scratch.template = step_template(d_row, d_col, cols);
            scratch.template_for = Some(canonical);
        }
        let SweepScratch {
            template,
            raw,
            samples,
            far,
            covered,
            ts,
            observers,
            keep,
            ..
        } = scratch;
        raw.clear();
        samples.clear();
        observers.clear();
        far.clear();
        let heights = &fine.heights_m;
        for m in 0..=(m1 - m0) {
            let base = ((r_start + m * d_row) * cols + c_start + m * d_col) as isize;
            for (j, e) in template.iter().enumerate() {
                if m == m1 - m0 && j > 0 {
                    break;
                }
                let h: f64 = (0..4)
                    .map(|k| e.w[k] * f64::from(heights[(base + e.off[k]) as usize]))
                    .sum();
                if h.is_nan() {
                    continue;
                }
                let t = t0_m + (m as f64 + e.f) * step_m;
                raw.push((t, h, (j == 0).then_some(base as usize), !e.crossing));
            }
        }
        let t_fine = (
            t0_m.min(t0_m + (m1 - m0) as f64 * step_m),
            t0_m.max(t0_m + (m1 - m0) as f64 * step_m),
        );
        // The finest layer's border beyond its outermost centres on this line (edge values
        // extended, as in `Dem::height_at_row_col`), then every coarser layer outside the
        // extents of the finer ones.
        let near = ObserverSpan {
            t_m: t_fine,
            near_m: fine.px_m(),
        };
        covered.clear();
        covered.push(t_fine);
        if let Some(((lo, hi), in_grid)) = extent_range(fine, &geom) {
            push_segment_samples(fine, in_grid, (lo, t_fine.0), near, covered, ts, far);
            push_segment_samples(fine, in_grid, (t_fine.1, hi), near, covered, ts, far);
            covered.push((lo, hi));
        }
        for dem in &self.stack.layers[1..] {
            if let Some((range, in_grid)) = extent_range(dem, &geom) {
                push_segment_samples(dem, in_grid, range, near, covered, ts, far);
                covered.push(range);
            }
        }
        far.sort_by(|a, b| a.0.total_cmp(&b.0));
        // The samples in increasing t (the arc tracker's order): the far ones before the finest
        // layer's, its own (concave pieces get more samples, see `refine_piece`), the far ones
        // after it.
        let mut arc = ArcTracker::new(&geom);
        let mut push = |samples: &mut Vec<LineSample>, t: f64, h: f64| {
            let (psi, s, c) = arc.at(t);
            let r = MOON_RADIUS_M + h;
            samples.push(LineSample {
                t_m: t,
                psi_rad: psi,
                r_m: r,
                x_m: r * s,
                y_m: r * c,
            });
        };
        for &(t, h) in far.iter().filter(|s| s.0 < t_fine.0) {
            push(samples, t, h);
        }
        let n_before = samples.len();
        for (i, &(t, h, pixel, mid)) in raw.iter().enumerate() {
            if mid {
                match (i.checked_sub(1).map(|k| raw[k]), raw.get(i + 1)) {
                    (Some((ta, ha, _, false)), Some(&(tb, hb, _, false))) => {
                        refine_piece((ta, ha), h, (tb, hb), SAG_TOLERANCE_M, |t, h| {
                            push(samples, t, h)
                        });
                    }
                    _ => push(samples, t, h),
                }
            } else {
                if let Some(p) = pixel {
                    observers.push(LineObserver {
                        sample: samples.len(),
                        pixel: p,
                    });
                }
                push(samples, t, h);
            }
        }
        if samples.len() == n_before {
            return None;
        }
        for &(t, h) in far.iter().filter(|s| s.0 > t_fine.1) {
            push(samples, t, h);
        }
        if self.drop_hidden {
            prune::drop_hidden_samples(samples, observers, self.theta_min_rad(), boundary, keep);
        }
        Some(geom)
    }

    /// One look along a line: `sign = +1` toward increasing `t`, `−1` toward decreasing.
    fn look(
        &self,
        geom: &LineGeometry,
        scratch: &mut SweepScratch,
        theta_min_rad: f64,
        sign: f64,
        out: &mut Vec<Look>,
    ) {
        let SweepScratch {
            samples,
            observers,
            hull,
            ..
        } = scratch;
        hull.clear();
        let n = samples.len();
        // Visit order: from the far end of the look toward the near end.
        let at = |k: usize| if sign > 0.0 { n - 1 - k } else { k };
        let obs_at = |k: usize| {
            if sign > 0.0 {
                observers[observers.len() - 1 - k]
            } else {
                observers[k]
            }
        };
        // Mirrored plane coordinates for the backward look.
        let xy = |s: &LineSample| (sign * s.x_m, s.y_m);
        let mut next = 0;
        let h_obs = self.params.observer_height_m;
        // The kept pixels (the kept rows): the rows along a line are monotonic, so the walk
        // stops at the first observer past them. Skipping an observer leaves the hull as it is:
        // the next one's loop adds every sample beyond it.
        let cols = self.grid_dem().grid.cols;
        let kept = self.rows.start * cols..self.rows.end * cols;
        let mut entered = false;
        for k in 0..observers.len() {
            let o = obs_at(k);
            if !kept.contains(&o.pixel) {
                if entered {
                    break;
                }
                continue;
            }
            entered = true;
            let so = samples[o.sample];
            let psi_o = sign * so.psi_rad;
            while next < n && sign * samples[at(next)].psi_rad >= psi_o + theta_min_rad {
                let q = at(next);
                let (qx, qy) = xy(&samples[q]);
                while let [.., c, b] = hull.as_slice() {
                    // q, b, c in increasing psi: b stays if q → b → c turns clockwise.
                    let cross = (b.x_m - qx) * (c.y_m - b.y_m) - (b.y_m - qy) * (c.x_m - b.x_m);
                    if cross >= 0.0 {
                        hull.pop();
                    } else {
                        break;
                    }
                }
                hull.push(HullVertex {
                    x_m: qx,
                    y_m: qy,
                    sample: q,
                });
                next += 1;
            }
            // The observer's own piece: from half a pixel out (where the per-site scan starts) to
            // the first shared sample passed, sampled at both ends' midpoint and its start.
            let r0 = so.r_m + h_obs;
            let (x, y) = geom.point(so.t_m);
            let up = self.projector.unit_from_xy(x, y);
            let obs = up * r0;
            // Best (sin elevation, distance m) so far, exact in 3-D.
            let mut best = (f64::NEG_INFINITY, f64::NAN);
            let mut offer = |t_m: f64, r_m: f64, psi_rad: f64| {
                let (x, y) = geom.point(t_m);
                let v = self.projector.unit_from_xy(x, y) * r_m - obs;
                let sin_el = v.dot(&up) / v.norm();
                if sin_el > best.0 {
                    best = (sin_el, (psi_rad - so.psi_rad).abs() * MOON_RADIUS_M);
                }
            };
            {
                // ψ(t) near the observer by its Taylor polynomial (the piece is a pixel or two
                // long: relative error below 1e-8, used for the distance alone), and its
                // inverse at half a pixel to second order (error below 1e-9 m): no `tan` or
                // `atan` per look.
                let (d1, d2) = geom.psi_derivatives(so.t_m);
                let psi_near = |t: f64| {
                    let dt = t - so.t_m;
                    so.psi_rad + dt * (d1 + 0.5 * d2 * dt)
                };
                let dt1 = theta_min_rad / d1;
                let t_start = so.t_m + sign * dt1 - 0.5 * d2 * dt1 * dt1 / d1;
                let t_first = if next > 0 {
                    samples[at(next - 1)].t_m
                } else {
                    t_start + sign * self.grid_dem().px_m()
                };
                let t_mid = 0.5 * (t_start + t_first);
                for t in [t_start, t_mid] {
                    // The stack's height there: at the fine grid's edge the piece reaches past
                    // it, onto the next layer (all layers share the map, checked in `new`).
                    let (x, y) = geom.point(t);
                    let h = bilinear_m(self.grid_dem(), x, y).or_else(|| {
                        self.stack.layers[1..]
                            .iter()
                            .find_map(|dem| dem.height_at_xy_m(x, y))
                    });
                    if let Some(h) = h {
                        offer(t, MOON_RADIUS_M + h, psi_near(t));
                    }
                }
            }
            let el_deg = |sin_el: f64| sin_el.clamp(-1.0, 1.0).asin().to_degrees() as f32;
            if hull.is_empty() {
                out.push(if best.0 == f64::NEG_INFINITY {
                    (o.pixel as u32, -90.0, f32::NAN)
                } else {
                    (o.pixel as u32, el_deg(best.0), best.1 as f32)
                });
                continue;
            }
            // Tangent from the observer: the nearest hull vertex whose farther neighbour is not
            // higher as seen from it (unimodal along the convex chain).
            // (r0 sin ψ, r0 cos ψ) from the sample's own plane point (r sin ψ, r cos ψ).
            let lift = r0 / so.r_m;
            let ox = sign * so.x_m * lift;
            let oy = so.y_m * lift;
            let higher = |i: usize| {
                // Is hull[i - 1] (farther) above the ray observer → hull[i]?
                let (v, w) = (hull[i], hull[i - 1]);
                (v.x_m - ox) * (w.y_m - oy) - (v.y_m - oy) * (w.x_m - ox) > 0.0
            };
            let (mut lo, mut hi) = (0, hull.len() - 1);
            while lo < hi {
                let mid = (lo + hi).div_ceil(2);
                if higher(mid) {
                    hi = mid - 1;
                } else {
                    lo = mid;
                }
            }
            // Exact 3-D elevation of the tangent vertex, and of a hull neighbour when it is within
            // NEAR_TIE_RAD of it in the plane (where the unrolling could swap them).
            let v = hull[lo];
            let tangent = samples[v.sample];
            offer(tangent.t_m, tangent.r_m, tangent.psi_rad);
            let (vx, vy) = (v.x_m - ox, v.y_m - oy);
            // (No overflow or underflow to guard against: plain square roots, not `hypot`.)
            let v_len = (vx * vx + vy * vy).sqrt();
            for i in [lo.wrapping_sub(1), lo + 1] {
                let Some(&w) = hull.get(i) else { continue };
                let (wx, wy) = (w.x_m - ox, w.y_m - oy);
                // Sine of the angle by which w lies below the tangent ray.
                let below = (wx * vy - wy * vx) / (v_len * (wx * wx + wy * wy).sqrt());
                if below.abs() < NEAR_TIE_RAD {
                    let s = samples[w.sample];
                    offer(s.t_m, s.r_m, s.psi_rad);
                }
            }
            out.push((o.pixel as u32, el_deg(best.0), best.1 as f32));
        }
    }
}

/// Hull neighbours of the tangent vertex closer than this to its ray (radians) are evaluated in
/// exact 3-D too: the unrolled cone keeps elevations to about 7e-5 rad in the worst case (a line
/// 260 km from the pole, an occluder 100 km away and 3 km higher).
const NEAR_TIE_RAD: f64 = 2e-4;

/// Bilinear height (m) of `dem` at map point (x, y): the four cell centres read directly inside
/// the lattice, [`Dem::height_at_xy_m`] (edges, holes) elsewhere.
#[inline]
fn bilinear_m(dem: &Dem, x_m: f64, y_m: f64) -> Option<f64> {
    let g = &dem.grid;
    let (row, col) = g.row_col_from_xy(x_m, y_m);
    let (r0, c0) = (row.floor(), col.floor());
    if r0 >= 0.0 && c0 >= 0.0 && r0 + 1.0 < g.rows as f64 && c0 + 1.0 < g.cols as f64 {
        let (fr, fc) = (row - r0, col - c0);
        let i = r0 as usize * g.cols + c0 as usize;
        let h = &dem.heights_m;
        let (a, b, c, d) = (
            f64::from(h[i]),
            f64::from(h[i + 1]),
            f64::from(h[i + g.cols]),
            f64::from(h[i + g.cols + 1]),
        );
        let v = (1.0 - fr) * ((1.0 - fc) * a + fc * b) + fr * ((1.0 - fc) * c + fc * d);
        if !v.is_nan() {
            return Some(v);
        }
    }
    dem.height_at_row_col(row, col)
}

#[cfg(test)]
mod tests;

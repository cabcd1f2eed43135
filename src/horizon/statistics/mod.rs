//! Long-period illumination statistics of every pixel from whole-grid horizons (Mazarico et al.
//! 2011, Icarus 211: horizon profiles at every pixel, then any geometry), instead of a shadow
//! map per epoch.
//!
//! ```text
//!  horizons (one band per grid azimuth, from `horizon-map sweep` or a sweep in memory)
//!      │ a block of rows at a time, every band
//!      ▼
//!  per pixel: frame (up, map +x and +y on the sphere), observer radius, horizon h(grid az)
//!      │ for every epoch in time order (f32, epochs in chunks that stay in cache)
//!      ▼
//!  Sun / Earth centre at the pixel → el (above the local horizontal), grid az → h(az) → fraction
//!      ▼
//!  mean fraction, % visible, % full, Earth %, both %, longest night, longest Earth-hidden run,
//!  mean irradiance (horizontal, tracking), PSR, rays the Moon beyond the DEM would block
//! ```
//!
//! Each pixel's own directions (parallax and the tilt of its vertical exact), the horizon linear
//! between bands, the fraction as the circular segment of paper 001 (eqs. 6–7); shortcuts in
//! `sectors.rs`. Details and measurements: `docs/horizon.md`, "Statistics from horizons".

mod blocks;
mod kernel;
mod lookup;
mod offload;
mod sectors;
mod source;
#[doc(hidden)]
pub mod testing;

use rayon::prelude::*;

pub use blocks::{BlockStore, NoStore};
use kernel::{BOUND_SECTORS, CellAcc, CellGeom, Epochs, Scratch, Thresholds};
pub use lookup::{AzimuthLookup, ChordTable, atan2_deg};
pub use offload::{CellKernel, EPOCH_CHUNK, KernelAcc, KernelCell, KernelEpoch, KernelShared};
use sectors::MapFrame;
pub use source::{
    HORIZON_NODATA_I16, HORIZON_PRODUCT, HorizonFile, HorizonRows, InMemoryHorizons,
    horizon_centideg,
};

use super::HorizonError;
use crate::illum::LimbDarkening;
use crate::output::BelowSphereExits;
use crate::terrain::unit_projector::UnitProjector;
use crate::terrain::{Dem, TerrainStack};
use crate::{AU_KM, MOON_RADIUS_M, SOLAR_CONSTANT_W_M2};

/// The bodies at one epoch.
#[derive(Debug, Clone, Copy)]
pub struct EpochBodies {
    /// The Sun's centre relative to the Moon's centre, `MOON_ME`, km (apparent).
    pub sun_in_moon_me_km: [f64; 3],
    /// The Sun's distance from the observer, km (irradiance).
    pub sun_range_km: f64,
    /// The Sun's angular radius, degrees.
    pub sun_radius_deg: f64,
    /// The Earth's centre relative to the Moon's centre, `MOON_ME`, km (apparent).
    pub earth_in_moon_me_km: [f64; 3],
    /// The Earth's angular radius, degrees.
    pub earth_radius_deg: f64,
}

impl EpochBodies {
    /// The Sun and the Earth at every epoch, seen from the centre of `dem` (positions relative
    /// to the Moon's centre; the engine moves them to each pixel).
    pub fn over_dem(
        dem: &Dem,
        kernels: &crate::ephem::Kernels,
        epochs: &[hifitime::Epoch],
        abcorr: crate::ephem::AbCorr,
    ) -> Result<Vec<EpochBodies>, crate::ephem::EphemError> {
        let g = dem.grid;
        let (cx, cy) = g.xy_from_row_col((g.rows as f64 - 1.0) / 2.0, (g.cols as f64 - 1.0) / 2.0);
        let (lat, lon) = dem.projection.lat_lon_from_xy(cx, cy);
        let site = crate::ephem::Site::new(lat, lon, 0.0)?;
        let sky = crate::ephem::sun_earth_series(kernels, &[site], epochs, abcorr)?;
        let at = |rel: nalgebra::Vector3<f64>| {
            let p = site.pos_in_moon_me_km + rel;
            [p.x, p.y, p.z]
        };
        Ok(sky[0]
            .iter()
            .map(|v| EpochBodies {
                sun_in_moon_me_km: at(v.sun.pos_in_moon_me_km),
                sun_range_km: v.sun.range_km,
                sun_radius_deg: v.sun.radius_deg,
                earth_in_moon_me_km: at(v.earth.pos_in_moon_me_km),
                earth_radius_deg: v.earth.radius_deg,
            })
            .collect())
    }
}

/// Parameters of the statistics.
#[derive(Debug, Clone, Copy)]
pub struct StatisticsParams {
    /// Limb darkening of the Sun's disc (the Earth's is uniform).
    pub limb: LimbDarkening,
    /// A disc is "visible" when more than this fraction is.
    pub visible_min_fraction: f64,
    /// The Sun is "fully lit" when at least this fraction is visible.
    pub full_min_fraction: f64,
}

/// Per-pixel statistics over the epochs, row-major on the horizons' (finest layer's) grid.
#[derive(Debug, Clone)]
pub struct HorizonStatistics {
    /// Number of epochs.
    pub epochs: usize,
    /// Pixels without data (DEM nodata or horizon nodata).
    pub nodata: Vec<bool>,
    /// Sum over the epochs of the Sun's visible (flux) fraction.
    pub sun_fraction_sum: Vec<f64>,
    /// Epochs with any part of the Sun visible.
    pub sun_visible_count: Vec<u32>,
    /// Epochs with the Sun fully visible.
    pub sun_full_count: Vec<u32>,
    /// Longest run of consecutive epochs with the Sun entirely hidden.
    pub longest_dark_epochs: Vec<u32>,
    /// Epochs with any part of the Earth visible.
    pub earth_visible_count: Vec<u32>,
    /// Longest run of consecutive epochs with the Earth entirely hidden.
    pub longest_earth_hidden_epochs: Vec<u32>,
    /// Epochs with both (partly) visible.
    pub sun_and_earth_count: Vec<u32>,
    /// Epochs with direct-to-Earth: any part of the Earth visible while a station sees the DEM
    /// ([`StatisticsEngine::with_link`]; all 0 without).
    pub dte_count: Vec<u32>,
    /// Longest run of consecutive epochs without direct-to-Earth (all 0 without a link).
    pub longest_dte_blackout_epochs: Vec<u32>,
    /// The stations of the direct-to-Earth statistics, described (`None` without a link).
    pub link: Option<String>,
    /// Sum over the epochs of the irradiance on a level surface, W/m².
    pub irradiance_horizontal_sum_w_m2: Vec<f64>,
    /// Sum over the epochs of the irradiance on a vertical panel facing the Sun's azimuth, W/m².
    pub irradiance_tracking_sum_w_m2: Vec<f64>,
    /// Sum over the epochs of the panel's power, W ([`StatisticsEngine::with_power`]; all 0
    /// without).
    pub power_sum_w: Vec<f64>,
    /// The smallest battery that, starting full, carries the load through every epoch, Wh (all
    /// 0 without a panel).
    pub required_battery_wh: Vec<f64>,
    /// The panel and load of the power statistics, described (`None` without).
    pub power: Option<String>,
    /// Lit results resting on rays the Moon beyond the DEM would block.
    pub below_sphere: BelowSphereExits,
}

/// Where a ray leaves the outermost layer, for the below-sphere count.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BeyondDem {
    x_m: f64,
    y_m: f64,
    up: [f64; 3],
    r0_m: f64,
    /// The highest elevation at which a ray may meet the reference sphere beyond the layers:
    /// the observer's geometric horizon on the sphere, `−acos(R / r0)` (0 when the observer is
    /// inside the sphere: then every descending ray meets it), or lower where every ray leaves
    /// the outermost layer far enough away to have risen above the sphere by then
    /// ([`StatisticsEngine::min_exit_angle_rad`]).
    dip_deg: f32,
    /// `sin(dip)` plus room for f32 rounding: a Sun whose sine of elevation is at least this
    /// needs no below-sphere test (no elevation needs computing).
    sin_dip_bound: f32,
}

/// The layers' map extents and the projection, shared by every pixel's [`BeyondDem`].
struct Edges {
    extents: Vec<(f64, f64, f64, f64)>,
    projector: UnitProjector,
}

/// The distance along a ray whose component on one axis is `d` (per unit distance) from `p` to
/// where it leaves `[lo, hi]` on that axis (`inf` for `d = 0`).
fn exit_along(p: f64, d: f64, lo: f64, hi: f64) -> f64 {
    if d > 0.0 {
        (hi - p) / d
    } else if d < 0.0 {
        (lo - p) / d
    } else {
        f64::INFINITY
    }
}

impl BeyondDem {
    /// Whether a ray at `el_deg` (< 0) can meet the reference sphere at all: its closest
    /// approach to the Moon's centre, `r0 cos(el)`, is inside the sphere, i.e. it is below the
    /// observer's geometric horizon `−acos(R / r0)` (a cheap filter before
    /// [`BeyondDem::meets_sphere`]).
    #[inline]
    fn may_meet_sphere(&self, el_deg: f32) -> bool {
        el_deg < self.dip_deg
    }

    /// See [`BeyondDem::sin_dip_bound`]'s field.
    #[inline]
    fn sin_dip_bound(&self) -> f32 {
        self.sin_dip_bound
    }

    /// Whether a ray at grid azimuth `grid_az_deg` and elevation `el_deg` (< 0), once past the
    /// outermost layer's edge, meets the reference sphere.
    fn meets_sphere(&self, edges: &Edges, grid_az_deg: f32, el_deg: f32) -> bool {
        let (dx, dy) = f64::from(grid_az_deg).to_radians().sin_cos();
        let mut t_exit = f64::NEG_INFINITY;
        for &(x0, y0, x1, y1) in &edges.extents {
            if !(self.x_m >= x0 && self.x_m <= x1 && self.y_m >= y0 && self.y_m <= y1) {
                continue;
            }
            let (tx, ty) = (
                exit_along(self.x_m, dx, x0, x1),
                exit_along(self.y_m, dy, y0, y1),
            );
            t_exit = t_exit.max(tx.min(ty));
        }
        if !t_exit.is_finite() {
            return false;
        }
        let ue = edges
            .projector
            .unit_from_xy(self.x_m + t_exit * dx, self.y_m + t_exit * dy);
        let up = nalgebra::Vector3::from(self.up);
        let phi = up.cross(&ue).norm().atan2(up.dot(&ue));
        let el = f64::from(el_deg).to_radians();
        let (r0, r) = (self.r0_m, MOON_RADIUS_M);
        let s_star = -r0 * el.sin();
        let c = (el + phi).cos();
        let s_e = if c > 0.0 {
            r0 * phi.sin() / c
        } else {
            f64::INFINITY
        };
        if s_e >= s_star {
            s_e.is_finite() && r0 * r0 + 2.0 * r0 * s_e * el.sin() + s_e * s_e < r * r
        } else {
            r0 * el.cos() < r
        }
    }
}

/// Bounds of a body's path over every epoch, seen from the grid centre: what
/// [`StatisticsEngine::cell`] needs to tell a cell that never (or always) sees it.
#[derive(Debug, Clone, Copy)]
struct BodyBounds {
    /// The elevation range at the grid centre, degrees.
    el_lo_deg: f64,
    el_hi_deg: f64,
    /// The largest angular radius, degrees.
    radius_max_deg: f64,
    /// The mean direction (`MOON_ME` unit vector) and the largest angle of any epoch's
    /// direction from it, degrees (≥ 90: the body goes all round).
    mean_dir: nalgebra::Vector3<f64>,
    spread_deg: f64,
    /// How much the direction can differ between the grid centre and any cell for the same
    /// epoch (parallax across the grid), degrees.
    parallax_deg: f64,
}

impl BodyBounds {
    /// The bounds of the body at `positions_km` (relative to the Moon's centre) seen from the
    /// point `centre_km` with radial `up`, over a grid reaching `reach_m` from it.
    fn new(
        positions_km: impl Iterator<Item = ([f64; 3], f64)>,
        centre_km: nalgebra::Vector3<f64>,
        up: nalgebra::Vector3<f64>,
        reach_m: f64,
    ) -> Self {
        let mut b = BodyBounds {
            el_lo_deg: f64::INFINITY,
            el_hi_deg: f64::NEG_INFINITY,
            radius_max_deg: 0.0,
            mean_dir: nalgebra::Vector3::zeros(),
            spread_deg: 0.0,
            parallax_deg: 0.0,
        };
        let mut dirs = Vec::new();
        let mut d_min_km = f64::INFINITY;
        for (p, radius_deg) in positions_km {
            let v = nalgebra::Vector3::from(p) - centre_km;
            let u = v / v.norm();
            let el = u.dot(&up).clamp(-1.0, 1.0).asin().to_degrees();
            b.el_lo_deg = b.el_lo_deg.min(el);
            b.el_hi_deg = b.el_hi_deg.max(el);
            b.radius_max_deg = b.radius_max_deg.max(radius_deg);
            b.mean_dir += u;
            d_min_km = d_min_km.min(v.norm());
            dirs.push(u);
        }
        b.mean_dir /= b.mean_dir.norm().max(1e-300);
        b.spread_deg = dirs
            .iter()
            .map(|u| u.dot(&b.mean_dir).clamp(-1.0, 1.0).acos().to_degrees())
            .fold(0.0, f64::max);
        // Cells stand up to `reach_m` from the centre and up to ±20 km from the sphere.
        b.parallax_deg = ((reach_m + 20_000.0) / (1000.0 * d_min_km)).to_degrees() + 1e-3;
        b
    }

    /// Whether the body never, always or sometimes clears the horizon `h` (`n + 1` band values
    /// at `lookup`'s azimuths) of a cell whose radial `up` is `tilt_deg` from the grid centre's, and
    /// where `mean_dir` has grid azimuth `mean_az_deg` and elevation `mean_el_deg`.
    fn reach(
        &self,
        h: &[f32],
        lookup: &AzimuthLookup,
        tilt_deg: f64,
        (mean_az_deg, mean_el_deg): (f64, f64),
    ) -> kernel::Reach {
        // Elevation range at the cell: the tilt of its vertical and the parallax move a
        // direction's sine of elevation by at most their angle, the elevation by that over cos.
        let steep = (self.el_lo_deg.abs().max(self.el_hi_deg.abs()) + tilt_deg).min(89.0);
        let grow = (tilt_deg + self.parallax_deg) / steep.to_radians().cos();
        let (el_lo, el_hi) = (self.el_lo_deg - grow, self.el_hi_deg + grow);
        // The azimuths the disc can cover: directions within `rho` of the mean direction (at
        // elevation `mean_el_deg` here). A cap that holds the zenith or the nadir covers every
        // azimuth; else its azimuths reach `asin(sin rho / cos e)` from the mean's. (Dividing
        // `rho` by the cosine of the bodies' elevations instead missed the whole circle when
        // the mean direction of a month of a polar Sun points near the nadir: cells that see
        // the Sun low over the DEM's edge were marked "never", found by the GPU kernel.)
        let rho = self.spread_deg + tilt_deg + self.parallax_deg + self.radius_max_deg + 0.1;
        let half_width = if rho >= 90.0 - mean_el_deg.abs() {
            180.0
        } else {
            ((rho.to_radians().sin() / mean_el_deg.to_radians().cos()).min(1.0))
                .asin()
                .to_degrees()
                + 0.1
        };
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut take = |k: usize| {
            lo = lo.min(h[k].min(h[k + 1]));
            hi = hi.max(h[k].max(h[k + 1]));
        };
        if half_width >= 180.0 {
            (0..lookup.n_bands()).for_each(&mut take);
        } else {
            lookup
                .segments_over((mean_az_deg - half_width) as f32, (2.0 * half_width) as f32)
                .for_each(&mut take);
        }
        // 1e-3° for the kernel's f32 geometry.
        let r = self.radius_max_deg + 1e-3;
        if f64::from(lo) >= el_hi + r {
            kernel::Reach::Never
        } else if f64::from(hi) <= el_lo - r {
            kernel::Reach::Always
        } else {
            kernel::Reach::Varies
        }
    }
}

/// The [`MapFrame`] at map point `(x, y)`.
fn map_frame(projector: &UnitProjector, x: f64, y: f64) -> MapFrame {
    let up = projector.unit_from_xy(x, y);
    let tangent = |d: nalgebra::Vector3<f64>| {
        let t = d - up * up.dot(&d);
        t / t.norm()
    };
    let eps_m = 1.0;
    MapFrame {
        up,
        east: tangent(projector.unit_from_xy(x + eps_m, y) - projector.unit_from_xy(x - eps_m, y)),
        north: tangent(projector.unit_from_xy(x, y + eps_m) - projector.unit_from_xy(x, y - eps_m)),
    }
}

/// Cells per parallel task (their horizons stay in L1/L2 while the epochs stream).
const CELLS_PER_TASK: usize = 16;
/// Bytes of horizons read per block of rows.
const BLOCK_BYTES: usize = 128 << 20;
/// The fewest blocks of rows a grid is split into (the units a killed run keeps).
const MIN_BLOCKS: usize = 16;

/// The statistics engine over a terrain stack and its whole-grid horizons.
pub struct StatisticsEngine<'a> {
    stack: &'a TerrainStack,
    params: StatisticsParams,
    /// Whether cells that never (or always) see a body skip it (off only to test that the
    /// bounds never change a result).
    skip_unseen: bool,
    /// Whether the shared sector classification decides most epochs (off only to test that it
    /// never changes a result).
    sector_tables: bool,
    /// Whether blocks of epochs decided whole by the tables skip the epoch-by-epoch path (off
    /// only to test that they never change a result).
    block_decisions: bool,
    /// The farthest corner of any layer from the map origin, map metres (for
    /// [`Self::min_exit_angle_rad`]).
    layers_reach_m: f64,
    /// Per epoch: a ground station sees the DEM, and the stations described
    /// ([`Self::with_link`]).
    link: Option<(Vec<bool>, String)>,
    /// A panel and its load ([`Self::with_power`]).
    power: Option<PowerInputs>,
}

/// A panel and its load per epoch, for the power statistics ([`crate::illum::power`]): each
/// sample's power and load hold for its step, as in `series`.
#[derive(Debug, Clone)]
pub struct PowerInputs {
    /// The panel's orientation (not `vertical-fixed`: the kernel does not follow the Sun's
    /// azimuth at every epoch).
    pub panel: crate::illum::power::Panel,
    /// Per epoch: area × efficiency × (1 − degradation), m².
    pub effective_area_m2: Vec<f64>,
    /// Per epoch: the load by day and by night, W.
    pub loads: Vec<crate::illum::power::Loads>,
    /// Hours per sample.
    pub step_h: f64,
    /// The panel and load, in words (for the files).
    pub described: String,
}

impl<'a> StatisticsEngine<'a> {
    /// An engine for `stack` (the horizons must be on its finest layer's grid).
    pub fn new(stack: &'a TerrainStack, params: StatisticsParams) -> Result<Self, HorizonError> {
        stack.layers.first().ok_or(HorizonError::NoLayers)?;
        let layers_reach_m = stack
            .layers
            .iter()
            .flat_map(|layer| {
                let (x0, y0, x1, y1) = layer.grid.bounds_m();
                [(x0, y0), (x0, y1), (x1, y0), (x1, y1)]
            })
            .map(|(x, y)| x.hypot(y))
            .fold(0.0, f64::max);
        Ok(StatisticsEngine {
            stack,
            params,
            skip_unseen: true,
            sector_tables: true,
            block_decisions: true,
            layers_reach_m,
            link: None,
            power: None,
        })
    }

    /// Adds the direct-to-Earth statistics: `station_sees_dem[k]` tells whether a ground station
    /// sees the DEM above its mask at epoch `k` (one flag per epoch for the whole grid, from the
    /// grid centre: the parallax across a polar DEM moves a station's elevation by < 0.03°).
    /// DTE at a pixel and epoch: any part of the Earth visible and the flag. The CPU only.
    pub fn with_link(mut self, station_sees_dem: Vec<bool>, stations: String) -> Self {
        self.link = Some((station_sees_dem, stations));
        self
    }

    /// Adds the power statistics of a panel and its load: the mean power and the smallest
    /// battery that survives every epoch, per pixel. The CPU only.
    pub fn with_power(mut self, power: PowerInputs) -> Self {
        self.power = Some(power);
        self
    }

    fn fine(&self) -> &'a Dem {
        &self.stack.layers[0]
    }

    /// Checks that `source` holds horizons of this stack's finest layer.
    pub fn check_source(&self, source: &dyn HorizonRows) -> Result<(), HorizonError> {
        let (a, b) = (source.grid(), self.fine().grid);
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * (1.0 + x.abs().max(y.abs()));
        if a.rows != b.rows
            || a.cols != b.cols
            || !close(a.x_left_m, b.x_left_m)
            || !close(a.y_top_m, b.y_top_m)
            || !close(a.px_x_m, b.px_x_m)
            || !close(a.px_y_m, b.px_y_m)
        {
            return Err(HorizonError::HorizonsMismatch {
                reason: format!(
                    "their grid ({} x {} px of {} m from ({}, {}) m) is not the finest \
                     layer's ({} x {} px of {} m from ({}, {}) m)",
                    a.rows,
                    a.cols,
                    a.px_x_m,
                    a.x_left_m,
                    a.y_top_m,
                    b.rows,
                    b.cols,
                    b.px_x_m,
                    b.x_left_m,
                    b.y_top_m
                ),
            });
        }
        if AzimuthLookup::new(source.grid_az_deg()).is_none() {
            return Err(HorizonError::HorizonsMismatch {
                reason: "their band azimuths are not strictly increasing in [0, 360)".into(),
            });
        }
        Ok(())
    }

    /// The statistics of every pixel over `epochs` (in time order). `progress` gets the rows
    /// done after each block of rows; when it returns `false` the run stops with
    /// [`HorizonError::Interrupted`].
    pub fn run(
        &self,
        source: &mut dyn HorizonRows,
        epochs: &[EpochBodies],
        progress: impl FnMut(usize) -> bool,
    ) -> Result<HorizonStatistics, HorizonError> {
        self.run_with_store(source, epochs, &mut NoStore, progress)
    }

    /// [`Self::run`], taking finished blocks of rows from `store` and giving it every block it
    /// computes (a resumed run gives the same bytes as an uninterrupted one: each pixel's
    /// statistics depend on its own horizon and the epochs only).
    fn run_with_store(
        &self,
        source: &mut dyn HorizonRows,
        epochs: &[EpochBodies],
        store: &mut dyn BlockStore,
        progress: impl FnMut(usize) -> bool,
    ) -> Result<HorizonStatistics, HorizonError> {
        let rows = 0..self.fine().grid.rows;
        self.run_rows_on(source, epochs, store, rows, None, progress)
    }

    /// [`Self::run`] for the finest layer's `rows` only (a shard of a map), taking finished
    /// blocks of rows from `store` and giving it every block it computes (a resumed run gives
    /// the same bytes as an uninterrupted one: each pixel's statistics depend on its own horizon
    /// and the epochs only), with the per-cell epoch loop on `kernel` (the GPU, or its CPU twin;
    /// `statistics/offload.rs` says what differs from the CPU engine), or on the CPU when `None`.
    /// The statistics returned hold those rows' pixels (pixel `i` is the grid's pixel
    /// `rows.start * cols + i`), bit for bit the values of a whole run, and `progress` gets the
    /// rows done from `rows.start`. `source` needs to hold those rows only. The geometry of the
    /// cells, the blocks, the store and the below-sphere tally are the CPU engine's.
    pub fn run_rows_on(
        &self,
        source: &mut dyn HorizonRows,
        epochs: &[EpochBodies],
        store: &mut dyn BlockStore,
        rows: std::ops::Range<usize>,
        mut kernel: Option<&mut dyn CellKernel>,
        mut progress: impl FnMut(usize) -> bool,
    ) -> Result<HorizonStatistics, HorizonError> {
        self.check_source(source)?;
        let fine = self.fine();
        let g = fine.grid;
        if rows.start >= rows.end || rows.end > g.rows {
            return Err(HorizonError::SweepUnsupported {
                reason: format!(
                    "statistics of rows {}..{} (the finest layer has {} rows)",
                    rows.start, rows.end, g.rows
                ),
            });
        }
        let base_px = rows.start * g.cols;
        let n_px = rows.len() * g.cols;
        let lookup = AzimuthLookup::new(source.grid_az_deg()).expect("checked");
        let n = lookup.n_bands();
        let h_obs_m = source.observer_height_m();
        let chord_sun = ChordTable::new(&self.params.limb);
        let chord_earth = ChordTable::new(&LimbDarkening::UNIFORM);
        let th = Thresholds {
            visible_min: self.params.visible_min_fraction as f32,
            full_min: self.params.full_min_fraction as f32,
        };
        let mut soa = Epochs::default();
        for e in epochs {
            let scale = AU_KM / e.sun_range_km;
            for i in 0..3 {
                soa.sun[i].push(e.sun_in_moon_me_km[i] as f32);
                soa.earth[i].push(e.earth_in_moon_me_km[i] as f32);
            }
            soa.sun_radius_deg.push(e.sun_radius_deg as f32);
            soa.sun_normal_w_m2
                .push((SOLAR_CONSTANT_W_M2 * scale * scale) as f32);
            soa.earth_radius_deg.push(e.earth_radius_deg as f32);
        }
        if let Some((link, _)) = &self.link {
            if link.len() != epochs.len() {
                return Err(HorizonError::SweepUnsupported {
                    reason: format!("{} station flags for {} epochs", link.len(), epochs.len()),
                });
            }
            if kernel.is_some() {
                return Err(HorizonError::SweepUnsupported {
                    reason: "direct-to-Earth statistics on the GPU kernel".into(),
                });
            }
            soa.link_bits = link
                .chunks(sectors::BLOCK)
                .map(|c| {
                    c.iter()
                        .enumerate()
                        .fold(0u32, |m, (j, &f)| m | (u32::from(f) << j))
                })
                .collect();
        }
        if let Some(p) = &self.power {
            use crate::illum::power::Panel;
            let panel = match p.panel {
                Panel::VerticalTracking => 0,
                Panel::Horizontal => 1,
                Panel::TwoAxis => 2,
                Panel::VerticalFixed { .. } => {
                    return Err(HorizonError::SweepUnsupported {
                        reason: "power maps of a fixed panel (vertical-fixed:AZ needs the Sun's \
                                 azimuth at every epoch): use vertical-tracking, horizontal or \
                                 two-axis, or a series at the site"
                            .into(),
                    });
                }
            };
            if p.effective_area_m2.len() != epochs.len() || p.loads.len() != epochs.len() {
                return Err(HorizonError::SweepUnsupported {
                    reason: format!(
                        "power inputs of {} epochs for {}",
                        p.loads.len(),
                        epochs.len()
                    ),
                });
            }
            if kernel.is_some() {
                return Err(HorizonError::SweepUnsupported {
                    reason: "power statistics on the GPU kernel".into(),
                });
            }
            soa.power = Some(kernel::PowerSoa {
                panel,
                scale: p.effective_area_m2.iter().map(|&a| a as f32).collect(),
                day_wh: p
                    .loads
                    .iter()
                    .map(|l| (l.day_w * p.step_h) as f32)
                    .collect(),
                night_wh: p
                    .loads
                    .iter()
                    .map(|l| (l.night_w * p.step_h) as f32)
                    .collect(),
                step_h: p.step_h as f32,
            });
        }
        // The bodies' paths over every epoch, from the grid centre.
        let (reference, reach_m) = {
            let projector = UnitProjector::new(&fine.projection);
            let (cx, cy) =
                g.xy_from_row_col((g.rows as f64 - 1.0) / 2.0, (g.cols as f64 - 1.0) / 2.0);
            let (x0, y0, x1, y1) = g.bounds_m();
            (
                map_frame(&projector, cx, cy),
                (x1 - x0).hypot(y1 - y0) / 2.0,
            )
        };
        let centre_up = reference.up;
        soa.sun_sectors = sectors::BodySectors::new(
            epochs,
            |e| (e.sun_in_moon_me_km, e.sun_radius_deg),
            &reference,
        );
        soa.earth_sectors = sectors::BodySectors::new(
            epochs,
            |e| (e.earth_in_moon_me_km, e.earth_radius_deg),
            &reference,
        );
        if !self.block_decisions {
            soa.sun_sectors.blocks.clear();
            soa.earth_sectors.blocks.clear();
        }
        let sector_edges = sectors::edges();
        // The Earth's statistics need only "any part visible".
        let earth_visible_only =
            self.params.visible_min_fraction < sectors::VISIBLE_ONLY_MAX_FRACTION;
        // The per-cell bounds serve a body without tables.
        let need_bounds =
            !self.sector_tables || !soa.sun_sectors.enabled || !soa.earth_sectors.enabled;
        let centre_km = centre_up * (MOON_RADIUS_M / 1000.0);
        let body_bounds = [
            BodyBounds::new(
                epochs
                    .iter()
                    .map(|e| (e.sun_in_moon_me_km, e.sun_radius_deg)),
                centre_km,
                centre_up,
                reach_m,
            ),
            BodyBounds::new(
                epochs
                    .iter()
                    .map(|e| (e.earth_in_moon_me_km, e.earth_radius_deg)),
                centre_km,
                centre_up,
                reach_m,
            ),
        ];
        let edges = Edges {
            extents: self
                .stack
                .layers
                .iter()
                .map(|l| l.grid.bounds_m())
                .collect(),
            projector: UnitProjector::new(&fine.projection),
        };

        if let Some(k) = kernel.as_deref_mut() {
            let kernel_epochs = (0..soa.len())
                .map(|j| KernelEpoch {
                    sun_km: [soa.sun[0][j], soa.sun[1][j], soa.sun[2][j]],
                    sun_radius_deg: soa.sun_radius_deg[j],
                    earth_km: [soa.earth[0][j], soa.earth[1][j], soa.earth[2][j]],
                    earth_radius_deg: soa.earth_radius_deg[j],
                    sun_normal_w_m2: soa.sun_normal_w_m2[j],
                    pad: [0.0; 3],
                })
                .collect();
            k.begin(std::sync::Arc::new(KernelShared::new(
                kernel_epochs,
                &lookup,
                (&chord_sun, &chord_earth),
                (th.visible_min, th.full_min),
            )))?;
        }

        let mut out = HorizonStatistics::empty(n_px, epochs.len());
        out.link = self.link.as_ref().map(|l| l.1.clone());
        out.power = self.power.as_ref().map(|p| p.described.clone());
        let arch = pulp::Arch::new();
        // At least MIN_BLOCKS blocks: the units a killed run keeps.
        let rows_per_block = (BLOCK_BYTES / (2 * n * g.cols).max(1))
            .min(rows.len().div_ceil(MIN_BLOCKS))
            .clamp(1, rows.len());
        let mut block: Vec<i16> = Vec::new();
        let mut row0 = rows.start;
        while row0 < rows.end {
            let row1 = (row0 + rows_per_block).min(rows.end);
            let block_px = (row1 - row0) * g.cols;
            let first_px = row0 * g.cols;
            if let Some(bytes) = store.load(row0..row1)
                && out.place_block_bytes(first_px - base_px, block_px, &bytes)
            {
                if !progress(row1 - rows.start) {
                    return Err(HorizonError::Interrupted);
                }
                row0 = row1;
                continue;
            }
            source.read_rows(row0..row1, &mut block)?;
            // The CPU engine on pixels `indices` of the block.
            let on_cpu = |indices: &[usize]| {
                let mut pixels = Vec::with_capacity(indices.len());
                let mut cells = Vec::with_capacity(indices.len());
                let mut horizons = Vec::with_capacity(indices.len() * (n + 1));
                let mut bounds = Vec::with_capacity(indices.len() * 2 * BOUND_SECTORS);
                let mut tables = Vec::new();
                let mut block_bounds = Vec::new();
                let mut tscratch = sectors::TableScratch::default();
                for &i in indices {
                    let px = first_px + i;
                    let start = horizons.len();
                    if let Some(cell) = self.cell(
                        px,
                        h_obs_m,
                        (&block, block_px, i, n),
                        &mut horizons,
                        (&body_bounds, &reference, &lookup),
                    ) {
                        if need_bounds {
                            for margin in [kernel::SUN_MARGIN_DEG, kernel::EARTH_MARGIN_DEG] {
                                kernel::sector_bounds(
                                    &horizons[start..],
                                    lookup.band_az_deg(),
                                    margin,
                                    &mut bounds,
                                );
                            }
                        }
                        if self.sector_tables {
                            arch.dispatch(sectors::CellTables {
                                bodies: [
                                    (&soa.sun_sectors, false, cell.sun == kernel::Reach::Varies),
                                    (
                                        &soa.earth_sectors,
                                        earth_visible_only,
                                        cell.earth == kernel::Reach::Varies,
                                    ),
                                ],
                                reference: &reference,
                                edges: &sector_edges,
                                frame: &cell.frame,
                                r_obs_km: f64::from(cell.r_obs_km),
                                h: &horizons[start..],
                                lookup: &lookup,
                                scratch: &mut tscratch,
                                out: &mut tables,
                                block_out: &mut block_bounds,
                            });
                        }
                        pixels.push(px);
                        cells.push(cell);
                    }
                }
                let mut acc = vec![CellAcc::default(); cells.len()];
                let mut scratch = Scratch::default();
                let mut j0 = 0;
                while j0 < soa.len() {
                    let j1 = (j0 + kernel::CHUNK).min(soa.len());
                    // The kernel compiled for the best SIMD level of this CPU (AVX2 + FMA
                    // where present) by autovectorisation, chosen at run time.
                    arch.dispatch(kernel::RunCells {
                        cells: &cells,
                        horizons: &horizons,
                        bounds: &bounds,
                        tables: &tables,
                        block_bounds: &block_bounds,
                        stride: n + 1,
                        epochs: &soa,
                        range: j0..j1,
                        lookup: &lookup,
                        chord_sun: &chord_sun,
                        chord_earth: &chord_earth,
                        th,
                        edges: &edges,
                        scratch: &mut scratch,
                        acc: &mut acc,
                    });
                    j0 = j1;
                }
                pixels.into_iter().zip(acc)
            };
            let results: Vec<(usize, CellAcc)> = match kernel.as_deref_mut() {
                None => (0..block_px.div_ceil(CELLS_PER_TASK))
                    .into_par_iter()
                    .flat_map_iter(|task| {
                        let lo = task * CELLS_PER_TASK;
                        let hi = (lo + CELLS_PER_TASK).min(block_px);
                        on_cpu(&(lo..hi).collect::<Vec<_>>())
                    })
                    .collect(),
                Some(k) => self.block_on_kernel(
                    k,
                    (first_px, h_obs_m),
                    (&block, block_px, n),
                    &reference,
                    &on_cpu,
                )?,
            };
            let mut below = (0u64, 0u64);
            for (px, a) in results {
                let px = px - base_px;
                out.nodata[px] = false;
                out.sun_fraction_sum[px] = a.sun_fraction_sum;
                out.sun_visible_count[px] = a.sun_visible;
                out.sun_full_count[px] = a.sun_full;
                out.longest_dark_epochs[px] = a.dark_max;
                out.earth_visible_count[px] = a.earth_visible;
                out.longest_earth_hidden_epochs[px] = a.earth_hidden_max;
                out.sun_and_earth_count[px] = a.sun_and_earth;
                out.dte_count[px] = a.dte;
                out.longest_dte_blackout_epochs[px] = a.dte_off_max;
                out.irradiance_horizontal_sum_w_m2[px] = a.irradiance_horizontal_sum;
                out.irradiance_tracking_sum_w_m2[px] = a.irradiance_tracking_sum;
                out.power_sum_w[px] = a.power_sum_w;
                out.required_battery_wh[px] = a.max_deficit_wh;
                if a.below_sphere > 0 {
                    below.0 += 1;
                    below.1 += u64::from(a.below_sphere);
                }
            }
            out.below_sphere.cells += below.0;
            out.below_sphere.cell_epochs += below.1;
            store
                .store(
                    row0..row1,
                    &out.block_bytes(first_px - base_px, block_px, below),
                )
                .map_err(HorizonError::Checkpoint)?;
            if !progress(row1 - rows.start) {
                return Err(HorizonError::Interrupted);
            }
            row0 = row1;
        }
        out.below_sphere.cells_total = out.nodata.iter().filter(|&&nd| !nd).count() as u64;
        Ok(out)
    }

    /// One block of pixels with the epoch loop on `kernel`: the cells' geometry here (in
    /// parallel), the loop there, and the cells with below-sphere candidates once more through
    /// `on_cpu` for the exact tally.
    fn block_on_kernel<I: Iterator<Item = (usize, CellAcc)>>(
        &self,
        kernel: &mut dyn CellKernel,
        (first_px, h_obs_m): (usize, f64),
        (block, block_px, n): (&[i16], usize, usize),
        reference: &MapFrame,
        on_cpu: &(dyn Fn(&[usize]) -> I + Sync),
    ) -> Result<Vec<(usize, CellAcc)>, HorizonError> {
        const TASK: usize = 256;
        let parts: Vec<(Vec<usize>, Vec<KernelCell>, Vec<f32>)> = (0..block_px.div_ceil(TASK))
            .into_par_iter()
            .map(|task| {
                let (lo, hi) = (task * TASK, ((task + 1) * TASK).min(block_px));
                let mut part = (Vec::new(), Vec::new(), Vec::new());
                for i in lo..hi {
                    let start = part.2.len();
                    let Some(c) = self.cell_frame(
                        first_px + i,
                        h_obs_m,
                        (block, block_px, i, n),
                        &mut part.2,
                        reference,
                    ) else {
                        continue;
                    };
                    let h = &part.2[start..];
                    part.0.push(i);
                    part.1.push(KernelCell {
                        up: c.up,
                        r_obs_km: c.r_obs_km,
                        grid_east: c.grid_east,
                        h_min_deg: h.iter().copied().fold(f32::INFINITY, f32::min),
                        grid_north: c.grid_north,
                        h_max_deg: h.iter().copied().fold(f32::NEG_INFINITY, f32::max),
                        sin_dip_bound: c.beyond.sin_dip_bound(),
                        pad: [0.0; 3],
                    });
                }
                part
            })
            .collect();
        let (mut index, mut cells, mut horizons) = (Vec::new(), Vec::new(), Vec::new());
        for (i, c, h) in parts {
            index.extend(i);
            cells.extend(c);
            horizons.extend(h);
        }
        let accs = kernel.run(&cells, &horizons)?;
        if accs.len() != cells.len() {
            return Err(HorizonError::Kernel(format!(
                "{} returned {} cells of {}",
                kernel.name(),
                accs.len(),
                cells.len()
            )));
        }
        let candidates: Vec<usize> = index
            .iter()
            .zip(&accs)
            .filter(|(_, a)| a.low_lit > 0)
            .map(|(&i, _)| i)
            .collect();
        // In the order of `candidates` (ascending, as `index`): matched by a merge walk.
        let exact: Vec<(usize, u32)> = candidates
            .par_chunks(CELLS_PER_TASK)
            .flat_map_iter(|c| on_cpu(c).map(|(px, a)| (px, a.below_sphere)))
            .collect();
        let mut exact = exact.into_iter().peekable();
        Ok(index
            .into_iter()
            .zip(accs)
            .map(|(i, a)| {
                let px = first_px + i;
                let below_sphere = exact.next_if(|e| e.0 == px).map_or(0, |e| e.1);
                let acc = CellAcc {
                    sun_fraction_sum: f64::from(a.sun_fraction_sum),
                    irradiance_horizontal_sum: f64::from(a.irradiance_horizontal_sum),
                    irradiance_tracking_sum: f64::from(a.irradiance_tracking_sum),
                    sun_visible: a.sun_visible,
                    sun_full: a.sun_full,
                    earth_visible: a.earth_visible,
                    sun_and_earth: a.sun_and_earth,
                    dark_run: a.dark_run,
                    dark_max: a.dark_max,
                    earth_hidden_run: a.earth_hidden_run,
                    earth_hidden_max: a.earth_hidden_max,
                    // The GPU kernel has no link (`run_rows_on` refuses the pair).
                    dte: 0,
                    dte_off_run: 0,
                    dte_off_max: 0,
                    below_sphere,
                    // Nor power statistics.
                    ..CellAcc::default()
                };
                (px, acc)
            })
            .collect())
    }

    /// The geometry of pixel `px` (index `i` of a block of `block_px` pixels of `n` bands),
    /// appending its `n + 1` horizon values (deg) to `horizons`; `None` for a pixel without
    /// data. `bodies` (bounds of the Sun's and the Earth's paths, the grid centre's radial, the
    /// band azimuths) tell whether the cell sees each body at all.
    fn cell(
        &self,
        px: usize,
        h_obs_m: f64,
        block: (&[i16], usize, usize, usize),
        horizons: &mut Vec<f32>,
        (bodies, reference, lookup): (&[BodyBounds; 2], &MapFrame, &AzimuthLookup),
    ) -> Option<CellGeom> {
        let start = horizons.len();
        let mut cell = self.cell_frame(px, h_obs_m, block, horizons, reference)?;
        if self.skip_unseen {
            let h = &horizons[start..];
            let MapFrame { up, east, north } = cell.frame;
            let tilt_deg = up
                .cross(&reference.up)
                .norm()
                .atan2(up.dot(&reference.up))
                .to_degrees();
            let reach = |b: &BodyBounds| {
                let az = b
                    .mean_dir
                    .dot(&east)
                    .atan2(b.mean_dir.dot(&north))
                    .to_degrees();
                let el = b.mean_dir.dot(&up).clamp(-1.0, 1.0).asin().to_degrees();
                b.reach(h, lookup, tilt_deg, (az.rem_euclid(360.0), el))
            };
            cell.sun = reach(&bodies[0]);
            cell.earth = reach(&bodies[1]);
        }
        Some(cell)
    }

    /// A lower bound of the angle at the Moon's centre between map point `(x, y)` and where
    /// any ray from it leaves the outermost layer holding it (the farthest exit, as
    /// [`BeyondDem::meets_sphere`] takes it): at least the map distance to the nearest edge of
    /// any layer holding the point, the exit within the layers' farthest corner from the map
    /// origin. `None` outside every layer or for a projection without the bound.
    fn min_exit_angle_rad(&self, x: f64, y: f64, projector: &UnitProjector) -> Option<f64> {
        let mut dist_m = f64::NEG_INFINITY;
        for layer in &self.stack.layers {
            let (x0, y0, x1, y1) = layer.grid.bounds_m();
            if x >= x0 && x <= x1 && y >= y0 && y <= y1 {
                dist_m = dist_m.max((x - x0).min(x1 - x).min(y - y0).min(y1 - y));
            }
        }
        if !dist_m.is_finite() {
            return None;
        }
        projector.min_angle_rad((x, y), dist_m, self.layers_reach_m)
    }

    /// [`Self::cell`] without the bounds: both bodies [`kernel::Reach::Varies`] (what a
    /// [`CellKernel`] needs, which reads no bounds).
    fn cell_frame(
        &self,
        px: usize,
        h_obs_m: f64,
        (block, block_px, i, n): (&[i16], usize, usize, usize),
        horizons: &mut Vec<f32>,
        reference: &MapFrame,
    ) -> Option<CellGeom> {
        let fine = self.fine();
        let ground_m = f64::from(fine.heights_m[px]);
        if ground_m.is_nan() {
            return None;
        }
        let values = (0..n).map(|b| block[b * block_px + i]);
        if values.clone().any(|v| v == HORIZON_NODATA_I16) {
            return None;
        }
        let start = horizons.len();
        horizons.extend(values.map(|v| f32::from(v) * 0.01));
        horizons.push(horizons[start]);

        let g = fine.grid;
        let (row, col) = ((px / g.cols) as f64, (px % g.cols) as f64);
        let (x, y) = g.xy_from_row_col(row, col);
        let projector = UnitProjector::new(&fine.projection);
        let frame = map_frame(&projector, x, y);
        let MapFrame { up, east, north } = frame;
        let r0_m = MOON_RADIUS_M + ground_m + h_obs_m;
        let v32 = |v: nalgebra::Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
        Some(CellGeom {
            up: v32(up),
            up_ref: up.dot(&reference.up) as f32,
            frame,
            grid_east: v32(east),
            grid_north: v32(north),
            r_obs_km: (r0_m / 1000.0) as f32,
            sun: kernel::Reach::Varies,
            earth: kernel::Reach::Varies,
            beyond: self.beyond_dem((x, y), up, r0_m, &projector),
        })
    }

    /// Where the rays of an observer at map point `(x, y)` (radial `up`, `r0_m` from the
    /// Moon's centre) leave the layers, and the highest elevation at which one may meet the
    /// sphere beyond them.
    fn beyond_dem(
        &self,
        (x, y): (f64, f64),
        up: nalgebra::Vector3<f64>,
        r0_m: f64,
        projector: &UnitProjector,
    ) -> BeyondDem {
        let r = MOON_RADIUS_M;
        // The observer's geometric horizon on the sphere (0 inside it: then every descending
        // ray meets it, unless it leaves the layers past its lowest point and rises above the
        // sphere first).
        let dip_rad = if r0_m > r { (r / r0_m).acos() } else { 0.0 };
        // Rays leave the outermost layer at least `p` (at the Moon's centre) away. A ray at
        // elevation e < 0 is at `r0 cos e / cos(e + φ)` from the centre at angle φ, rising
        // once e + φ > 0: it meets the sphere beyond an exit at φ ≥ p only if `R cos(e + p) >
        // r0 cos e`, i.e. below `e* = atan((R cos p − r0) / (R sin p))` — when `R cos p < r0`
        // (no ray just below the horizontal meets it) and `R > r0 cos p` (e* > −p: the exit
        // is past the lowest point of every ray above e*), i.e. when
        // `p > acos(min(R, r0) / max(R, r0))`. Higher rays need no test.
        let cut_rad = self.min_exit_angle_rad(x, y, projector).and_then(|p| {
            (p > (r.min(r0_m) / r.max(r0_m)).acos())
                .then(|| ((r * p.cos() - r0_m) / (r * p.sin())).atan())
        });
        // The cut with 1e-6° of room for its f32 rounding; the horizon as before (rays within
        // f32 rounding of tangent to the sphere stay uncounted, as the per-epoch maps do).
        let dip_deg = match cut_rad {
            Some(c) if c < -dip_rad => (c.to_degrees() + 1e-6).min(-dip_rad.to_degrees()),
            _ => -dip_rad.to_degrees(),
        } as f32;
        BeyondDem {
            x_m: x,
            y_m: y,
            up: [up.x, up.y, up.z],
            r0_m,
            dip_deg,
            sin_dip_bound: (f64::from(dip_deg).to_radians().sin() + 1e-5) as f32,
        }
    }
}

#[cfg(test)]
mod tests;

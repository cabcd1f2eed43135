//! The map pipeline's engine for per-site series (`penumbra series --engine smap-dp`): each
//! site's visible fractions come from the model-space height field of the map pipeline
//! ([`crate::model::MapGrid`]) and the DP maximum-mipmap search ([`crate::shadow::dp`]) instead of a
//! per-site horizon ([`crate::horizon`]).
//!
//! **Set-up, once per run.** The [`MapGrid`] (the finest DEM layer resampled into model space, with
//! the coarser layers filling its margin) and its [`MaxMipmap`] are built once for all sites.
//!
//! **The site's point.** No cell snapping: the site's ground point (`lat/lon` at the bilinear DEM
//! height of the finest layer with data, as in [`crate::horizon`]) is mapped into model space; the
//! observer stands `height_above_ground` along the radial direction above the **model grid's own
//! surface** there (the bilinear interpolation of the 4 neighbouring model cells), at a fractional
//! `(row, col)`. Standing on the model surface rather than at the DEM height matters on peaks:
//! the resampling into model space lowers a 240 m ridge top by metres, and an observer left at the
//! DEM height would float above its own near field (at the Connecting Ridge that moved the horizon
//! by up to 1.4° and the mean Sun fraction by 0.044; on the model surface, 0.013). The DP's exact
//! costs are taken where the ray crosses the lines through cell centres (the bilinear surface,
//! [`crate::shadow`] conventions). As in the horizon engine, terrain closer than half a cell is the
//! observer's own ground: the first sample is the bilinear surface at exactly half a cell, then
//! the crossings beyond.
//!
//! **Light directions.** Per site and epoch, exactly as the horizon engine: the topocentric
//! (light-time and aberration corrected) vector from the site to the Sun or the Earth
//! ([`crate::ephem::topo`]), rotated into model space. So there is no parallax error; taking the
//! map-centre direction instead ([`crate::model::epoch_lights`]) would cost, at a site `d` from the
//! centre, `d / 1 au` for the Sun (1.2e-6 rad at 184 km, nothing) and `d / 384,400 km` for the
//! Earth (4.8e-4 rad = 0.027° at 184 km, 3% of its radius).
//!
//! **Visible fraction.** Per light: one DP search of the minimum shadow cost `J*` along the centre
//! ray, capped at the cost above which the disc is fully visible (so a clear sky stops at the
//! first mipmap bounds), and the prism assumption of papers 000/003 §3.4: the horizon is a
//! straight horizontal edge at `e_h = atan(tan e_c − J*)` across the disc,
//! and the fraction is the chord fraction [`chord_visible_fraction`] with the series' limb
//! darkening (uniform for the Earth).
//!
//! *No SMap pre-test.* In a map, [`crate::shadow::dp::soft_combined`] first classifies whole
//! cells with two SMaps (the disc's limbs) and runs DP only in the penumbra: an SMap is built per
//! light over the whole grid (0.37 s for 1536², docs/PERFORMANCE.md) and then answers every cell.
//! At a handful of points the build never pays: the capped DP search answers the lit and the
//! deep-shadow cases in microseconds (see the `series_engines` bench), so the per-site engine
//! runs DP alone, and the SMap's role (decide early away from the limb) is played by the cap and
//! the branch-and-bound pruning.
//!
//! *No local-horizontal floor* (the one blocking rule of every engine, [`crate::shadow`]). A site
//! on a slope or a rim sees below that plane (the horizon engine reports horizons of −13° on the
//! synthetic ridge), so here, as in the horizon engine and the map engines, the horizon is the
//! highest terrain sample of the grid along the ray,
//! whatever its sign; on a flat sphere that is the dip of the geometric horizon.
//!
//! **Horizon profile** (for `horizon.csv`, the plots and the CSV's horizon columns): per azimuth
//! of the site's local frame, the DP search of the horizontal direction without a cap gives the
//! terrain elevation along that model-space azimuth, converted back to the site's frame. The
//! distance column is `NaN` (the search does not keep the argmin).
//!
//! **What differs from the horizon engine** (measured in docs/VALIDATION.md): the grid is the
//! model-space resampling of the DEM (not the DEM's own bilinear surface along great circles),
//! only the finest layer's extent (plus a 2-cell margin) casts shadows (the horizon engine reads
//! every layer, so far-field terrain can differ), and the disc is cut by a straight edge at the
//! centre azimuth's horizon instead of the strip integral over the sampled profile.

use anyhow::Context as _;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::config::{SeriesConfig, SeriesSite};
use crate::ephem::topo::{self, MoonGeometry};
use crate::ephem::{AbCorr, Site};
use crate::gpu::GpuContext;
use crate::horizon::Horizon;
use crate::illum::LimbDarkening;
use crate::illum::disc::chord_visible_fraction;
use crate::model::MapGrid;
use crate::shadow::dp::{DpConfig, DpScene, MaxMipmap, dp_cost_beyond, full_visibility_cap};
use crate::shadow::{LightDir, Observer, max_height_m};
use crate::terrain::TerrainStack;
use crate::terrain::model_space::ModelFrame;
use crate::twins::{self, MarchGrid};

/// Terrain nearer than this (cells of the model grid) is the observer's own ground (as
/// [`crate::horizon`]'s `min_distance_m`, half a cell).
pub const MIN_DISTANCE_CELLS: f64 = crate::shadow::OWN_HALF_PIXEL_CELLS;

/// Errors of the smap-dp series engine.
#[derive(Debug, thiserror::Error)]
pub enum SeriesDpError {
    /// The site is outside every DEM layer or in a nodata hole.
    #[error("site '{site}' ({lat_deg} deg, {lon_deg} deg) has no DEM height")]
    NoGround {
        /// Site name.
        site: String,
        /// Latitude, degrees.
        lat_deg: f64,
        /// Longitude, degrees.
        lon_deg: f64,
    },
    /// The site lies outside the model grid of the map pipeline (or on a hole of it).
    #[error(
        "site '{site}' lies outside the map grid of the finest DEM layer (the smap-dp engine sees only that layer's extent; use --engine horizon)"
    )]
    OffGrid {
        /// Site name.
        site: String,
    },
    /// The azimuth step does not divide 360 into a whole number of steps.
    #[error("azimuth step {0} deg must be > 0 and divide 360 into a whole number of steps")]
    BadAzStep(f64),
}

/// One disc of the GPU table: the f32 light of the kernel and its f64 centre elevation and
/// radius (rad).
type GpuDisc = ([f32; 4], (f64, f64));

/// The map grid, its maximum mipmap and the sites' observers, built once for a series run.
pub struct SmapDpSites {
    grid: MapGrid,
    mip: MaxMipmap,
    z_max_m: f64,
    model_from_moon_me: Matrix3<f64>,
    observers: Vec<Observer>,
    ground_height_m: Vec<f64>,
    cfg: DpConfig,
}

impl SmapDpSites {
    /// Builds the model grid of `stack` (as `penumbra map` does), its maximum mipmap, and the
    /// observer of each site (see the module docs).
    pub fn new(stack: &TerrainStack, sites: &[SeriesSite]) -> anyhow::Result<Self> {
        let grid = MapGrid::new(stack)?;
        Self::from_grid(grid, stack, sites)
    }

    /// As [`SmapDpSites::new`] with an already built grid.
    pub fn from_grid(
        grid: MapGrid,
        stack: &TerrainStack,
        sites: &[SeriesSite],
    ) -> anyhow::Result<Self> {
        let hf = &grid.hf;
        let frame = ModelFrame::of(hf);
        let mut observers = Vec::with_capacity(sites.len());
        let mut ground_height_m = Vec::with_capacity(sites.len());
        for s in sites {
            let (ground_m, _) =
                stack
                    .height_at_lat_lon_m(s.lat_deg, s.lon_deg)
                    .ok_or_else(|| SeriesDpError::NoGround {
                        site: s.name.clone(),
                        lat_deg: s.lat_deg,
                        lon_deg: s.lon_deg,
                    })?;
            // The ground point, then the model grid's own surface under it (bilinear), then the
            // observer `h` above it along the radial direction.
            let g = frame.model_from_lat_lon_height(s.lat_deg, s.lon_deg, ground_m);
            let (row_g, col_g) = hf.row_col_from_xy(g.x, g.y);
            let inside = row_g >= 0.0
                && col_g >= 0.0
                && row_g <= (hf.rows - 1) as f64
                && col_g <= (hf.cols - 1) as f64;
            let z_surface_m = inside
                .then(|| crate::shadow::brute::bilinear(hf, row_g, col_g))
                .flatten()
                .ok_or_else(|| SeriesDpError::OffGrid {
                    site: s.name.clone(),
                })?;
            let up = hf.up_at(g.x, g.y, z_surface_m);
            let p = Vector3::new(g.x, g.y, z_surface_m) + s.height_above_ground_m * up;
            let (row, col) = hf.row_col_from_xy(p.x, p.y);
            observers.push(Observer {
                row: row.clamp(0.0, (hf.rows - 1) as f64),
                col: col.clamp(0.0, (hf.cols - 1) as f64),
                z_m: p.z,
            });
            ground_height_m.push(ground_m);
        }
        let mip = MaxMipmap::new(hf);
        let z_max_m = max_height_m(hf);
        let model_from_moon_me = frame.model_from_moon_me;
        Ok(SmapDpSites {
            grid,
            mip,
            z_max_m,
            model_from_moon_me,
            observers,
            ground_height_m,
            cfg: DpConfig::default(),
        })
    }

    /// The model grid.
    pub fn grid(&self) -> &MapGrid {
        &self.grid
    }

    /// Number of sites.
    pub fn len(&self) -> usize {
        self.observers.len()
    }

    /// Whether there are no sites.
    pub fn is_empty(&self) -> bool {
        self.observers.is_empty()
    }

    /// Ground height (m above the sphere) under site `i`, from the DEM layers.
    pub fn ground_height_m(&self, i: usize) -> f64 {
        self.ground_height_m[i]
    }

    /// Model-space position (row, col, z_m) of site `i`'s observer.
    pub fn observer_row_col_z(&self, i: usize) -> (f64, f64, f64) {
        let o = &self.observers[i];
        (o.row, o.col, o.z_m)
    }

    fn cost(&self, i: usize, dir: &LightDir, cap: f64) -> f64 {
        let scene = DpScene {
            hf: &self.grid.hf,
            mip: &self.mip,
            z_max_m: self.z_max_m,
            cfg: &self.cfg,
        };
        dp_cost_beyond(&scene, &self.observers[i], dir, cap, MIN_DISTANCE_CELLS)
    }

    /// Visible (flux) fraction at site `i` of a disc of angular radius `radius_rad` whose centre
    /// is along `light_in_moon_me` (any length, `MOON_ME` axes), weighted by `limb`.
    pub fn fraction(
        &self,
        i: usize,
        light_in_moon_me: &Vector3<f64>,
        radius_rad: f64,
        limb: &LimbDarkening,
    ) -> f64 {
        let Some(dir) = self.light_dir(light_in_moon_me) else {
            return 0.0;
        };
        let j = self.cost(i, &dir, full_visibility_cap(&dir, radius_rad));
        // No terrain sample along the ray (a site at the grid's edge): nothing hides the disc.
        let e_h = if j.is_finite() {
            (dir.tan_el - j).atan()
        } else {
            f64::NEG_INFINITY
        };
        fraction_above_horizon(e_h, dir.elevation_rad(), radius_rad, limb)
    }

    /// The model-space direction of a light along `light_in_moon_me` (any length), `None` for a
    /// zero or non-finite vector.
    fn light_dir(&self, light_in_moon_me: &Vector3<f64>) -> Option<LightDir> {
        let v = self.model_from_moon_me * light_in_moon_me;
        let n = v.norm();
        (n > 0.0 && n.is_finite()).then(|| LightDir::new(v / n))
    }

    /// The sites' observers as the GPU kernel `shaders/dp_sites.wgsl` reads them
    /// ([`twins::site_observer_to_f32`] on `march`, the [`MarchGrid`] of [`Self::grid`]).
    pub fn site_observers_f32(&self, march: &MarchGrid) -> Vec<[f32; 4]> {
        self.observers
            .iter()
            .map(|o| twins::site_observer_to_f32(march, o.row, o.col, o.z_m, MIN_DISTANCE_CELLS))
            .collect()
    }

    /// The disc table of the GPU kernel for `sites` (the ephemeris sites, one per series site,
    /// in order) over the epochs `table` (in order): per site, per epoch, the Sun then the Earth,
    /// each the topocentric direction of [`crate::ephem::topo`] rotated into model space and
    /// rounded to f32 with its angular radius ([`twins::disc_light_to_f32`]); site-major.
    /// The second vector holds the f64 centre elevation and radius (rad) of every disc, for
    /// [`fraction_from_horizon_tan`]. Rayon over (site, epoch).
    pub fn disc_table(
        &self,
        table: &[MoonGeometry],
        sites: &[Site],
        abcorr: AbCorr,
    ) -> (Vec<[f32; 4]>, Vec<(f64, f64)>) {
        let per_epoch: Vec<[GpuDisc; 2]> = (0..sites.len() * table.len())
            .into_par_iter()
            .map(|n| {
                let (site, geo) = (&sites[n / table.len()], &table[n % table.len()]);
                let obs = topo::Observer::new(geo, site);
                [
                    (&geo.sun_wrt_moon, crate::SUN_RADIUS_KM),
                    (&geo.earth_wrt_moon, crate::EARTH_RADIUS_KM),
                ]
                .map(|(target, radius_km)| {
                    let pos = topo::target_from_observer(geo, target, &obs, abcorr);
                    let body = topo::apparent_without_azimuth(pos, site, radius_km);
                    let r = body.radius_deg.to_radians();
                    match self.light_dir(&body.pos_in_moon_me_km) {
                        Some(dir) => (
                            twins::disc_light_to_f32(&dir.unit, r),
                            (dir.elevation_rad(), r),
                        ),
                        // A degenerate vector (never for real ephemerides): reported as
                        // hidden, like the CPU engine's `fraction`.
                        None => ([0.0, 0.0, 1.0, r as f32], (f64::NAN, r)),
                    }
                })
            })
            .collect();
        per_epoch.into_iter().flatten().unzip()
    }

    /// The terrain horizon of site `i` seen by the DP search (see the module docs), at
    /// `az_step_deg` steps of the site's local azimuth; `site` is the ephemeris site (its ENU
    /// frame), `spec` the series site.
    pub fn horizon(
        &self,
        i: usize,
        spec: &SeriesSite,
        site: &Site,
        config: &SeriesConfig,
    ) -> anyhow::Result<Horizon> {
        self.horizon_with(i, spec, site, config, |dirs| {
            Ok(dirs
                .iter()
                .map(|dir| {
                    let j = self.cost(i, dir, f64::INFINITY);
                    (j.is_finite() && dir.hor > 0.0).then_some(dir.tan_el - j)
                })
                .collect())
        })
    }

    /// The model-space directions of the horizon profile of `site` (one per `az_step_deg` of
    /// the site's local azimuth, horizontal in the site's ENU frame).
    fn profile_dirs(&self, site: &Site, config: &SeriesConfig) -> anyhow::Result<Vec<LightDir>> {
        let step = config.az_step_deg;
        let n_f = 360.0 / step;
        if !(step.is_finite() && step >= 0.001 && (n_f - n_f.round()).abs() < 1e-6 * n_f) {
            return Err(SeriesDpError::BadAzStep(step).into());
        }
        let n = n_f.round() as usize;
        let model_from_enu = self.model_from_moon_me * site.enu_from_moon_me.transpose();
        Ok((0..n)
            .map(|k| {
                let az = k as f64 * step;
                let (s, c) = az.to_radians().sin_cos();
                let d = model_from_enu * Vector3::new(s, c, 0.0);
                LightDir::new(d.normalize())
            })
            .collect())
    }

    /// [`Self::horizon`] with `tan_horizon` giving, per profile direction, the tangent of the
    /// terrain horizon's elevation in model space (`None`: no terrain along it).
    fn horizon_with(
        &self,
        i: usize,
        spec: &SeriesSite,
        site: &Site,
        config: &SeriesConfig,
        tan_horizon: impl FnOnce(&[LightDir]) -> anyhow::Result<Vec<Option<f64>>>,
    ) -> anyhow::Result<Horizon> {
        let step = config.az_step_deg;
        let dirs = self.profile_dirs(site, config)?;
        let n = dirs.len();
        let tans = tan_horizon(&dirs)?;
        let enu_from_model = site.enu_from_moon_me * self.model_from_moon_me.transpose();
        let mut az_deg = Vec::with_capacity(n);
        let mut elevation_deg = Vec::with_capacity(n);
        for (k, (dir, tan_h)) in dirs.iter().zip(tans).enumerate() {
            let el = match tan_h {
                Some(tan_h) if dir.hor > 0.0 => {
                    let e_t = tan_h.atan();
                    let (ax, ay) = (dir.unit.x / dir.hor, dir.unit.y / dir.hor);
                    let v = Vector3::new(e_t.cos() * ax, e_t.cos() * ay, e_t.sin());
                    (enu_from_model * v).z.clamp(-1.0, 1.0).asin().to_degrees()
                }
                _ => -90.0,
            };
            az_deg.push(k as f64 * step);
            elevation_deg.push(el);
        }
        Ok(Horizon {
            lat_deg: spec.lat_deg,
            lon_deg: spec.lon_deg,
            ground_height_m: self.ground_height_m[i],
            observer_height_m: spec.height_above_ground_m,
            ground_layer: format!("smap-dp model grid of {}", self.grid.dem.name),
            min_distance_m: MIN_DISTANCE_CELLS * self.grid.hf.px_m,
            method: config.horizon_method,
            az_step_deg: step,
            az_deg,
            elevation_deg,
            distance_m: vec![f64::NAN; n],
        })
    }
}

/// Visible (flux) fraction, weighted by `limb`, of a disc of centre elevation `e_c_rad` and
/// angular radius `radius_rad` cut by a straight horizontal horizon at `e_h_rad` (the prism
/// assumption, module docs); radius 0: 1 above the horizon, else 0. A `NaN` centre is hidden.
pub fn fraction_above_horizon(
    e_h_rad: f64,
    e_c_rad: f64,
    radius_rad: f64,
    limb: &LimbDarkening,
) -> f64 {
    if e_c_rad.is_nan() {
        return 0.0;
    }
    if radius_rad <= 0.0 {
        return if e_c_rad > e_h_rad { 1.0 } else { 0.0 };
    }
    // Positive: the edge is above the centre (paper 001 eq. 6 apothem).
    chord_visible_fraction((e_h_rad - e_c_rad) / radius_rad, limb)
}

/// [`fraction_above_horizon`] for a horizon tangent from the GPU kernel `dp_sites` (or its twin
/// [`twins::dp_sites`]): [`twins::NO_HORIZON_TAN`] is "no terrain".
pub fn fraction_from_horizon_tan(
    tan_h: f32,
    e_c_rad: f64,
    radius_rad: f64,
    limb: &LimbDarkening,
) -> f64 {
    let e_h = if tan_h > 0.5 * twins::NO_HORIZON_TAN {
        f64::from(tan_h).atan()
    } else {
        f64::NEG_INFINITY
    };
    fraction_above_horizon(e_h, e_c_rad, radius_rad, limb)
}

/// Discs (Sun + Earth per epoch, per site) per GPU call of [`SmapDpGpu::fractions`]: 2²¹ discs
/// are a 32 MiB table and 8 MiB of output, so a long series runs in bounded memory on any GPU
/// (and under the 128 MiB default storage binding); 192 epochs × 100 sites are one call.
pub const GPU_DISCS_PER_CALL: usize = 1 << 21;

/// The GPU path of the smap-dp engine (`series --engine smap-dp --backend gpu|auto`): the model
/// grid and its maximum mipmap uploaded once, then the per-site DP search of
/// `shaders/dp_sites.wgsl` for the horizon profiles and for the Sun and Earth of every epoch
/// (one upload and one read-back per batch of [`GPU_DISCS_PER_CALL`] discs). The disc weighting
/// stays on the CPU in f64 ([`fraction_from_horizon_tan`]), so the CSV and statistics are
/// written by the same code as the CPU engine.
pub struct SmapDpGpu<'a> {
    ctx: &'a GpuContext,
    #[cfg(feature = "gpu")]
    grid: crate::gpu::dp::GpuDpGrid,
    #[cfg(feature = "gpu")]
    observers: Vec<[f32; 4]>,
    discs_per_call: usize,
}

impl<'a> SmapDpGpu<'a> {
    /// Uploads the model grid of `dp` and its maximum mipmap (f32, heights relative to the
    /// grid's mid height, [`MarchGrid`]).
    pub fn new(ctx: &'a GpuContext, dp: &SmapDpSites) -> anyhow::Result<Self> {
        let march = MarchGrid::from_height_field(&dp.grid.hf, 0.0)?;
        #[cfg(feature = "gpu")]
        {
            let observers = dp.site_observers_f32(&march);
            let mip = twins::DpMip::build(&march);
            let grid = crate::gpu::dp::GpuDpGrid::upload(ctx, &march, &mip)?;
            Ok(SmapDpGpu {
                ctx,
                grid,
                observers,
                discs_per_call: GPU_DISCS_PER_CALL,
            })
        }
        #[cfg(not(feature = "gpu"))]
        {
            let _ = march;
            match *ctx {}
        }
    }

    /// Sets the batch size of [`Self::fractions`] (discs per GPU call, default
    /// [`GPU_DISCS_PER_CALL`]; at least one epoch of every site per call whatever the value).
    pub fn with_discs_per_call(mut self, discs: usize) -> Self {
        self.discs_per_call = discs;
        self
    }

    /// One kernel call: `lights` holds the same number of discs per site, site-major.
    fn run(&self, lights: &[[f32; 4]]) -> anyhow::Result<Vec<f32>> {
        #[cfg(feature = "gpu")]
        {
            Ok(crate::gpu::dp::dp_sites_gpu(
                self.ctx,
                &self.grid,
                &self.observers,
                lights,
            )?)
        }
        #[cfg(not(feature = "gpu"))]
        {
            let _ = lights;
            match *self.ctx {}
        }
    }

    /// Every site's horizon profile (as [`SmapDpSites::horizon`], one GPU call for all sites,
    /// uncapped searches); `sites` are the ephemeris sites of `specs`.
    pub fn horizons(
        &self,
        dp: &SmapDpSites,
        specs: &[SeriesSite],
        sites: &[Site],
        config: &SeriesConfig,
    ) -> anyhow::Result<Vec<Horizon>> {
        let mut lights = Vec::new();
        let mut n = 0;
        for site in sites {
            let dirs = dp.profile_dirs(site, config)?;
            n = dirs.len();
            // Negative radius: no cap (the exact horizon).
            lights.extend(dirs.iter().map(|d| twins::disc_light_to_f32(&d.unit, -1.0)));
        }
        let tans = self.run(&lights)?;
        specs
            .iter()
            .zip(sites)
            .enumerate()
            .map(|(i, (spec, site))| {
                dp.horizon_with(i, spec, site, config, |_| {
                    Ok(tans[i * n..(i + 1) * n]
                        .iter()
                        .map(|&t| (t > 0.5 * twins::NO_HORIZON_TAN).then_some(f64::from(t)))
                        .collect())
                })
                .with_context(|| format!("horizon of site '{}'", spec.name))
            })
            .collect()
    }

    /// Every site's Sun and Earth visible fractions over `table` (`sites` as in
    /// [`SmapDpSites::disc_table`]), in batches of at most [`GPU_DISCS_PER_CALL`] discs (see
    /// [`Self::with_discs_per_call`]).
    pub fn fractions(
        &self,
        dp: &SmapDpSites,
        table: &[MoonGeometry],
        sites: &[Site],
        config: &SeriesConfig,
    ) -> anyhow::Result<Vec<(Vec<f64>, Vec<f64>)>> {
        let limb = config.limb_darkening.law();
        let mut out: Vec<(Vec<f64>, Vec<f64>)> = sites
            .iter()
            .map(|_| {
                (
                    Vec::with_capacity(table.len()),
                    Vec::with_capacity(table.len()),
                )
            })
            .collect();
        let batch = (self.discs_per_call / (2 * sites.len().max(1))).max(1);
        for chunk in table.chunks(batch) {
            let (lights, discs) = dp.disc_table(chunk, sites, config.abcorr);
            let tans = self.run(&lights)?;
            out.par_iter_mut()
                .enumerate()
                .for_each(|(i, (sun, earth))| {
                    let base = i * 2 * chunk.len();
                    for e in 0..chunk.len() {
                        let k = base + 2 * e;
                        let (e_c, r) = discs[k];
                        sun.push(fraction_from_horizon_tan(tans[k], e_c, r, &limb));
                        let (e_c, r) = discs[k + 1];
                        earth.push(fraction_from_horizon_tan(
                            tans[k + 1],
                            e_c,
                            r,
                            &LimbDarkening::UNIFORM,
                        ));
                    }
                });
        }
        Ok(out)
    }
}

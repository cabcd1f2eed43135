//! The smap-dp series engine (`penumbra series --engine smap-dp`) on either backend: each site's
//! visible fractions come from the map pipeline's model grid ([`crate::model::MapGrid`]) and the
//! DP maximum-mipmap search ([`crate::shadow::dp`]) instead of a per-site horizon.
//!
//! The grid and its mipmap are built once for all sites; each observer stands its height above
//! the model grid's own surface at the site (no cell snapping). Per site and epoch the light is
//! the exact topocentric direction ([`crate::ephem::topo`]) rotated into model space; one capped
//! DP search gives the minimum shadow cost `J*` along the centre ray, and the prism assumption of
//! papers 000/003 (§3.4) cuts the disc with a horizontal edge at `atan(tan e_c − J*)`
//! ([`chord_visible_fraction`]). No SMap pre-test (the capped search decides lit and deep-shadow
//! cases in microseconds) and no local-horizontal floor (the one blocking rule). The horizon
//! profile for `horizon.csv` is the uncapped search per azimuth of the site's frame. On the GPU,
//! `shaders/dp_sites.wgsl` runs the searches and the disc weighting stays on the CPU in f64.
//! Derivation and measured differences from the horizon engine: docs/shadow.md, "The smap-dp
//! series engine".

use anyhow::Context as _;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::ephem::topo::{self, MoonGeometry};
use crate::ephem::{AbCorr, Site};
use crate::gpu::GpuContext;
use crate::horizon::{Horizon, HorizonMethod};
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

/// How a site's horizon profile (`horizon.csv`, the plots) is sampled: every `az_step_deg` of the
/// site's local azimuth; `method` is recorded with it.
#[derive(Debug, Clone, Copy)]
pub struct ProfileParams {
    /// Azimuth step, degrees (must divide 360).
    pub az_step_deg: f64,
    /// The horizon method the run asked for (recorded in the profile).
    pub method: HorizonMethod,
}

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
        "site '{site}' lies outside the map grid of the DEM layers (or on a hole of it): the smap-dp engine needs the model grid under the site; use --engine horizon"
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
    pub fn new(stack: &TerrainStack, sites: &[crate::model::Site]) -> anyhow::Result<Self> {
        let grid = MapGrid::new(stack)?;
        Self::from_grid(grid, stack, sites)
    }

    /// As [`SmapDpSites::new`] with an already built grid.
    pub fn from_grid(
        grid: MapGrid,
        stack: &TerrainStack,
        sites: &[crate::model::Site],
    ) -> anyhow::Result<Self> {
        let hf = &grid.hf;
        let frame = ModelFrame::of(hf);
        let mut observers = Vec::with_capacity(sites.len());
        let mut ground_height_m = Vec::with_capacity(sites.len());
        for s in sites {
            let (ground_m, _) = stack
                .height_at_lat_lon_m(s.lat_deg(), s.lon_deg())
                .ok_or_else(|| SeriesDpError::NoGround {
                    site: s.name().to_string(),
                    lat_deg: s.lat_deg(),
                    lon_deg: s.lon_deg(),
                })?;
            // The ground point, then the model grid's own surface under it (bilinear), then the
            // observer `h` above it along the radial direction.
            let g = frame.model_from_lat_lon_height(s.lat_deg(), s.lon_deg(), ground_m);
            let (row_g, col_g) = hf.row_col_from_xy(g.x, g.y);
            let inside = row_g >= 0.0
                && col_g >= 0.0
                && row_g <= (hf.rows - 1) as f64
                && col_g <= (hf.cols - 1) as f64;
            let z_surface_m = inside
                .then(|| crate::shadow::brute::bilinear(hf, row_g, col_g))
                .flatten()
                .ok_or_else(|| SeriesDpError::OffGrid {
                    site: s.name().to_string(),
                })?;
            let up = hf.up_at(g.x, g.y, z_surface_m);
            let p = Vector3::new(g.x, g.y, z_surface_m) + s.height_above_ground_m() * up;
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

    /// Every site's Sun and Earth visible fractions over `table` on the CPU (`sites`: the
    /// ephemeris sites, one per site of [`Self::new`], in order), the Sun's weighted by `limb`;
    /// the bodies' topocentric directions as [`Self::disc_table`] takes them. Rayon over sites.
    pub fn fractions(
        &self,
        table: &[MoonGeometry],
        sites: &[Site],
        limb: &LimbDarkening,
        abcorr: AbCorr,
    ) -> Vec<(Vec<f64>, Vec<f64>)> {
        sites
            .par_iter()
            .enumerate()
            .map(|(i, site)| {
                table
                    .iter()
                    .map(|geo| {
                        let obs = topo::Observer::new(geo, site);
                        let disc = |target, radius_km, limb| {
                            let pos = topo::target_from_observer(geo, target, &obs, abcorr);
                            let body = topo::apparent_without_azimuth(pos, site, radius_km);
                            self.fraction(
                                i,
                                &body.pos_in_moon_me_km,
                                body.radius_deg.to_radians(),
                                limb,
                            )
                        };
                        (
                            disc(&geo.sun_wrt_moon, crate::SUN_RADIUS_KM, limb),
                            disc(
                                &geo.earth_wrt_moon,
                                crate::EARTH_RADIUS_KM,
                                &LimbDarkening::UNIFORM,
                            ),
                        )
                    })
                    .unzip()
            })
            .collect()
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

    /// The terrain horizon of site `i` seen by the DP search (see the module docs), sampled as
    /// `profile` says; `site` is the ephemeris site (its ENU frame), `spec` the series site.
    pub fn horizon(
        &self,
        i: usize,
        spec: &crate::model::Site,
        site: &Site,
        profile: ProfileParams,
    ) -> anyhow::Result<Horizon> {
        self.horizon_with(i, spec, site, profile, |dirs| {
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
    fn profile_dirs(&self, site: &Site, profile: ProfileParams) -> anyhow::Result<Vec<LightDir>> {
        let step = profile.az_step_deg;
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
        spec: &crate::model::Site,
        site: &Site,
        profile: ProfileParams,
        tan_horizon: impl FnOnce(&[LightDir]) -> anyhow::Result<Vec<Option<f64>>>,
    ) -> anyhow::Result<Horizon> {
        let step = profile.az_step_deg;
        let dirs = self.profile_dirs(site, profile)?;
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
            lat_deg: spec.lat_deg(),
            lon_deg: spec.lon_deg(),
            ground_height_m: self.ground_height_m[i],
            observer_height_m: spec.height_above_ground_m(),
            ground_layer: format!("smap-dp model grid of {}", self.grid.dem.name),
            min_distance_m: MIN_DISTANCE_CELLS * self.grid.hf.px_m,
            method: profile.method,
            az_step_deg: step,
            az_deg,
            elevation_deg,
            distance_m: vec![f64::NAN; n],
        })
    }
}

/// What the smap-dp engine computes for a series: the sites, the epochs and the settings.
#[derive(Clone, Copy)]
pub struct SiteDpRequest<'a> {
    /// Every terrain layer (the model grid is built from them as `penumbra map` does).
    pub stack: &'a TerrainStack,
    /// The sites, in order.
    pub sites: &'a [crate::model::Site],
    /// The Moon-centred geometry of every epoch, in order.
    pub table: &'a [MoonGeometry],
    /// How the horizon profiles are sampled.
    pub profile: ProfileParams,
    /// The Sun's limb darkening (the Earth's disc is uniform).
    pub limb: LimbDarkening,
    /// The aberration correction.
    pub abcorr: AbCorr,
}

/// Every site's horizon profile and its Sun and Earth fractions per epoch from the smap-dp
/// engine, and what ran.
#[derive(Debug)]
pub struct SiteDpRun {
    /// Each site's horizon profile (its ground height is the DEM's under the site).
    pub horizons: Vec<Horizon>,
    /// Each site's Sun and Earth visible fractions, one per epoch.
    pub fractions: Vec<(Vec<f64>, Vec<f64>)>,
    /// What ran, for `run.json`.
    pub note: String,
}

/// The smap-dp engine on the backend `requested` resolves to (after the sites are checked, so a
/// bad site is one error line with no backend warning): the CPU DP searches, or the GPU kernel
/// `shaders/dp_sites.wgsl` with the disc weighting on the CPU in f64.
pub fn site_dp(requested: super::Backend, req: SiteDpRequest<'_>) -> anyhow::Result<SiteDpRun> {
    let dp = SmapDpSites::new(req.stack, req.sites)?;
    let places = req
        .sites
        .iter()
        .enumerate()
        .map(|(i, s)| {
            Site::new(
                s.lat_deg(),
                s.lon_deg(),
                dp.ground_height_m(i) + s.height_above_ground_m(),
            )
            .with_context(|| format!("site '{}'", s.name()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    match super::resolve(requested, super::OnGpu::Preferred)? {
        super::ResolvedBackend::Cpu => {
            let horizons = req
                .sites
                .iter()
                .zip(&places)
                .enumerate()
                .map(|(i, (s, place))| {
                    dp.horizon(i, s, place, req.profile)
                        .with_context(|| format!("horizon of site '{}'", s.name()))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            let fractions = dp.fractions(req.table, &places, &req.limb, req.abcorr);
            Ok(SiteDpRun {
                horizons,
                fractions,
                note: "cpu: smap-dp searches".into(),
            })
        }
        super::ResolvedBackend::Gpu(ctx) => {
            let gpu = SmapDpGpu::new(&ctx, &dp)?;
            let horizons = gpu.horizons(&dp, req.sites, &places, req.profile)?;
            let fractions = gpu.fractions(&dp, req.table, &places, req.limb, req.abcorr)?;
            Ok(SiteDpRun {
                horizons,
                fractions,
                note: gpu_note(&ctx, "smap-dp searches"),
            })
        }
    }
}

/// `run.json`'s description of a GPU stage: `gpu: <what> on <adapter>`.
#[cfg(feature = "gpu")]
pub(crate) fn gpu_note(ctx: &GpuContext, what: &str) -> String {
    format!("gpu: {what} on {}", ctx.adapter_name())
}

#[cfg(not(feature = "gpu"))]
pub(crate) fn gpu_note(ctx: &GpuContext, _what: &str) -> String {
    match *ctx {}
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
        specs: &[crate::model::Site],
        sites: &[Site],
        profile: ProfileParams,
    ) -> anyhow::Result<Vec<Horizon>> {
        let mut lights = Vec::new();
        let mut n = 0;
        for site in sites {
            let dirs = dp.profile_dirs(site, profile)?;
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
                dp.horizon_with(i, spec, site, profile, |_| {
                    Ok(tans[i * n..(i + 1) * n]
                        .iter()
                        .map(|&t| (t > 0.5 * twins::NO_HORIZON_TAN).then_some(f64::from(t)))
                        .collect())
                })
                .with_context(|| format!("horizon of site '{}'", spec.name()))
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
        limb: LimbDarkening,
        abcorr: AbCorr,
    ) -> anyhow::Result<Vec<(Vec<f64>, Vec<f64>)>> {
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
            let (lights, discs) = dp.disc_table(chunk, sites, abcorr);
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

//! Per-site illumination time series (`penumbra series` and scenario `[series]`): horizons from
//! the terrain, the Sun's and the Earth's apparent discs from the ephemeris, visible fractions,
//! irradiance, statistics and plots.
//!
//! Pipeline for a set of sites and epochs:
//! 1. one horizon per site ([`crate::horizon`]), at the site's ground height from the DEM layers
//!    plus the observer's height above the ground;
//! 2. the Moon-centred geometry of every epoch, queried once and shared by all sites
//!    ([`crate::ephem::moon_geometry_table`]); each site then gets its exact topocentric Sun and
//!    Earth (no approximation: the site offset is applied exactly, see `src/ephem/topo.rs`);
//! 3. per site and epoch: the visible fractions of both discs ([`crate::illum::disc`]) and the
//!    solar irradiance ([`crate::illum::irradiance`]);
//! 4. per site: `series.csv`, `horizon.csv`, `stats.json` and PNG plots; for all sites together a
//!    combined `stats.json` (each site's location, and "at least one site lit") and the tidy long
//!    table `series_long.csv` (site, lat, lon, heights, then the `series.csv` columns).
//!
//! Sites are processed in parallel; each site's rows are written and dropped before the next, so
//! memory holds only the shared ephemeris table (≈300 B per epoch) and two `f64` fractions per site
//! and epoch (for the combined statistics).

use std::io::Write;
use std::path::Path;

use anyhow::Context as _;
use hifitime::Epoch;
use rayon::prelude::*;

use crate::ephem::{self, Kernels, MoonGeometry, Site, time::format_iso};
use crate::horizon::{self, Horizon, HorizonParams};
use crate::illum::stats::{SiteSeries, StatsFile};
use crate::illum::{self, Disc, HorizonProfile, LimbDarkening};
use crate::terrain::TerrainStack;

pub mod config;
pub mod dp;

pub use config::{
    LimbLaw, SeriesConfig, SeriesEngine, SeriesSite, check_site_name, parse_site_flag,
    read_sites_file, validate_sites,
};

/// The CSV header of a site's `series.csv`.
pub const SERIES_CSV_HEADER: &str = "utc,sun_az_deg,sun_el_deg,sun_horizon_el_deg,sun_visible_fraction,sun_irradiance_normal_w_m2,sun_irradiance_horizontal_w_m2,sun_irradiance_vertical_tracking_w_m2,earth_az_deg,earth_el_deg,earth_horizon_el_deg,earth_visible_fraction";

/// One site's results kept after its files are written.
#[derive(Debug, Clone)]
pub struct SiteOutcome {
    /// The site.
    pub site: SeriesSite,
    /// Its horizon.
    pub horizon: Horizon,
    /// Visible fraction of the Sun per epoch.
    pub sun_fraction: Vec<f64>,
    /// Visible fraction of the Earth per epoch.
    pub earth_fraction: Vec<f64>,
    /// Files written, relative to the output folder.
    pub files: Vec<String>,
}

/// Computes the horizons of every site (in order), failing with the site's name. With
/// `config.backend` other than `cpu` the backend is resolved here (`auto`: one warning line and
/// the CPU when no adapter exists) and on the GPU all sites go to the GPU horizon scan at once.
pub fn site_horizons(
    stack: &TerrainStack,
    sites: &[SeriesSite],
    config: &SeriesConfig,
) -> anyhow::Result<Vec<Horizon>> {
    Ok(site_horizons_on(stack, sites, config)?.0)
}

/// [`site_horizons`] and the backend that computed them (`run.json`'s `series_backend`).
fn site_horizons_on(
    stack: &TerrainStack,
    sites: &[SeriesSite],
    config: &SeriesConfig,
) -> anyhow::Result<(Vec<Horizon>, String)> {
    // `auto` takes the CPU scan here: for a few sites it is the fast method (`--horizon-method
    // fast`, ≤ 0.002 deg), while the GPU scan samples like the exact one.
    if config.backend == crate::gpu::Backend::Gpu {
        let resolved = crate::gpu::resolve_backend(config.backend)
            .with_context(|| format!("resolving backend {}", config.backend.as_str()))?;
        if let crate::gpu::ResolvedBackend::Gpu(ctx) = resolved {
            let horizons = gpu_site_horizons(&ctx, stack, sites, config)?;
            return Ok((horizons, gpu_backend_note(&ctx, "per-site horizon scan")));
        }
    }
    let engine = horizon::HorizonEngine::new(stack);
    sites
        .iter()
        .map(|s| {
            let params = HorizonParams {
                observer_height_m: s.height_above_ground_m,
                az_step_deg: config.az_step_deg,
                method: config.horizon_method,
                ..HorizonParams::default()
            };
            engine
                .horizon(s.lat_deg, s.lon_deg, &params)
                .with_context(|| format!("horizon of site '{}'", s.name))
        })
        .collect::<anyhow::Result<Vec<_>>>()
        .map(|h| (h, "cpu: per-site horizon scan".to_string()))
}

/// `run.json`'s description of a GPU stage: `gpu: <what> on <adapter>`.
#[cfg(feature = "gpu")]
fn gpu_backend_note(ctx: &crate::gpu::GpuContext, what: &str) -> String {
    format!("gpu: {what} on {}", ctx.adapter_name())
}

#[cfg(not(feature = "gpu"))]
fn gpu_backend_note(ctx: &crate::gpu::GpuContext, _what: &str) -> String {
    match *ctx {}
}

/// The GPU path of [`site_horizons`].
#[cfg(feature = "gpu")]
fn gpu_site_horizons(
    ctx: &crate::gpu::GpuContext,
    stack: &TerrainStack,
    sites: &[SeriesSite],
    config: &SeriesConfig,
) -> anyhow::Result<Vec<Horizon>> {
    let engine = horizon::HorizonEngine::new(stack);
    for s in sites {
        crate::twins::horizon_scan::site_setup(
            &engine,
            s.lat_deg,
            s.lon_deg,
            s.height_above_ground_m,
        )
        .with_context(|| format!("horizon of site '{}'", s.name))?;
    }
    let specs: Vec<(f64, f64, f64)> = sites
        .iter()
        .map(|s| (s.lat_deg, s.lon_deg, s.height_above_ground_m))
        .collect();
    Ok(crate::gpu::horizon::horizons_gpu(
        ctx,
        stack,
        None,
        &specs,
        config.az_step_deg,
    )?)
}

#[cfg(not(feature = "gpu"))]
fn gpu_site_horizons(
    ctx: &crate::gpu::GpuContext,
    _stack: &TerrainStack,
    _sites: &[SeriesSite],
    _config: &SeriesConfig,
) -> anyhow::Result<Vec<Horizon>> {
    match *ctx {}
}

/// Sun and Earth fractions of one site for every epoch of the shared table, calling `row` for each
/// epoch (in order) with the values of the CSV row. Azimuths are computed for the epochs where
/// `need_azimuths(k)` is true (CSV rows, plot tracks) and wherever a disc is cut by the horizon;
/// elsewhere they are `NaN`.
pub fn site_fractions(
    table: &[MoonGeometry],
    site: &Site,
    horizon: &Horizon,
    config: &SeriesConfig,
    need_azimuths: impl Fn(usize) -> bool,
    row: impl FnMut(usize, &SeriesRow) -> anyhow::Result<()>,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let profile = HorizonProfile::new(&horizon.elevation_deg)?;
    // The horizon is the polyline through its samples, so a disc entirely above the highest
    // sample is fully visible and one entirely below the lowest is hidden, whatever the method:
    // most epochs at a polar site end here without looking at the profile.
    let (h_min_deg, h_max_deg) = horizon
        .elevation_deg
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
    let fraction = |_: usize, _: Body, body: &mut ephem::Apparent, limb: &LimbDarkening| -> f64 {
        if body.el_deg - body.radius_deg >= h_max_deg {
            1.0
        } else if body.el_deg + body.radius_deg <= h_min_deg {
            0.0
        } else {
            body.fill_azimuth(site);
            let disc = Disc {
                az_deg: body.az_deg,
                el_deg: body.el_deg,
                radius_deg: body.radius_deg,
            };
            illum::visible_fraction(&profile, &disc, config.disc_method, limb)
        }
    };
    fractions_with(table, site, &profile, config, need_azimuths, row, fraction)
}

/// As [`site_fractions`] with the smap-dp engine ([`crate::series::dp`]): the fractions of site
/// `index` of `dp` come from the DP search on the map grid; `horizon` (from
/// [`dp::SmapDpSites::horizon`]) only fills the CSV's horizon columns.
#[expect(
    clippy::too_many_arguments,
    reason = "site_fractions plus the engine and index"
)]
pub fn site_fractions_smap_dp(
    table: &[MoonGeometry],
    site: &Site,
    dp: &dp::SmapDpSites,
    index: usize,
    horizon: &Horizon,
    config: &SeriesConfig,
    need_azimuths: impl Fn(usize) -> bool,
    row: impl FnMut(usize, &SeriesRow) -> anyhow::Result<()>,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let profile = HorizonProfile::new(&horizon.elevation_deg)?;
    let fraction = |_: usize, _: Body, body: &mut ephem::Apparent, limb: &LimbDarkening| -> f64 {
        dp.fraction(
            index,
            &body.pos_in_moon_me_km,
            body.radius_deg.to_radians(),
            limb,
        )
    };
    fractions_with(table, site, &profile, config, need_azimuths, row, fraction)
}

/// As [`site_fractions`] with fractions already computed (the GPU path of the smap-dp engine,
/// [`dp::SmapDpGpu::fractions`]): `sun` and `earth` hold one fraction per epoch of
/// `table`; the ephemeris is still evaluated per epoch for the CSV columns and sky tracks.
#[expect(
    clippy::too_many_arguments,
    reason = "site_fractions plus the two fraction series"
)]
pub fn site_fractions_given(
    table: &[MoonGeometry],
    site: &Site,
    horizon: &Horizon,
    sun: &[f64],
    earth: &[f64],
    config: &SeriesConfig,
    need_azimuths: impl Fn(usize) -> bool,
    row: impl FnMut(usize, &SeriesRow) -> anyhow::Result<()>,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    anyhow::ensure!(
        sun.len() == table.len() && earth.len() == table.len(),
        "{} / {} precomputed fractions for {} epochs",
        sun.len(),
        earth.len(),
        table.len()
    );
    let profile = HorizonProfile::new(&horizon.elevation_deg)?;
    let fraction = |k: usize, b: Body, _: &mut ephem::Apparent, _: &LimbDarkening| -> f64 {
        match b {
            Body::Sun => sun[k],
            Body::Earth => earth[k],
        }
    };
    fractions_with(table, site, &profile, config, need_azimuths, row, fraction)
}

/// Which disc [`fractions_with`] asks for.
#[derive(Debug, Clone, Copy)]
enum Body {
    Sun,
    Earth,
}

/// The per-epoch loop shared by both engines: ephemeris per site, `fraction` per disc (epoch
/// index, body, apparent body, limb darkening), CSV row.
fn fractions_with(
    table: &[MoonGeometry],
    site: &Site,
    profile: &HorizonProfile<'_>,
    config: &SeriesConfig,
    need_azimuths: impl Fn(usize) -> bool,
    mut row: impl FnMut(usize, &SeriesRow) -> anyhow::Result<()>,
    fraction: impl Fn(usize, Body, &mut ephem::Apparent, &LimbDarkening) -> f64,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let limb = config.limb_darkening.law();
    let mut sun_fraction = Vec::with_capacity(table.len());
    let mut earth_fraction = Vec::with_capacity(table.len());
    for (k, geo) in table.iter().enumerate() {
        let obs = ephem::topo::Observer::new(geo, site);
        let sun_pos =
            ephem::topo::target_from_observer(geo, &geo.sun_wrt_moon, &obs, config.abcorr);
        let earth_pos =
            ephem::topo::target_from_observer(geo, &geo.earth_wrt_moon, &obs, config.abcorr);
        let (mut sun, mut earth) = if need_azimuths(k) {
            (
                ephem::topo::apparent(sun_pos, site, crate::SUN_RADIUS_KM),
                ephem::topo::apparent(earth_pos, site, crate::EARTH_RADIUS_KM),
            )
        } else {
            (
                ephem::topo::apparent_without_azimuth(sun_pos, site, crate::SUN_RADIUS_KM),
                ephem::topo::apparent_without_azimuth(earth_pos, site, crate::EARTH_RADIUS_KM),
            )
        };
        let sun_f = fraction(k, Body::Sun, &mut sun, &limb);
        let earth_f = fraction(k, Body::Earth, &mut earth, &LimbDarkening::UNIFORM);
        // The horizon at the bodies' azimuths is only needed for the CSV columns.
        let (sun_horizon_el_deg, earth_horizon_el_deg) = if config.write_csv {
            (
                profile.el_at_az_deg(sun.az_deg),
                profile.el_at_az_deg(earth.az_deg),
            )
        } else {
            (f64::NAN, f64::NAN)
        };
        let r = SeriesRow {
            sun,
            earth,
            sun_horizon_el_deg,
            earth_horizon_el_deg,
            sun_fraction: sun_f,
            earth_fraction: earth_f,
        };
        row(k, &r)?;
        sun_fraction.push(sun_f);
        earth_fraction.push(earth_f);
    }
    Ok((sun_fraction, earth_fraction))
}

/// One epoch of one site.
#[derive(Debug, Clone, Copy)]
pub struct SeriesRow {
    /// The Sun seen from the site.
    pub sun: ephem::Apparent,
    /// The Earth seen from the site.
    pub earth: ephem::Apparent,
    /// Horizon elevation at the Sun's azimuth, degrees (`NaN` when no CSV is written).
    pub sun_horizon_el_deg: f64,
    /// Horizon elevation at the Earth's azimuth, degrees (`NaN` when no CSV is written).
    pub earth_horizon_el_deg: f64,
    /// Visible (flux) fraction of the Sun's disc.
    pub sun_fraction: f64,
    /// Visible fraction of the Earth's disc.
    pub earth_fraction: f64,
}

/// The values of a `series.csv` row after its `utc`, in the header's order
/// ([`SERIES_CSV_HEADER`]): the Sun's az, el, horizon, fraction and three irradiances, the Earth's
/// az, el, horizon and fraction.
pub fn row_values(r: &SeriesRow) -> [f64; 11] {
    let normal = illum::irradiance::normal_irradiance_w_m2(r.sun.range_km, r.sun_fraction);
    let horizontal =
        illum::irradiance::horizontal_irradiance_w_m2(r.sun.range_km, r.sun.el_deg, r.sun_fraction);
    let vertical = illum::irradiance::vertical_tracking_irradiance_w_m2(
        r.sun.range_km,
        r.sun.el_deg,
        r.sun_fraction,
    );
    [
        r.sun.az_deg,
        r.sun.el_deg,
        r.sun_horizon_el_deg,
        r.sun_fraction,
        normal,
        horizontal,
        vertical,
        r.earth.az_deg,
        r.earth.el_deg,
        r.earth_horizon_el_deg,
        r.earth_fraction,
    ]
}

fn write_row(w: &mut dyn Write, epoch: Epoch, r: &SeriesRow) -> std::io::Result<()> {
    let v = row_values(r);
    writeln!(
        w,
        "{},{:.6},{:.6},{:.6},{:.6},{:.3},{:.3},{:.3},{:.6},{:.6},{:.6},{:.6}",
        format_iso(epoch),
        v[0],
        v[1],
        v[2],
        v[3],
        v[4],
        v[5],
        v[6],
        v[7],
        v[8],
        v[9],
        v[10]
    )
}

/// What [`run_series`] did: every site's outcome, the files written (relative to `out_dir`,
/// including the combined `stats.json`) and the backend that computed the terrain part.
#[derive(Debug)]
pub struct SeriesRun {
    /// Every site's outcome, in input order.
    pub outcomes: Vec<SiteOutcome>,
    /// The files written, relative to `out_dir`.
    pub files: Vec<String>,
    /// The backend that ran the terrain part (`cpu: …` or `gpu: … on <adapter>`), for `run.json`.
    pub backend: String,
}

/// Runs a whole series: horizons, ephemeris, fractions, files (see [`SeriesRun`]).
pub fn run_series(
    kernels: &Kernels,
    stack: &TerrainStack,
    sites: &[SeriesSite],
    epochs: &[Epoch],
    step_s: f64,
    config: &SeriesConfig,
    out_dir: &Path,
) -> anyhow::Result<SeriesRun> {
    if sites.is_empty() {
        anyhow::bail!("no sites given");
    }
    let mut gpu_fractions: Option<Vec<(Vec<f64>, Vec<f64>)>> = None;
    let mut backend_note = "cpu: smap-dp searches".to_string();
    let (horizons, dp, table) = match config.engine {
        SeriesEngine::Horizon => {
            let (horizons, note) = site_horizons_on(stack, sites, config)?;
            backend_note = note;
            (horizons, None, ephem::moon_geometry_table(kernels, epochs)?)
        }
        SeriesEngine::SmapDp => {
            let dp = dp::SmapDpSites::new(stack, sites)?;
            let ephem_sites = sites
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    Site::new(
                        s.lat_deg,
                        s.lon_deg,
                        dp.ground_height_m(i) + s.height_above_ground_m,
                    )
                    .with_context(|| format!("site '{}'", s.name))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            // smap-dp on the GPU: `gpu` needs an adapter (else one error line), `auto` takes a hardware
            // one or falls back to the CPU with one warning line (crate::gpu::resolve_backend).
            // (resolved after the sites are checked: a bad site is one error line, no backend warning)
            let gpu_ctx = match (config.engine, config.backend) {
                (SeriesEngine::SmapDp, backend) if backend != crate::gpu::Backend::Cpu => {
                    match crate::gpu::resolve_backend(backend)
                        .with_context(|| format!("resolving backend {}", backend.as_str()))?
                    {
                        crate::gpu::ResolvedBackend::Gpu(ctx) => Some(ctx),
                        crate::gpu::ResolvedBackend::Cpu => None,
                    }
                }
                _ => None,
            };
            match gpu_ctx.as_deref() {
                Some(ctx) => {
                    let gpu = dp::SmapDpGpu::new(ctx, &dp)?;
                    let horizons = gpu.horizons(&dp, sites, &ephem_sites, config)?;
                    let table = ephem::moon_geometry_table(kernels, epochs)?;
                    gpu_fractions = Some(gpu.fractions(&dp, &table, &ephem_sites, config)?);
                    backend_note = gpu_backend_note(ctx, "smap-dp searches");
                    (horizons, None, table)
                }
                None => {
                    let horizons = sites
                        .iter()
                        .zip(&ephem_sites)
                        .enumerate()
                        .map(|(i, (s, site))| {
                            dp.horizon(i, s, site, config)
                                .with_context(|| format!("horizon of site '{}'", s.name))
                        })
                        .collect::<anyhow::Result<Vec<_>>>()?;
                    let table = ephem::moon_geometry_table(kernels, epochs)?;
                    (horizons, Some(dp), table)
                }
            }
        }
    };
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("creating output folder {}", out_dir.display()))?;

    let progress = crate::output::progress_bar(
        sites.len() * epochs.len(),
        "{spinner} series [{bar:30}] {percent}% ({pos}/{len} site-epochs, eta {eta})",
    );
    let outcomes: Vec<SiteOutcome> = sites
        .par_iter()
        .zip(horizons)
        .enumerate()
        .map(|(i, (spec, horizon))| {
            let engine = match (&dp, &gpu_fractions) {
                (Some(d), _) => SiteEngine::SmapDp(d, i),
                (None, Some(f)) => SiteEngine::Given(&f[i].0, &f[i].1),
                (None, None) => SiteEngine::Horizon,
            };
            run_one_site(
                &table, epochs, step_s, spec, horizon, engine, config, out_dir, &progress,
            )
        })
        .collect::<anyhow::Result<_>>()?;
    progress.finish_and_clear();

    let mut files: Vec<String> = outcomes.iter().flat_map(|o| o.files.clone()).collect();
    let all: Vec<SiteSeries<'_>> = outcomes
        .iter()
        .map(|o| SiteSeries {
            site: &o.site.name,
            start_utc: epochs[0],
            step_s,
            sun_fraction: &o.sun_fraction,
            earth_fraction: &o.earth_fraction,
        })
        .collect();
    let mut stats = StatsFile::from_series(&all)?;
    for (s, o) in stats.sites.iter_mut().zip(&outcomes) {
        s.location = Some(site_location(&o.site, &o.horizon));
    }
    stats.write_json(&out_dir.join("stats.json"))?;
    files.push("stats.json".into());
    if config.write_csv {
        write_long_table(&outcomes, out_dir)?;
        files.push(LONG_TABLE.into());
    }
    Ok(SeriesRun {
        outcomes,
        files,
        backend: backend_note,
    })
}

/// Where a site stands, for `stats.json`: its coordinates, its height above the ground and the
/// ground height its horizon was computed from.
pub fn site_location(site: &SeriesSite, horizon: &Horizon) -> illum::stats::SiteLocation {
    illum::stats::SiteLocation {
        lat_deg: site.lat_deg,
        lon_deg: site.lon_deg,
        height_above_ground_m: site.height_above_ground_m,
        ground_height_m: horizon.ground_height_m,
    }
}

/// The run's tidy long table: every site's `series.csv` rows, one table.
pub const LONG_TABLE: &str = "series_long.csv";

/// The columns [`LONG_TABLE`] puts before [`SERIES_CSV_HEADER`]'s.
pub const LONG_TABLE_SITE_COLUMNS: &str =
    "site,lat_deg,lon_deg,height_above_ground_m,ground_height_m";

/// Writes [`LONG_TABLE`]: the rows of each site's `series.csv` (read back, so that the values are
/// the same text) after the site's name, latitude, longitude and heights, sites in input order.
fn write_long_table(outcomes: &[SiteOutcome], out_dir: &Path) -> anyhow::Result<()> {
    use std::io::BufRead as _;
    crate::output::write_atomic(&out_dir.join(LONG_TABLE), |w| -> anyhow::Result<()> {
        writeln!(w, "{LONG_TABLE_SITE_COLUMNS},{SERIES_CSV_HEADER}")?;
        for o in outcomes {
            let path = out_dir.join(&o.site.name).join("series.csv");
            let file = std::fs::File::open(&path)
                .with_context(|| format!("reading back {}", path.display()))?;
            let prefix = format!(
                "{},{},{},{},{:.3}",
                csv_field(&o.site.name),
                o.site.lat_deg,
                o.site.lon_deg,
                o.site.height_above_ground_m,
                o.horizon.ground_height_m
            );
            for line in std::io::BufReader::new(file).lines().skip(1) {
                writeln!(w, "{prefix},{}", line?)?;
            }
        }
        Ok(())
    })
}

/// A CSV field: quoted (with doubled quotes) when it holds a comma, a quote or a space at an end.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) || s.starts_with(' ') || s.ends_with(' ') {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Where [`run_one_site`] takes its fractions from.
#[derive(Clone, Copy)]
enum SiteEngine<'a> {
    /// The site's horizon (strip integrals).
    Horizon,
    /// The smap-dp engine on the CPU, site index.
    SmapDp(&'a dp::SmapDpSites, usize),
    /// Already computed (the smap-dp engine on the GPU): Sun and Earth fractions per epoch.
    Given(&'a [f64], &'a [f64]),
}

#[expect(clippy::too_many_arguments, reason = "one site's slice of run_series")]
fn run_one_site(
    table: &[MoonGeometry],
    epochs: &[Epoch],
    step_s: f64,
    spec: &SeriesSite,
    horizon: Horizon,
    engine: SiteEngine<'_>,
    config: &SeriesConfig,
    out_dir: &Path,
    progress: &indicatif::ProgressBar,
) -> anyhow::Result<SiteOutcome> {
    let site_dir = out_dir.join(&spec.name);
    std::fs::create_dir_all(&site_dir)
        .with_context(|| format!("creating {}", site_dir.display()))?;
    let rel = |f: &str| format!("{}/{f}", spec.name);
    let mut files = Vec::new();
    let site = Site::new(
        spec.lat_deg,
        spec.lon_deg,
        horizon.ground_height_m + spec.height_above_ground_m,
    )
    .with_context(|| format!("site '{}'", spec.name))?;

    // Horizon CSV.
    crate::output::write_atomic(&site_dir.join("horizon.csv"), |w| -> anyhow::Result<()> {
        crate::horizon::write_csv(&horizon, w)?;
        Ok(())
    })?;
    files.push(rel("horizon.csv"));

    // Series rows, streamed to the CSV; the sky tracks are thinned for the plots.
    let track_stride = (epochs.len() / 20_000).max(1);
    let mut sun_track = Vec::new();
    let mut earth_track = Vec::new();
    let mut fractions = (Vec::new(), Vec::new());
    let mut compute = |w: Option<&mut dyn Write>| -> anyhow::Result<()> {
        let mut w = w;
        let need_azimuths = |k: usize| config.write_csv || k.is_multiple_of(track_stride);
        let on_row = |k: usize, r: &SeriesRow| -> anyhow::Result<()> {
            if let Some(w) = w.as_deref_mut() {
                write_row(w, epochs[k], r)?;
            }
            if k.is_multiple_of(track_stride) {
                sun_track.push((r.sun.az_deg, r.sun.el_deg));
                earth_track.push((r.earth.az_deg, r.earth.el_deg));
            }
            if k % 4096 == 4095 {
                progress.inc(4096);
            }
            Ok(())
        };
        fractions = match engine {
            SiteEngine::Horizon => {
                site_fractions(table, &site, &horizon, config, need_azimuths, on_row)?
            }
            SiteEngine::Given(sun, earth) => site_fractions_given(
                table,
                &site,
                &horizon,
                sun,
                earth,
                config,
                need_azimuths,
                on_row,
            )?,
            SiteEngine::SmapDp(dp, i) => site_fractions_smap_dp(
                table,
                &site,
                dp,
                i,
                &horizon,
                config,
                need_azimuths,
                on_row,
            )?,
        };
        progress.inc((epochs.len() % 4096) as u64);
        Ok(())
    };
    if config.write_csv {
        crate::output::write_atomic(&site_dir.join("series.csv"), |w| -> anyhow::Result<()> {
            writeln!(w, "{SERIES_CSV_HEADER}")?;
            compute(Some(w))
        })?;
        files.push(rel("series.csv"));
    } else {
        compute(None)?;
    }
    let (sun_fraction, earth_fraction) = fractions;

    let series = SiteSeries {
        site: &spec.name,
        start_utc: epochs[0],
        step_s,
        sun_fraction: &sun_fraction,
        earth_fraction: &earth_fraction,
    };
    StatsFile::from_series(&[series])?.write_json(&site_dir.join("stats.json"))?;
    files.push(rel("stats.json"));

    if config.plots {
        let profile = HorizonProfile::new(&horizon.elevation_deg)?;
        let tracks = illum::plot::SkyTracks {
            sun_az_el_deg: &sun_track,
            earth_az_el_deg: &earth_track,
        };
        let title = format!(
            "{} ({:.3}°, {:.3}°), {:.1} m above ground",
            spec.name, spec.lat_deg, spec.lon_deg, spec.height_above_ground_m
        );
        illum::plot::write_horizon_plot(
            &site_dir.join("horizon.png"),
            &format!("Horizon and sky tracks: {title}"),
            &profile,
            &tracks,
            (1400, 600),
        )?;
        illum::plot::write_horizon_polar_plot(
            &site_dir.join("horizon_polar.png"),
            &format!("Horizon (polar): {}", spec.name),
            &profile,
            &tracks,
            900,
        )?;
        illum::plot::write_fraction_plot(
            &site_dir.join("visibility.png"),
            &format!("Visible fraction of the Sun and the Earth: {title}"),
            &illum::plot::FractionSeries {
                start_utc: epochs[0],
                step_s,
                sun_fraction: &sun_fraction,
                earth_fraction: Some(&earth_fraction),
            },
            (1400, 500),
        )?;
        files.extend([
            rel("horizon.png"),
            rel("horizon_polar.png"),
            rel("visibility.png"),
        ]);
    }
    Ok(SiteOutcome {
        site: spec.clone(),
        horizon,
        sun_fraction,
        earth_fraction,
        files,
    })
}

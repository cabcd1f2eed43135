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

use crate::comms::{self, LinkSample, Station};
use crate::ephem::{self, Kernels, MoonGeometry, time::format_iso};
use crate::horizon::Horizon;
use crate::illum::stats::{SiteSeries, StatsFile};
use crate::illum::{self, Disc, HorizonProfile, LimbDarkening};
use crate::model::Site;
use crate::terrain::TerrainStack;

use super::neighbourhood::{self, SiteNeighbourhood};
use super::{SeriesConfig, SeriesEngine};

/// The CSV header of a site's `series.csv`.
pub const SERIES_CSV_HEADER: &str = "utc,sun_az_deg,sun_el_deg,sun_horizon_el_deg,sun_visible_fraction,sun_irradiance_normal_w_m2,sun_irradiance_horizontal_w_m2,sun_irradiance_vertical_tracking_w_m2,earth_az_deg,earth_el_deg,earth_horizon_el_deg,earth_visible_fraction";

/// The columns a run with ground stations adds to `series.csv` ([`crate::comms`]): `dte` (1 when
/// the Earth's centre is above the terrain horizon and a station sees the site above its mask),
/// the best station's elevation of the site and its name.
pub const LINK_CSV_COLUMNS: &str = "dte,station_el_deg,station";

/// The columns a run with relays adds to `series.csv` ([`crate::comms::RelayTable`]):
/// `relay_visible` (1 when a relay is above the terrain horizon and within the range limit), the
/// best relay's elevation above the local horizontal and its name.
pub const RELAY_CSV_COLUMNS: &str = "relay_visible,relay_el_deg,relay";

/// One site's results kept after its files are written.
#[derive(Debug, Clone)]
pub struct SiteOutcome {
    /// The site.
    pub site: Site,
    /// Its horizon.
    pub horizon: Horizon,
    /// Visible fraction of the Sun per epoch.
    pub sun_fraction: Vec<f64>,
    /// Visible fraction of the Earth per epoch.
    pub earth_fraction: Vec<f64>,
    /// The Sun centre's elevation above the local horizontal per epoch, degrees.
    pub sun_el_deg: Vec<f64>,
    /// Statistics of the link to Earth (`None` without stations).
    pub link: Option<illum::stats::LinkStats>,
    /// Statistics of the relays (`None` without).
    pub relay: Option<illum::stats::RelayStats>,
    /// Statistics of the panel and battery (`None` without a panel).
    pub power: Option<illum::power::PowerStats>,
    /// Direct-to-Earth per epoch (empty without stations).
    pub dte: Vec<bool>,
    /// The site's neighbourhood (`None` when the run asks for none).
    pub neighbourhood: Option<illum::stats::Neighbourhood>,
    /// What a bare sphere beyond the DEM would change (`None` when nothing).
    pub beyond_dem: Option<illum::stats::BeyondDemEffect>,
    /// Files written, relative to the output folder.
    pub files: Vec<String>,
}

/// Where a site's visible fractions come from.
#[derive(Debug, Clone, Copy)]
pub enum SiteFractions<'a> {
    /// The strip integral of each disc against the site's horizon (the horizon engine).
    FromHorizon,
    /// Already computed (the smap-dp engine, [`crate::compute::site_dp::site_dp`]): one Sun and
    /// one Earth fraction per epoch.
    Given {
        /// The Sun's visible fraction per epoch.
        sun: &'a [f64],
        /// The Earth's visible fraction per epoch.
        earth: &'a [f64],
    },
}

/// Sun and Earth fractions of one site for every epoch of the shared table, calling `row` for each
/// epoch (in order) with the values of the CSV row (the ephemeris is evaluated per epoch for the
/// CSV columns and sky tracks whatever the fractions' source). Azimuths are computed for the
/// epochs where `need_azimuths(k)` is true (CSV rows, plot tracks) and wherever a disc is cut by
/// the horizon; elsewhere they are `NaN`.
pub fn site_fractions(
    table: &[MoonGeometry],
    site: &ephem::Site,
    horizon: &Horizon,
    source: SiteFractions<'_>,
    config: &SeriesConfig,
    need_azimuths: impl Fn(usize) -> bool,
    row: impl FnMut(usize, &SeriesRow) -> anyhow::Result<()>,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let profile = HorizonProfile::new(&horizon.elevation_deg)?;
    if let SiteFractions::Given { sun, earth } = source {
        anyhow::ensure!(
            sun.len() == table.len() && earth.len() == table.len(),
            "{} / {} precomputed fractions for {} epochs",
            sun.len(),
            earth.len(),
            table.len()
        );
        let fraction = |k: usize, b: Body, _: &mut ephem::Apparent, _: &LimbDarkening| -> f64 {
            match b {
                Body::Sun => sun[k],
                Body::Earth => earth[k],
            }
        };
        return fractions_with(table, site, &profile, config, need_azimuths, row, fraction);
    }
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
    site: &ephem::Site,
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

fn write_row(
    w: &mut dyn Write,
    epoch: Epoch,
    r: &SeriesRow,
    link: Option<(&LinkSample, &LinkContext)>,
    power: Option<(f64, Option<f64>)>,
) -> std::io::Result<()> {
    let v = row_values(r);
    write!(
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
    )?;
    if let Some((l, ctx)) = link {
        write!(w, "{}", ctx.csv_fields(l))?;
    }
    if let Some((p, battery)) = power {
        write!(w, ",{p:.3}")?;
        if let Some(b) = battery {
            write!(w, ",{b:.3}")?;
        }
    }
    writeln!(w)
}

/// What every site's link shares: the ground stations and their positions at every epoch of a
/// run's ephemeris table, and the relays' tracks. The command line, scenarios and Python use it
/// alike.
pub struct LinkContext {
    stations: Vec<Station>,
    at: Vec<comms::StationsAt>,
    relays: Option<comms::RelayTable>,
}

impl LinkContext {
    /// The link context of `config`'s stations and relays over `table`'s epochs; `None` with
    /// neither.
    pub fn new(
        kernels: &Kernels,
        config: &SeriesConfig,
        table: &[MoonGeometry],
    ) -> anyhow::Result<Option<Self>> {
        let stations = config.stations.resolve(config.station_mask_deg)?;
        let relays = if config.relays.is_empty() {
            if !config.relay_spks.is_empty() {
                anyhow::bail!(
                    "relay SPK given without a relay: name the body with --relay NAME=NAIF_ID"
                );
            }
            None
        } else {
            Some(comms::RelayTable::new(
                kernels,
                &config.relay_spks,
                &config.relays,
                config.relay_max_range_km,
                table,
            )?)
        };
        if stations.is_none() && relays.is_none() {
            return Ok(None);
        }
        let stations = stations.unwrap_or_default();
        Ok(Some(LinkContext {
            at: if stations.is_empty() {
                Vec::new()
            } else {
                comms::stations_table(&stations, table)
            },
            stations,
            relays,
        }))
    }

    /// The stations (empty when only relays were asked for).
    pub fn stations(&self) -> &[Station] {
        &self.stations
    }

    /// Whether the run has ground stations (DTE columns and statistics).
    pub fn has_stations(&self) -> bool {
        !self.stations.is_empty()
    }

    /// The relays (empty without).
    pub fn relays(&self) -> &[comms::Relay] {
        self.relays.as_ref().map_or(&[], |r| r.relays())
    }

    /// The columns this link adds to `series.csv`: [`LINK_CSV_COLUMNS`] with stations,
    /// [`RELAY_CSV_COLUMNS`] with relays.
    pub fn csv_columns(&self) -> String {
        let mut cols = Vec::new();
        if self.has_stations() {
            cols.push(LINK_CSV_COLUMNS);
        }
        if self.relays.is_some() {
            cols.push(RELAY_CSV_COLUMNS);
        }
        cols.join(",")
    }

    /// The link of `site` at epoch `k` of the table, the Earth seen as `earth` (its azimuth
    /// filled in here when missing) against the site's horizon `profile`. `scratch` is reused.
    pub fn sample(
        &self,
        table: &[MoonGeometry],
        k: usize,
        site: &ephem::Site,
        earth: &ephem::Apparent,
        profile: &HorizonProfile<'_>,
        scratch: &mut LinkScratch,
    ) -> LinkSample {
        let mut earth = *earth;
        if earth.az_deg.is_nan() {
            earth.fill_azimuth(site);
        }
        let best = if self.has_stations() {
            scratch.station_el.resize(self.stations.len(), 0.0);
            comms::site_elevations_deg(
                &table[k],
                &self.at[k],
                &site.pos_in_moon_me_km,
                &mut scratch.station_el,
            );
            comms::best_station(&self.stations, &scratch.station_el)
        } else {
            None
        };
        let relay = self.relays.as_ref().and_then(|r| {
            r.best(
                &table[k],
                k,
                site,
                |az| profile.el_at_az_deg(az),
                &mut scratch.relay,
            )
        });
        LinkSample {
            station: best.map(|b| b.0),
            station_el_deg: best.map_or(f64::NAN, |b| b.1),
            station_sees_site: best.is_some_and(|(i, e)| e >= self.stations[i].mask_deg()),
            earth_centre_visible: earth.el_deg > profile.el_at_az_deg(earth.az_deg),
            relay: relay.map(|r| r.0),
            relay_el_deg: relay.map_or(f64::NAN, |r| r.1),
            relay_visible: relay.is_some_and(|r| r.2),
        }
    }

    /// The relay statistics of one site's link samples; `None` without relays.
    pub fn relay_summary(
        &self,
        series: &SiteSeries<'_>,
        links: &[LinkSample],
    ) -> anyhow::Result<Option<illum::stats::RelayStats>> {
        if self.relays.is_none() {
            return Ok(None);
        }
        let relay: Vec<bool> = links.iter().map(|s| s.relay_visible).collect();
        let dte: Vec<bool> = links.iter().map(LinkSample::dte).collect();
        Ok(Some(illum::stats::relay_stats(
            series,
            &relay,
            self.has_stations().then_some(dte.as_slice()),
        )?))
    }

    /// The CSV fields of one sample ([`Self::csv_columns`]), each after a comma.
    pub fn csv_fields(&self, l: &LinkSample) -> String {
        let mut out = String::new();
        if self.has_stations() {
            let name = l.station.map_or("", |i| self.stations[i].name());
            out += &format!(
                ",{},{:.4},{}",
                u8::from(l.dte()),
                l.station_el_deg,
                csv_field(name)
            );
        }
        if self.relays.is_some() {
            let name = l.relay.map_or("", |i| self.relays()[i].name.as_str());
            out += &format!(
                ",{},{:.4},{}",
                u8::from(l.relay_visible),
                l.relay_el_deg,
                csv_field(name)
            );
        }
        out
    }

    /// The statistics and windows of one site's link samples (`series`: its Sun fractions and
    /// time grid).
    pub fn summary(
        &self,
        series: &SiteSeries<'_>,
        links: &[LinkSample],
    ) -> anyhow::Result<(illum::stats::LinkStats, Vec<comms::LinkWindow>)> {
        let dte: Vec<bool> = links.iter().map(LinkSample::dte).collect();
        let station: Vec<bool> = links.iter().map(|s| s.station_sees_site).collect();
        let earth_centre: Vec<bool> = links.iter().map(|s| s.earth_centre_visible).collect();
        let idx: Vec<Option<usize>> = links.iter().map(|s| s.station).collect();
        let windows =
            comms::link_windows(&dte, &idx, &self.stations, series.start_utc, series.step_s);
        let stats = illum::stats::link_stats(
            series,
            &illum::stats::LinkSeries {
                dte: &dte,
                station: &station,
                earth_centre: &earth_centre,
            },
        )?;
        Ok((stats, windows))
    }
}

/// The columns a run with a panel adds to `series.csv` ([`crate::illum::power`]): the panel's
/// power, and the battery's charge at the epoch when a capacity is given.
pub const POWER_CSV_COLUMNS: &str = "power_w";
/// The column a battery capacity adds after [`POWER_CSV_COLUMNS`].
pub const BATTERY_CSV_COLUMN: &str = "battery_wh";

/// A site's panel and battery stepped through its epochs in order (the CSV rows, Python's
/// columns): the power of each sample and the battery's charge at its epoch.
#[derive(Debug, Clone)]
pub struct PowerTrack {
    config: illum::power::PowerConfig,
    battery: illum::power::Battery,
    start: Epoch,
    step_h: f64,
    loads: Vec<illum::power::Loads>,
    next: usize,
}

impl PowerTrack {
    /// The track of `config`'s panel over `epochs` (its load profile read and checked against
    /// them), samples `step_s` apart.
    pub fn new(
        config: &illum::power::PowerConfig,
        epochs: &[Epoch],
        step_s: f64,
    ) -> Result<Self, illum::power::PowerError> {
        Ok(PowerTrack {
            battery: illum::power::Battery::new(config),
            config: config.clone(),
            start: epochs.first().copied().unwrap_or_default(),
            step_h: step_s / 3600.0,
            loads: config.loads(epochs)?,
            next: 0,
        })
    }

    /// The next sample (in the order of the epochs given to [`Self::new`]): `(power_w,
    /// battery_wh at the epoch)`.
    pub fn sample(&mut self, epoch: Epoch, r: &SeriesRow) -> (f64, Option<f64>) {
        let years = (epoch - self.start).to_seconds() / (365.25 * 86_400.0);
        let power_w = self.config.power_w(
            r.sun.range_km,
            r.sun.el_deg,
            r.sun.az_deg,
            r.sun_fraction,
            years,
        );
        let load_w = self.loads[self.next.min(self.loads.len() - 1)].at(r.sun_fraction);
        self.next += 1;
        (power_w, self.battery.step(power_w, load_w, self.step_h))
    }

    /// The statistics of the samples so far.
    pub fn stats(&self) -> illum::power::PowerStats {
        self.battery.stats()
    }
}

/// The columns after [`SERIES_CSV_HEADER`] of a run: the link's, then the panel's.
pub fn extra_csv_columns(link: Option<&LinkContext>, config: &SeriesConfig) -> String {
    let mut cols = String::new();
    if let Some(l) = link {
        cols += ",";
        cols += &l.csv_columns();
    }
    if let Some(p) = &config.power {
        cols += ",";
        cols += POWER_CSV_COLUMNS;
        if p.battery_wh.is_some() {
            cols += ",";
            cols += BATTERY_CSV_COLUMN;
        }
    }
    cols
}

/// Scratch space of [`LinkContext::sample`], one per thread.
#[derive(Debug, Default)]
pub struct LinkScratch {
    station_el: Vec<f64>,
    relay: Vec<(f64, f64, f64)>,
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
    /// The ground stations, as `run.json` records them (`None` without).
    pub stations: Option<serde_json::Value>,
}

/// Runs a whole series: horizons, ephemeris, fractions, files (see [`SeriesRun`]).
pub fn run_series(
    kernels: &Kernels,
    stack: &TerrainStack,
    sites: &[Site],
    epochs: &[Epoch],
    step_s: f64,
    config: &SeriesConfig,
    out_dir: &Path,
) -> anyhow::Result<SeriesRun> {
    if sites.is_empty() {
        anyhow::bail!("no sites given");
    }
    // Stations, power and the neighbourhood first: bad settings fail before any work.
    config.stations.resolve(config.station_mask_deg)?;
    if let Some(r) = config.neighbourhood_m {
        neighbourhood::check_radius_m(r)?;
    }
    if let Some(p) = &config.power {
        p.validate()?;
        p.loads(epochs)?;
    }
    let table = ephem::moon_geometry_table(kernels, epochs)?;
    let link = LinkContext::new(kernels, config, &table)?;
    let (horizons, fractions, backend_note) = match config.engine {
        SeriesEngine::Horizon => {
            let (horizons, note) = crate::compute::horizons::site_horizons(
                config.backend,
                stack,
                sites,
                config.az_step_deg,
                config.horizon_method,
            )?;
            (horizons, None, note)
        }
        SeriesEngine::SmapDp => {
            let run = crate::compute::site_dp::site_dp(
                config.backend,
                crate::compute::site_dp::SiteDpRequest {
                    stack,
                    sites,
                    table: &table,
                    profile: crate::compute::site_dp::ProfileParams {
                        az_step_deg: config.az_step_deg,
                        method: config.horizon_method,
                    },
                    limb: config.limb_darkening.law(),
                    abcorr: config.abcorr,
                },
            )?;
            (run.horizons, Some(run.fractions), run.note)
        }
    };
    let hoods = neighbourhoods(stack, sites, config)?;
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("creating output folder {}", out_dir.display()))?;

    let quiet = SeriesConfig {
        write_csv: false,
        plots: false,
        ..config.clone()
    };
    let progress = crate::output::progress_bar(
        sites.len() * epochs.len(),
        "{spinner} series [{bar:30}] {percent}% ({pos}/{len} site-epochs, eta {eta})",
    );
    let shared = Shared {
        table: &table,
        epochs,
        step_s,
        config,
        out_dir,
        progress: &progress,
        link: link.as_ref(),
        stack,
        quiet: &quiet,
    };
    let outcomes: Vec<SiteOutcome> = sites
        .par_iter()
        .zip(horizons)
        .zip(&hoods)
        .enumerate()
        .map(|(i, ((spec, horizon), hood))| {
            let source = match &fractions {
                Some(f) => SiteFractions::Given {
                    sun: &f[i].0,
                    earth: &f[i].1,
                },
                None => SiteFractions::FromHorizon,
            };
            run_one_site(&shared, spec, horizon, source, hood.as_ref())
        })
        .collect::<anyhow::Result<_>>()?;
    progress.finish_and_clear();
    for o in &outcomes {
        report_site(o);
    }

    let mut files: Vec<String> = outcomes.iter().flat_map(|o| o.files.clone()).collect();
    let all: Vec<SiteSeries<'_>> = outcomes
        .iter()
        .map(|o| SiteSeries {
            site: o.site.name(),
            start_utc: epochs[0],
            step_s,
            sun_fraction: &o.sun_fraction,
            earth_fraction: &o.earth_fraction,
        })
        .collect();
    let mut stats = StatsFile::from_series(&all)?;
    for (s, o) in stats.sites.iter_mut().zip(&outcomes) {
        s.location = Some(site_location(&o.site, &o.horizon));
        s.link = o.link.clone();
        s.relay = o.relay.clone();
        s.power = o.power.clone();
        s.neighbourhood = o.neighbourhood.clone();
        s.beyond_dem = o.beyond_dem;
    }
    stats.write_json(&out_dir.join("stats.json"))?;
    files.push("stats.json".into());
    files.extend(super::gis::write_sites(out_dir, &stats.sites)?);
    if config.write_csv {
        write_long_table(&outcomes, out_dir, link.as_ref(), config)?;
        files.push(LONG_TABLE.into());
    }
    Ok(SeriesRun {
        outcomes,
        files,
        backend: backend_note,
        stations: link_record(config)?,
    })
}

/// The link of a run as `run.json` records it (`ground_stations`): the stations and their
/// source, and the relays with their SPKs (path and sha256); `None` with neither.
pub fn link_record(config: &SeriesConfig) -> anyhow::Result<Option<serde_json::Value>> {
    let stations = config.stations.resolve(config.station_mask_deg)?;
    if stations.is_none() && config.relays.is_empty() {
        return Ok(None);
    }
    let mut record = match &stations {
        Some(s) => comms::stations_record(&config.stations, s),
        None => serde_json::json!({}),
    };
    if !config.relays.is_empty() {
        record["relays"] = serde_json::json!(
            config
                .relays
                .iter()
                .map(|r| String::from(r.clone()))
                .collect::<Vec<_>>()
        );
        record["relay_spks"] = serde_json::json!(
            config
                .relay_spks
                .iter()
                .map(|p| match crate::output::InputFile::of(p) {
                    Ok(f) => serde_json::json!(f),
                    Err(_) => serde_json::json!(p.display().to_string()),
                })
                .collect::<Vec<_>>()
        );
        record["relay_max_range_km"] = serde_json::json!(config.relay_max_range_km);
    }
    Ok(Some(record))
}

/// Where a site stands, for `stats.json`: its coordinates, its height above the ground and the
/// ground height its horizon was computed from.
pub fn site_location(site: &Site, horizon: &Horizon) -> illum::stats::SiteLocation {
    illum::stats::SiteLocation {
        lat_deg: site.lat_deg(),
        lon_deg: site.lon_deg(),
        height_above_ground_m: site.height_above_ground_m(),
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
fn write_long_table(
    outcomes: &[SiteOutcome],
    out_dir: &Path,
    link: Option<&LinkContext>,
    config: &SeriesConfig,
) -> anyhow::Result<()> {
    use std::io::BufRead as _;
    crate::output::write_atomic(&out_dir.join(LONG_TABLE), |w| -> anyhow::Result<()> {
        writeln!(
            w,
            "{LONG_TABLE_SITE_COLUMNS},{SERIES_CSV_HEADER}{}",
            extra_csv_columns(link, config)
        )?;
        for o in outcomes {
            let path = out_dir.join(o.site.name()).join("series.csv");
            let file = std::fs::File::open(&path)
                .with_context(|| format!("reading back {}", path.display()))?;
            let prefix = format!(
                "{},{},{},{},{:.3}",
                csv_field(o.site.name()),
                o.site.lat_deg(),
                o.site.lon_deg(),
                o.site.height_above_ground_m(),
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
pub fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) || s.starts_with(' ') || s.ends_with(' ') {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// What every site of a run shares.
struct Shared<'a> {
    table: &'a [MoonGeometry],
    epochs: &'a [Epoch],
    step_s: f64,
    config: &'a SeriesConfig,
    out_dir: &'a Path,
    progress: &'a indicatif::ProgressBar,
    link: Option<&'a LinkContext>,
    stack: &'a TerrainStack,
    /// The run's settings without CSV and plots, for the neighbourhood and the sphere check.
    quiet: &'a SeriesConfig,
}

/// One site's slice of [`run_series`]: its fractions, files and outcome.
fn run_one_site(
    shared: &Shared<'_>,
    spec: &Site,
    horizon: Horizon,
    source: SiteFractions<'_>,
    hood: Option<&HoodHorizons>,
) -> anyhow::Result<SiteOutcome> {
    let Shared {
        table,
        epochs,
        step_s,
        config,
        out_dir,
        progress,
        link,
        ..
    } = *shared;
    let site_dir = out_dir.join(spec.name());
    std::fs::create_dir_all(&site_dir)
        .with_context(|| format!("creating {}", site_dir.display()))?;
    let rel = |f: &str| format!("{}/{f}", spec.name());
    let mut files = Vec::new();
    let site = ephem::Site::new(
        spec.lat_deg(),
        spec.lon_deg(),
        horizon.ground_height_m + spec.height_above_ground_m(),
    )
    .with_context(|| format!("site '{}'", spec.name()))?;

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
    let link_profile = HorizonProfile::new(&horizon.elevation_deg)?;
    let mut links: Vec<LinkSample> =
        Vec::with_capacity(if link.is_some() { epochs.len() } else { 0 });
    let mut scratch = LinkScratch::default();
    let mut power = config
        .power
        .as_ref()
        .map(|p| PowerTrack::new(p, epochs, step_s))
        .transpose()?;
    let mut power_w: Vec<f64> = Vec::new();
    let mut sun_el_deg: Vec<f64> = Vec::with_capacity(epochs.len());
    let mut battery_wh: Vec<f64> = Vec::new();
    let power_needs_az = config
        .power
        .as_ref()
        .is_some_and(|p| p.panel.needs_azimuth());
    let mut compute = |w: Option<&mut dyn Write>| -> anyhow::Result<()> {
        let mut w = w;
        let need_azimuths =
            |k: usize| config.write_csv || power_needs_az || k.is_multiple_of(track_stride);
        let on_row = |k: usize, r: &SeriesRow| -> anyhow::Result<()> {
            let sample =
                link.map(|l| l.sample(table, k, &site, &r.earth, &link_profile, &mut scratch));
            let p = power.as_mut().map(|t| t.sample(epochs[k], r));
            sun_el_deg.push(r.sun.el_deg);
            if let Some((pw, b)) = p
                && config.plots
            {
                power_w.push(pw);
                battery_wh.push(b.unwrap_or(f64::NAN));
            }
            if let Some(w) = w.as_deref_mut() {
                let with = sample.as_ref().zip(link);
                write_row(w, epochs[k], r, with, p)?;
            }
            if let Some(s) = sample {
                links.push(s);
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
        fractions = site_fractions(
            table,
            &site,
            &horizon,
            source,
            config,
            need_azimuths,
            on_row,
        )?;
        progress.inc((epochs.len() % 4096) as u64);
        Ok(())
    };
    if config.write_csv {
        crate::output::write_atomic(&site_dir.join("series.csv"), |w| -> anyhow::Result<()> {
            writeln!(w, "{SERIES_CSV_HEADER}{}", extra_csv_columns(link, config))?;
            compute(Some(w))
        })?;
        files.push(rel("series.csv"));
    } else {
        compute(None)?;
    }
    let (sun_fraction, earth_fraction) = fractions;

    let series = SiteSeries {
        site: spec.name(),
        start_utc: epochs[0],
        step_s,
        sun_fraction: &sun_fraction,
        earth_fraction: &earth_fraction,
    };
    let relay_stats = match link {
        Some(l) => l.relay_summary(&series, &links)?,
        None => None,
    };
    let link_stats = match link {
        Some(l) if l.has_stations() => {
            let (stats, windows) = l.summary(&series, &links)?;
            comms::write_windows_csv(&site_dir.join("dte_windows.csv"), &windows)?;
            comms::write_windows_ics(&site_dir.join("dte_windows.ics"), spec.name(), &windows)?;
            files.extend([rel("dte_windows.csv"), rel("dte_windows.ics")]);
            Some(stats)
        }
        _ => None,
    };
    let power_stats = power.as_ref().map(PowerTrack::stats);
    let mut site_stats = StatsFile::from_series(&[series])?;
    site_stats.sites[0].link = link_stats.clone();
    site_stats.sites[0].relay = relay_stats.clone();
    site_stats.sites[0].power = power_stats.clone();
    let neighbourhood = match hood {
        Some((h, horizons)) => {
            let n = site_neighbourhood(
                shared,
                spec,
                &horizon,
                &site_stats.sites[0],
                h,
                horizons,
                &sun_el_deg,
            )?;
            neighbourhood::write_csv(&site_dir.join(neighbourhood::NEIGHBOURHOOD_CSV), &n.0, &n.1)?;
            files.push(rel(neighbourhood::NEIGHBOURHOOD_CSV));
            Some(n.2)
        }
        None => None,
    };
    let beyond_dem = sphere_effect(shared, spec, &horizon, &site_stats.sites[0])?;
    site_stats.sites[0].neighbourhood = neighbourhood.clone();
    site_stats.sites[0].beyond_dem = beyond_dem;
    site_stats.write_json(&site_dir.join("stats.json"))?;
    files.push(rel("stats.json"));

    if config.plots {
        let profile = HorizonProfile::new(&horizon.elevation_deg)?;
        let tracks = illum::plot::SkyTracks {
            sun_az_el_deg: &sun_track,
            earth_az_el_deg: &earth_track,
        };
        let title = format!(
            "{} ({:.3}°, {:.3}°), {:.1} m above ground",
            spec.name(),
            spec.lat_deg(),
            spec.lon_deg(),
            spec.height_above_ground_m()
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
            &format!("Horizon (polar): {}", spec.name()),
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
        if let Some(p) = &config.power {
            let night: Vec<bool> = sun_fraction.iter().map(|&f| f <= 0.0).collect();
            illum::plot::write_power_plot(
                &site_dir.join("power.png"),
                &format!("Panel power ({}) and battery: {title}", p.panel.name()),
                epochs[0],
                step_s,
                &power_w,
                p.battery_wh.is_some().then_some(battery_wh.as_slice()),
                &night,
                (1400, if p.battery_wh.is_some() { 800 } else { 450 }),
            )?;
            files.push(rel("power.png"));
        }
        if let Some(l) = link {
            // The link's windows as bars beside sunlight.
            let lit: Vec<bool> = sun_fraction.iter().map(|&f| f > 0.0).collect();
            let dte: Vec<bool> = links.iter().map(LinkSample::dte).collect();
            let relay: Vec<bool> = links.iter().map(|s| s.relay_visible).collect();
            let both: Vec<bool> = lit.iter().zip(&dte).map(|(a, b)| *a && *b).collect();
            let mut rows = vec![illum::plot::WindowRow {
                label: "Sun",
                on: &lit,
                rgb: (230, 130, 0),
            }];
            if l.has_stations() {
                rows.push(illum::plot::WindowRow {
                    label: "DTE",
                    on: &dte,
                    rgb: (30, 90, 200),
                });
                rows.push(illum::plot::WindowRow {
                    label: "Sun+DTE",
                    on: &both,
                    rgb: (40, 150, 60),
                });
            }
            if !l.relays().is_empty() {
                rows.push(illum::plot::WindowRow {
                    label: "relay",
                    on: &relay,
                    rgb: (140, 60, 160),
                });
            }
            illum::plot::write_windows_plot(
                &site_dir.join("dte_windows.png"),
                &format!("Sunlight and links: {title}"),
                epochs[0],
                step_s,
                &rows,
                (1400, 120 + 70 * rows.len() as u32),
            )?;
            files.push(rel("dte_windows.png"));
        }
    }
    Ok(SiteOutcome {
        site: spec.clone(),
        horizon,
        sun_fraction,
        earth_fraction,
        sun_el_deg,
        link: link_stats,
        relay: relay_stats,
        power: power_stats,
        dte: match link {
            Some(l) if l.has_stations() => links.iter().map(LinkSample::dte).collect(),
            _ => Vec::new(),
        },
        neighbourhood,
        beyond_dem,
        files,
    })
}

/// A site's neighbourhood and the horizon of each of its pixels.
type HoodHorizons = (SiteNeighbourhood, Vec<Horizon>);

/// Each site's neighbourhood ([`neighbourhood::neighbour_pixels`]) with the horizons of its
/// pixels, computed together (one batch on the run's backend).
fn neighbourhoods(
    stack: &TerrainStack,
    sites: &[Site],
    config: &SeriesConfig,
) -> anyhow::Result<Vec<Option<HoodHorizons>>> {
    // The default (no radius given) is for a planner's handful of sites: a ranking of many
    // sites is its own neighbourhood, and would pay ~29 series per site.
    if config.neighbourhood_m.is_none() && sites.len() > neighbourhood::DEFAULT_MAX_SITES {
        crate::note!(
            "penumbra: {} sites: no neighbourhoods by default beyond {} sites (give --neighbourhood-m to ask for them)",
            sites.len(),
            neighbourhood::DEFAULT_MAX_SITES
        );
        return Ok(vec![None; sites.len()]);
    }
    let hoods = sites
        .iter()
        .map(|s| neighbourhood::neighbour_pixels(stack, s, config.neighbourhood_m))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let all: Vec<Site> = hoods
        .iter()
        .flatten()
        .flat_map(|h| h.pixels.iter().map(|p| p.0.clone()))
        .collect();
    let mut horizons = if all.is_empty() {
        Vec::new()
    } else {
        crate::compute::horizons::site_horizons(
            config.backend,
            stack,
            &all,
            config.az_step_deg,
            config.horizon_method,
        )?
        .0
    }
    .into_iter();
    Ok(hoods
        .into_iter()
        .map(|h| {
            h.map(|h| {
                let n = h.pixels.len();
                let hs: Vec<Horizon> = horizons.by_ref().take(n).collect();
                (h, hs)
            })
        })
        .collect())
}

/// The statistics of one point's series from its horizon (no files written).
fn point_stats(
    shared: &Shared<'_>,
    name: &str,
    (lat_deg, lon_deg, height_above_ground_m): (f64, f64, f64),
    horizon: &Horizon,
) -> anyhow::Result<illum::stats::SiteStats> {
    let site = ephem::Site::new(
        lat_deg,
        lon_deg,
        horizon.ground_height_m + height_above_ground_m,
    )?;
    let (sun, earth) = site_fractions(
        shared.table,
        &site,
        horizon,
        SiteFractions::FromHorizon,
        shared.quiet,
        |_| false,
        |_, _| Ok(()),
    )?;
    let series = SiteSeries {
        site: name,
        start_utc: shared.epochs[0],
        step_s: shared.step_s,
        sun_fraction: &sun,
        earth_fraction: &earth,
    };
    Ok(StatsFile::from_series(&[series])?.sites.remove(0))
}

/// The site's neighbourhood: the site's own spot, every pixel's, and the summary.
fn site_neighbourhood(
    shared: &Shared<'_>,
    spec: &Site,
    horizon: &Horizon,
    here_stats: &illum::stats::SiteStats,
    hood: &SiteNeighbourhood,
    horizons: &[Horizon],
    sun_el_deg: &[f64],
) -> anyhow::Result<(
    illum::stats::SpotStats,
    Vec<illum::stats::SpotStats>,
    illum::stats::Neighbourhood,
)> {
    let here = neighbourhood::spot(
        (spec.lat_deg(), spec.lon_deg()),
        (0.0, 0.0),
        horizon.ground_height_m,
        here_stats,
    );
    let spots = hood
        .pixels
        .par_iter()
        .zip(horizons)
        .map(|((p, distance_m, bearing_deg), h)| {
            let s = point_stats(
                shared,
                p.name(),
                (p.lat_deg(), p.lon_deg(), p.height_above_ground_m()),
                h,
            )?;
            Ok(neighbourhood::spot(
                (p.lat_deg(), p.lon_deg()),
                (*distance_m, *bearing_deg),
                h.ground_height_m,
                &s,
            ))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let nearness = neighbourhood::sun_horizon_nearness(
        horizon,
        sun_el_deg,
        illum::stats::NEAR_HORIZON_PX * hood.px_m,
    );
    let summary = neighbourhood::summarise(spec, &here, hood, &spots, nearness);
    Ok((here, spots, summary))
}

/// What a bare sphere beyond the DEM would change at the site: its horizon raised to the
/// sphere's floor ([`crate::horizon::beyond::sphere_floor_deg`]) and the statistics again,
/// compared with `here` (the site's own statistics: those of `horizon` for the horizon engine);
/// `None` when the floor raises no azimuth or changes neither percentage.
fn sphere_effect(
    shared: &Shared<'_>,
    spec: &Site,
    horizon: &Horizon,
    here: &illum::stats::SiteStats,
) -> anyhow::Result<Option<illum::stats::BeyondDemEffect>> {
    let floor = crate::horizon::beyond::sphere_floor_deg(shared.stack, horizon);
    let raised = horizon
        .elevation_deg
        .iter()
        .zip(&floor)
        .filter(|(e, f)| e < f)
        .count();
    if raised == 0 {
        return Ok(None);
    }
    let mut floored = horizon.clone();
    for (e, f) in floored.elevation_deg.iter_mut().zip(&floor) {
        *e = e.max(*f);
    }
    let location = (spec.lat_deg(), spec.lon_deg(), spec.height_above_ground_m());
    let with = point_stats(shared, spec.name(), location, &floored)?;
    // The horizon engine's own statistics are those of this horizon; smap-dp's are not, so
    // its comparison takes the unraised horizon's.
    let without_owned;
    let without = match shared.config.engine {
        SeriesEngine::Horizon => here,
        SeriesEngine::SmapDp => {
            without_owned = point_stats(shared, spec.name(), location, horizon)?;
            &without_owned
        }
    };
    let effect = illum::stats::BeyondDemEffect {
        azimuths_raised_pct: 100.0 * raised as f64 / floor.len() as f64,
        sun_visible_pct_with_sphere: with.sun_visible_pct,
        earth_visible_pct_with_sphere: with.earth_visible_pct,
    };
    let changed = (with.sun_visible_pct - without.sun_visible_pct).abs() >= 0.005
        || (with.earth_visible_pct - without.earth_visible_pct).abs() >= 0.005;
    Ok(changed.then_some(effect))
}

/// Says what a site gave (one line) and, on stderr whatever the verbosity, its cautions and
/// what the Moon beyond the DEM would change.
fn report_site(o: &SiteOutcome) {
    let n = o.sun_fraction.len().max(1) as f64;
    let pct = |f: &[f64]| {
        100.0
            * f.iter()
                .filter(|&&x| x > illum::stats::VISIBLE_MIN_FRACTION)
                .count() as f64
            / n
    };
    let hood = o
        .neighbourhood
        .as_ref()
        .map(|h| {
            format!(
                "; within {:.0} m ({} px): Sun {:.1}–{:.1} %, best {:.1} % {:.0} m away",
                h.radius_m,
                h.pixels,
                h.sun_visible_pct.min,
                h.sun_visible_pct.max,
                h.best.sun_visible_pct,
                h.best.distance_m
            )
        })
        .unwrap_or_default();
    crate::note!(
        "penumbra: {}: Sun visible {:.1} %, Earth visible {:.1} %{hood}",
        o.site.name(),
        pct(&o.sun_fraction),
        pct(&o.earth_fraction)
    );
    for c in o.neighbourhood.iter().flat_map(|h| &h.cautions) {
        eprintln!("penumbra: caution: {c}");
    }
    if let Some(b) = o.beyond_dem {
        let mut changes = Vec::new();
        for (body, with, without) in [
            ("Sun", b.sun_visible_pct_with_sphere, pct(&o.sun_fraction)),
            (
                "Earth",
                b.earth_visible_pct_with_sphere,
                pct(&o.earth_fraction),
            ),
        ] {
            if (with - without).abs() >= 0.005 {
                changes.push(format!(
                    "the {body} visible {with:.2} % of the time, not {without:.2} %"
                ));
            }
        }
        eprintln!(
            "penumbra: warning: site '{}': rays leave the DEM below the sphere on {:.0} % of its azimuths; with a bare sphere beyond the DEM: {} (add a far-field layer)",
            o.site.name(),
            b.azimuths_raised_pct,
            changes.join(", ")
        );
    }
}

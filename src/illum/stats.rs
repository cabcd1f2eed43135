//! Time-weighted statistics of per-site visibility series, written as `stats.json`.
//!
//! **Time weighting.** A series is sampled on a uniform grid `t_k = start + k · step`,
//! `k = 0..n`. Sample `k` stands for the interval `[t_k, t_k + step)`, so every sample weighs one
//! step, percentages are sample counts / n · 100, and a run of `m` consecutive samples that meet a
//! condition is a window from `t_k` to `t_k + m · step`, `m · step` long. Window lengths are thus
//! resolved to ±1 step (the true event can start up to one step earlier or end up to one step
//! later than sampled). A window that touches the first or last sample may be cut by the ends of
//! the series (its true length can be longer). Ties: the earliest longest window is reported.
//!
//! **Thresholds** (constants below, recorded in the file's `definitions`):
//! * Sun *fully visible*: fraction ≥ [`SUN_FULL_MIN_FRACTION`] (0.999: the hidden part is a
//!   sliver of at most 0.1% of the disc);
//! * *visible* (Sun or Earth, any part): fraction > [`VISIBLE_MIN_FRACTION`] (1e-9, i.e.
//!   numerically non-zero); *partly visible* = visible but not fully;
//! * *dark* (Sun) / *hidden* (Earth): not visible;
//! * *low Sun*: fraction < [`LOW_SUN_MAX_FRACTION`] (10%, dark included).
//!
//! Combined figures for a set of sites sharing one time grid: "at least one site lit" (any site's
//! Sun visible) and the longest darkness of the union (every site dark at once).

use std::path::Path;

use hifitime::{Duration, Epoch};
use serde::{Deserialize, Serialize};

use super::IllumError;

/// Minimum visible fraction for the Sun to count as fully visible.
pub const SUN_FULL_MIN_FRACTION: f64 = 0.999;
/// A disc counts as visible (any part) when its fraction exceeds this.
pub const VISIBLE_MIN_FRACTION: f64 = 1e-9;
/// The "low Sun" threshold: fraction strictly below 10%.
pub const LOW_SUN_MAX_FRACTION: f64 = 0.10;

/// One site's series on a uniform time grid.
#[derive(Debug, Clone, Copy)]
pub struct SiteSeries<'a> {
    /// Site name (copied into the statistics).
    pub site: &'a str,
    /// Epoch of the first sample.
    pub start_utc: Epoch,
    /// Time step between samples, seconds.
    pub step_s: f64,
    /// Visible (flux) fraction of the Sun's disc per sample, 0..=1.
    pub sun_fraction: &'a [f64],
    /// Visible fraction of the Earth's disc per sample, 0..=1.
    pub earth_fraction: &'a [f64],
}

impl SiteSeries<'_> {
    fn validate(&self) -> Result<(), IllumError> {
        let n = self.sun_fraction.len();
        if n == 0 {
            return Err(IllumError::EmptySeries {
                site: self.site.to_string(),
            });
        }
        if !(self.step_s > 0.0 && self.step_s.is_finite()) {
            return Err(IllumError::BadStep {
                step_s: self.step_s,
            });
        }
        if self.earth_fraction.len() != n {
            return Err(IllumError::LengthMismatch {
                site: self.site.to_string(),
                what: "earth_fraction",
                got: self.earth_fraction.len(),
                expected: n,
            });
        }
        Ok(())
    }

    /// Epoch of the start of sample `k` (`k = n` gives the end of the series).
    fn epoch_at(&self, k: usize) -> Epoch {
        let offset_s = k as f64 * self.step_s;
        self.start_utc + Duration::from_seconds(offset_s)
    }
}

/// A time window of consecutive samples (see the module docs for the weighting).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    /// Its first sample.
    pub first: usize,
    /// Its number of samples.
    pub len: usize,
}

/// The earliest longest run of consecutive indices in `0..n` for which `pred` holds.
pub fn longest_run(n: usize, pred: impl Fn(usize) -> bool) -> Option<Run> {
    let mut best: Option<Run> = None;
    let mut cur_first = 0;
    let mut cur_len = 0;
    for k in 0..n {
        if pred(k) {
            if cur_len == 0 {
                cur_first = k;
            }
            cur_len += 1;
            if best.is_none_or(|b| cur_len > b.len) {
                best = Some(Run {
                    first: cur_first,
                    len: cur_len,
                });
            }
        } else {
            cur_len = 0;
        }
    }
    best
}

/// Percentage of samples in `0..n` for which `pred` holds.
fn pct(n: usize, pred: impl Fn(usize) -> bool) -> f64 {
    let count = (0..n).filter(|&k| pred(k)).count();
    100.0 * count as f64 / n as f64
}

/// A window's duration (h) and start/end UTC strings, or 0 h and `None`s if there is none.
fn window(series: &SiteSeries<'_>, run: Option<Run>) -> (f64, Option<String>, Option<String>) {
    match run {
        Some(r) => {
            let hours = r.len as f64 * series.step_s / 3600.0;
            (
                hours,
                Some(crate::ephem::time::format_iso(series.epoch_at(r.first))),
                Some(crate::ephem::time::format_iso(
                    series.epoch_at(r.first + r.len),
                )),
            )
        }
        None => (0.0, None, None),
    }
}

/// Where a site stands, as written into `stats.json` next to its statistics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SiteLocation {
    /// Planetocentric latitude, degrees.
    pub lat_deg: f64,
    /// East longitude, degrees.
    pub lon_deg: f64,
    /// Observer height above the ground, metres.
    pub height_above_ground_m: f64,
    /// Ground height above the 1737.4 km sphere at the site (from the finest layer), metres.
    pub ground_height_m: f64,
}

/// Time-weighted statistics of one site's series. Percentages are of the whole series (0–100);
/// durations in hours; times ISO 8601 UTC; `None` where no such window exists.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SiteStats {
    /// Site name.
    pub site: String,
    /// Where the site stands (filled in by the series runner; absent for bare fraction series).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub location: Option<SiteLocation>,
    /// Start of the first sample (UTC).
    pub start_utc: String,
    /// End of the last sample's interval, `start + n · step` (UTC).
    pub end_utc: String,
    /// Time step, seconds.
    pub step_s: f64,
    /// Number of samples.
    pub samples: usize,
    /// Length of the series, `n · step`, hours.
    pub span_h: f64,
    /// % of time the Sun is fully visible (fraction ≥ 0.999).
    pub sun_full_pct: f64,
    /// % of time the Sun is partly visible (visible, not fully).
    pub sun_partial_pct: f64,
    /// % of time any part of the Sun is visible (full + partial).
    pub sun_visible_pct: f64,
    /// % of time the Sun is entirely hidden.
    pub sun_dark_pct: f64,
    /// Time-mean visible fraction of the Sun (0–1).
    pub sun_mean_visible_fraction: f64,
    /// Longest continuous darkness (Sun entirely hidden), hours.
    pub longest_dark_h: f64,
    /// Start of the longest darkness (UTC).
    pub longest_dark_start_utc: Option<String>,
    /// End of the longest darkness (UTC).
    pub longest_dark_end_utc: Option<String>,
    /// Longest stretch with less than 10% of the Sun visible (darkness included), hours.
    pub longest_below_10pct_h: f64,
    /// Start of that stretch (UTC).
    pub longest_below_10pct_start_utc: Option<String>,
    /// End of that stretch (UTC).
    pub longest_below_10pct_end_utc: Option<String>,
    /// % of time any part of the Earth is visible.
    pub earth_visible_pct: f64,
    /// Time-mean visible fraction of the Earth (0–1).
    pub earth_mean_visible_fraction: f64,
    /// Longest continuous window with the Earth (partly) visible, hours.
    pub longest_earth_visible_h: f64,
    /// Start of that window (UTC).
    pub longest_earth_visible_start_utc: Option<String>,
    /// End of that window (UTC).
    pub longest_earth_visible_end_utc: Option<String>,
    /// Longest continuous window with the Earth entirely hidden, hours.
    pub longest_earth_hidden_h: f64,
    /// Start of that window (UTC).
    pub longest_earth_hidden_start_utc: Option<String>,
    /// End of that window (UTC).
    pub longest_earth_hidden_end_utc: Option<String>,
    /// % of time both the Sun and the Earth are (at least partly) visible.
    pub sun_and_earth_pct: f64,
    /// The link to Earth through ground stations (absent when the run has no stations).
    #[serde(default, flatten, skip_serializing_if = "Option::is_none")]
    pub link: Option<LinkStats>,
    /// The relays (absent when the run has none).
    #[serde(default, flatten, skip_serializing_if = "Option::is_none")]
    pub relay: Option<RelayStats>,
    /// Solar power and battery (absent when the run has no panel).
    #[serde(default, flatten, skip_serializing_if = "Option::is_none")]
    pub power: Option<super::power::PowerStats>,
    /// The same statistics over the pixels around the site, the best spot among them and the
    /// cautions they raise (absent when the run asks for none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub neighbourhood: Option<Neighbourhood>,
    /// What a bare sphere beyond the DEM would change (absent when the DEM holds every ray
    /// that matters).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beyond_dem: Option<BeyondDemEffect>,
}

/// A statistic at the site and its spread over the site's neighbourhood.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// At the site itself.
    pub here: f64,
    /// The smallest over the neighbourhood's pixels and the site.
    pub min: f64,
    /// The median over the neighbourhood's pixels and the site.
    pub median: f64,
    /// The largest over the neighbourhood's pixels and the site.
    pub max: f64,
}

impl Spread {
    /// The spread of `values` (not empty), `here` the site's own value.
    pub fn of(here: f64, values: &[f64]) -> Self {
        let mut v: Vec<f64> = values.iter().copied().chain([here]).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Spread {
            here,
            min: v[0],
            median,
            max: v[n - 1],
        }
    }

    /// `max − min`.
    pub fn range(&self) -> f64 {
        self.max - self.min
    }
}

/// One point of a neighbourhood: where it is and its key statistics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpotStats {
    /// Planetocentric latitude, degrees.
    pub lat_deg: f64,
    /// East longitude, degrees.
    pub lon_deg: f64,
    /// Ground distance from the site (on the 1737.4 km sphere), metres.
    pub distance_m: f64,
    /// Direction from the site, degrees clockwise from north.
    pub bearing_deg: f64,
    /// Ground height above the sphere, metres.
    pub ground_height_m: f64,
    /// % of time any part of the Sun is visible.
    pub sun_visible_pct: f64,
    /// Time-mean visible fraction of the Sun (0–1).
    pub sun_mean_visible_fraction: f64,
    /// Longest continuous darkness, hours.
    pub longest_dark_h: f64,
    /// % of time any part of the Earth is visible.
    pub earth_visible_pct: f64,
}

/// How a site's statistics vary over the pixels around it (`docs/sites.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Neighbourhood {
    /// Radius of the neighbourhood, metres.
    pub radius_m: f64,
    /// The layer whose pixel centres make the neighbourhood (the finest under the site).
    pub layer: String,
    /// That layer's pixel size, metres.
    pub px_m: f64,
    /// Number of pixel centres within the radius.
    pub pixels: usize,
    /// % of time any part of the Sun is visible.
    pub sun_visible_pct: Spread,
    /// Time-mean visible fraction of the Sun.
    pub sun_mean_visible_fraction: Spread,
    /// Longest continuous darkness, hours.
    pub longest_dark_h: Spread,
    /// % of time any part of the Earth is visible.
    pub earth_visible_pct: Spread,
    /// The point with the most Sun (ties: the nearest), the site itself included.
    pub best: SpotStats,
    /// Ground distance to the nearest terrain that sets the horizon where the Sun goes behind
    /// it (azimuths whose horizon is above the Sun's lowest elevation), metres.
    pub nearest_sun_horizon_m: f64,
    /// % of those azimuths whose horizon is set by ground within [`NEAR_HORIZON_PX`] pixels.
    pub near_sun_horizon_pct: f64,
    /// One line per reason to doubt the value at the typed point (empty when there is none).
    pub cautions: Vec<String>,
}

/// A horizon set by ground within this many pixels of the site is "near": the result then
/// rests on the DEM at pixel scale.
pub const NEAR_HORIZON_PX: f64 = 3.0;

/// What a bare sphere beyond the outermost layer would change at a site: rays toward the Sun
/// leave the layers below the sphere, so the Moon there would hide what the DEM shows lit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BeyondDemEffect {
    /// % of the horizon's azimuths whose horizon the sphere beyond the DEM would raise.
    pub azimuths_raised_pct: f64,
    /// % of time any part of the Sun is visible with the sphere beyond the DEM.
    pub sun_visible_pct_with_sphere: f64,
    /// % of time any part of the Earth is visible with the sphere beyond the DEM.
    pub earth_visible_pct_with_sphere: f64,
}

/// Statistics of a site's relays: a relay visible (above the terrain horizon, within range),
/// and any link (DTE or a relay).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RelayStats {
    /// % of time a relay is visible.
    pub relay_pct: f64,
    /// Longest time without a visible relay, hours.
    pub longest_relay_blackout_h: f64,
    /// Number of relay windows.
    pub relay_windows: usize,
    /// % of time with a link: DTE or a relay (the relays alone without stations).
    pub link_pct: f64,
    /// Longest time without any link, hours.
    pub longest_link_blackout_h: f64,
}

/// Relay statistics of `series` (its time grid): `relay[k]` a relay visible, `dte[k]` DTE (if the
/// run has stations).
pub fn relay_stats(
    series: &SiteSeries<'_>,
    relay: &[bool],
    dte: Option<&[bool]>,
) -> Result<RelayStats, IllumError> {
    series.validate()?;
    let n = series.sun_fraction.len();
    if relay.len() != n || dte.is_some_and(|d| d.len() != n) {
        return Err(IllumError::LengthMismatch {
            site: series.site.to_string(),
            what: "relay",
            got: relay.len(),
            expected: n,
        });
    }
    let link = |k: usize| relay[k] || dte.is_some_and(|d| d[k]);
    Ok(RelayStats {
        relay_pct: pct(n, |k| relay[k]),
        longest_relay_blackout_h: window(series, longest_run(n, |k| !relay[k])).0,
        relay_windows: (0..n)
            .filter(|&k| relay[k] && (k == 0 || !relay[k - 1]))
            .count(),
        link_pct: pct(n, link),
        longest_link_blackout_h: window(series, longest_run(n, |k| !link(k))).0,
    })
}

/// A site's link to Earth per sample (`crate::comms`): DTE, a station sees the site, the Earth's
/// centre is above the terrain horizon.
#[derive(Debug, Clone, Copy)]
pub struct LinkSeries<'a> {
    /// Direct-to-Earth: the Earth's centre above the terrain horizon and a station above its mask.
    pub dte: &'a [bool],
    /// A station sees the site above its mask.
    pub station: &'a [bool],
    /// The Earth's centre is above the terrain horizon.
    pub earth_centre: &'a [bool],
}

/// Statistics of a site's link to Earth (see [`LinkSeries`]); weighting as for the rest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkStats {
    /// % of time with DTE.
    pub dte_pct: f64,
    /// Longest time without DTE, hours.
    pub longest_dte_blackout_h: f64,
    /// Start of the longest blackout (UTC).
    pub longest_dte_blackout_start_utc: Option<String>,
    /// End of the longest blackout (UTC).
    pub longest_dte_blackout_end_utc: Option<String>,
    /// Number of DTE windows (runs of consecutive samples with DTE).
    pub dte_windows: usize,
    /// Mean length of a DTE window, hours (0 without windows).
    pub mean_dte_window_h: f64,
    /// % of time a station sees the site above its mask (the terrain ignored).
    pub station_pct: f64,
    /// % of time the Earth's centre is above the terrain horizon (stations ignored).
    pub earth_centre_visible_pct: f64,
    /// % of time with DTE while (part of) the Sun is visible.
    pub sun_and_dte_pct: f64,
}

/// Link statistics of `series` (its Sun fractions and time grid) with `link`.
pub fn link_stats(series: &SiteSeries<'_>, link: &LinkSeries<'_>) -> Result<LinkStats, IllumError> {
    series.validate()?;
    let n = series.sun_fraction.len();
    for (what, v) in [
        ("dte", link.dte),
        ("station", link.station),
        ("earth_centre", link.earth_centre),
    ] {
        if v.len() != n {
            return Err(IllumError::LengthMismatch {
                site: series.site.to_string(),
                what,
                got: v.len(),
                expected: n,
            });
        }
    }
    let dte = link.dte;
    let (longest_dte_blackout_h, longest_dte_blackout_start_utc, longest_dte_blackout_end_utc) =
        window(series, longest_run(n, |k| !dte[k]));
    let windows = (0..n)
        .filter(|&k| dte[k] && (k == 0 || !dte[k - 1]))
        .count();
    let dte_samples = dte.iter().filter(|&&d| d).count();
    Ok(LinkStats {
        dte_pct: pct(n, |k| dte[k]),
        longest_dte_blackout_h,
        longest_dte_blackout_start_utc,
        longest_dte_blackout_end_utc,
        dte_windows: windows,
        mean_dte_window_h: if windows == 0 {
            0.0
        } else {
            dte_samples as f64 * series.step_s / 3600.0 / windows as f64
        },
        station_pct: pct(n, |k| link.station[k]),
        earth_centre_visible_pct: pct(n, |k| link.earth_centre[k]),
        sun_and_dte_pct: pct(n, |k| {
            dte[k] && series.sun_fraction[k] > VISIBLE_MIN_FRACTION
        }),
    })
}

/// Statistics of one site's series.
fn site_stats(series: &SiteSeries<'_>) -> Result<SiteStats, IllumError> {
    series.validate()?;
    let sun = series.sun_fraction;
    let earth = series.earth_fraction;
    let n = sun.len();
    let sun_vis = |k: usize| sun[k] > VISIBLE_MIN_FRACTION;
    let earth_vis = |k: usize| earth[k] > VISIBLE_MIN_FRACTION;
    let (nf, span_h) = (n as f64, n as f64 * series.step_s / 3600.0);

    let (longest_dark_h, longest_dark_start_utc, longest_dark_end_utc) =
        window(series, longest_run(n, |k| !sun_vis(k)));
    let (longest_below_10pct_h, longest_below_10pct_start_utc, longest_below_10pct_end_utc) =
        window(series, longest_run(n, |k| sun[k] < LOW_SUN_MAX_FRACTION));
    let (longest_earth_visible_h, longest_earth_visible_start_utc, longest_earth_visible_end_utc) =
        window(series, longest_run(n, earth_vis));
    let (longest_earth_hidden_h, longest_earth_hidden_start_utc, longest_earth_hidden_end_utc) =
        window(series, longest_run(n, |k| !earth_vis(k)));

    let sun_full_pct = pct(n, |k| sun[k] >= SUN_FULL_MIN_FRACTION);
    let sun_visible_pct = pct(n, sun_vis);
    Ok(SiteStats {
        site: series.site.to_string(),
        location: None,
        start_utc: crate::ephem::time::format_iso(series.start_utc),
        end_utc: crate::ephem::time::format_iso(series.epoch_at(n)),
        step_s: series.step_s,
        samples: n,
        span_h,
        sun_full_pct,
        sun_partial_pct: pct(n, |k| sun_vis(k) && sun[k] < SUN_FULL_MIN_FRACTION),
        sun_visible_pct,
        sun_dark_pct: pct(n, |k| !sun_vis(k)),
        sun_mean_visible_fraction: sun.iter().sum::<f64>() / nf,
        longest_dark_h,
        longest_dark_start_utc,
        longest_dark_end_utc,
        longest_below_10pct_h,
        longest_below_10pct_start_utc,
        longest_below_10pct_end_utc,
        earth_visible_pct: pct(n, earth_vis),
        earth_mean_visible_fraction: earth.iter().sum::<f64>() / nf,
        longest_earth_visible_h,
        longest_earth_visible_start_utc,
        longest_earth_visible_end_utc,
        longest_earth_hidden_h,
        longest_earth_hidden_start_utc,
        longest_earth_hidden_end_utc,
        sun_and_earth_pct: pct(n, |k| sun_vis(k) && earth_vis(k)),
        link: None,
        relay: None,
        power: None,
        neighbourhood: None,
        beyond_dem: None,
    })
}

/// Combined figures for a set of sites on one time grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CombinedStats {
    /// The sites combined.
    pub sites: Vec<String>,
    /// % of time at least one site sees (part of) the Sun.
    pub any_sun_visible_pct: f64,
    /// % of time at least one site sees the Sun fully.
    pub any_sun_full_pct: f64,
    /// Longest window with every site dark at once (the union's darkness), hours.
    pub longest_all_dark_h: f64,
    /// Start of that window (UTC).
    pub longest_all_dark_start_utc: Option<String>,
    /// End of that window (UTC).
    pub longest_all_dark_end_utc: Option<String>,
    /// % of time at least one site sees (part of) the Earth.
    pub any_earth_visible_pct: f64,
    /// Longest window with the Earth hidden from every site at once, hours.
    pub longest_all_earth_hidden_h: f64,
    /// Start of that window (UTC).
    pub longest_all_earth_hidden_start_utc: Option<String>,
    /// End of that window (UTC).
    pub longest_all_earth_hidden_end_utc: Option<String>,
}

/// Combined statistics of several sites; they must share start epoch, step and length.
fn combined_stats(all: &[SiteSeries<'_>]) -> Result<CombinedStats, IllumError> {
    let Some(first) = all.first() else {
        return Err(IllumError::EmptySeries {
            site: "(no sites)".to_string(),
        });
    };
    for s in all {
        s.validate()?;
        if s.start_utc != first.start_utc
            || s.step_s != first.step_s
            || s.sun_fraction.len() != first.sun_fraction.len()
        {
            return Err(IllumError::MismatchedGrids {
                site: s.site.to_string(),
            });
        }
    }
    let n = first.sun_fraction.len();
    let any_sun = |k: usize| all.iter().any(|s| s.sun_fraction[k] > VISIBLE_MIN_FRACTION);
    let any_earth = |k: usize| {
        all.iter()
            .any(|s| s.earth_fraction[k] > VISIBLE_MIN_FRACTION)
    };
    let (longest_all_dark_h, longest_all_dark_start_utc, longest_all_dark_end_utc) =
        window(first, longest_run(n, |k| !any_sun(k)));
    let (
        longest_all_earth_hidden_h,
        longest_all_earth_hidden_start_utc,
        longest_all_earth_hidden_end_utc,
    ) = window(first, longest_run(n, |k| !any_earth(k)));
    Ok(CombinedStats {
        sites: all.iter().map(|s| s.site.to_string()).collect(),
        any_sun_visible_pct: pct(n, any_sun),
        any_sun_full_pct: pct(n, |k| {
            all.iter()
                .any(|s| s.sun_fraction[k] >= SUN_FULL_MIN_FRACTION)
        }),
        longest_all_dark_h,
        longest_all_dark_start_utc,
        longest_all_dark_end_utc,
        any_earth_visible_pct: pct(n, any_earth),
        longest_all_earth_hidden_h,
        longest_all_earth_hidden_start_utc,
        longest_all_earth_hidden_end_utc,
    })
}

/// The thresholds and weighting used, recorded in `stats.json` so the file is self-describing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatsDefinitions {
    /// Sun fully visible: fraction ≥ this.
    pub sun_full_min_fraction: f64,
    /// Visible (any part): fraction > this.
    pub visible_min_fraction: f64,
    /// Low Sun: fraction < this.
    pub low_sun_max_fraction: f64,
    /// How samples are weighted in time.
    pub time_weighting: String,
}

impl Default for StatsDefinitions {
    fn default() -> Self {
        Self {
            sun_full_min_fraction: SUN_FULL_MIN_FRACTION,
            visible_min_fraction: VISIBLE_MIN_FRACTION,
            low_sun_max_fraction: LOW_SUN_MAX_FRACTION,
            time_weighting: "each sample stands for [t, t + step); a run of m samples lasts \
                             m * step (resolution +-1 step); windows touching the series ends \
                             may be cut by them"
                .to_string(),
        }
    }
}

/// The `schema` of `stats.json` files this penumbra writes: bumped when a field changes meaning
/// or goes away (new fields keep the number).
pub const STATS_SCHEMA: &str = "penumbra-stats/1";

fn stats_schema() -> String {
    STATS_SCHEMA.to_string()
}

/// The content of `stats.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatsFile {
    /// The file's schema and version ([`STATS_SCHEMA`]).
    #[serde(default = "stats_schema")]
    pub schema: String,
    /// Thresholds and weighting.
    pub definitions: StatsDefinitions,
    /// Per-site statistics.
    pub sites: Vec<SiteStats>,
    /// Combined figures when there is more than one site.
    pub combined: Option<CombinedStats>,
}

impl StatsFile {
    /// Per-site statistics for every series, plus the combined figures when there are ≥ 2.
    pub fn from_series(all: &[SiteSeries<'_>]) -> Result<Self, IllumError> {
        let sites = all.iter().map(site_stats).collect::<Result<Vec<_>, _>>()?;
        let combined = if all.len() >= 2 {
            Some(combined_stats(all)?)
        } else {
            None
        };
        Ok(Self {
            schema: stats_schema(),
            definitions: StatsDefinitions::default(),
            sites,
            combined,
        })
    }

    /// Writes the statistics as pretty JSON, atomically, each number to the precision of its
    /// unit ([`crate::output::round_json_numbers`]).
    pub fn write_json(&self, path: &Path) -> Result<(), IllumError> {
        let mut value = serde_json::to_value(self)?;
        crate::output::round_json_numbers(&mut value);
        let mut bytes = serde_json::to_vec_pretty(&value)?;
        bytes.push(b'\n');
        crate::output::write_bytes_atomic(path, &bytes)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start() -> Epoch {
        Epoch::from_gregorian_utc_at_midnight(2024, 1, 1)
    }

    #[test]
    fn longest_run_is_earliest_longest() {
        let v = [1, 0, 0, 1, 0, 0, 1, 0];
        let r = longest_run(v.len(), |k| v[k] == 0).unwrap();
        assert_eq!(r, Run { first: 1, len: 2 });
        assert_eq!(longest_run(3, |_| false), None);
        assert_eq!(longest_run(3, |_| true), Some(Run { first: 0, len: 3 }));
    }

    /// Hand-made hourly series of 10 samples; every answer counted by hand below.
    #[test]
    fn hand_made_series() {
        //           k:  0    1    2    3     4    5    6    7    8     9
        let sun = [1.0, 1.0, 0.5, 0.0, 0.0, 0.0, 0.05, 0.2, 0.9995, 0.0];
        let earth = [0.0, 0.3, 0.3, 0.3, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let s = SiteSeries {
            site: "A",
            start_utc: start(),
            step_s: 3600.0,
            sun_fraction: &sun,
            earth_fraction: &earth,
        };
        let st = site_stats(&s).unwrap();
        assert_eq!(st.samples, 10);
        assert_eq!(st.span_h, 10.0);
        assert_eq!(st.start_utc, "2024-01-01T00:00:00Z");
        assert_eq!(st.end_utc, "2024-01-01T10:00:00Z");
        // Full: k = 0, 1, 8 → 30%. Partial: 2, 6, 7 → 30%. Dark: 3, 4, 5, 9 → 40%.
        assert!((st.sun_full_pct - 30.0).abs() < 1e-12);
        assert!((st.sun_partial_pct - 30.0).abs() < 1e-12);
        assert!((st.sun_visible_pct - 60.0).abs() < 1e-12);
        assert!((st.sun_dark_pct - 40.0).abs() < 1e-12);
        let mean = (1.0 + 1.0 + 0.5 + 0.05 + 0.2 + 0.9995) / 10.0;
        assert!((st.sun_mean_visible_fraction - mean).abs() < 1e-15);
        // Longest dark: k = 3..=5, 03:00 → 06:00, 3 h.
        assert_eq!(st.longest_dark_h, 3.0);
        assert_eq!(
            st.longest_dark_start_utc.as_deref(),
            Some("2024-01-01T03:00:00Z")
        );
        assert_eq!(
            st.longest_dark_end_utc.as_deref(),
            Some("2024-01-01T06:00:00Z")
        );
        // Below 10%: k = 3..=6 (0.05 < 0.1), 4 h.
        assert_eq!(st.longest_below_10pct_h, 4.0);
        assert_eq!(
            st.longest_below_10pct_start_utc.as_deref(),
            Some("2024-01-01T03:00:00Z")
        );
        // Earth visible: 1, 2, 3, 7, 8, 9 → 60%; longest visible 3 h (k = 1..=3, the earliest);
        // hidden k = 4..=6, 3 h.
        assert!((st.earth_visible_pct - 60.0).abs() < 1e-12);
        assert_eq!(st.longest_earth_visible_h, 3.0);
        assert_eq!(
            st.longest_earth_visible_start_utc.as_deref(),
            Some("2024-01-01T01:00:00Z")
        );
        assert_eq!(st.longest_earth_hidden_h, 3.0);
        assert_eq!(
            st.longest_earth_hidden_end_utc.as_deref(),
            Some("2024-01-01T07:00:00Z")
        );
        // Sun and Earth together: k = 1, 2, 7, 8 → 40%.
        assert!((st.sun_and_earth_pct - 40.0).abs() < 1e-12);
    }

    #[test]
    fn always_lit_has_no_dark_window() {
        let sun = [1.0; 5];
        let earth = [0.0; 5];
        let s = SiteSeries {
            site: "lit",
            start_utc: start(),
            step_s: 1800.0,
            sun_fraction: &sun,
            earth_fraction: &earth,
        };
        let st = site_stats(&s).unwrap();
        assert_eq!(st.longest_dark_h, 0.0);
        assert_eq!(st.longest_dark_start_utc, None);
        assert_eq!(st.sun_full_pct, 100.0);
        // Earth hidden for the whole 5 × 30 min = 2.5 h.
        assert_eq!(st.longest_earth_hidden_h, 2.5);
    }

    #[test]
    fn combined_union_of_two_sites() {
        // Two sites over 8 hourly samples: A dark at 2..=5, B dark at 4..=7.
        let a = [1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0];
        let b = [0.5, 0.5, 0.5, 0.5, 0.0, 0.0, 0.0, 0.0];
        let ea = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let eb = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0];
        let series = [
            SiteSeries {
                site: "A",
                start_utc: start(),
                step_s: 3600.0,
                sun_fraction: &a,
                earth_fraction: &ea,
            },
            SiteSeries {
                site: "B",
                start_utc: start(),
                step_s: 3600.0,
                sun_fraction: &b,
                earth_fraction: &eb,
            },
        ];
        let file = StatsFile::from_series(&series).unwrap();
        let c = file.combined.as_ref().unwrap();
        // Both dark only at k = 4, 5 → 2 h, 04:00–06:00; at least one lit 6/8 = 75%.
        assert_eq!(c.longest_all_dark_h, 2.0);
        assert_eq!(
            c.longest_all_dark_start_utc.as_deref(),
            Some("2024-01-01T04:00:00Z")
        );
        assert!((c.any_sun_visible_pct - 75.0).abs() < 1e-12);
        // Fully lit somewhere: A at 0, 1, 6, 7 → 50%.
        assert!((c.any_sun_full_pct - 50.0).abs() < 1e-12);
        // Earth visible somewhere at k = 3 and 7 → 25%; hidden from all at 0..=2 and 4..=6 → 3 h.
        assert!((c.any_earth_visible_pct - 25.0).abs() < 1e-12);
        assert_eq!(c.longest_all_earth_hidden_h, 3.0);
        assert_eq!(
            c.longest_all_earth_hidden_start_utc.as_deref(),
            Some("2024-01-01T00:00:00Z")
        );

        // Round trip through JSON on disk.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stats.json");
        file.write_json(&path).unwrap();
        let back: StatsFile = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        // The file holds each number to its unit's precision: the same statistics, rounded.
        let mut rounded = serde_json::to_value(&file).unwrap();
        crate::output::round_json_numbers(&mut rounded);
        assert_eq!(back, serde_json::from_value::<StatsFile>(rounded).unwrap());
        assert_eq!(back.sites[0].samples, file.sites[0].samples);
        let pct = back.sites[0].sun_visible_pct;
        assert!(
            (pct - file.sites[0].sun_visible_pct).abs() <= 0.005
                && ((pct * 100.0).round() - pct * 100.0).abs() < 1e-9,
            "{pct}"
        );
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\"longest_dark_h\""), "{text}");
    }

    #[test]
    fn bad_series_are_errors() {
        let ok = [1.0; 3];
        let s = SiteSeries {
            site: "X",
            start_utc: start(),
            step_s: 3600.0,
            sun_fraction: &[],
            earth_fraction: &[],
        };
        assert!(matches!(
            site_stats(&s),
            Err(IllumError::EmptySeries { .. })
        ));
        let s = SiteSeries {
            sun_fraction: &ok,
            earth_fraction: &ok[..2],
            ..s
        };
        assert!(matches!(
            site_stats(&s),
            Err(IllumError::LengthMismatch { .. })
        ));
        let s = SiteSeries {
            earth_fraction: &ok,
            step_s: 0.0,
            ..s
        };
        assert!(matches!(site_stats(&s), Err(IllumError::BadStep { .. })));
        let a = SiteSeries { step_s: 60.0, ..s };
        let b = SiteSeries {
            step_s: 120.0,
            site: "Y",
            ..a
        };
        assert!(matches!(
            combined_stats(&[a, b]),
            Err(IllumError::MismatchedGrids { .. })
        ));
    }
}

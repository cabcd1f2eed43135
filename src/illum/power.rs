//! Solar power of a panel and the state of charge of a battery behind it.
//!
//! ```text
//! P = A · η · (1 − d · t_years) · S0 · (1 au / r)² · f · cos(incidence)
//! ```
//!
//! `A` the panel area, `η` its efficiency, `d` an optional linear degradation per year from the
//! first epoch, `S0 (1 au / r)² f` the normal irradiance of [`super::irradiance`] (the Sun's range
//! `r`, its visible flux fraction `f` with the run's limb darkening), and the incidence factor of
//! the panel's orientation against the Sun's centre (elevation above the local horizontal `el`,
//! azimuth `az`):
//!
//! | panel | `cos(incidence)` |
//! |---|---|
//! | `vertical-tracking` (the polar default: a vertical panel turned to the Sun's azimuth) | `cos el` |
//! | `horizontal` | `max(sin el, 0)` |
//! | `vertical-fixed:AZ` (facing azimuth `AZ`) | `max(cos el · cos(az − AZ), 0)` |
//! | `two-axis` (facing the Sun) | 1 |
//!
//! The mast height is the observer height of the panel's centre (the site's height above
//! ground). **Time weighting**: each sample's power and load hold for `[t, t + step)`, as the
//! series' statistics weight time. The battery starts full (or at a given charge), is clipped at
//! its capacity and at empty; the **required capacity** is the smallest battery that, starting
//! full, never runs empty: the largest drawdown of the cumulative net energy (`max_k D_k`,
//! `D_{k+1} = max(0, D_k − (P_k − L_k) · step)`), which needs no capacity to be given.

use serde::{Deserialize, Serialize};

use crate::{AU_KM, SOLAR_CONSTANT_W_M2};

/// Hours in a mean synodic month (a lunar day–night cycle), for the energy per lunar day.
pub const LUNAR_DAY_H: f64 = 29.530_589 * 24.0;

/// A panel's or a battery's settings are wrong.
#[derive(Debug, thiserror::Error)]
pub enum PowerError {
    /// An unknown or malformed panel orientation.
    #[error(
        "panel '{0}': use vertical-tracking, horizontal, vertical-fixed:AZ_DEG (0 … 360) or two-axis"
    )]
    Panel(String),
    /// A load profile that cannot be used.
    #[error("{0}")]
    Profile(String),
    /// A number out of its range.
    #[error("{what} {value} is outside {range}")]
    Range {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range, in words.
        range: &'static str,
    },
}

/// The orientation of a panel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Panel {
    /// Vertical, turned to the Sun's azimuth.
    VerticalTracking,
    /// Level.
    Horizontal,
    /// Vertical, facing a fixed azimuth (degrees clockwise from north).
    VerticalFixed {
        /// The azimuth the panel faces, degrees.
        az_deg: f64,
    },
    /// Facing the Sun.
    TwoAxis,
}

impl Panel {
    /// `vertical-tracking`, `horizontal`, `vertical-fixed:AZ_DEG` or `two-axis`.
    pub fn parse(text: &str) -> Result<Self, PowerError> {
        let bad = || PowerError::Panel(text.to_string());
        match text.trim() {
            "vertical-tracking" => Ok(Panel::VerticalTracking),
            "horizontal" => Ok(Panel::Horizontal),
            "two-axis" => Ok(Panel::TwoAxis),
            t => {
                let az = t.strip_prefix("vertical-fixed:").ok_or_else(bad)?;
                let az_deg: f64 = az.trim().parse().map_err(|_| bad())?;
                if !(0.0..=360.0).contains(&az_deg) {
                    return Err(bad());
                }
                Ok(Panel::VerticalFixed { az_deg })
            }
        }
    }

    /// The name [`Panel::parse`] reads.
    pub fn name(&self) -> String {
        match self {
            Panel::VerticalTracking => "vertical-tracking".into(),
            Panel::Horizontal => "horizontal".into(),
            Panel::VerticalFixed { az_deg } => format!("vertical-fixed:{az_deg}"),
            Panel::TwoAxis => "two-axis".into(),
        }
    }

    /// Whether the incidence needs the Sun's azimuth.
    pub fn needs_azimuth(&self) -> bool {
        matches!(self, Panel::VerticalFixed { .. })
    }

    /// `cos(incidence)` of the Sun's centre at `sun_el_deg`, `sun_az_deg` (clipped at 0).
    pub fn incidence_factor(&self, sun_el_deg: f64, sun_az_deg: f64) -> f64 {
        let el = sun_el_deg.to_radians();
        match self {
            Panel::VerticalTracking => el.cos(),
            Panel::Horizontal => el.sin().max(0.0),
            Panel::VerticalFixed { az_deg } => {
                (el.cos() * (sun_az_deg - az_deg).to_radians().cos()).max(0.0)
            }
            Panel::TwoAxis => 1.0,
        }
    }
}

impl TryFrom<String> for Panel {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Panel::parse(&s).map_err(|e| e.to_string())
    }
}

impl From<Panel> for String {
    fn from(p: Panel) -> String {
        p.name()
    }
}

impl Serialize for Panel {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.name())
    }
}

impl<'de> Deserialize<'de> for Panel {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        Panel::parse(&s).map_err(serde::de::Error::custom)
    }
}

/// A panel, a load and a battery (`series --panel …`, a scenario's `[series.power]`, Python's
/// `series(panel=…)`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PowerConfig {
    /// The panel's orientation.
    pub panel: Panel,
    /// Panel area, m² (> 0).
    pub area_m2: f64,
    /// Efficiency, 0 < η ≤ 1.
    pub efficiency: f64,
    /// Linear loss of efficiency per year from the first epoch, % (0 … 100).
    pub degradation_pct_per_year: f64,
    /// Load while any part of the Sun is visible, W (≥ 0).
    pub load_w: f64,
    /// Load while the Sun is entirely hidden, W (≥ 0; the day load when absent).
    pub night_load_w: Option<f64>,
    /// Battery capacity, Wh (> 0): adds the state of charge; absent, only the required capacity.
    pub battery_wh: Option<f64>,
    /// Charge at the first epoch, % of the capacity (default 100).
    pub battery_start_pct: f64,
    /// A time-varying load instead of `load_w` / `night_load_w`: a CSV file of
    /// `start_utc,stop_utc,load_w[,night_load_w]` rows ([`LoadProfile`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_profile: Option<std::path::PathBuf>,
}

impl Default for PowerConfig {
    fn default() -> Self {
        PowerConfig {
            panel: Panel::VerticalTracking,
            area_m2: 1.0,
            efficiency: 0.30,
            degradation_pct_per_year: 0.0,
            load_w: 100.0,
            night_load_w: None,
            battery_wh: None,
            battery_start_pct: 100.0,
            load_profile: None,
        }
    }
}

/// The power options as the command line and Python take them (all optional; any one turns the
/// panel on, the rest take [`PowerConfig::default`]'s values).
#[derive(Debug, Clone, Default)]
pub struct PowerOptions<'a> {
    /// Panel orientation ([`Panel::parse`]).
    pub panel: Option<&'a str>,
    /// Area, m².
    pub area_m2: Option<f64>,
    /// Efficiency.
    pub efficiency: Option<f64>,
    /// Degradation, %/year.
    pub degradation_pct_per_year: Option<f64>,
    /// Day load, W.
    pub load_w: Option<f64>,
    /// Night load, W.
    pub night_load_w: Option<f64>,
    /// Battery capacity, Wh.
    pub battery_wh: Option<f64>,
    /// Start charge, %.
    pub battery_start_pct: Option<f64>,
    /// A load profile file ([`LoadProfile`]).
    pub load_profile: Option<&'a std::path::Path>,
}

impl PowerConfig {
    /// The validated configuration of `o`; `None` when no option is given.
    pub fn from_options(o: &PowerOptions<'_>) -> Result<Option<Self>, PowerError> {
        let any = o.panel.is_some()
            || [
                o.area_m2,
                o.efficiency,
                o.degradation_pct_per_year,
                o.load_w,
                o.night_load_w,
                o.battery_wh,
                o.battery_start_pct,
            ]
            .iter()
            .any(Option::is_some)
            || o.load_profile.is_some();
        if !any {
            return Ok(None);
        }
        if o.load_profile.is_some() && (o.load_w.is_some() || o.night_load_w.is_some()) {
            return Err(PowerError::Profile(
                "give a load (--load-w, --night-load-w) or a load profile, not both".into(),
            ));
        }
        let d = PowerConfig::default();
        let config = PowerConfig {
            panel: o.panel.map_or(Ok(d.panel), Panel::parse)?,
            area_m2: o.area_m2.unwrap_or(d.area_m2),
            efficiency: o.efficiency.unwrap_or(d.efficiency),
            degradation_pct_per_year: o
                .degradation_pct_per_year
                .unwrap_or(d.degradation_pct_per_year),
            load_w: o.load_w.unwrap_or(d.load_w),
            night_load_w: o.night_load_w,
            battery_wh: o.battery_wh,
            battery_start_pct: o.battery_start_pct.unwrap_or(d.battery_start_pct),
            load_profile: o.load_profile.map(std::path::Path::to_path_buf),
        };
        config.validate()?;
        Ok(Some(config))
    }

    /// Checks every number; the first wrong one is the error. (A load profile's file is read
    /// and checked against the epochs by [`Self::loads`].)
    pub fn validate(&self) -> Result<(), PowerError> {
        if self.load_profile.is_some()
            && (self.load_w != Self::default().load_w || self.night_load_w.is_some())
        {
            return Err(PowerError::Profile(
                "give a load (--load-w, --night-load-w) or a load profile, not both".into(),
            ));
        }
        let check = |what, value: f64, ok: bool, range| {
            if ok && value.is_finite() {
                Ok(())
            } else {
                Err(PowerError::Range { what, value, range })
            }
        };
        check(
            "panel area",
            self.area_m2,
            self.area_m2 > 0.0 && self.area_m2 <= 1e6,
            "(0, 1e6] m²",
        )?;
        check(
            "panel efficiency",
            self.efficiency,
            self.efficiency > 0.0 && self.efficiency <= 1.0,
            "(0, 1]",
        )?;
        check(
            "panel degradation",
            self.degradation_pct_per_year,
            (0.0..=100.0).contains(&self.degradation_pct_per_year),
            "[0, 100] %/year",
        )?;
        check(
            "load",
            self.load_w,
            (0.0..=1e9).contains(&self.load_w),
            "[0, 1e9] W",
        )?;
        if let Some(n) = self.night_load_w {
            check("night load", n, (0.0..=1e9).contains(&n), "[0, 1e9] W")?;
        }
        if let Some(c) = self.battery_wh {
            check("battery capacity", c, c > 0.0 && c <= 1e12, "(0, 1e12] Wh")?;
        }
        check(
            "battery start charge",
            self.battery_start_pct,
            (0.0..=100.0).contains(&self.battery_start_pct),
            "[0, 100] %",
        )?;
        Ok(())
    }

    /// Power of the panel, W: the Sun at `sun_range_km`, `sun_el_deg`, `sun_az_deg` with visible
    /// fraction `fraction`, `years` after the first epoch.
    pub fn power_w(
        &self,
        sun_range_km: f64,
        sun_el_deg: f64,
        sun_az_deg: f64,
        fraction: f64,
        years: f64,
    ) -> f64 {
        if fraction <= 0.0 {
            return 0.0;
        }
        let scale = AU_KM / sun_range_km;
        let eff = self.efficiency * (1.0 - self.degradation_pct_per_year / 100.0 * years).max(0.0);
        self.area_m2
            * eff
            * SOLAR_CONSTANT_W_M2
            * scale
            * scale
            * fraction
            * self.panel.incidence_factor(sun_el_deg, sun_az_deg)
    }

    /// The panel and load in words (for the files' descriptions).
    pub fn describe(&self) -> String {
        let mut t = format!(
            "{} panel, {} m2, efficiency {}",
            self.panel.name(),
            self.area_m2,
            self.efficiency
        );
        if self.degradation_pct_per_year > 0.0 {
            t += &format!(", -{} %/year", self.degradation_pct_per_year);
        }
        match (&self.load_profile, self.night_load_w) {
            (Some(p), _) => t += &format!(", load profile {}", p.display()),
            (None, Some(n)) => t += &format!(", load {} W by day, {n} W by night", self.load_w),
            (None, None) => t += &format!(", load {} W", self.load_w),
        }
        t
    }

    /// The loads at `epochs`, W, as `(day, night)` per epoch (night: the Sun entirely hidden):
    /// the constant loads, or the load profile's rows, which must cover every epoch.
    pub fn loads(&self, epochs: &[hifitime::Epoch]) -> Result<Vec<Loads>, PowerError> {
        let Some(path) = &self.load_profile else {
            let l = Loads {
                day_w: self.load_w,
                night_w: self.night_load_w.unwrap_or(self.load_w),
            };
            return Ok(vec![l; epochs.len()]);
        };
        LoadProfile::read(path)?.at(epochs)
    }
}

/// The load at one epoch, W.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loads {
    /// While any part of the Sun is visible.
    pub day_w: f64,
    /// While the Sun is entirely hidden.
    pub night_w: f64,
}

impl Loads {
    /// The load with the Sun's visible fraction `fraction`.
    pub fn at(&self, fraction: f64) -> f64 {
        if fraction <= 0.0 {
            self.night_w
        } else {
            self.day_w
        }
    }
}

/// A time-varying load: rows `start_utc,stop_utc,load_w[,night_load_w]` (a header line, then
/// one row per interval `[start, stop)`; each row starts where the one before stops, no gap and
/// no overlap; without `night_load_w` the load is the same by night). A sample takes the load of
/// the row its epoch falls in and holds it for its step, as a constant load does.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadProfile {
    /// The file, for messages.
    pub path: std::path::PathBuf,
    /// `(start, stop, loads)` per row, in time order.
    pub rows: Vec<(hifitime::Epoch, hifitime::Epoch, Loads)>,
}

impl LoadProfile {
    /// Reads and checks a profile file.
    pub fn read(path: &std::path::Path) -> Result<Self, PowerError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| PowerError::Profile(format!("load profile {}: {e}", path.display())))?;
        Self::parse(&text, path)
    }

    /// Parses a profile's text (`path` for messages).
    pub fn parse(text: &str, path: &std::path::Path) -> Result<Self, PowerError> {
        let bad =
            |why: String| PowerError::Profile(format!("load profile {}: {why}", path.display()));
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .comment(Some(b'#'))
            .flexible(true)
            .from_reader(text.as_bytes());
        let header: Vec<String> = reader
            .headers()
            .map_err(|e| bad(e.to_string()))?
            .iter()
            .map(str::to_string)
            .collect();
        let want = ["start_utc", "stop_utc", "load_w"];
        if header.len() < 3
            || header[..3] != want
            || header.len() > 4
            || (header.len() == 4 && header[3] != "night_load_w")
        {
            return Err(bad(format!(
                "its header is '{}'; it must be 'start_utc,stop_utc,load_w[,night_load_w]'",
                header.join(",")
            )));
        }
        let mut rows: Vec<(hifitime::Epoch, hifitime::Epoch, Loads)> = Vec::new();
        for (i, rec) in reader.records().enumerate() {
            let line = i + 2;
            let rec = rec.map_err(|e| bad(format!("line {line}: {e}")))?;
            if rec.len() != header.len() {
                return Err(bad(format!(
                    "line {line} has {} fields, the header {}",
                    rec.len(),
                    header.len()
                )));
            }
            let time = |k: usize| {
                crate::ephem::time::parse_utc(&rec[k]).map_err(|e| bad(format!("line {line}: {e}")))
            };
            let load = |k: usize| {
                let v: f64 = rec[k]
                    .parse()
                    .map_err(|_| bad(format!("line {line}: '{}' is not a load in W", &rec[k])))?;
                if !(v.is_finite() && (0.0..=1e9).contains(&v)) {
                    return Err(bad(format!(
                        "line {line}: load {v} W is outside [0, 1e9] W"
                    )));
                }
                Ok(v)
            };
            let (start, stop) = (time(0)?, time(1)?);
            if stop <= start {
                return Err(bad(format!("line {line}: it stops at or before it starts")));
            }
            if let Some(&(_, prev_stop, _)) = rows.last()
                && start != prev_stop
            {
                let what = if start > prev_stop {
                    "a gap"
                } else {
                    "an overlap"
                };
                return Err(bad(format!(
                    "{what} between {} and {} (line {line}): each row must start where the one \
                     before stops",
                    crate::ephem::time::format_utc(prev_stop.min(start)),
                    crate::ephem::time::format_utc(prev_stop.max(start)),
                )));
            }
            let day_w = load(2)?;
            let night_w = if rec.len() == 4 { load(3)? } else { day_w };
            rows.push((start, stop, Loads { day_w, night_w }));
        }
        if rows.is_empty() {
            return Err(bad("it has no rows (an empty profile)".into()));
        }
        Ok(LoadProfile {
            path: path.to_path_buf(),
            rows,
        })
    }

    /// The loads at `epochs` (in time order), each from the row it falls in.
    pub fn at(&self, epochs: &[hifitime::Epoch]) -> Result<Vec<Loads>, PowerError> {
        let (first, last) = (self.rows[0].0, self.rows[self.rows.len() - 1].1);
        let mut k = 0;
        epochs
            .iter()
            .map(|&t| {
                if t < first || t >= last {
                    return Err(PowerError::Profile(format!(
                        "load profile {} covers {} to {}, not the epoch {}",
                        self.path.display(),
                        crate::ephem::time::format_utc(first),
                        crate::ephem::time::format_utc(last),
                        crate::ephem::time::format_utc(t)
                    )));
                }
                if t < self.rows[k].0 {
                    k = 0;
                }
                while t >= self.rows[k].1 {
                    k += 1;
                }
                Ok(self.rows[k].2)
            })
            .collect()
    }
}

/// A battery stepped through a series in time order (streams with the CSV rows).
#[derive(Debug, Clone)]
pub struct Battery {
    capacity_wh: Option<f64>,
    charge_wh: f64,
    deficit_wh: f64,
    max_deficit_wh: f64,
    min_charge_wh: f64,
    empty_h: f64,
    energy_wh: f64,
    load_energy_wh: f64,
    hours: f64,
}

impl Battery {
    /// A battery of `config`'s capacity at its start charge.
    pub fn new(config: &PowerConfig) -> Self {
        let start = config
            .battery_wh
            .map_or(0.0, |c| c * config.battery_start_pct / 100.0);
        Battery {
            capacity_wh: config.battery_wh,
            charge_wh: start,
            deficit_wh: 0.0,
            max_deficit_wh: 0.0,
            min_charge_wh: start,
            empty_h: 0.0,
            energy_wh: 0.0,
            load_energy_wh: 0.0,
            hours: 0.0,
        }
    }

    /// One sample: `power_w` and `load_w` held for `step_h` hours. Returns the charge at the
    /// sample's epoch (before its interval), `None` without a capacity.
    pub fn step(&mut self, power_w: f64, load_w: f64, step_h: f64) -> Option<f64> {
        let net_w = power_w - load_w;
        self.energy_wh += power_w * step_h;
        self.load_energy_wh += load_w * step_h;
        self.hours += step_h;
        self.deficit_wh = (self.deficit_wh - net_w * step_h).max(0.0);
        self.max_deficit_wh = self.max_deficit_wh.max(self.deficit_wh);
        let cap = self.capacity_wh?;
        let at_epoch = self.charge_wh;
        if net_w < 0.0 {
            let to_empty_h = self.charge_wh / -net_w;
            if to_empty_h < step_h {
                self.empty_h += step_h - to_empty_h;
            }
        }
        self.charge_wh = (self.charge_wh + net_w * step_h).clamp(0.0, cap);
        self.min_charge_wh = self.min_charge_wh.min(self.charge_wh);
        Some(at_epoch)
    }

    /// The statistics of the samples stepped so far.
    pub fn stats(&self) -> PowerStats {
        let mean_power_w = if self.hours > 0.0 {
            self.energy_wh / self.hours
        } else {
            0.0
        };
        PowerStats {
            mean_power_w,
            energy_wh: self.energy_wh,
            load_energy_wh: self.load_energy_wh,
            energy_per_lunar_day_wh: mean_power_w * LUNAR_DAY_H,
            required_battery_wh: self.max_deficit_wh,
            min_battery_wh: self.capacity_wh.map(|_| self.min_charge_wh),
            hours_below_empty_h: self.capacity_wh.map(|_| self.empty_h),
        }
    }
}

/// A site's power statistics (`stats.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PowerStats {
    /// Mean power of the panel over the period, W.
    pub mean_power_w: f64,
    /// Energy collected over the period, Wh.
    pub energy_wh: f64,
    /// Energy drawn by the load over the period, Wh.
    pub load_energy_wh: f64,
    /// Mean energy per lunar day (29.53 d), Wh.
    pub energy_per_lunar_day_wh: f64,
    /// The smallest battery that, starting full, never runs empty over the period, Wh.
    pub required_battery_wh: f64,
    /// Lowest charge of the given battery, Wh (absent without a capacity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_battery_wh: Option<f64>,
    /// Hours the given battery was empty with the load unmet (absent without a capacity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hours_below_empty_h: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn panels_parse_and_name_round_trip() {
        for t in [
            "vertical-tracking",
            "horizontal",
            "two-axis",
            "vertical-fixed:90",
        ] {
            assert_eq!(Panel::parse(t).unwrap().name(), t);
        }
        for t in ["", "vertical", "vertical-fixed:", "vertical-fixed:400", "x"] {
            assert!(Panel::parse(t).is_err(), "{t}");
        }
    }

    #[test]
    fn incidence_factors_are_the_cosines() {
        let c = |p: Panel, el: f64, az: f64| p.incidence_factor(el, az);
        assert!((c(Panel::VerticalTracking, 60.0, 0.0) - 0.5).abs() < 1e-15);
        assert!((c(Panel::Horizontal, 30.0, 0.0) - 0.5).abs() < 1e-15);
        assert_eq!(c(Panel::Horizontal, -1.0, 0.0), 0.0);
        let east = Panel::VerticalFixed { az_deg: 90.0 };
        assert!((c(east, 0.0, 150.0) - 0.5).abs() < 1e-15);
        assert_eq!(c(east, 0.0, 270.0), 0.0);
        assert_eq!(c(Panel::TwoAxis, 1.0, 0.0), 1.0);
    }

    #[test]
    fn required_capacity_is_the_largest_drawdown() {
        // Net +10, −30, +5, −20, +100 W for 1 h each: the cumulative energy 10, −20, −15, −35,
        // 65 falls at most 45 Wh below its running maximum (10 → −35).
        let config = PowerConfig {
            load_w: 0.0,
            battery_wh: Some(45.0),
            ..PowerConfig::default()
        };
        let mut b = Battery::new(&config);
        for net in [10.0_f64, -30.0, 5.0, -20.0, 100.0] {
            b.step(net.max(0.0), (-net).max(0.0), 1.0);
        }
        let s = b.stats();
        assert!((s.required_battery_wh - 45.0).abs() < 1e-12);
        // 45 Wh, starting full: the +10 is lost to the full battery, so the low is 0, never below.
        assert!(s.min_battery_wh.unwrap().abs() < 1e-12);
        assert_eq!(s.hours_below_empty_h, Some(0.0));
        // One Wh less runs empty for 1/20 h in the −20 W hour.
        let mut small = Battery::new(&PowerConfig {
            battery_wh: Some(44.0),
            ..config
        });
        for net in [10.0_f64, -30.0, 5.0, -20.0, 100.0] {
            small.step(net.max(0.0), (-net).max(0.0), 1.0);
        }
        assert!((small.stats().hours_below_empty_h.unwrap() - 0.05).abs() < 1e-12);
    }

    #[test]
    fn bad_numbers_are_refused() {
        let bad = |c: PowerConfig| c.validate().unwrap_err().to_string();
        assert!(
            bad(PowerConfig {
                area_m2: -1.0,
                ..Default::default()
            })
            .contains("panel area -1")
        );
        assert!(
            bad(PowerConfig {
                efficiency: 1.5,
                ..Default::default()
            })
            .contains("panel efficiency 1.5")
        );
        assert!(PowerConfig::default().validate().is_ok());
    }
}

//! The values a user types, parsed once into types that cannot be invalid ("parse, don't
//! validate"): an observer height, a site, the epochs of a run. The command line, the scenario
//! files and the Python module build the same values through these constructors, so a value gets
//! the same bound and the same error message wherever it is typed.

use std::fmt;

use hifitime::{Duration, Epoch};
use serde::{Deserialize, Serialize};

use crate::ephem::time;

/// A value a user typed that penumbra refuses; the message names the value and the bound.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    /// An observer height out of bounds.
    #[error(
        "observer height {} m must be a finite number from 0 to {max} m",
        short_number(*.0),
        max = ObserverHeight::MAX_M
    )]
    ObserverHeight(f64),
    /// A site name that cannot name a folder.
    #[error(
        "site name '{0}' must be 1 … {MAX_SITE_NAME_CHARS} letters, digits, spaces (not at either \
         end) or - _ . ( ) + , ' and not start with '.' (it names the site's folder)"
    )]
    SiteName(String),
    /// Two sites whose names name the same folder.
    #[error(
        "site name '{0}' is used twice (names are folder names: they must differ in more than \
         letter case)"
    )]
    SiteNameTwice(String),
    /// A site whose latitude or longitude cannot be.
    #[error("site '{name}': {why}")]
    Site {
        /// The site's name as given.
        name: String,
        /// Why it is refused.
        why: String,
    },
    /// An epoch, step or epoch range that cannot be.
    #[error("{0}")]
    Epochs(String),
}

/// `x` as a message shows it: plainly, or in exponent form when it is huge or tiny (`1e308`, not
/// 309 digits).
fn short_number(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-3..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Height of an observer above the ground, metres: finite, from 0 to 100 km.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct ObserverHeight(f64);

impl ObserverHeight {
    /// The largest observer height, metres (a mast, a crater rim seen from orbit: not a satellite).
    pub const MAX_M: f64 = 100_000.0;
    /// The default: a lander's solar panel or antenna, 2 m above the ground.
    pub const DEFAULT: ObserverHeight = ObserverHeight(crate::DEFAULT_OBSERVER_HEIGHT_M);

    /// An observer height of `m` metres, if it lies in `0 ..= MAX_M`.
    pub fn new(m: f64) -> Result<Self, InputError> {
        if m.is_finite() && (0.0..=Self::MAX_M).contains(&m) {
            Ok(ObserverHeight(m))
        } else {
            Err(InputError::ObserverHeight(m))
        }
    }

    /// The height, metres.
    pub fn m(self) -> f64 {
        self.0
    }
}

impl Default for ObserverHeight {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl TryFrom<f64> for ObserverHeight {
    type Error = InputError;
    fn try_from(m: f64) -> Result<Self, InputError> {
        Self::new(m)
    }
}

impl From<ObserverHeight> for f64 {
    fn from(h: ObserverHeight) -> f64 {
        h.0
    }
}

impl std::str::FromStr for ObserverHeight {
    type Err = InputError;
    /// Parses a number of metres (`2`, `10.5`, `1e3`).
    fn from_str(s: &str) -> Result<Self, InputError> {
        Self::new(s.trim().parse::<f64>().unwrap_or(f64::NAN))
    }
}

impl fmt::Display for ObserverHeight {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// Longest site name, characters.
pub const MAX_SITE_NAME_CHARS: usize = 100;

/// A named place where an observer stands: planetocentric latitude and east longitude, degrees,
/// and the observer's height above the ground. The name names the site's output folder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Site {
    name: String,
    lat_deg: f64,
    lon_deg: f64,
    height_above_ground: ObserverHeight,
}

impl Site {
    /// A site, if its name can name a folder (1 … 100 letters and digits of any script, spaces
    /// not at either end, `- _ . ( ) + , '`, not starting with `.`), its latitude lies in
    /// −90 … 90° and its longitude in −360 … 360°.
    pub fn new(
        name: &str,
        lat_deg: f64,
        lon_deg: f64,
        height_above_ground: ObserverHeight,
    ) -> Result<Self, InputError> {
        let refuse = |why: String| InputError::Site {
            name: name.escape_debug().to_string(),
            why,
        };
        let ok_char = |c: char| {
            c.is_alphanumeric() || matches!(c, ' ' | '-' | '_' | '.' | '(' | ')' | '+' | ',' | '\'')
        };
        if name.is_empty()
            || name.chars().count() > MAX_SITE_NAME_CHARS
            || name.trim() != name
            || name.starts_with('.')
            || !name.chars().all(ok_char)
        {
            return Err(InputError::SiteName(name.escape_debug().to_string()));
        }
        if !(lat_deg.is_finite() && (-90.0..=90.0).contains(&lat_deg)) {
            return Err(refuse(format!(
                "latitude {lat_deg} deg must lie in -90 .. 90"
            )));
        }
        if !(lon_deg.is_finite() && (-360.0..=360.0).contains(&lon_deg)) {
            return Err(refuse(format!(
                "longitude {lon_deg} deg must lie in -360 .. 360"
            )));
        }
        Ok(Site {
            name: name.to_string(),
            lat_deg,
            lon_deg,
            height_above_ground,
        })
    }

    /// The site's name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Planetocentric latitude, degrees.
    pub fn lat_deg(&self) -> f64 {
        self.lat_deg
    }
    /// East longitude, degrees.
    pub fn lon_deg(&self) -> f64 {
        self.lon_deg
    }
    /// The observer's height above the ground.
    pub fn height_above_ground(&self) -> ObserverHeight {
        self.height_above_ground
    }
    /// The observer's height above the ground, metres.
    pub fn height_above_ground_m(&self) -> f64 {
        self.height_above_ground.m()
    }
}

/// Checks that site names can name folders side by side: unique, also ignoring letter case (for
/// case-insensitive file systems).
pub fn check_distinct_sites(sites: &[Site]) -> Result<(), InputError> {
    let mut seen = std::collections::HashSet::new();
    for s in sites {
        if !seen.insert(s.name.to_lowercase()) {
            return Err(InputError::SiteNameTwice(s.name.clone()));
        }
    }
    Ok(())
}

/// Evenly stepped epochs: `start`, `start + step`, … up to `stop` (inclusive when it falls on the
/// step grid); at least one epoch, at most [`time::MAX_EPOCHS`], a step of at least 1 s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpochRange {
    start: Epoch,
    stop: Epoch,
    step: Duration,
    len: usize,
}

impl EpochRange {
    /// The range from `start` to `stop` every `step`.
    pub fn new(start: Epoch, stop: Epoch, step: Duration) -> Result<Self, InputError> {
        if step < Duration::from_seconds(1.0) {
            return Err(InputError::Epochs(format!(
                "step {step}: the step must be at least 1 s"
            )));
        }
        let len =
            time::epoch_count(start, stop, step).map_err(|e| InputError::Epochs(e.to_string()))?;
        Ok(EpochRange {
            start,
            stop,
            step,
            len,
        })
    }

    /// Parses UTC `start` and `stop` and a `step` such as `6h`.
    pub fn parse(start: &str, stop: &str, step: &str) -> Result<Self, InputError> {
        let epochs = |e: crate::ephem::EphemError| InputError::Epochs(e.to_string());
        Self::new(
            time::parse_utc(start).map_err(epochs)?,
            time::parse_utc(stop).map_err(epochs)?,
            time::parse_step(step).map_err(epochs)?,
        )
    }

    /// The range that `epochs` are, if they are at least two, evenly spaced (to 1 µs) and in
    /// order.
    pub fn from_epochs(epochs: &[Epoch]) -> Result<Self, InputError> {
        let uneven = || {
            InputError::Epochs(
                "the times must be at least two, in order and evenly spaced (use time_range)"
                    .into(),
            )
        };
        let [first, second, ..] = epochs else {
            return Err(uneven());
        };
        let step = *second - *first;
        let tol_s = 1e-6;
        let even = epochs
            .windows(2)
            .all(|w| ((w[1] - w[0]) - step).to_seconds().abs() <= tol_s);
        if !even || step <= Duration::ZERO {
            return Err(uneven());
        }
        let last = epochs[epochs.len() - 1];
        let range = Self::new(*first, last, step)?;
        if range.len != epochs.len() {
            return Err(uneven());
        }
        Ok(range)
    }

    /// The epochs, in order.
    pub fn epochs(&self) -> Vec<Epoch> {
        (0..self.len)
            .map(|i| self.start + self.step * (i as i64))
            .collect()
    }
    /// How many epochs.
    pub fn len(&self) -> usize {
        self.len
    }
    /// Always false: a range holds at least one epoch.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// The first epoch.
    pub fn start(&self) -> Epoch {
        self.start
    }
    /// The stop given (the last epoch when it falls on the step grid).
    pub fn stop(&self) -> Epoch {
        self.stop
    }
    /// The step.
    pub fn step(&self) -> Duration {
        self.step
    }
    /// The step, seconds.
    pub fn step_s(&self) -> f64 {
        self.step.to_seconds()
    }
}

/// The epochs of a run: one epoch (one light) or a range (statistics over time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Epochs {
    /// A single epoch.
    One(Epoch),
    /// Evenly stepped epochs.
    Range(EpochRange),
}

impl Epochs {
    /// Parses `utc` or all of `start`, `stop`, `step` (UTC strings and a step such as `6h`);
    /// `Ok(None)` when none is given. Any other combination is an error naming the options.
    pub fn parse(
        utc: Option<&str>,
        start: Option<&str>,
        stop: Option<&str>,
        step: Option<&str>,
    ) -> Result<Option<Self>, InputError> {
        match (utc, start, stop, step) {
            (None, None, None, None) => Ok(None),
            (Some(t), None, None, None) => Ok(Some(Epochs::One(
                time::parse_utc(t).map_err(|e| InputError::Epochs(e.to_string()))?,
            ))),
            (None, Some(a), Some(b), Some(s)) => {
                Ok(Some(Epochs::Range(EpochRange::parse(a, b, s)?)))
            }
            _ => Err(InputError::Epochs(
                "give either --utc T or all of --start T --stop T --step S".into(),
            )),
        }
    }

    /// Like [`Epochs::parse`], but one of the two forms is required.
    pub fn parse_required(
        utc: Option<&str>,
        start: Option<&str>,
        stop: Option<&str>,
        step: Option<&str>,
    ) -> Result<Self, InputError> {
        Self::parse(utc, start, stop, step)?.ok_or_else(|| {
            InputError::Epochs("give either --utc T or all of --start T --stop T --step S".into())
        })
    }

    /// The epochs, in order.
    pub fn epochs(&self) -> Vec<Epoch> {
        match self {
            Epochs::One(e) => vec![*e],
            Epochs::Range(r) => r.epochs(),
        }
    }

    /// The weight of one sample in the statistics, seconds: the step of a range, or 3600 s for a
    /// single epoch.
    pub fn step_s(&self) -> f64 {
        match self {
            Epochs::One(_) => 3600.0,
            Epochs::Range(r) => r.step_s(),
        }
    }

    /// The range, if this is one.
    pub fn range(&self) -> Option<&EpochRange> {
        match self {
            Epochs::One(_) => None,
            Epochs::Range(r) => Some(r),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observer_height_bounds() {
        for m in [0.0, 2.0, 100_000.0] {
            assert_eq!(ObserverHeight::new(m).unwrap().m(), m);
        }
        for m in [-0.1, 100_000.1, f64::NAN, f64::INFINITY, 1e308] {
            let e = ObserverHeight::new(m).unwrap_err();
            assert!(e.to_string().contains("from 0 to 100000 m"), "{e}");
        }
        assert!("1e6".parse::<ObserverHeight>().is_err());
        assert!("abc".parse::<ObserverHeight>().is_err());
        assert_eq!("10".parse::<ObserverHeight>().unwrap().m(), 10.0);
    }

    #[test]
    fn site_checks() {
        let h = ObserverHeight::DEFAULT;
        assert!(Site::new("ridge 1", -89.5, 222.7, h).is_ok());
        for (name, lat, lon) in [
            ("", -89.0, 0.0),
            (".hidden", -89.0, 0.0),
            ("a/b", -89.0, 0.0),
            ("ok", -91.0, 0.0),
            ("ok", f64::NAN, 0.0),
            ("ok", -89.0, 400.0),
        ] {
            assert!(Site::new(name, lat, lon, h).is_err(), "{name} {lat} {lon}");
        }
        let a = Site::new("A", -89.0, 0.0, h).unwrap();
        let b = Site::new("a", -89.0, 1.0, h).unwrap();
        assert!(check_distinct_sites(&[a, b]).is_err());
    }

    #[test]
    fn epoch_range_from_epochs_round_trips() {
        let r = EpochRange::parse("2027-01-01", "2027-01-02", "6h").unwrap();
        assert_eq!(r.len(), 5);
        assert_eq!(EpochRange::from_epochs(&r.epochs()).unwrap(), r);
        let mut uneven = r.epochs();
        uneven[2] += Duration::from_seconds(1.0);
        assert!(EpochRange::from_epochs(&uneven).is_err());
        assert!(EpochRange::parse("2027-01-02", "2027-01-01", "1h").is_err());
        assert!(EpochRange::parse("2027-01-01", "2027-01-02", "0.5s").is_err());
    }
}

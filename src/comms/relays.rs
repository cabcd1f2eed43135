//! Relays: bodies of a user's SPK (a lunar relay orbiter) as link targets. A relay is visible from
//! a site when its centre is above the site's terrain horizon (the Sun's and the Earth's rule)
//! and, if asked, within a slant range. Positions are geometric (a lunar orbiter's light time is
//! ≤ 0.03 s: ≤ 50 m along its orbit).

use std::path::PathBuf;

use anise::prelude::{Almanac, Frame, SPK};
use nalgebra::Vector3;

use crate::ephem::{Kernels, MoonGeometry};

/// A relay could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum RelayError {
    /// The relay's text is malformed.
    #[error("--relay '{text}': {why}")]
    Bad {
        /// The text given.
        text: String,
        /// What is wrong.
        why: String,
    },
    /// An SPK file could not be read.
    #[error("relay SPK {path}: {why}")]
    Spk {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
    /// No loaded SPK holds the body over the epochs.
    #[error("relay '{name}' (NAIF id {id}): {why}")]
    Missing {
        /// The relay's name.
        name: String,
        /// Its NAIF id.
        id: i32,
        /// What is missing.
        why: String,
    },
}

/// A relay: a name and the NAIF id of its SPK segments.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Relay {
    /// The name in files and columns.
    pub name: String,
    /// The NAIF id.
    pub naif_id: i32,
}

impl Relay {
    /// `NAME=ID` or `ID` (the name is then the id).
    pub fn parse(text: &str) -> Result<Self, RelayError> {
        let bad = |why: &str| RelayError::Bad {
            text: text.to_string(),
            why: why.to_string(),
        };
        let (name, id) = match text.split_once('=') {
            Some((n, i)) => (n.trim(), i.trim()),
            None => (text.trim(), text.trim()),
        };
        if name.is_empty() || name.contains([',', '"', '\n', '\r']) {
            return Err(bad(
                "expected NAME=NAIF_ID or NAIF_ID (a name without commas or quotes)",
            ));
        }
        let naif_id = id
            .parse::<i32>()
            .map_err(|_| bad("the NAIF id must be an integer, e.g. LRO=-85"))?;
        Ok(Relay {
            name: name.to_string(),
            naif_id,
        })
    }
}

impl TryFrom<String> for Relay {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Relay::parse(&s).map_err(|e| e.to_string())
    }
}

impl From<Relay> for String {
    fn from(r: Relay) -> String {
        format!("{}={}", r.name, r.naif_id)
    }
}

/// The relays of a run: each one's position relative to the Moon's centre in J2000 (km) at every
/// epoch of a run's table, and the slant-range limit.
pub struct RelayTable {
    relays: Vec<Relay>,
    /// `pos_km[r][k]`: relay `r` at epoch `k`.
    pos_km: Vec<Vec<Vector3<f64>>>,
    max_range_km: Option<f64>,
}

impl RelayTable {
    /// Loads `spks` beside `kernels` and queries every relay at every epoch of `table`; an error
    /// names a relay no SPK covers.
    pub fn new(
        kernels: &Kernels,
        spks: &[PathBuf],
        relays: &[Relay],
        max_range_km: Option<f64>,
        table: &[MoonGeometry],
    ) -> Result<Self, RelayError> {
        if let Some(r) = max_range_km
            && !(r.is_finite() && r > 0.0)
        {
            return Err(RelayError::Bad {
                text: format!("max range {r}"),
                why: "the slant-range limit must be a positive number of km".into(),
            });
        }
        if spks.is_empty() {
            return Err(RelayError::Bad {
                text: relays
                    .iter()
                    .map(|r| format!("{}={}", r.name, r.naif_id))
                    .collect::<Vec<_>>()
                    .join(" "),
                why: "give the SPK that holds the relay (--relay-spk FILE)".into(),
            });
        }
        let mut almanac: Almanac = kernels.almanac.clone();
        for p in spks {
            let err = |why: String| RelayError::Spk {
                path: p.display().to_string(),
                why,
            };
            crate::output::guard::check_regular(p).map_err(|e| err(e.to_string()))?;
            let bytes = std::fs::read(p).map_err(|e| err(e.to_string()))?;
            let spk = SPK::parse(&bytes[..]).map_err(|e| err(e.to_string()))?;
            almanac = almanac.with_spk(spk);
        }
        let moon = Frame::new(301, 1);
        let mut pos_km = Vec::with_capacity(relays.len());
        for r in relays {
            let missing = |why: String| RelayError::Missing {
                name: r.name.clone(),
                id: r.naif_id,
                why,
            };
            let (s, e) = almanac.spk_domain(r.naif_id).map_err(|_| {
                missing(format!(
                    "no relay SPK ({}) holds it",
                    spks.iter()
                        .map(|p| p.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })?;
            if let (Some(first), Some(last)) = (table.first(), table.last())
                && (first.epoch < s || last.epoch > e)
            {
                return Err(missing(format!(
                    "its SPK covers {} .. {} UTC, not the run's {} .. {} UTC",
                    crate::ephem::time::format_iso(s),
                    crate::ephem::time::format_iso(e),
                    crate::ephem::time::format_iso(first.epoch),
                    crate::ephem::time::format_iso(last.epoch)
                )));
            }
            let track = table
                .iter()
                .map(|g| {
                    almanac
                        .translate(Frame::new(r.naif_id, 1), moon, g.epoch, None)
                        .map(|s| Vector3::new(s.radius_km.x, s.radius_km.y, s.radius_km.z))
                        .map_err(|e| missing(e.to_string()))
                })
                .collect::<Result<Vec<_>, _>>()?;
            pos_km.push(track);
        }
        Ok(RelayTable {
            relays: relays.to_vec(),
            pos_km,
            max_range_km,
        })
    }

    /// The relays.
    pub fn relays(&self) -> &[Relay] {
        &self.relays
    }

    /// Each relay seen from `site` at epoch `k`: `(az_deg, el_deg, range_km)` into `out`.
    pub fn seen_from(
        &self,
        geo: &MoonGeometry,
        k: usize,
        site: &crate::ephem::Site,
        out: &mut Vec<(f64, f64, f64)>,
    ) {
        out.clear();
        for track in &self.pos_km {
            let rel_me = geo.moon_me_from_j2000 * track[k] - site.pos_in_moon_me_km;
            let a = crate::ephem::topo::apparent(rel_me, site, 0.0);
            out.push((a.az_deg, a.el_deg, a.range_km));
        }
    }

    /// Whether a relay at `range_km` is within the slant-range limit.
    pub fn in_range(&self, range_km: f64) -> bool {
        self.max_range_km.is_none_or(|m| range_km <= m)
    }

    /// The best relay at epoch `k` from `site`, against its terrain horizon `horizon_el_at_az`
    /// (degrees at an azimuth): the highest visible one (above the horizon, within range), else
    /// the highest. `(index, el_deg, visible)`; `None` without relays. `scratch` is reused.
    pub fn best(
        &self,
        geo: &MoonGeometry,
        k: usize,
        site: &crate::ephem::Site,
        horizon_el_at_az: impl Fn(f64) -> f64,
        scratch: &mut Vec<(f64, f64, f64)>,
    ) -> Option<(usize, f64, bool)> {
        self.seen_from(geo, k, site, scratch);
        scratch
            .iter()
            .enumerate()
            .map(|(i, &(az, el, range))| (i, el, el > horizon_el_at_az(az) && self.in_range(range)))
            .max_by(|a, b| {
                (a.2, a.1)
                    .partial_cmp(&(b.2, b.1))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
    }
}

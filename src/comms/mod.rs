//! Talking to Earth: ground stations, their view of a lunar site, and direct-to-Earth (DTE)
//! windows.
//!
//! A station sees a site when the site's elevation above the station's horizon (the WGS84
//! ellipsoid's normal) is at least the station's mask. The site's position is light-time
//! corrected (emitted at `t − lt`, received at `t`) with the site's velocity relative to the Earth;
//! station and site share the barycentric motion of the Earth–Moon system, so the annual
//! aberration cancels (the residual, ≈ relative velocity / c, is < 1″). Stations turn with the
//! Earth of [`crate::ephem::earth`]. DTE at an epoch: the Earth's centre is above the site's
//! terrain horizon *and* at least one station sees the site. Conventions and sources:
//! `docs/comms.md`.

mod relays;
mod stations;
mod windows;

use nalgebra::Vector3;

use crate::ephem::{MoonGeometry, earth};

pub use relays::{Relay, RelayError, RelayTable};
pub use stations::{
    DSN_SOURCE, Station, StationError, Stations, dsn, read_stations_file, stations_record,
};
pub use windows::{
    IcsEvent, LinkWindow, link_windows, write_ics, write_windows_csv, write_windows_ics,
};

/// The default elevation mask of a station, degrees (the DSN's usual 10°).
pub const DEFAULT_MASK_DEG: f64 = 10.0;

/// Every station's position and up direction in J2000 (GCRS axes) at one epoch, km.
#[derive(Debug, Clone)]
pub struct StationsAt {
    pos_km: Vec<Vector3<f64>>,
    up: Vec<Vector3<f64>>,
}

impl StationsAt {
    /// The stations turned to `epoch`.
    pub fn new(stations: &[Station], epoch: hifitime::Epoch) -> Self {
        let m = earth::gcrs_from_itrs(epoch);
        StationsAt {
            pos_km: stations.iter().map(|s| m * s.itrs_m() / 1000.0).collect(),
            up: stations.iter().map(|s| m * s.itrs_up()).collect(),
        }
    }
}

/// The stations at every epoch of a run (one Earth-orientation evaluation per epoch, shared by
/// all sites).
pub fn stations_table(stations: &[Station], geo: &[MoonGeometry]) -> Vec<StationsAt> {
    use rayon::prelude::*;
    geo.par_iter()
        .with_min_len(256)
        .map(|g| StationsAt::new(stations, g.epoch))
        .collect()
}

/// The elevation (deg) of a lunar site seen from each station, written to `out` (one per
/// station): the site at `site_in_moon_me_km` (from the Moon's centre), light-time corrected.
pub fn site_elevations_deg(
    geo: &MoonGeometry,
    at: &StationsAt,
    site_in_moon_me_km: &Vector3<f64>,
    out: &mut [f64],
) {
    let site_from_moon = geo.moon_me_from_j2000.tr_mul(site_in_moon_me_km);
    let site_from_earth = site_from_moon - geo.earth_wrt_moon.pos_km;
    let site_vel =
        geo.moon_me_from_j2000_dt.tr_mul(site_in_moon_me_km) - geo.earth_wrt_moon.vel_km_s;
    for ((el, stn), up) in out.iter_mut().zip(&at.pos_km).zip(&at.up) {
        let rel = site_from_earth - stn;
        let lt_s = rel.norm() / crate::SPEED_OF_LIGHT_KM_S;
        let rel = rel - site_vel * lt_s;
        *el = (up.dot(&rel) / rel.norm())
            .clamp(-1.0, 1.0)
            .asin()
            .to_degrees();
    }
}

/// The best station at one epoch: the one with the largest margin above its mask, and its
/// elevation (deg); `None` with no stations.
pub fn best_station(stations: &[Station], el_deg: &[f64]) -> Option<(usize, f64)> {
    stations
        .iter()
        .zip(el_deg)
        .enumerate()
        .max_by(|(_, (a, ea)), (_, (b, eb))| {
            (**ea - a.mask_deg()).total_cmp(&(**eb - b.mask_deg()))
        })
        .map(|(i, (_, &e))| (i, e))
}

/// One epoch of a site's link to Earth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkSample {
    /// The best station (index into the station list), `None` with no stations.
    pub station: Option<usize>,
    /// The best station's elevation of the site, degrees (`NaN` with no stations).
    pub station_el_deg: f64,
    /// A station sees the site above its mask.
    pub station_sees_site: bool,
    /// The Earth's centre is above the site's terrain horizon.
    pub earth_centre_visible: bool,
    /// The best relay (index into the relay list: the highest visible one, else the highest),
    /// `None` without relays.
    pub relay: Option<usize>,
    /// That relay's elevation above the site's local horizontal, degrees (`NaN` without relays).
    pub relay_el_deg: f64,
    /// A relay is above the site's terrain horizon (and within the slant-range limit).
    pub relay_visible: bool,
}

impl LinkSample {
    /// Direct-to-Earth: the Earth's centre is above the terrain horizon and a station sees the
    /// site.
    pub fn dte(&self) -> bool {
        self.station_sees_site && self.earth_centre_visible
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn best_station_is_the_largest_margin() {
        let s = vec![
            Station::new("a", 0.0, 0.0, 0.0, 10.0).unwrap(),
            Station::new("b", 0.0, 90.0, 0.0, 30.0).unwrap(),
        ];
        assert_eq!(best_station(&s, &[20.0, 35.0]), Some((0, 20.0)));
        assert_eq!(best_station(&s, &[5.0, 45.0]), Some((1, 45.0)));
        assert_eq!(best_station(&[], &[]), None);
    }
}

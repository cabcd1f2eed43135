//! Topocentric Sun and Earth directions for sites fixed on the Moon, SPICE-exact.
//!
//! For each epoch `t` (UTC → TDB by hifitime) penumbra queries `anise` once for the Moon-centred
//! geometry shared by every site ([`MoonGeometry`]): the Sun's and the Earth's geometric states
//! relative to the Moon, the Moon's state relative to the solar-system barycentre (all J2000), and
//! the J2000 → `MOON_ME` rotation with its time derivative. Each site then gets its exact
//! topocentric vector with the same arithmetic as SPICE's `spkcpo(target, t, 'MOON_ME',
//! 'OBSERVER', abcorr, site, 'MOON', 'MOON_ME')`:
//!
//! 1. observer `o(t) = moon(t) + Rᵀ(t)·s` and `ȯ = moon_vel + Ṙᵀ(t)·s` (J2000, relative to the SSB),
//!    where `s` is the site in `MOON_ME` and `R` the J2000 → `MOON_ME` rotation;
//! 2. light time, one Newtonian iteration as SPICE's `LT`: `lt₀ = |T(t) − o(t)| / c`, target
//!    position `T(t − lt₀) − o(t)` (SPICE `spkltc` with one iteration);
//! 3. stellar aberration of that vector for the observer velocity `ȯ` (SPICE `stelab`: rotate the
//!    vector towards `ȯ` about `u × ȯ/c` by `asin(|u × ȯ/c|)`);
//! 4. rotation into `MOON_ME` at the observer epoch `t` (`'OBSERVER'` reference locus).
//!
//! `T(t − lt)` is taken as `T(t) − lt · Ṫ(t)` with the target's barycentric velocity `Ṫ`: the
//! neglected `½ a lt²` is below 3e-5 km for the Sun (lt ≈ 500 s) and 5e-6 km for the Earth
//! (lt ≈ 1.3 s), i.e. below 1e-5 arcsec. The comparison with SPICE is in `docs/VALIDATION.md`.

use anise::prelude::{Aberration, Almanac, Epoch, Frame};
use nalgebra::{Matrix3, Vector3};

use super::EphemError;
use super::kernels::{EARTH_ID, EMB_ID, J2000_ID, Kernels, MOON_ID, MOON_J2000, SSB_ID, SUN_ID};
use crate::frames::{az_el_deg_from_enu, enu_from_moon_me, site_in_moon_me_km};
use crate::{EARTH_RADIUS_KM, SPEED_OF_LIGHT_KM_S, SUN_RADIUS_KM};

/// Aberration correction applied to the topocentric directions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum AbCorr {
    /// Light time (one Newtonian iteration) + stellar aberration, SPICE `LT+S`.
    #[default]
    #[serde(rename = "lt+s")]
    LtS,
    /// Geometric positions, SPICE `NONE`.
    #[serde(rename = "none")]
    None,
}

impl AbCorr {
    /// Parses `lt+s` or `none` (case-insensitive).
    pub fn parse(text: &str) -> Result<Self, EphemError> {
        match text.to_ascii_lowercase().as_str() {
            "lt+s" => Ok(AbCorr::LtS),
            "none" => Ok(AbCorr::None),
            _ => Err(EphemError::BadAbCorr(text.to_string())),
        }
    }

    /// The SPICE spelling (`LT+S` or `NONE`).
    pub fn spice_name(self) -> &'static str {
        match self {
            AbCorr::LtS => "LT+S",
            AbCorr::None => "NONE",
        }
    }
}

/// A Moon-centred state: position (km) and velocity (km/s) in J2000.
#[derive(Debug, Clone, Copy)]
pub struct StateJ2000 {
    /// Position, km.
    pub pos_km: Vector3<f64>,
    /// Velocity, km/s.
    pub vel_km_s: Vector3<f64>,
}

/// The Moon-centred geometry of one epoch, shared by every site.
#[derive(Debug, Clone, Copy)]
pub struct MoonGeometry {
    /// The epoch.
    pub epoch: Epoch,
    /// Rotation J2000 → `MOON_ME`.
    pub moon_me_from_j2000: Matrix3<f64>,
    /// Time derivative of `moon_me_from_j2000`, 1/s.
    pub moon_me_from_j2000_dt: Matrix3<f64>,
    /// The Moon relative to the solar-system barycentre.
    pub moon_wrt_ssb: StateJ2000,
    /// The Sun relative to the Moon (geometric).
    pub sun_wrt_moon: StateJ2000,
    /// The Earth relative to the Moon (geometric).
    pub earth_wrt_moon: StateJ2000,
}

fn state(
    almanac: &Almanac,
    target: i32,
    observer: i32,
    epoch: Epoch,
) -> Result<StateJ2000, EphemError> {
    let s = almanac
        .translate(
            Frame::new(target, J2000_ID),
            Frame::new(observer, J2000_ID),
            epoch,
            None::<Aberration>,
        )
        .map_err(|e| EphemError::Query {
            action: "translating",
            why: e.to_string(),
        })?;
    Ok(StateJ2000 {
        pos_km: Vector3::new(s.radius_km.x, s.radius_km.y, s.radius_km.z),
        vel_km_s: Vector3::new(s.velocity_km_s.x, s.velocity_km_s.y, s.velocity_km_s.z),
    })
}

fn to_na(m: &anise::math::Matrix3) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| m[(r, c)])
}

impl MoonGeometry {
    /// Queries the kernels for one epoch: four single-segment SPK evaluations (Sun and EMB wrt
    /// the SSB, Moon and Earth wrt the EMB, i.e. the DE440 segments themselves) combined here, and
    /// one rotation. Asking anise for Sun-wrt-Moon directly would walk the tree and evaluate seven
    /// segments.
    pub fn at(kernels: &Kernels, epoch: Epoch) -> Result<Self, EphemError> {
        let almanac = &kernels.almanac;
        let dcm = almanac
            .rotate(MOON_J2000, kernels.moon_me(), epoch)
            .map_err(|e| EphemError::Query {
                action: "rotating J2000 to MOON_ME",
                why: e.to_string(),
            })?;
        let rot_dt = dcm.rot_mat_dt.ok_or_else(|| EphemError::Query {
            action: "rotating J2000 to MOON_ME",
            why: "the rotation has no time derivative".into(),
        })?;
        let sun_wrt_ssb = state(almanac, SUN_ID, SSB_ID, epoch)?;
        let emb_wrt_ssb = state(almanac, EMB_ID, SSB_ID, epoch)?;
        let moon_wrt_emb = state(almanac, MOON_ID, EMB_ID, epoch)?;
        let earth_wrt_emb = state(almanac, EARTH_ID, EMB_ID, epoch)?;
        let moon_wrt_ssb = StateJ2000 {
            pos_km: emb_wrt_ssb.pos_km + moon_wrt_emb.pos_km,
            vel_km_s: emb_wrt_ssb.vel_km_s + moon_wrt_emb.vel_km_s,
        };
        Ok(MoonGeometry {
            epoch,
            moon_me_from_j2000: to_na(&dcm.rot_mat),
            moon_me_from_j2000_dt: to_na(&rot_dt),
            moon_wrt_ssb,
            sun_wrt_moon: StateJ2000 {
                pos_km: sun_wrt_ssb.pos_km - moon_wrt_ssb.pos_km,
                vel_km_s: sun_wrt_ssb.vel_km_s - moon_wrt_ssb.vel_km_s,
            },
            earth_wrt_moon: StateJ2000 {
                pos_km: earth_wrt_emb.pos_km - moon_wrt_emb.pos_km,
                vel_km_s: earth_wrt_emb.vel_km_s - moon_wrt_emb.vel_km_s,
            },
        })
    }
}

/// SPICE `stelab`: the apparent position of an object at `pos` for an observer moving at `vel_km_s`
/// relative to the solar-system barycentre.
///
/// SPICE rotates `pos` about `u × v/c` by `φ = asin(|u × v/c|)`. The rotation needs only `sin φ`
/// (the norm itself) and `cos φ = sqrt(1 − sin² φ)` (φ < 1e-3 rad, so no quadrant question), which
/// is what is used here instead of `asin` followed by `sin`/`cos`.
fn stellar_aberration(pos: &Vector3<f64>, obs_vel_km_s: &Vector3<f64>) -> Vector3<f64> {
    let Some(u) = pos.try_normalize(0.0) else {
        return *pos;
    };
    let vbyc = obs_vel_km_s / SPEED_OF_LIGHT_KM_S;
    let h = u.cross(&vbyc);
    let sin_phi = h.norm();
    if sin_phi == 0.0 {
        return *pos;
    }
    let cos_phi = (1.0 - sin_phi * sin_phi).sqrt();
    let k = h / sin_phi;
    // Rodrigues rotation of `pos` about the unit axis `k` (SPICE `vrotv`).
    pos * cos_phi + k.cross(pos) * sin_phi + k * (k.dot(pos) * (1.0 - cos_phi))
}

/// A site fixed on the Moon, with its body-fixed position and local frame precomputed.
#[derive(Debug, Clone, Copy)]
pub struct Site {
    /// Planetocentric latitude, degrees.
    pub lat_deg: f64,
    /// East longitude, degrees.
    pub lon_deg: f64,
    /// Height above the 1737.4 km sphere, metres.
    pub height_m: f64,
    /// Position in `MOON_ME`, km.
    pub pos_in_moon_me_km: Vector3<f64>,
    /// `MOON_ME` → local ENU rotation.
    pub enu_from_moon_me: Matrix3<f64>,
}

impl Site {
    /// A site from planetocentric latitude / east longitude (deg) and height above the sphere (m).
    pub fn new(lat_deg: f64, lon_deg: f64, height_m: f64) -> Result<Self, EphemError> {
        if !(-90.0..=90.0).contains(&lat_deg) {
            return Err(EphemError::BadSite(format!(
                "latitude {lat_deg} deg is outside [-90, 90]"
            )));
        }
        if !lon_deg.is_finite() || !(-360.0..=360.0).contains(&lon_deg) {
            return Err(EphemError::BadSite(format!(
                "longitude {lon_deg:.6e} deg is outside [-360, 360]"
            )));
        }
        if !height_m.is_finite() || height_m.abs() > 100_000.0 {
            return Err(EphemError::BadSite(format!(
                "height {height_m:.6e} m is not within ±100 km of the reference sphere"
            )));
        }
        Ok(Site {
            lat_deg,
            lon_deg,
            height_m,
            pos_in_moon_me_km: site_in_moon_me_km(lat_deg, lon_deg, height_m),
            enu_from_moon_me: enu_from_moon_me(lat_deg, lon_deg),
        })
    }
}

/// A body as seen from a site.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Apparent {
    /// Azimuth, degrees clockwise from local north, in `[0, 360)`.
    pub az_deg: f64,
    /// Elevation above the plane normal to the radial direction, degrees.
    pub el_deg: f64,
    /// Distance, km.
    pub range_km: f64,
    /// Apparent angular radius of the disc, degrees.
    pub radius_deg: f64,
    /// The (apparent) position relative to the site in `MOON_ME`, km.
    #[serde(skip)]
    pub pos_in_moon_me_km: Vector3<f64>,
}

/// The Sun and the Earth seen from one site at one epoch.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct SunEarth {
    /// The Sun.
    pub sun: Apparent,
    /// The Earth.
    pub earth: Apparent,
}

/// The site's position and barycentric velocity in J2000 at the epoch of a [`MoonGeometry`],
/// shared by every target seen from it.
#[derive(Debug, Clone, Copy)]
pub struct Observer {
    /// Site position relative to the Moon's centre, J2000, km.
    pub pos_j2000_km: Vector3<f64>,
    /// Site velocity relative to the solar-system barycentre, J2000, km/s.
    pub vel_ssb_km_s: Vector3<f64>,
}

impl Observer {
    /// The observer state of `site` at the epoch of `geo`.
    pub fn new(geo: &MoonGeometry, site: &Site) -> Self {
        Observer {
            pos_j2000_km: geo.moon_me_from_j2000.tr_mul(&site.pos_in_moon_me_km),
            vel_ssb_km_s: geo.moon_wrt_ssb.vel_km_s
                + geo.moon_me_from_j2000_dt.tr_mul(&site.pos_in_moon_me_km),
        }
    }
}

/// Topocentric position of a target in `MOON_ME` for an observer state (see the module docs),
/// computed once per site and epoch ([`Observer::new`]).
pub fn target_from_observer(
    geo: &MoonGeometry,
    target_wrt_moon: &StateJ2000,
    obs: &Observer,
    abcorr: AbCorr,
) -> Vector3<f64> {
    let rel_geometric = target_wrt_moon.pos_km - obs.pos_j2000_km;
    let rel = match abcorr {
        AbCorr::None => rel_geometric,
        AbCorr::LtS => {
            let target_vel_ssb = target_wrt_moon.vel_km_s + geo.moon_wrt_ssb.vel_km_s;
            let lt_s = rel_geometric.norm() / SPEED_OF_LIGHT_KM_S;
            let rel_lt = rel_geometric - target_vel_ssb * lt_s;
            stellar_aberration(&rel_lt, &obs.vel_ssb_km_s)
        }
    };
    geo.moon_me_from_j2000 * rel
}

/// The angular radius (deg) of a sphere of radius `body_radius_km` seen from `range_km`
/// (exact: `asin(R/d)`; `range_km` must exceed `body_radius_km`).
fn angular_radius_deg(body_radius_km: f64, range_km: f64) -> f64 {
    (body_radius_km / range_km).asin().to_degrees()
}

/// A body at `pos_in_moon_me_km` (relative to the site) seen from `site`.
pub fn apparent(pos_in_moon_me_km: Vector3<f64>, site: &Site, body_radius_km: f64) -> Apparent {
    let enu = site.enu_from_moon_me * pos_in_moon_me_km;
    let (az_deg, el_deg) = az_el_deg_from_enu(&enu);
    let range_km = pos_in_moon_me_km.norm();
    Apparent {
        az_deg,
        el_deg,
        range_km,
        radius_deg: angular_radius_deg(body_radius_km, range_km),
        pos_in_moon_me_km,
    }
}

/// As [`apparent`] without the azimuth (`az_deg` is `NaN`; [`Apparent::fill_azimuth`] computes
/// it): the elevation is `asin(up · p / |p|)`, equal to [`apparent`]'s `atan2` form. Long series
/// need the azimuth only for the few epochs when a disc is cut by the horizon.
pub fn apparent_without_azimuth(
    pos_in_moon_me_km: Vector3<f64>,
    site: &Site,
    body_radius_km: f64,
) -> Apparent {
    let range_km = pos_in_moon_me_km.norm();
    let up = site.enu_from_moon_me.row(2).transpose();
    Apparent {
        az_deg: f64::NAN,
        el_deg: (up.dot(&pos_in_moon_me_km) / range_km)
            .clamp(-1.0, 1.0)
            .asin()
            .to_degrees(),
        range_km,
        radius_deg: angular_radius_deg(body_radius_km, range_km),
        pos_in_moon_me_km,
    }
}

impl Apparent {
    /// Computes the azimuth if it is missing (see [`apparent_without_azimuth`]).
    pub fn fill_azimuth(&mut self, site: &Site) {
        if self.az_deg.is_nan() {
            let enu = site.enu_from_moon_me * self.pos_in_moon_me_km;
            self.az_deg = az_el_deg_from_enu(&enu).0;
        }
    }
}

/// The Sun and the Earth seen from `site` for the epoch of `geo`.
pub fn sun_earth(geo: &MoonGeometry, site: &Site, abcorr: AbCorr) -> SunEarth {
    let obs = Observer::new(geo, site);
    SunEarth {
        sun: apparent(
            target_from_observer(geo, &geo.sun_wrt_moon, &obs, abcorr),
            site,
            SUN_RADIUS_KM,
        ),
        earth: apparent(
            target_from_observer(geo, &geo.earth_wrt_moon, &obs, abcorr),
            site,
            EARTH_RADIUS_KM,
        ),
    }
}

/// Planetocentric latitude and east longitude (deg) of a sub-observer point on the Moon.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SubPoint {
    /// Planetocentric latitude, degrees.
    pub lat_deg: f64,
    /// East longitude, degrees, in `(-180, 180]`.
    pub lon_deg: f64,
}

/// The sub-solar (or sub-Earth) point on the Moon at the epoch of `geo`: where the apparent body
/// stands at the zenith, i.e. the planetocentric latitude and longitude of the body's apparent
/// direction from the Moon's centre in `MOON_ME` (SPICE
/// `spkpos(body, et, 'MOON_ME', abcorr, 'MOON')` + `reclat`).
///
/// This is the Moon-centred definition that matters to a lunar observer. SPICE's `subpnt` with the
/// Sun as observer instead takes the Moon ≈8.3 minutes earlier (the light time from the Sun), which
/// moves the sub-solar point by up to 0.077°; for the Earth the two differ by 0.0002°.
pub fn sub_body_point(
    geo: &MoonGeometry,
    target_wrt_moon: &StateJ2000,
    abcorr: AbCorr,
) -> SubPoint {
    let centre = Site {
        lat_deg: 0.0,
        lon_deg: 0.0,
        height_m: -crate::MOON_RADIUS_M,
        pos_in_moon_me_km: Vector3::zeros(),
        enu_from_moon_me: Matrix3::identity(),
    };
    let p = target_from_observer(geo, target_wrt_moon, &Observer::new(geo, &centre), abcorr);
    let (lat_deg, lon_deg, _) = crate::frames::lat_lon_height_from_moon_me_km(&p);
    SubPoint { lat_deg, lon_deg }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stellar_aberration_matches_the_classical_formula() {
        // For a velocity perpendicular to the line of sight the deflection is asin(v/c).
        let pos = Vector3::new(1.0e8, 0.0, 0.0);
        let vel = Vector3::new(0.0, 30.0, 0.0);
        let app = stellar_aberration(&pos, &vel);
        let angle = app.cross(&pos).norm().atan2(app.dot(&pos));
        assert!((angle - (30.0 / SPEED_OF_LIGHT_KM_S).asin()).abs() < 1e-14);
        assert!(app.y > 0.0, "deflected towards the velocity");
        assert!((app.norm() - pos.norm()).abs() < 1e-6, "length preserved");
        // Parallel velocity: no deflection.
        assert_eq!(stellar_aberration(&pos, &Vector3::new(5.0, 0.0, 0.0)), pos);
    }

    #[test]
    fn angular_radius_of_sun_and_earth() {
        // asin(R/d) against the independent form atan(R / sqrt(d² - R²)).
        for (radius_km, range_km) in [(696_000.0, 149_597_870.7), (6_378.136_6, 384_400.0)] {
            let got = angular_radius_deg(radius_km, range_km);
            let want = (radius_km / (range_km * range_km - radius_km * radius_km).sqrt())
                .atan()
                .to_degrees();
            assert!((got - want).abs() < 1e-13, "{got} vs {want}");
        }
        // The Sun at 1 au is 0.2666° (696,000 km / 1 au = 4.6525e-3 rad).
        assert!((angular_radius_deg(696_000.0, 149_597_870.7) - 0.266_56).abs() < 1e-5);
    }

    #[test]
    fn abcorr_parsing() {
        assert_eq!(AbCorr::parse("LT+S").unwrap(), AbCorr::LtS);
        assert_eq!(AbCorr::parse("none").unwrap(), AbCorr::None);
        assert!(AbCorr::parse("cn+s").is_err());
    }

    #[test]
    fn site_validation() {
        assert!(Site::new(-91.0, 0.0, 0.0).is_err());
        assert!(Site::new(f64::NAN, 0.0, 0.0).is_err());
        assert!(Site::new(-89.0, 0.0, f64::INFINITY).is_err());
        assert!(Site::new(-89.45, -137.3, 2.0).is_ok());
    }
}

//! Site geometry on the Moon: body-fixed positions of surface sites and the local
//! east-north-up (ENU) frame, with azimuth/elevation conversions.
//!
//! ```text
//!            up (radial)
//!             ^   north (increasing latitude)
//!             |  /
//!             | /
//!             |/_____> east (increasing east longitude)
//! ```
//!
//! Azimuth is measured from north, clockwise (towards east), in `[0, 360)` degrees. Elevation is
//! the angle above the plane normal to the radial (spherical "up") direction. These conventions are
//! the ones of `docs/ARCHITECTURE.md`.

use nalgebra::{Matrix3, Vector3};

use crate::MOON_RADIUS_KM;

/// Position of a site in the body-fixed `MOON_ME` frame, km, from its planetocentric latitude and
/// east longitude (deg) and its height above the 1737.4 km reference sphere (m).
pub fn site_in_moon_me_km(lat_deg: f64, lon_deg: f64, height_m: f64) -> Vector3<f64> {
    let r_km = MOON_RADIUS_KM + height_m * 1e-3;
    let (slat, clat) = lat_deg.to_radians().sin_cos();
    let (slon, clon) = lon_deg.to_radians().sin_cos();
    Vector3::new(r_km * clat * clon, r_km * clat * slon, r_km * slat)
}

/// Two unit vectors perpendicular to the unit vector `axis` and to each other, `(e1, e2)` with
/// `e2 = axis × e1`: the tangent frame of sample points around a direction (any helper axis
/// not parallel to `axis` gives one; `z` unless `axis` is within 26° of it, then `x`).
pub fn perpendicular_pair(axis: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if axis.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let e1 = axis.cross(&helper).normalize();
    (e1, axis.cross(&e1))
}

/// Rotation from `MOON_ME` to the local ENU frame at a site: the rows are the unit east, north and
/// up vectors expressed in `MOON_ME`, so `v_enu = enu_from_moon_me * v_moon_me`.
///
/// At the poles themselves (|lat| = 90°) east and north are taken from the limit along the given
/// longitude, so the frame stays defined.
pub fn enu_from_moon_me(lat_deg: f64, lon_deg: f64) -> Matrix3<f64> {
    let (slat, clat) = lat_deg.to_radians().sin_cos();
    let (slon, clon) = lon_deg.to_radians().sin_cos();
    let east = Vector3::new(-slon, clon, 0.0);
    let north = Vector3::new(-slat * clon, -slat * slon, clat);
    let up = Vector3::new(clat * clon, clat * slon, slat);
    Matrix3::from_rows(&[east.transpose(), north.transpose(), up.transpose()])
}

/// Azimuth (deg, clockwise from north, in `[0, 360)`) and elevation (deg) of a direction given in
/// the local ENU frame. The vector need not be normalised; a zero vector gives `(0, 0)`.
pub fn az_el_deg_from_enu(v_enu: &Vector3<f64>) -> (f64, f64) {
    let horizontal = v_enu.x.hypot(v_enu.y);
    let el_deg = v_enu.z.atan2(horizontal).to_degrees();
    let mut az_deg = v_enu.x.atan2(v_enu.y).to_degrees();
    if az_deg < 0.0 {
        az_deg += 360.0;
    }
    if az_deg >= 360.0 {
        az_deg -= 360.0;
    }
    (az_deg, el_deg)
}

/// Unit vector in the local ENU frame for an azimuth (deg, clockwise from north) and an elevation
/// (deg). Inverse of [`az_el_deg_from_enu`].
pub fn enu_from_az_el_deg(az_deg: f64, el_deg: f64) -> Vector3<f64> {
    let (saz, caz) = az_deg.to_radians().sin_cos();
    let (sel, cel) = el_deg.to_radians().sin_cos();
    Vector3::new(cel * saz, cel * caz, sel)
}

/// Planetocentric latitude and east longitude (deg, longitude in `(-180, 180]`) and height above
/// the reference sphere (m) of a body-fixed position in km.
pub fn lat_lon_height_from_moon_me_km(p_km: &Vector3<f64>) -> (f64, f64, f64) {
    let r_km = p_km.norm();
    let lat_deg = p_km.z.atan2(p_km.x.hypot(p_km.y)).to_degrees();
    let lon_deg = p_km.y.atan2(p_km.x).to_degrees();
    (lat_deg, lon_deg, (r_km - MOON_RADIUS_KM) * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f64 = 1e-12;

    #[test]
    fn enu_basis_is_orthonormal_and_right_handed() {
        for &(lat, lon) in &[(-89.45, -137.3), (0.0, 0.0), (45.0, 120.0), (-90.0, 30.0)] {
            let m = enu_from_moon_me(lat, lon);
            let should_be_identity = m * m.transpose();
            assert!((should_be_identity - Matrix3::identity()).abs().max() < EPS);
            // east x north = up for a right-handed ENU frame.
            let (e, n, u) = (m.row(0), m.row(1), m.row(2));
            assert!((e.cross(&n) - u).abs().max() < EPS);
        }
    }

    #[test]
    fn enu_axes_point_where_their_names_say() {
        // At (lat 0, lon 0): east = +Y, north = +Z, up = +X of the body frame.
        let m = enu_from_moon_me(0.0, 0.0);
        let v = m * Vector3::new(0.0, 1.0, 0.0);
        assert_eq!(az_el_deg_from_enu(&v), (90.0, 0.0));
        let v = m * Vector3::new(0.0, 0.0, 1.0);
        assert!(az_el_deg_from_enu(&v).0.abs() < 1e-12);
        let v = m * Vector3::new(1.0, 0.0, 0.0);
        assert!((az_el_deg_from_enu(&v).1 - 90.0).abs() < 1e-12);
        // At the south pole looking along lon 0: north points to +X (away from the pole, towards
        // the lon-0 meridian; latitude increases in every horizontal direction at the south pole).
        let m = enu_from_moon_me(-90.0, 0.0);
        let north = m.row(1);
        assert!(
            (north - Vector3::new(1.0, 0.0, 0.0).transpose())
                .abs()
                .max()
                < EPS
        );
    }

    #[test]
    fn az_el_round_trip() {
        for az in [0.0, 10.0, 90.0, 179.5, 270.0, 359.9] {
            for el in [-30.0, -1.0, 0.0, 1.5, 60.0] {
                let (a, e) = az_el_deg_from_enu(&enu_from_az_el_deg(az, el));
                assert!((a - az).abs() < 1e-9, "az {az} -> {a}");
                assert!((e - el).abs() < 1e-9, "el {el} -> {e}");
            }
        }
    }

    #[test]
    fn site_position_round_trip() {
        let p = site_in_moon_me_km(-89.45, -137.3, 1954.9);
        let (lat, lon, h) = lat_lon_height_from_moon_me_km(&p);
        assert!((lat + 89.45).abs() < 1e-10);
        assert!((lon + 137.3).abs() < 1e-9);
        assert!((h - 1954.9).abs() < 1e-6);
        assert!((p.norm() - (MOON_RADIUS_KM + 1.9549)).abs() < 1e-10);
    }
}

//! Radial unit vectors (`MOON_ME`) to map coordinates, fast for polar stereographic.

use nalgebra::Vector3;

use super::Projection;

/// Projects unit radial vectors in `MOON_ME` to map coordinates. Polar stereographic is
/// evaluated straight from the vector (`tan(pi/4 + lat/2) cos(lat) = 1 + sin(lat)` turns the
/// formulas of [`crate::terrain::Projection`] into `x = 2 R k0 e / (1 - z)`, `y = 2 R k0 n /
/// (1 - z)` for the south aspect, with `e`, `n` the components along the rotated `lon0` axes),
/// which avoids the asin/atan2/tan of going through latitude and longitude; other projections
/// go through them.
#[derive(Debug, Clone, Copy)]
pub(crate) enum UnitProjector {
    /// Polar stereographic with its constants precomputed.
    Stereographic {
        south: bool,
        sin_lon0: f64,
        cos_lon0: f64,
        two_r_k0_m: f64,
    },
    /// Any other projection, through latitude and longitude.
    Other(Projection),
}

impl UnitProjector {
    pub(crate) fn new(projection: &Projection) -> Self {
        match *projection {
            Projection::PolarStereographic {
                south,
                lon0_deg,
                k0,
                radius_m,
            } => {
                let (sin_lon0, cos_lon0) = lon0_deg.to_radians().sin_cos();
                UnitProjector::Stereographic {
                    south,
                    sin_lon0,
                    cos_lon0,
                    two_r_k0_m: 2.0 * radius_m * k0,
                }
            }
            other => UnitProjector::Other(other),
        }
    }

    /// A lower bound of the angle (radians) at the Moon's centre between map point
    /// `(x_m, y_m)` and any map point at least `dist_m` from it and at most `reach_m` from the
    /// map origin, or `None` for a projection without the bound. Polar stereographic: with
    /// `P`, `Q` the points in units of `2 R k0`, their sphere points are
    /// `2 |P − Q| / √((1 + |P|²)(1 + |Q|²))` apart (chord of the unit sphere).
    pub(crate) fn min_angle_rad(
        &self,
        (x_m, y_m): (f64, f64),
        dist_m: f64,
        reach_m: f64,
    ) -> Option<f64> {
        match *self {
            UnitProjector::Stereographic { two_r_k0_m, .. } => {
                let t = two_r_k0_m;
                let p2 = (x_m * x_m + y_m * y_m) / (t * t);
                let q2 = (reach_m / t).powi(2);
                let chord = 2.0 * (dist_m.max(0.0) / t) / ((1.0 + p2) * (1.0 + q2)).sqrt();
                Some(2.0 * (0.5 * chord).min(1.0).asin())
            }
            UnitProjector::Other(_) => None,
        }
    }

    /// Map coordinates (m) of the unit radial vector `u`.
    #[inline]
    pub(crate) fn xy_from_unit(&self, u: &Vector3<f64>) -> (f64, f64) {
        match *self {
            UnitProjector::Stereographic {
                south,
                sin_lon0,
                cos_lon0,
                two_r_k0_m,
            } => {
                // sin(lon - lon0) cos(lat) and cos(lon - lon0) cos(lat).
                let e = u.y * cos_lon0 - u.x * sin_lon0;
                let n = u.x * cos_lon0 + u.y * sin_lon0;
                if south {
                    let f = two_r_k0_m / (1.0 - u.z);
                    (f * e, f * n)
                } else {
                    let f = two_r_k0_m / (1.0 + u.z);
                    (f * e, -f * n)
                }
            }
            UnitProjector::Other(p) => {
                let lat_deg = u.z.clamp(-1.0, 1.0).asin().to_degrees();
                let lon_deg = u.y.atan2(u.x).to_degrees();
                p.xy_from_lat_lon(lat_deg, lon_deg)
            }
        }
    }

    /// The unit radial vector (`MOON_ME`) of map point `(x_m, y_m)`: the inverse of
    /// [`Self::xy_from_unit`] (rational for polar stereographic: with `q = (x² + y²) / (2 R k0)²`,
    /// the axial component is `±(q − 1) / (q + 1)` and the horizontal ones `2 (x, y) / (2 R k0 (1 + q))`
    /// turned back by `lon0`).
    #[inline]
    pub(crate) fn unit_from_xy(&self, x_m: f64, y_m: f64) -> Vector3<f64> {
        match *self {
            UnitProjector::Stereographic {
                south,
                sin_lon0,
                cos_lon0,
                two_r_k0_m,
            } => {
                let (a, b) = (x_m / two_r_k0_m, y_m / two_r_k0_m);
                let q = a * a + b * b;
                let s = 2.0 / (1.0 + q);
                // e, n: the components along the rotated lon0 axes (see xy_from_unit).
                let (e, n, z) = if south {
                    (a * s, b * s, (q - 1.0) / (q + 1.0))
                } else {
                    (a * s, -b * s, (1.0 - q) / (1.0 + q))
                };
                Vector3::new(n * cos_lon0 - e * sin_lon0, e * cos_lon0 + n * sin_lon0, z)
            }
            UnitProjector::Other(p) => {
                let (lat_deg, lon_deg) = p.lat_lon_from_xy(x_m, y_m);
                let (sl, cl) = lat_deg.to_radians().sin_cos();
                let (so, co) = lon_deg.to_radians().sin_cos();
                Vector3::new(cl * co, cl * so, sl)
            }
        }
    }
}

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
}

//! The Moon beyond the DEM: where a site's rays leave the outermost layer, and the lowest
//! horizon a bare 1737.4 km sphere there would set.
//!
//! A scan sees only the terrain the layers hold; a ray that leaves them still descending can
//! meet the Moon beyond. Along azimuth `az` the ray leaves the layers at ground angle `p` from
//! the site; for an observer at `r0` from the centre it meets the sphere beyond that exit when
//! its elevation is below `e*(p) = atan((R cos p − r0) / (R sin p))` (or below the geometric
//! horizon `−acos(R / r0)` when the exit is nearer than the ray's lowest point), the same cut
//! the map products count their below-sphere rays with (`horizon::statistics::BeyondDem`).
//! Raising a horizon to that floor is what a bare sphere beyond the DEM would do.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::Horizon;
use crate::terrain::TerrainStack;
use crate::{MOON_RADIUS_KM, MOON_RADIUS_M};

/// The ground angle (rad) from `(lat, lon)` along `az_deg` at which the terrain ends: the first
/// point, stepping by a pixel of the layer under the current point, where no layer has a
/// surface (at most half the Moon away).
fn exit_angle_rad(
    stack: &TerrainStack,
    up: &Vector3<f64>,
    north: &Vector3<f64>,
    east: &Vector3<f64>,
    az_deg: f64,
) -> f64 {
    let (s, c) = az_deg.to_radians().sin_cos();
    let dir = c * north + s * east;
    let mut p = 0.0f64;
    while p < std::f64::consts::FRAC_PI_2 {
        let u = p.cos() * up + p.sin() * dir;
        let (lat, lon, _) = crate::frames::lat_lon_height_from_moon_me_km(&(u * MOON_RADIUS_KM));
        match stack.height_at_lat_lon_m(lat, lon) {
            Some((_, layer)) => p += stack.layers[layer].px_m() / MOON_RADIUS_M,
            None => return p,
        }
    }
    p
}

/// The horizon floor a bare sphere beyond the layers sets at each of `horizon`'s azimuths,
/// degrees (see the module docs).
pub fn sphere_floor_deg(stack: &TerrainStack, horizon: &Horizon) -> Vec<f64> {
    let r = MOON_RADIUS_M;
    let r0 = r + horizon.ground_height_m + horizon.observer_height_m;
    let enu = crate::frames::enu_from_moon_me(horizon.lat_deg, horizon.lon_deg);
    let (east, north, up) = (
        enu.row(0).transpose(),
        enu.row(1).transpose(),
        enu.row(2).transpose(),
    );
    let dip_rad = if r0 > r { (r / r0).acos() } else { 0.0 };
    horizon
        .az_deg
        .par_iter()
        .map(|&az| {
            let p = exit_angle_rad(stack, &up, &north, &east, az);
            let cut = (p > 0.0 && p > (r.min(r0) / r.max(r0)).acos())
                .then(|| ((r * p.cos() - r0) / (r * p.sin())).atan());
            match cut {
                Some(c) if c < -dip_rad => c.to_degrees(),
                _ => -dip_rad.to_degrees(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::horizon::{HorizonEngine, HorizonParams};
    use crate::terrain::synth;

    /// The highest elevation (deg) at which a ray from `r0` (m from the centre) meets the
    /// sphere at a ground angle beyond `p` (rad), by brute force: elevations stepped by
    /// 0.0002°, each ray intersected with the sphere (`|o + t d| = R`), "meets beyond" when the
    /// far intersection lies past angle `p`. No `atan` closed form involved.
    fn brute_floor_deg(r0: f64, p: f64) -> f64 {
        let r = MOON_RADIUS_M;
        let mut e_deg: f64 = 0.0;
        while e_deg > -10.0 {
            let (s, c) = e_deg.to_radians().sin_cos();
            // |(0, r0) + t (c, s)|² = R²  →  t² + 2 r0 s t + r0² − R² = 0.
            let disc = (r0 * s).powi(2) - (r0 * r0 - r * r);
            if disc > 0.0 {
                let t2 = -r0 * s + disc.sqrt();
                if t2 > 0.0 && (t2 * c).atan2(r0 + t2 * s) > p {
                    return e_deg;
                }
            }
            e_deg -= 0.0002;
        }
        f64::NAN
    }

    /// A level DEM centred on the pole, the observer at the pole: along azimuth `az` the
    /// layer ends at map distance `ρ = L / max(|cos az|, |sin az|)` (its square edge), ground
    /// angle `p = 2 atan(ρ / 2R)` (polar stereographic, k0 = 1). Two heights: 300 m (every ray
    /// below the geometric horizon meets the sphere: the floor is the dip) and 0 m (the edge
    /// lies beyond the rays' lowest points: the floor is the cut).
    #[test]
    fn floor_of_a_level_square_dem_matches_brute_force_ray_sphere_intersection() {
        let (n, px_m) = (200usize, 100.0);
        for h_m in [300.0, 0.0] {
            let stack = TerrainStack::new(vec![synth::flat(n, n, px_m, h_m)]);
            let params = HorizonParams {
                observer_height_m: 2.0,
                az_step_deg: 5.0,
                ..HorizonParams::default()
            };
            let horizon = HorizonEngine::new(&stack)
                .horizon(-90.0, 0.0, &params)
                .unwrap();
            let floor = sphere_floor_deg(&stack, &horizon);
            let r0 = MOON_RADIUS_M + h_m + 2.0;
            let half_m = n as f64 * px_m / 2.0;
            let mut worst: f64 = 0.0;
            for (&az, &got) in horizon.az_deg.iter().zip(&floor) {
                // At the pole, azimuth 0 points along a map axis (the prime meridian); the
                // square is symmetric under quarter turns and reflections.
                let a = az.to_radians();
                let rho = half_m / a.cos().abs().max(a.sin().abs());
                let p = 2.0 * (rho / (2.0 * MOON_RADIUS_M)).atan();
                worst = worst.max((got - brute_floor_deg(r0, p)).abs());
            }
            // The march steps one pixel (100 m: 5.8e-5 rad of ground angle, which moves the
            // cut by about half that, 0.0017°), the brute force 0.0002°.
            assert!(worst < 0.003, "h {h_m} m: worst floor error {worst} deg");
        }
    }
}

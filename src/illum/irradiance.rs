//! Solar irradiance (W/m²) from the solar constant, the Sun's range and the visible fraction.
//!
//! ```text
//! E_normal     = S0 · (1 au / d)² · f          on a surface facing the Sun
//! E_horizontal = E_normal · max(sin el, 0)     on a level surface (normal = local up)
//! E_vertical   = E_normal · cos el             on a vertical panel turned to the Sun's azimuth
//! ```
//!
//! `S0` = [`crate::SOLAR_CONSTANT_W_M2`] (total solar irradiance at 1 au), `d` the Sun's range,
//! `f` the visible (flux) fraction of the disc, `el` the elevation of the disc centre. The Sun is
//! treated as a point at its centre for the incidence angle (the disc's 0.27° radius changes the
//! cosine factor by < 0.5% of `sin el` only when el < ~0.5°, where `f` dominates anyway). No
//! light reflected or emitted by the terrain is included. The sin/cos factors use the elevation
//! above the local horizontal plane (normal to the radial direction), i.e. a level surface of the
//! reference sphere, not the local slope.

use crate::{AU_KM, SOLAR_CONSTANT_W_M2};

/// Irradiance on a surface facing the Sun (W/m²): `S0 · (AU/range)² · visible_fraction`.
pub fn normal_irradiance_w_m2(sun_range_km: f64, visible_fraction: f64) -> f64 {
    let scale = AU_KM / sun_range_km;
    SOLAR_CONSTANT_W_M2 * scale * scale * visible_fraction
}

/// Irradiance on a level (horizontal) surface (W/m²): the normal irradiance times
/// `sin(sun_el_deg)`, 0 when the Sun's centre is below the horizontal plane.
pub fn horizontal_irradiance_w_m2(
    sun_range_km: f64,
    sun_el_deg: f64,
    visible_fraction: f64,
) -> f64 {
    let sin_el = sun_el_deg.to_radians().sin().max(0.0);
    normal_irradiance_w_m2(sun_range_km, visible_fraction) * sin_el
}

/// Irradiance on a vertical panel that tracks the Sun's azimuth (W/m²): the normal irradiance
/// times `cos(sun_el_deg)`.
pub fn vertical_tracking_irradiance_w_m2(
    sun_range_km: f64,
    sun_el_deg: f64,
    visible_fraction: f64,
) -> f64 {
    normal_irradiance_w_m2(sun_range_km, visible_fraction) * sun_el_deg.to_radians().cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative tolerance for closed-form checks: a few ulps.
    const REL_TOL: f64 = 1e-14;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= REL_TOL * b.abs().max(1.0)
    }

    #[test]
    fn one_au_full_disc_is_the_solar_constant() {
        assert!(close(normal_irradiance_w_m2(AU_KM, 1.0), 1360.8));
        assert!(close(normal_irradiance_w_m2(AU_KM, 0.5), 680.4));
        // Inverse-square: at 2 au a quarter.
        assert!(close(normal_irradiance_w_m2(2.0 * AU_KM, 1.0), 340.2));
        // Perihelion-like range 0.983 au: 1360.8 / 0.983².
        assert!(close(
            normal_irradiance_w_m2(0.983 * AU_KM, 1.0),
            1360.8 / (0.983 * 0.983)
        ));
    }

    #[test]
    fn horizontal_and_vertical_factors() {
        // sin 30° = 1/2, cos 60° = 1/2, sin 90° = 1, cos 0° = 1.
        assert!(close(horizontal_irradiance_w_m2(AU_KM, 30.0, 1.0), 680.4));
        assert!(close(horizontal_irradiance_w_m2(AU_KM, 90.0, 1.0), 1360.8));
        assert!(close(
            vertical_tracking_irradiance_w_m2(AU_KM, 60.0, 1.0),
            680.4
        ));
        assert!(close(
            vertical_tracking_irradiance_w_m2(AU_KM, 0.0, 0.25),
            340.2
        ));
        // Below the horizontal plane a level surface gets nothing, a vertical one cos(el).
        assert_eq!(horizontal_irradiance_w_m2(AU_KM, -0.5, 0.3), 0.0);
        let v = vertical_tracking_irradiance_w_m2(AU_KM, -0.5, 0.3);
        assert!(close(v, 1360.8 * 0.3 * 0.5_f64.to_radians().cos()));
        // Polar case: Sun at 1.5° elevation, fully visible: sin/cos closed forms.
        let el = 1.5_f64;
        let h = horizontal_irradiance_w_m2(AU_KM, el, 1.0);
        let v = vertical_tracking_irradiance_w_m2(AU_KM, el, 1.0);
        assert!(close(h * h + v * v, 1360.8 * 1360.8), "sin² + cos² = 1");
    }
}

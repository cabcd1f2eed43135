//! The light directions of each epoch in a model grid's frame.

use hifitime::Epoch;

use super::MapGrid;
use crate::ephem::{self, AbCorr, Kernels};

/// The light directions (model space) and angular radii of one epoch.
#[derive(Debug, Clone, Copy)]
pub struct EpochLights {
    /// The epoch.
    pub epoch: Epoch,
    /// Unit vector to the Sun, model space.
    pub sun: [f64; 3],
    /// The Sun's angular radius, radians.
    pub sun_radius_rad: f64,
    /// Unit vector to the Earth, model space.
    pub earth: [f64; 3],
    /// The Earth's angular radius, radians.
    pub earth_radius_rad: f64,
}

/// Light directions for every epoch, seen from the map centre (f64 ephemeris reduced to unit
/// vectors in model space).
pub fn epoch_lights(
    grid: &MapGrid,
    kernels: &Kernels,
    epochs: &[Epoch],
    abcorr: AbCorr,
) -> anyhow::Result<Vec<EpochLights>> {
    let site = grid.centre_site()?;
    let sky = ephem::sun_earth_series(kernels, &[site], epochs, abcorr)?;
    Ok(epochs
        .iter()
        .zip(&sky[0])
        .map(|(&epoch, v)| EpochLights {
            epoch,
            sun: grid.light_from_moon_me(&v.sun.pos_in_moon_me_km),
            sun_radius_rad: v.sun.radius_deg.to_radians(),
            earth: grid.light_from_moon_me(&v.earth.pos_in_moon_me_km),
            earth_radius_rad: v.earth.radius_deg.to_radians(),
        })
        .collect())
}

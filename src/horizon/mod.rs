//! Terrain horizons: the elevation of the terrain horizon against azimuth for an observer
//! standing on a [`TerrainStack`], in exact 3-D geometry on the Moon's reference sphere.
//!
//! ```text
//!   observer O at r0 = R + h_ground + h_obs (radial)        terrain point T at R + h(theta)
//!        O . . . . . . . . . . . . . . . . . . . . . . . . T      on the great circle that leaves
//!        |\  el = atan2((R+h) cos theta - r0, (R+h) sin theta)    O with initial azimuth az
//!        | \________ theta = ground angle O-centre-T
//! ```
//!
//! [`HorizonMethod::Exact`] samples every crossing of the path with the lines through cell
//! centres and the tangent point of every bilinear patch crossed (the maximum over the bilinear
//! surface); [`HorizonMethod::Fast`] skips what a block-maximum bound says cannot beat the
//! current horizon by more than `fast_tolerance_deg`, so its error lies in
//! `[-fast_tolerance_deg, 0]` by construction. Terrain nearer than `min_distance_m` (half a cell)
//! is the observer's own ground and is ignored; a direction with no terrain has horizon `-90°`
//! and distance `NaN`. Definitions, methods and measurements: `docs/horizon.md`.

pub mod beyond;
mod io;
mod scan;
pub mod statistics;
pub mod sweep;

pub use io::{write_csv, write_json};
pub use scan::HorizonEngine;
pub use sweep::{HorizonSweep, SweepBand, SweepDirection, SweepParams, SweepScratch, SweptLine};

use serde::Serialize;

use crate::terrain::TerrainStack;

/// Default azimuth step, degrees (1440 azimuths).
pub const DEFAULT_AZ_STEP_DEG: f64 = 0.25;
/// Default skip tolerance of the fast method, degrees: its horizon is never more than this below
/// the exact scan's.
pub const DEFAULT_FAST_TOLERANCE_DEG: f64 = 0.002;

/// Errors of the horizon subsystem.
#[derive(Debug, thiserror::Error)]
pub enum HorizonError {
    /// The terrain stack has no layers.
    #[error("the terrain stack has no DEM layers")]
    NoLayers,
    /// Latitude or longitude is not a finite number or the latitude is outside [-90, 90].
    #[error("site latitude {lat_deg} / longitude {lon_deg} deg is not a valid position")]
    BadSite {
        /// Latitude given, degrees.
        lat_deg: f64,
        /// Longitude given, degrees.
        lon_deg: f64,
    },
    /// The site lies outside every DEM layer.
    #[error("site {lat_deg} deg, {lon_deg} deg lies outside every DEM layer ({layers})")]
    OffDem {
        /// Latitude of the site, degrees.
        lat_deg: f64,
        /// Longitude of the site, degrees.
        lon_deg: f64,
        /// Names of the layers, for the message.
        layers: String,
    },
    /// The site lies inside a layer but in a nodata hole of every layer covering it.
    #[error("site {lat_deg} deg, {lon_deg} deg lies in a nodata hole of {layer}")]
    InHole {
        /// Latitude of the site, degrees.
        lat_deg: f64,
        /// Longitude of the site, degrees.
        lon_deg: f64,
        /// The finest layer whose extent contains the site.
        layer: String,
    },
    /// The observer height is negative or not finite.
    #[error("observer height {observer_height_m} m must be a finite number >= 0")]
    BadObserverHeight {
        /// Height given, metres.
        observer_height_m: f64,
    },
    /// The azimuth step is not positive, too small, or 360 is not an integer multiple of it.
    #[error(
        "azimuth step {az_step_deg} deg must be > 0, >= 0.001 and divide 360 into a whole number of steps"
    )]
    BadAzStep {
        /// Step given, degrees.
        az_step_deg: f64,
    },
    /// The terrain stack cannot go to the GPU horizon scan (layer count, projection, size).
    #[error("the GPU horizon scan does not support this terrain stack: {reason}")]
    GpuUnsupported {
        /// What is unsupported.
        reason: String,
    },
    /// The whole-grid sweep cannot run on this stack or with these parameters.
    #[error("the horizon sweep does not support this input: {reason}")]
    SweepUnsupported {
        /// What is unsupported.
        reason: String,
    },
    /// Whole-grid horizons that do not belong to this terrain (grid, azimuths).
    #[error("the horizons do not fit this terrain: {reason}")]
    HorizonsMismatch {
        /// What differs.
        reason: String,
    },
    /// The caller's progress callback asked to stop.
    #[error("interrupted")]
    Interrupted,
    /// The kernel the statistics ran on elsewhere (the GPU) failed.
    #[error("statistics kernel: {0}")]
    Kernel(String),
    /// Keeping a finished block for a resumed run failed.
    #[error("checkpoint: {0}")]
    Checkpoint(String),
    /// A horizon GeoTIFF cannot be used.
    #[error("horizon map {path}: {detail}")]
    BadHorizonFile {
        /// The file.
        path: String,
        /// What is wrong.
        detail: String,
    },
    /// The fast method's tolerance is negative or not finite.
    #[error("fast-method tolerance {tolerance_deg} deg must be a finite number >= 0")]
    BadTolerance {
        /// Tolerance given, degrees.
        tolerance_deg: f64,
    },
}

/// How the horizon is scanned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum HorizonMethod {
    /// Every grid-line crossing and every bilinear patch maximum on the finest layer (reference).
    Exact,
    /// The exact scan with conservative block-maximum skipping (error <= the tolerance).
    Fast,
}

/// Parameters of a horizon computation.
#[derive(Debug, Clone, Copy)]
pub struct HorizonParams {
    /// Observer height above the terrain surface along the radial direction, metres (>= 0).
    pub observer_height_m: f64,
    /// Azimuth step, degrees; azimuths are `0, step, 2 step, …` up to 360 (excluded).
    pub az_step_deg: f64,
    /// Scan method.
    pub method: HorizonMethod,
    /// Skip tolerance of [`HorizonMethod::Fast`], degrees (ignored by the exact scan).
    pub fast_tolerance_deg: f64,
}

impl Default for HorizonParams {
    fn default() -> Self {
        HorizonParams {
            observer_height_m: crate::DEFAULT_OBSERVER_HEIGHT_M,
            az_step_deg: DEFAULT_AZ_STEP_DEG,
            method: HorizonMethod::Fast,
            fast_tolerance_deg: DEFAULT_FAST_TOLERANCE_DEG,
        }
    }
}

/// A horizon profile: elevation (and the distance to the terrain point that sets it) at evenly
/// spaced azimuths, clockwise from north.
#[derive(Debug, Clone, Serialize)]
pub struct Horizon {
    /// Site latitude, degrees.
    pub lat_deg: f64,
    /// Site east longitude, degrees.
    pub lon_deg: f64,
    /// Terrain height under the observer, metres above the 1737.4 km sphere.
    pub ground_height_m: f64,
    /// Observer height above the terrain, metres.
    pub observer_height_m: f64,
    /// Name of the layer that carries the observer.
    pub ground_layer: String,
    /// Terrain nearer than this ground distance is the observer's own cell and is ignored, metres.
    pub min_distance_m: f64,
    /// Method used.
    pub method: HorizonMethod,
    /// Azimuth step, degrees.
    pub az_step_deg: f64,
    /// Azimuths, degrees clockwise from north.
    pub az_deg: Vec<f64>,
    /// Horizon elevation at each azimuth, degrees above the plane normal to the radial direction
    /// (`-90` where there is no terrain).
    pub elevation_deg: Vec<f64>,
    /// Ground distance (on the reference sphere, `R * theta`) to the terrain point that sets the
    /// horizon, metres (`NaN` where there is no terrain).
    pub distance_m: Vec<f64>,
}

/// Computes the horizon of a site on a terrain stack (builds a [`HorizonEngine`]; reuse an engine
/// for many sites).
pub fn horizon(
    stack: &TerrainStack,
    lat_deg: f64,
    lon_deg: f64,
    params: &HorizonParams,
) -> Result<Horizon, HorizonError> {
    HorizonEngine::new(stack).horizon(lat_deg, lon_deg, params)
}

/// Validates an azimuth step and returns the number of azimuths.
pub(crate) fn azimuth_count(az_step_deg: f64) -> Result<usize, HorizonError> {
    let bad = HorizonError::BadAzStep { az_step_deg };
    if !(az_step_deg.is_finite() && (0.001..=360.0).contains(&az_step_deg)) {
        return Err(bad);
    }
    let n = 360.0 / az_step_deg;
    let n_round = n.round();
    if (n - n_round).abs() > 1e-6 * n_round.max(1.0) {
        return Err(bad);
    }
    Ok(n_round as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn azimuth_step_validation() {
        assert_eq!(azimuth_count(0.25).unwrap(), 1440);
        assert_eq!(azimuth_count(1.0).unwrap(), 360);
        for bad in [0.0, -1.0, 0.7, f64::NAN, 400.0, 1e-5] {
            assert!(azimuth_count(bad).is_err(), "{bad}");
        }
    }
}

//! Ephemerides: the Sun's and the Earth's topocentric directions in `MOON_ME`, from SPICE kernels
//! read with `anise`, at UTC epochs handled by `hifitime`. Everything here is `f64`.
//!
//! - [`kernels`]: finding and loading the kernel set, its coverage.
//! - [`time`]: UTC parsing, steps and epoch ranges.
//! - [`topo`]: the SPICE-exact topocentric computation (light time + stellar aberration).

pub mod earth;
pub mod embedded;
pub mod kernels;
pub mod metakernel;
pub mod time;
pub mod topo;

pub use kernels::Kernels;
pub use topo::{AbCorr, Apparent, MoonGeometry, Site, SunEarth};

/// Errors of the ephemeris subsystem.
#[derive(Debug, thiserror::Error)]
pub enum EphemError {
    /// An epoch string could not be parsed as UTC.
    #[error("bad UTC epoch '{text}': {why}")]
    BadEpoch {
        /// The text given.
        text: String,
        /// What is wrong with it.
        why: String,
    },
    /// A time step could not be parsed or is not positive.
    #[error("bad time step '{text}': {why}")]
    BadStep {
        /// The text given.
        text: String,
        /// What is wrong with it.
        why: String,
    },
    /// An epoch range is empty or too large.
    #[error("bad epoch range: {why}")]
    BadRange {
        /// What is wrong with it.
        why: String,
    },
    /// An unknown aberration-correction name.
    #[error("unknown aberration correction '{0}' (use lt+s or none)")]
    BadAbCorr(String),
    /// A site's coordinates are out of range.
    #[error("bad site: {0}")]
    BadSite(String),
    /// The kernel folder is missing, empty or incomplete.
    #[error("kernel folder {path}: {why}")]
    KernelDir {
        /// The folder.
        path: String,
        /// What is wrong with it.
        why: String,
    },
    /// One kernel file could not be read or parsed.
    #[error("kernel {path}: {why}")]
    Kernel {
        /// The file.
        path: String,
        /// What is wrong with it.
        why: String,
    },
    /// An epoch lies outside the time span that the kernels cover.
    #[error("epoch {epoch} UTC is outside the kernels' coverage {start} .. {stop} UTC")]
    OutsideCoverage {
        /// The epoch asked for.
        epoch: String,
        /// First covered epoch.
        start: String,
        /// Last covered epoch.
        stop: String,
    },
    /// An `anise` query failed.
    #[error("ephemeris query failed while {action}: {why}")]
    Query {
        /// What was being computed.
        action: &'static str,
        /// anise's message.
        why: String,
    },
}

use anise::prelude::Epoch;
use rayon::prelude::*;

/// The Moon-centred geometry of every epoch (four `anise` queries each, in parallel), after
/// checking every epoch against the kernels' coverage. This table is what all sites share: at
/// ≈300 bytes an epoch, 18.6 years hourly take ≈50 MB.
pub fn moon_geometry_table(
    kernels: &Kernels,
    epochs: &[Epoch],
) -> Result<Vec<MoonGeometry>, EphemError> {
    if let Some(&e) = epochs.iter().find(|&&e| kernels.check_epoch(e).is_err()) {
        kernels.check_epoch(e)?;
    }
    epochs
        .par_iter()
        .with_min_len(256)
        .map(|&epoch| MoonGeometry::at(kernels, epoch))
        .collect()
}

/// Sun and Earth seen from every site at every epoch, indexed `[site][epoch]`.
///
/// The Moon-centred geometry is queried once per epoch ([`moon_geometry_table`]) and shared by all
/// sites; each site then costs a few hundred flops per epoch. For many sites over long spans,
/// prefer [`moon_geometry_table`] + [`topo::sun_earth`] in a streaming loop: this function keeps
/// every result (112 bytes per site and epoch).
pub fn sun_earth_series(
    kernels: &Kernels,
    sites: &[Site],
    epochs: &[Epoch],
    abcorr: AbCorr,
) -> Result<Vec<Vec<SunEarth>>, EphemError> {
    let table = moon_geometry_table(kernels, epochs)?;
    Ok(sites
        .par_iter()
        .map(|site| {
            table
                .iter()
                .map(|geo| topo::sun_earth(geo, site, abcorr))
                .collect()
        })
        .collect())
}

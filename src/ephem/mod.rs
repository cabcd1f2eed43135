//! Ephemerides: the Sun's and the Earth's topocentric directions in `MOON_ME`, from SPICE kernels
//! read with `anise`, at UTC epochs handled by `hifitime`. Everything here is `f64`.
//!
//! - [`kernels`]: finding and loading the kernel set, its coverage.
//! - [`time`]: UTC parsing, steps and epoch ranges.
//! - [`topo`]: the SPICE-exact topocentric computation (light time + stellar aberration).

pub mod kernels;
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

/// Sun and Earth seen from every site at every epoch, indexed `[site][epoch]`.
///
/// The Moon-centred geometry is queried once per epoch and shared by all sites, so the cost is
/// about four `anise` queries per epoch plus a few hundred flops per site and epoch. Epochs are
/// processed in parallel (rayon). Every epoch is checked against the kernels' coverage first.
pub fn sun_earth_series(
    kernels: &Kernels,
    sites: &[Site],
    epochs: &[Epoch],
    abcorr: AbCorr,
) -> Result<Vec<Vec<SunEarth>>, EphemError> {
    for &e in epochs.iter().take(1).chain(epochs.iter().last()) {
        kernels.check_epoch(e)?;
    }
    if let Some(&e) = epochs.iter().find(|&&e| kernels.check_epoch(e).is_err()) {
        kernels.check_epoch(e)?;
    }
    let per_epoch: Vec<Vec<SunEarth>> = epochs
        .par_iter()
        .with_min_len(256)
        .map(|&epoch| {
            let geo = MoonGeometry::at(&kernels.almanac, epoch)?;
            Ok(sites
                .iter()
                .map(|site| topo::sun_earth(&geo, site, abcorr))
                .collect())
        })
        .collect::<Result<_, EphemError>>()?;
    // Transpose to [site][epoch].
    let mut out: Vec<Vec<SunEarth>> = (0..sites.len())
        .map(|_| Vec::with_capacity(epochs.len()))
        .collect();
    for row in per_epoch {
        for (site_out, v) in out.iter_mut().zip(row) {
            site_out.push(v);
        }
    }
    Ok(out)
}

//! Illumination: visible fractions of the Sun's and the Earth's discs above a horizon profile,
//! solar irradiance, time-series statistics and plots.
//!
//! * [`disc`]: the visible (optionally limb-darkened, flux-weighted) fraction of a disc given a
//!   horizon profile, by an exact strip integral or the fast circular-segment approximation.
//! * [`irradiance`]: W/m² from the solar constant, the Sun's range and the visible fraction.
//! * [`stats`]: time-weighted statistics of a per-site series (`stats.json`).
//! * [`plot`]: PNG plots of a series and of a horizon with the Sun's and the Earth's tracks.
//!
//! See `docs/illum.md` for the formulas, the definitions and the measured errors.

pub mod disc;
pub mod irradiance;
pub mod plot;
pub mod power;
pub mod stats;

pub use disc::{
    Disc, DiscMethod, HorizonProfile, LimbDarkening, chord_visible_fraction,
    polyline_visible_fraction_uniform, visible_fraction,
};

/// Errors of the illumination subsystem.
#[derive(Debug, thiserror::Error)]
pub enum IllumError {
    /// A horizon profile with no samples.
    #[error("horizon profile is empty")]
    EmptyHorizon,
    /// A horizon profile with a NaN or infinite elevation.
    #[error("horizon profile has a non-finite elevation {value} at sample {index}")]
    NonFiniteHorizon {
        /// Index of the offending sample.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// A time series with no samples.
    #[error("time series for site '{site}' is empty")]
    EmptySeries {
        /// The site's name.
        site: String,
    },
    /// A time step that is not a positive finite number of seconds.
    #[error("time step must be positive and finite, got {step_s} s")]
    BadStep {
        /// The step given, seconds.
        step_s: f64,
    },
    /// Series columns of different lengths.
    #[error("series for site '{site}': {what} has {got} samples, expected {expected}")]
    LengthMismatch {
        /// The site's name.
        site: String,
        /// Which column is wrong.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The expected length.
        expected: usize,
    },
    /// Sites combined into one figure must share the start epoch, step and length.
    #[error("site '{site}' does not share the time grid of the first site")]
    MismatchedGrids {
        /// The site whose grid differs.
        site: String,
    },
    /// Drawing a plot failed.
    #[error("plotting {what}: {message}")]
    Plot {
        /// What was being drawn.
        what: &'static str,
        /// The backend's message.
        message: String,
    },
    /// Writing an output file failed.
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// Serialising statistics failed.
    #[error("serialising statistics: {0}")]
    Json(#[from] serde_json::Error),
}

/// Limb-darkening choices for the Sun's visible fraction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LimbLaw {
    /// Uniform disc: the visible fraction is an area fraction.
    None,
    /// Eddington law `(2 + 3μ)/5`, for total (bolometric) irradiance: the default, since the
    /// irradiance columns are total irradiance.
    #[default]
    Eddington,
    /// Allen's 550 nm quadratic law (visible band).
    Allen550nm,
}

impl LimbLaw {
    /// The intensity law.
    pub fn law(self) -> LimbDarkening {
        match self {
            LimbLaw::None => LimbDarkening::UNIFORM,
            LimbLaw::Eddington => LimbDarkening::EDDINGTON,
            LimbLaw::Allen550nm => LimbDarkening::ALLEN_550NM,
        }
    }

    /// The name used on the command line and in scenarios.
    pub fn name(self) -> &'static str {
        match self {
            LimbLaw::None => "none",
            LimbLaw::Eddington => "eddington",
            LimbLaw::Allen550nm => "allen550nm",
        }
    }
}

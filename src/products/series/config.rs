//! What a series run is asked for besides its sites and epochs: engine, backend and disc settings
//! (the command line, the scenario `[series]` table and the Python module build the same).

use serde::{Deserialize, Serialize};

use crate::ephem::AbCorr;
use crate::horizon::HorizonMethod;
use crate::illum::{DiscMethod, LimbLaw};

/// Which engine computes the per-site visible fractions (`--engine`, scenario `[series] engine`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SeriesEngine {
    /// One horizon per site from every DEM layer ([`crate::horizon`]), then the strip integral of
    /// each disc against it.
    #[default]
    Horizon,
    /// The map pipeline: the model-space grid of the finest layer and the DP max-mipmap search at
    /// each site's point, per epoch and light ([`crate::compute::site_dp`]).
    SmapDp,
}

impl SeriesEngine {
    /// The name used on the command line and in scenarios.
    pub fn name(self) -> &'static str {
        match self {
            SeriesEngine::Horizon => "horizon",
            SeriesEngine::SmapDp => "smap-dp",
        }
    }
}

/// Settings of a series run.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SeriesConfig {
    /// Aberration correction of the ephemeris.
    pub abcorr: AbCorr,
    /// Disc integration method (`exact` strip integral or the fast approximations).
    pub disc_method: DiscMethod,
    /// Limb darkening of the Sun (the Earth's disc is always uniform).
    pub limb_darkening: LimbLaw,
    /// Horizon azimuth step, degrees.
    pub az_step_deg: f64,
    /// Horizon method.
    #[serde(with = "horizon_method_serde")]
    pub horizon_method: HorizonMethod,
    /// Whether to draw PNG plots.
    pub plots: bool,
    /// Whether to write the per-epoch CSV (statistics are always written).
    pub write_csv: bool,
    /// The engine of the visible fractions.
    pub engine: SeriesEngine,
    /// Where the horizons are computed: `auto` (default: the CPU scan for the horizon engine,
    /// the GPU for smap-dp when a hardware adapter exists), `cpu`, or `gpu` (the GPU horizon
    /// scan, sampled like the exact method; `horizon_method` is then ignored). See docs/gpu.md.
    #[serde(with = "backend_serde")]
    pub backend: crate::gpu::Backend,
    /// Ground stations of the link to Earth: `dsn` (default), `none` or a CSV file
    /// ([`crate::comms::Stations`]).
    pub stations: crate::comms::Stations,
    /// Elevation mask of the DSN stations and of file rows without their own, degrees.
    pub station_mask_deg: f64,
    /// Relays (`NAME=NAIF_ID`) as link targets, from `relay_spks` ([`crate::comms::Relay`]).
    pub relays: Vec<crate::comms::Relay>,
    /// The SPK files that hold the relays.
    pub relay_spks: Vec<std::path::PathBuf>,
    /// Slant-range limit of a relay link, km (none by default).
    pub relay_max_range_km: Option<f64>,
    /// A solar panel, load and battery: adds `power_w` (and `battery_wh`) to `series.csv` and
    /// the power statistics to `stats.json` ([`crate::illum::power`]); none by default.
    pub power: Option<crate::illum::power::PowerConfig>,
    /// Radius of each site's neighbourhood, metres: the key statistics at every pixel centre
    /// of the finest layer within it, their spread and the best spot (`neighbourhood.csv`,
    /// `stats.json`; docs/sites.md). `None`: 3 pixels of the layer under the site; 0: none.
    pub neighbourhood_m: Option<f64>,
}

mod backend_serde {
    use crate::gpu::Backend;
    use serde::{Deserialize as _, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(b: &Backend, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(b.as_str())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Backend, D::Error> {
        match String::deserialize(d)?.as_str() {
            "cpu" => Ok(Backend::Cpu),
            "gpu" => Ok(Backend::Gpu),
            "auto" => Ok(Backend::Auto),
            other => Err(serde::de::Error::custom(format!(
                "unknown backend '{other}' (use cpu, gpu or auto)"
            ))),
        }
    }
}

mod horizon_method_serde {
    use super::HorizonMethod;
    use serde::{Deserialize as _, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(m: &HorizonMethod, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(match m {
            HorizonMethod::Exact => "exact",
            HorizonMethod::Fast => "fast",
        })
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<HorizonMethod, D::Error> {
        match String::deserialize(d)?.as_str() {
            "exact" => Ok(HorizonMethod::Exact),
            "fast" => Ok(HorizonMethod::Fast),
            other => Err(serde::de::Error::custom(format!(
                "unknown horizon method '{other}' (use fast or exact)"
            ))),
        }
    }
}

impl Default for SeriesConfig {
    fn default() -> Self {
        SeriesConfig {
            abcorr: AbCorr::LtS,
            disc_method: DiscMethod::Exact,
            limb_darkening: LimbLaw::Eddington,
            az_step_deg: crate::horizon::DEFAULT_AZ_STEP_DEG,
            horizon_method: HorizonMethod::Fast,
            plots: true,
            write_csv: true,
            engine: SeriesEngine::Horizon,
            backend: crate::gpu::Backend::Auto,
            stations: crate::comms::Stations::Dsn,
            station_mask_deg: crate::comms::DEFAULT_MASK_DEG,
            relays: Vec::new(),
            relay_spks: Vec::new(),
            relay_max_range_km: None,
            power: None,
            neighbourhood_m: None,
        }
    }
}

//! What a series run is asked for: its sites, engine, backend and disc settings (the types the
//! command line, the scenario `[series]` table and the engines share), and their parsing.

use serde::{Deserialize, Serialize};

use crate::ephem::AbCorr;
use crate::horizon::HorizonMethod;
use crate::illum::{DiscMethod, LimbDarkening};

/// A named site of a series run.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SeriesSite {
    /// Name, used as the site's output folder.
    pub name: String,
    /// Planetocentric latitude, degrees.
    pub lat_deg: f64,
    /// East longitude, degrees.
    pub lon_deg: f64,
    /// Observer height above the ground, metres.
    pub height_above_ground_m: f64,
}

/// Limb-darkening choices for the Sun's visible fraction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
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

/// Which engine computes the per-site visible fractions (`--engine`, scenario `[series] engine`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SeriesEngine {
    /// One horizon per site from every DEM layer ([`crate::horizon`]), then the strip integral of
    /// each disc against it.
    #[default]
    Horizon,
    /// The map pipeline: the model-space grid of the finest layer and the DP max-mipmap search at
    /// each site's point, per epoch and light ([`crate::series::dp`]).
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
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
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
        }
    }
}

/// Parses a `--site NAME,LAT,LON[,HEIGHT_ABOVE_GROUND_M]` value.
pub fn parse_site_flag(text: &str, default_height_m: f64) -> anyhow::Result<SeriesSite> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let bad = || {
        anyhow::anyhow!("--site '{text}': expected NAME,LAT_DEG,LON_DEG[,HEIGHT_ABOVE_GROUND_M]")
    };
    if !(3..=4).contains(&parts.len()) || parts[0].is_empty() {
        return Err(bad());
    }
    let num = |s: &str| s.parse::<f64>().map_err(|_| bad());
    Ok(SeriesSite {
        name: parts[0].to_string(),
        lat_deg: num(parts[1])?,
        lon_deg: num(parts[2])?,
        height_above_ground_m: if parts.len() == 4 {
            num(parts[3])?
        } else {
            default_height_m
        },
    })
}

/// Checks site names (used as folder names) and heights.
pub fn validate_sites(sites: &[SeriesSite]) -> anyhow::Result<()> {
    let mut seen = std::collections::HashSet::new();
    for s in sites {
        if s.name.is_empty()
            || !s
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            anyhow::bail!("site name '{}' must be letters, digits, '-' or '_'", s.name);
        }
        if !seen.insert(s.name.as_str()) {
            anyhow::bail!("site name '{}' is used twice", s.name);
        }
        if s.height_above_ground_m.is_nan() || s.height_above_ground_m < 0.0 {
            anyhow::bail!(
                "site '{}': height above ground {} m must be >= 0",
                s.name,
                s.height_above_ground_m
            );
        }
    }
    Ok(())
}

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

/// Longest site name, characters.
pub const MAX_SITE_NAME_CHARS: usize = 100;

/// Checks one site name, which names the site's output folder: 1 … 100 characters, letters and
/// digits of any script, spaces (not at either end), `-`, `_`, `.`, `(`, `)`, `+`, `,`, `'`; not
/// starting with `.`. `Err` says why.
pub fn check_site_name(name: &str) -> Result<(), String> {
    let ok_char = |c: char| {
        c.is_alphanumeric() || matches!(c, ' ' | '-' | '_' | '.' | '(' | ')' | '+' | ',' | '\'')
    };
    if name.is_empty()
        || name.chars().count() > MAX_SITE_NAME_CHARS
        || name.trim() != name
        || name.starts_with('.')
        || !name.chars().all(ok_char)
    {
        return Err(format!(
            "site name '{}' must be 1 … {MAX_SITE_NAME_CHARS} letters, digits, spaces (not at \
             either end) or - _ . ( ) + , ' and not start with '.' (it names the site's folder)",
            name.escape_debug()
        ));
    }
    Ok(())
}

/// Checks site names (used as folder names: unique, also ignoring case, for case-insensitive
/// file systems) and heights.
pub fn validate_sites(sites: &[SeriesSite]) -> anyhow::Result<()> {
    let mut seen = std::collections::HashSet::new();
    for s in sites {
        check_site_name(&s.name).map_err(anyhow::Error::msg)?;
        if !seen.insert(s.name.to_lowercase()) {
            anyhow::bail!(
                "site name '{}' is used twice (names are folder names: they must differ in more \
                 than letter case)",
                s.name
            );
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

/// Largest sites file read, bytes.
const MAX_SITES_FILE_BYTES: u64 = 16 << 20;
/// Most sites in one file.
const MAX_SITES: usize = 100_000;

/// Reads the sites of `path`: a CSV table with a header (`name`, `lat_deg`, `lon_deg` and
/// optionally `height_m`; `lat`/`latitude`, `lon`/`longitude` and `height_above_ground_m` are
/// accepted too) or GeoJSON (`.geojson`/`.json`, or text starting with `{`): a FeatureCollection
/// of Points `[lon_deg, lat_deg]` (a third coordinate is ignored: heights here are above the
/// ground) with `properties.name` and optionally `properties.height_m`. Sites without a height
/// get `default_height_m`. Errors name the file and the row or feature.
pub fn read_sites_file(
    path: &std::path::Path,
    default_height_m: f64,
) -> anyhow::Result<Vec<SeriesSite>> {
    let text = crate::output::guard::read_small_text(path, MAX_SITES_FILE_BYTES)
        .map_err(|e| anyhow::anyhow!("sites file {}: {e}", path.display()))?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let json = ext == "geojson" || ext == "json" || text.trim_start().starts_with('{');
    let sites = if json {
        sites_from_geojson(&text, default_height_m)
    } else {
        sites_from_csv(&text, default_height_m)
    }
    .map_err(|e| anyhow::anyhow!("sites file {}: {e}", path.display()))?;
    if sites.is_empty() {
        anyhow::bail!("sites file {}: no sites", path.display());
    }
    if sites.len() > MAX_SITES {
        anyhow::bail!(
            "sites file {}: {} sites, at most {MAX_SITES}",
            path.display(),
            sites.len()
        );
    }
    Ok(sites)
}

fn sites_from_csv(text: &str, default_height_m: f64) -> Result<Vec<SeriesSite>, String> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .map_err(|e| format!("reading the header: {e}"))?
        .iter()
        .map(|h| h.to_ascii_lowercase())
        .collect();
    let column = |names: &[&str]| header.iter().position(|h| names.contains(&h.as_str()));
    let (Some(name), Some(lat), Some(lon)) = (
        column(&["name", "site"]),
        column(&["lat_deg", "lat", "latitude"]),
        column(&["lon_deg", "lon", "longitude"]),
    ) else {
        return Err(format!(
            "the header must name columns name, lat_deg and lon_deg (optionally height_m); it has: {}",
            header.join(", ")
        ));
    };
    let height = column(&["height_m", "height_above_ground_m"]);
    let mut sites = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        let record = record.map_err(|e| format!("line {line}: {e}"))?;
        let field = |k: usize| record.get(k).unwrap_or("");
        let num = |k: usize, what: &str| {
            field(k)
                .parse::<f64>()
                .map_err(|_| format!("line {line}: {what} '{}' is not a number", field(k)))
        };
        sites.push(SeriesSite {
            name: field(name).to_string(),
            lat_deg: num(lat, "latitude")?,
            lon_deg: num(lon, "longitude")?,
            height_above_ground_m: match height {
                Some(h) if !field(h).is_empty() => num(h, "height")?,
                _ => default_height_m,
            },
        });
        if sites.len() > MAX_SITES {
            break;
        }
    }
    Ok(sites)
}

fn sites_from_geojson(text: &str, default_height_m: f64) -> Result<Vec<SeriesSite>, String> {
    let doc: serde_json::Value =
        serde_json::from_str(text).map_err(|e| format!("not JSON: {e}"))?;
    let features = match doc.get("type").and_then(|t| t.as_str()) {
        Some("FeatureCollection") => doc
            .get("features")
            .and_then(|f| f.as_array())
            .ok_or("a FeatureCollection without a features array")?
            .clone(),
        Some("Feature") => vec![doc.clone()],
        _ => return Err("expected a GeoJSON FeatureCollection or Feature of Points".into()),
    };
    let mut sites = Vec::with_capacity(features.len());
    for (i, f) in features.iter().enumerate() {
        let geometry = f.get("geometry").unwrap_or(&serde_json::Value::Null);
        if geometry.get("type").and_then(|t| t.as_str()) != Some("Point") {
            return Err(format!("feature {i}: its geometry is not a Point"));
        }
        let coords = geometry
            .get("coordinates")
            .and_then(|c| c.as_array())
            .filter(|c| (2..=3).contains(&c.len()))
            .and_then(|c| Some((c[0].as_f64()?, c[1].as_f64()?)))
            .ok_or_else(|| format!("feature {i}: coordinates must be [lon_deg, lat_deg]"))?;
        let props = f.get("properties").unwrap_or(&serde_json::Value::Null);
        let name = props
            .get("name")
            .and_then(|n| n.as_str())
            .ok_or_else(|| format!("feature {i}: no properties.name"))?;
        let height = match props
            .get("height_m")
            .or_else(|| props.get("height_above_ground_m"))
        {
            None | Some(serde_json::Value::Null) => default_height_m,
            Some(h) => h
                .as_f64()
                .ok_or_else(|| format!("feature {i} ({name}): height_m is not a number"))?,
        };
        sites.push(SeriesSite {
            name: name.to_string(),
            lat_deg: coords.1,
            lon_deg: coords.0,
            height_above_ground_m: height,
        });
    }
    Ok(sites)
}

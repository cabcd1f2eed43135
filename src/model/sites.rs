//! Sites from a `--site` flag or a sites file (CSV or GeoJSON), each checked as it is read.

use super::{ObserverHeight, Site};

/// Parses a `--site NAME,LAT,LON[,HEIGHT_ABOVE_GROUND_M]` value.
pub fn parse_site_flag(text: &str, default_height: ObserverHeight) -> anyhow::Result<Site> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let bad = || {
        anyhow::anyhow!("--site '{text}': expected NAME,LAT_DEG,LON_DEG[,HEIGHT_ABOVE_GROUND_M]")
    };
    if !(3..=4).contains(&parts.len()) || parts[0].is_empty() {
        return Err(bad());
    }
    let num = |s: &str| s.parse::<f64>().map_err(|_| bad());
    let height = if parts.len() == 4 {
        ObserverHeight::new(num(parts[3])?)?
    } else {
        default_height
    };
    Ok(Site::new(parts[0], num(parts[1])?, num(parts[2])?, height)?)
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
/// get `default_height`. Errors name the file and the row or feature.
pub fn read_sites_file(
    path: &std::path::Path,
    default_height: ObserverHeight,
) -> anyhow::Result<Vec<Site>> {
    let text = crate::output::guard::read_small_text(path, MAX_SITES_FILE_BYTES)
        .map_err(|e| anyhow::anyhow!("sites file {}: {e}", path.display()))?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let json = ext == "geojson" || ext == "json" || text.trim_start().starts_with('{');
    let sites = if json {
        sites_from_geojson(&text, default_height)
    } else {
        sites_from_csv(&text, default_height)
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

fn sites_from_csv(text: &str, default_height: ObserverHeight) -> Result<Vec<Site>, String> {
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
        let height = match height {
            Some(h) if !field(h).is_empty() => {
                ObserverHeight::new(num(h, "height")?).map_err(|e| format!("line {line}: {e}"))?
            }
            _ => default_height,
        };
        sites.push(
            Site::new(
                field(name),
                num(lat, "latitude")?,
                num(lon, "longitude")?,
                height,
            )
            .map_err(|e| format!("line {line}: {e}"))?,
        );
        if sites.len() > MAX_SITES {
            break;
        }
    }
    Ok(sites)
}

fn sites_from_geojson(text: &str, default_height: ObserverHeight) -> Result<Vec<Site>, String> {
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
            None | Some(serde_json::Value::Null) => default_height,
            Some(h) => ObserverHeight::new(
                h.as_f64()
                    .ok_or_else(|| format!("feature {i} ({name}): height_m is not a number"))?,
            )
            .map_err(|e| format!("feature {i} ({name}): {e}"))?,
        };
        sites.push(
            Site::new(name, coords.1, coords.0, height).map_err(|e| format!("feature {i}: {e}"))?,
        );
    }
    Ok(sites)
}

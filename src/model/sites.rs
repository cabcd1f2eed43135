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
/// of Points `[lon_deg, lat_deg]` (or `[x_m, y_m]` in a lunar polar stereographic `crs`; a third
/// coordinate is ignored: heights here are above the ground) with `properties.name` and
/// optionally `properties.height_m` (any letter case). Sites without a height
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
    let crs = geojson_crs(&doc)?;
    let mut sites = Vec::with_capacity(features.len());
    for (i, f) in features.iter().enumerate() {
        let geometry = f.get("geometry").unwrap_or(&serde_json::Value::Null);
        if geometry.get("type").and_then(|t| t.as_str()) != Some("Point") {
            return Err(format!("feature {i}: its geometry is not a Point"));
        }
        let xy = geometry
            .get("coordinates")
            .and_then(|c| c.as_array())
            .filter(|c| (2..=3).contains(&c.len()))
            .and_then(|c| Some((c[0].as_f64()?, c[1].as_f64()?)))
            .ok_or_else(|| match crs {
                None => format!("feature {i}: coordinates must be [lon_deg, lat_deg]"),
                Some(_) => format!("feature {i}: coordinates must be [x_m, y_m]"),
            })?;
        let coords = match crs {
            None => xy,
            Some(p) => {
                let (lat, lon) = p.lat_lon_from_xy(xy.0, xy.1);
                (lon.rem_euclid(360.0), lat)
            }
        };
        // Property names as GIS tools write them: any letter case.
        let props_map = f
            .get("properties")
            .and_then(|p| p.as_object())
            .cloned()
            .unwrap_or_default();
        let prop = |names: &[&str]| {
            props_map
                .iter()
                .find(|(k, _)| names.iter().any(|n| k.eq_ignore_ascii_case(n)))
                .map(|(_, v)| v.clone())
        };
        let name_value = prop(&["name", "site"]);
        let name = name_value
            .as_ref()
            .and_then(|n| n.as_str())
            .ok_or_else(|| format!("feature {i}: no properties.name"))?;
        let height = match prop(&["height_m", "height_above_ground_m"]) {
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

/// The CRS of a GeoJSON document's coordinates: `None` for longitude/latitude in degrees (no
/// `crs` member, or a geographic lunar CRS: `IAU_2015:30100`, `ESRI:104903`, `OGC CRS84`), the
/// projection for the lunar polar stereographic CRSs penumbra writes (`IAU_2015:30135` south,
/// `IAU_2015:30130` north, on the 1737.4 km sphere); any other CRS is refused (its coordinates
/// would be read wrongly).
fn geojson_crs(doc: &serde_json::Value) -> Result<Option<crate::terrain::Projection>, String> {
    let Some(crs) = doc.get("crs") else {
        return Ok(None);
    };
    let name = crs
        .get("properties")
        .and_then(|p| p.get("name"))
        .and_then(|n| n.as_str())
        .ok_or("a `crs` member without properties.name (use a named CRS or none)")?;
    // `urn:ogc:def:crs:IAU_2015::30135`, `IAU_2015:30135`, `IAU:30135`, … → authority, code.
    let upper = name.to_ascii_uppercase();
    let parts: Vec<&str> = upper.split(':').filter(|p| !p.is_empty()).collect();
    let code = parts.last().copied().unwrap_or("");
    let authority = parts
        .iter()
        .rev()
        .skip(1)
        .find(|p| !p.chars().all(|c| c.is_ascii_digit() || c == '.'))
        .copied()
        .unwrap_or("");
    let polar = |south: bool| {
        Some(crate::terrain::Projection::PolarStereographic {
            south,
            lon0_deg: 0.0,
            k0: 1.0,
            radius_m: crate::MOON_RADIUS_M,
        })
    };
    match (authority, code) {
        ("OGC", "CRS84") | ("IAU_2015" | "IAU2015" | "IAU", "30100") | ("ESRI", "104903") => {
            Ok(None)
        }
        ("IAU_2015" | "IAU2015" | "IAU", "30135") => Ok(polar(true)),
        ("IAU_2015" | "IAU2015" | "IAU", "30130") => Ok(polar(false)),
        _ => Err(format!(
            "GeoJSON crs '{name}' is not one penumbra reads: give lunar longitude/latitude in degrees (no crs, IAU_2015:30100) or polar stereographic metres (IAU_2015:30135 south, IAU_2015:30130 north)"
        )),
    }
}

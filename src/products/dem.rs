//! `penumbra dem info|synth`: describe a DEM, or write the synthetic one.

use std::path::Path;

use crate::terrain::{self, DemInfo, synth};

/// Output format of [`info`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InfoFormat {
    /// `key: value` lines.
    #[default]
    Text,
    /// One JSON object.
    Json,
}

/// A DEM's description (size, pixel size, CRS, bounds, heights, nodata) and the bilinear height
/// at each `(lat_deg, lon_deg)` of `points`, as text or JSON. A point outside the DEM is an error.
pub fn info(file: &Path, format: InfoFormat, points: &[(f64, f64)]) -> anyhow::Result<String> {
    let dem = terrain::load_dem(file)?;
    let info = DemInfo::of(&dem);
    let stack = terrain::TerrainStack::new(vec![dem]);
    let heights = points
        .iter()
        .map(|&(lat, lon)| Ok((lat, lon, stack.height_at_lat_lon_m_checked(lat, lon)?.0)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(match format {
        InfoFormat::Text => {
            let mut out = info.to_text();
            for (lat, lon, h) in &heights {
                out.push_str(&format!("height at {lat}, {lon}: {h:.3} m\n"));
            }
            out
        }
        InfoFormat::Json => {
            let mut v = serde_json::to_value(&info)?;
            v["points"] = heights
                .iter()
                .map(|(lat, lon, h)| serde_json::json!({"lat_deg": lat, "lon_deg": lon, "height_m": h}))
                .collect();
            format!("{}\n", serde_json::to_string_pretty(&v)?)
        }
    })
}

/// Writes the deterministic synthetic south-polar DEM as a float32 GeoTIFF (atomically).
pub fn synth(params: &synth::SynthParams, out: &Path) -> anyhow::Result<()> {
    let dem = synth::south_polar_dem(params)?;
    let version = env!("CARGO_PKG_VERSION");
    terrain::write_dem(
        out,
        &dem,
        &[
            ("software", &format!("penumbra {version}")),
            ("synth_seed", &params.seed.to_string()),
            ("synth_size_px", &params.size_px.to_string()),
            ("synth_px_m", &params.px_m.to_string()),
            ("units", "m above the 1737.4 km sphere"),
        ],
    )?;
    Ok(())
}

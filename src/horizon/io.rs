//! The CSV and JSON writers of a [`Horizon`].

use std::io::Write;

use super::Horizon;

/// Writes `az_deg,horizon_el_deg,distance_m`, one row per azimuth (`NaN` distance where there is
/// no terrain).
pub fn write_csv(horizon: &Horizon, w: &mut dyn Write) -> std::io::Result<()> {
    writeln!(w, "az_deg,horizon_el_deg,distance_m")?;
    for ((az, el), d) in horizon
        .az_deg
        .iter()
        .zip(&horizon.elevation_deg)
        .zip(&horizon.distance_m)
    {
        writeln!(w, "{az:.4},{el:.6},{d:.1}")?;
    }
    Ok(())
}

/// Writes the profile and its site description as one JSON object (`null` for `NaN` distances).
pub fn write_json(horizon: &Horizon, w: &mut dyn Write) -> std::io::Result<()> {
    serde_json::to_writer_pretty(&mut *w, horizon)?;
    writeln!(w)
}

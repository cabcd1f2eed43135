//! `penumbra ephem`: the Sun's and the Earth's topocentric directions seen from one site.

use std::io::Write;
use std::path::PathBuf;

use hifitime::Epoch;

use super::{KernelSource, write_output};
use crate::ephem::{self, AbCorr, Site, SunEarth, time::format_iso};
use crate::model::Epochs;

/// Output formats of a table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TableFormat {
    /// Comma-separated values with a header row.
    #[default]
    Csv,
    /// A JSON document.
    Json,
}

/// What `penumbra ephem` computes.
#[derive(Debug, Clone)]
pub struct EphemRequest {
    /// The site: planetocentric latitude, east longitude (deg), height above the sphere (m).
    pub site: Site,
    /// The epochs.
    pub epochs: Epochs,
    /// Aberration correction.
    pub abcorr: AbCorr,
    /// The kernels.
    pub kernels: KernelSource,
    /// Output format.
    pub format: TableFormat,
    /// Output file (written atomically); stdout when `None`.
    pub out: Option<PathBuf>,
}

/// The exact CSV header of `penumbra ephem`.
pub const EPHEM_CSV_HEADER: &str = "utc,sun_az_deg,sun_el_deg,sun_range_km,sun_radius_deg,earth_az_deg,earth_el_deg,earth_range_km,earth_radius_deg";

/// Writes one `ephem` CSV row.
pub fn write_ephem_row(w: &mut dyn Write, epoch: Epoch, v: &SunEarth) -> std::io::Result<()> {
    writeln!(
        w,
        "{},{:.9},{:.9},{:.6},{:.9},{:.9},{:.9},{:.6},{:.9}",
        format_iso(epoch),
        v.sun.az_deg,
        v.sun.el_deg,
        v.sun.range_km,
        v.sun.radius_deg,
        v.earth.az_deg,
        v.earth.el_deg,
        v.earth.range_km,
        v.earth.radius_deg
    )
}

/// Runs `penumbra ephem`.
pub fn run(req: &EphemRequest) -> anyhow::Result<()> {
    let abcorr = req.abcorr;
    let site = req.site;
    let epochs = req.epochs.epochs();
    let kernels = req.kernels.load()?;
    let series = ephem::sun_earth_series(&kernels, &[site], &epochs, abcorr)?;
    let rows = &series[0];
    // Sub-solar and sub-Earth points go into the JSON output only (the CSV columns are fixed).
    let sub_points = if req.format == TableFormat::Json {
        use rayon::prelude::*;
        epochs
            .par_iter()
            .map(|&e| {
                let geo = ephem::MoonGeometry::at(&kernels, e)?;
                Ok((
                    ephem::topo::sub_body_point(&geo, &geo.sun_wrt_moon, abcorr),
                    ephem::topo::sub_body_point(&geo, &geo.earth_wrt_moon, abcorr),
                ))
            })
            .collect::<Result<Vec<_>, ephem::EphemError>>()?
    } else {
        Vec::new()
    };
    write_output(req.out.as_deref(), |w| {
        match req.format {
            TableFormat::Csv => {
                writeln!(w, "{EPHEM_CSV_HEADER}")?;
                for (e, v) in epochs.iter().zip(rows) {
                    write_ephem_row(w, *e, v)?;
                }
            }
            TableFormat::Json => {
                let doc = serde_json::json!({
                    "site": {"lat_deg": site.lat_deg, "lon_deg": site.lon_deg, "height_m": site.height_m},
                    "abcorr": abcorr.spice_name(),
                    "frame": "MOON_ME",
                    "epochs": epochs.iter().zip(rows).zip(&sub_points).map(|((e, v), (ss, se))| serde_json::json!({
                        "utc": format_iso(*e),
                        "sun": v.sun,
                        "earth": v.earth,
                        "subsolar_point": ss,
                        "sub_earth_point": se,
                    })).collect::<Vec<_>>(),
                });
                serde_json::to_writer_pretty(&mut *w, &doc)?;
                writeln!(w)?;
            }
        }
        Ok(())
    })
}

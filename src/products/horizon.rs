//! `penumbra horizon`: the terrain horizon seen by an observer above one site.

use std::path::PathBuf;

use super::write_output;
use crate::gpu::Backend;
use crate::horizon::{HorizonParams, write_csv, write_json};

/// Output format of a horizon profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HorizonFormat {
    /// `az_deg,horizon_el_deg,distance_m` rows.
    #[default]
    Csv,
    /// One JSON object with the site and the arrays.
    Json,
}

/// What `penumbra horizon` computes.
#[derive(Debug, Clone)]
pub struct HorizonRequest {
    /// DEM layers, finest first.
    pub dems: Vec<PathBuf>,
    /// Site planetocentric latitude, degrees.
    pub lat_deg: f64,
    /// Site east longitude, degrees.
    pub lon_deg: f64,
    /// Observer height, azimuth step and scan method.
    pub params: HorizonParams,
    /// Output format.
    pub format: HorizonFormat,
    /// Output file (written atomically); stdout when `None`.
    pub out: Option<PathBuf>,
    /// Compute backend (`gpu`: the GPU scan, sampled like the exact method).
    pub backend: Backend,
}

/// Runs `penumbra horizon`: loads the layers, computes the profile and writes it.
pub fn run(req: &HorizonRequest) -> anyhow::Result<()> {
    let stack = super::load_stack(&req.dems)?;
    // `auto` takes the CPU scan for one site (the fast method; the GPU scan samples like the
    // exact one): the same answer as the series' horizons.
    let backend = crate::compute::resolve(req.backend, crate::compute::OnGpu::WhenAsked)?;
    let horizon = crate::compute::horizons::site_horizon(
        &backend,
        &stack,
        req.lat_deg,
        req.lon_deg,
        &req.params,
    )?;
    write_output(req.out.as_deref(), |w| {
        match req.format {
            HorizonFormat::Csv => write_csv(&horizon, w)?,
            HorizonFormat::Json => write_json(&horizon, w)?,
        }
        Ok(())
    })
}

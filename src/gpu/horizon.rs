//! GPU runner of `shaders/horizon_scan.wgsl`: per-site terrain horizons, one invocation per
//! (site, azimuth), over the layers of a [`TerrainStack`] in their own grids (the terrain of the
//! CPU [`HorizonEngine`]). The data layout and the CPU twin are in
//! [`crate::twins::horizon_scan`].
//!
//! [`GpuHorizonScan::new`] builds the pipeline and uploads the concatenated heights once;
//! [`GpuHorizonScan::scan`] runs any number of sites (dispatches of at most
//! [`SITES_PER_DISPATCH`] sites, so that one submit stays short) and reads the `(tan el, ground
//! angle)` pairs back once. [`horizons_gpu`] is the whole path from sites to [`Horizon`]s.

use super::GpuError;
use std::sync::Arc;

use super::context::{ErrorScope, GpuContext, KernelPipeline, storage_init};
use crate::horizon::{Horizon, HorizonEngine, HorizonError};
use crate::terrain::TerrainStack;
use crate::twins::horizon_scan::{
    ScanParams, ScanTerrain, SiteParams, azimuth_table, site_setup, to_horizon,
};

/// Sites per dispatch (one submit each).
pub const SITES_PER_DISPATCH: u32 = 64;
/// Workgroup size along the azimuths. Keep in sync with shaders/horizon_scan.wgsl.
const WORKGROUP_SIZE: u32 = 64;

/// Errors of the GPU horizon path: a bad site or terrain (as on the CPU), or a GPU failure.
#[derive(Debug, thiserror::Error)]
pub enum GpuHorizonError {
    /// The site, the observer height, the azimuth step or the terrain stack is invalid.
    #[error(transparent)]
    Horizon(#[from] HorizonError),
    /// The GPU failed (device, validation, readback, limits).
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

single_kernel! {
    /// The horizon scan: params; heights, sites, azimuths; output.
    HorizonScanKernel = HORIZON_SCAN, 3, 1, "building the horizon_scan pipeline"
}

/// The horizon-scan pipeline and a terrain stack resident on the GPU.
pub struct GpuHorizonScan {
    kernel: Arc<KernelPipeline<HorizonScanKernel>>,
    params: ScanParams,
    params_buf: wgpu::Buffer,
    heights: wgpu::Buffer,
}

impl GpuHorizonScan {
    /// Builds the pipeline and uploads `terrain`. Fails when the heights exceed the adapter's
    /// storage binding limit.
    pub fn new(ctx: &GpuContext, terrain: &ScanTerrain) -> Result<Self, GpuError> {
        let bytes = terrain.heights_m.len() as u64 * 4;
        let limits = ctx.limits();
        if bytes
            > limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size)
        {
            return Err(GpuError::InvalidInput {
                kernel: "horizon_scan",
                message: format!(
                    "the terrain layers ({bytes} B) exceed the adapter's storage binding limit \
                     ({} B)",
                    limits.max_storage_buffer_binding_size
                ),
            });
        }
        let kernel = ctx.pipelines::<KernelPipeline<HorizonScanKernel>>()?;
        let scope = ErrorScope::push(&ctx.device);
        let params_buf = ctx.uniform_buffer(
            "penumbra horizon_scan params",
            size_of::<ScanParams>() as u64,
        );
        let heights = storage_init(ctx, "penumbra horizon_scan heights", &terrain.heights_m);
        scope.pop("uploading the horizon_scan terrain")?;
        Ok(GpuHorizonScan {
            kernel,
            params: terrain.params,
            params_buf,
            heights,
        })
    }

    /// `(tan el, ground angle rad)` for every (site, azimuth), `site * n_az + az` (as the twin
    /// [`crate::twins::horizon_scan::horizon_scan`]).
    pub fn scan(
        &self,
        ctx: &GpuContext,
        sites: &[SiteParams],
        azimuths: &[[f32; 2]],
    ) -> Result<Vec<[f32; 2]>, GpuError> {
        let n_out = sites.len() as u64 * azimuths.len() as u64;
        if n_out == 0 {
            return Ok(Vec::new());
        }
        let groups_x = (azimuths.len() as u32).div_ceil(WORKGROUP_SIZE);
        if groups_x > ctx.limits().max_compute_workgroups_per_dimension {
            return Err(GpuError::InvalidInput {
                kernel: "horizon_scan",
                message: format!("{} azimuths exceed one dispatch row", azimuths.len()),
            });
        }
        let scope = ErrorScope::push(&ctx.device);
        let site_buf = storage_init(ctx, "penumbra horizon_scan sites", sites);
        let az_buf = storage_init(ctx, "penumbra horizon_scan azimuths", azimuths);
        let out = ctx.output_buffer("penumbra horizon_scan out", n_out * 8);
        let bind_group = self.kernel.bind(
            ctx,
            &[&self.params_buf, &self.heights, &site_buf, &az_buf, &out],
        );
        let n_sites = sites.len() as u32;
        let mut site0 = 0;
        while site0 < n_sites {
            let chunk = SITES_PER_DISPATCH.min(n_sites - site0);
            let params = ScanParams {
                n_sites: chunk,
                n_az: azimuths.len() as u32,
                site0,
                ..self.params
            };
            ctx.queue
                .write_buffer(&self.params_buf, 0, bytemuck::bytes_of(&params));
            ctx.dispatch(
                "horizon_scan",
                &self.kernel.pipeline,
                &bind_group,
                &[],
                [groups_x, chunk, 1],
            );
            site0 += chunk;
        }
        let bytes = ctx.read_back(&out, n_out * 8, "the horizons")?;
        scope.pop("running horizon_scan")?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

/// Horizons of `sites` (`(lat_deg, lon_deg, observer_height_m)`) on the GPU: sites validated and
/// set up on the CPU exactly as [`HorizonEngine::horizon`] does, the scan on the GPU, `atan` on the
/// CPU. Pass a prepared `scan` (terrain uploaded once) to reuse it across calls.
pub fn horizons_gpu(
    ctx: &GpuContext,
    stack: &TerrainStack,
    scan: Option<&GpuHorizonScan>,
    sites: &[(f64, f64, f64)],
    az_step_deg: f64,
) -> Result<Vec<Horizon>, GpuHorizonError> {
    let engine = HorizonEngine::new(stack);
    let azimuths = azimuth_table(az_step_deg)?;
    let setups = sites
        .iter()
        .map(|&(lat, lon, h)| site_setup(&engine, lat, lon, h))
        .collect::<Result<Vec<_>, _>>()?;
    let owned;
    let scan = match scan {
        Some(s) => s,
        None => {
            owned = GpuHorizonScan::new(ctx, &ScanTerrain::new(stack)?)?;
            &owned
        }
    };
    let recs: Vec<SiteParams> = setups.iter().map(|s| s.site).collect();
    let out = scan.scan(ctx, &recs, &azimuths)?;
    Ok(setups
        .iter()
        .zip(out.chunks(azimuths.len()))
        .map(|(s, o)| to_horizon(s, az_step_deg, o))
        .collect())
}

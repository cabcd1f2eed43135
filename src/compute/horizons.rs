//! Horizons on the resolved backend: one site's profile, and a whole-grid Fourier horizon map.

use crate::horizon::{Horizon, HorizonEngine, HorizonParams, HorizonSweep, SweepBand};
use crate::shadow::fourier::{HorizonMap, HorizonMapParams};
use crate::terrain::{HeightField, TerrainStack};

use super::ResolvedBackend;

/// The horizon of the observer `params.observer_height_m` above the ground at (`lat_deg`,
/// `lon_deg`) over every layer of `stack`: the CPU scan of `params.method`, or the GPU scan
/// (sampled like the exact method).
pub fn site_horizon(
    backend: &ResolvedBackend,
    stack: &TerrainStack,
    lat_deg: f64,
    lon_deg: f64,
    params: &HorizonParams,
) -> anyhow::Result<Horizon> {
    match backend {
        ResolvedBackend::Cpu => Ok(HorizonEngine::new(stack).horizon(lat_deg, lon_deg, params)?),
        #[cfg(feature = "gpu")]
        ResolvedBackend::Gpu(ctx) => {
            let site = (lat_deg, lon_deg, params.observer_height_m);
            let mut hz =
                crate::gpu::horizon::horizons_gpu(ctx, stack, None, &[site], params.az_step_deg)?;
            anyhow::Context::context(hz.pop(), "the GPU horizon scan returned no site")
        }
        #[cfg(not(feature = "gpu"))]
        ResolvedBackend::Gpu(ctx) => match **ctx {},
    }
}

/// The Fourier-compressed horizon map of `hf` (CPU f64 engine, or `fourier_build.wgsl` in f32).
pub fn horizon_map(
    backend: &ResolvedBackend,
    hf: &HeightField,
    params: &HorizonMapParams,
) -> anyhow::Result<HorizonMap> {
    match backend {
        ResolvedBackend::Cpu => Ok(HorizonMap::build_with(
            hf,
            params.observer_height_m,
            params.n_azimuths,
            params.max_distance_cells,
            params.n_coeffs,
        )?),
        #[cfg(feature = "gpu")]
        ResolvedBackend::Gpu(ctx) => {
            Ok(crate::gpu::fourier::build_horizon_map_gpu(ctx, hf, params)?)
        }
        #[cfg(not(feature = "gpu"))]
        ResolvedBackend::Gpu(ctx) => match **ctx {},
    }
}

/// The whole-grid line sweep on the resolved backend: the CPU sweep (f64, exact 3-D
/// elevations), or its looks on the GPU (`shaders/line_sweep.wgsl`, f32: lines built and packed
/// on the CPU, hulls and tangents on the GPU; within 0.01° of the CPU sweep, docs/gpu.md). Bands
/// go to `sink` in the same order and layout either way.
pub fn run_sweep(
    backend: &ResolvedBackend,
    sweep: &HorizonSweep,
    sink: impl FnMut(SweepBand<'_>) -> anyhow::Result<()>,
    progress: impl FnMut(usize),
) -> anyhow::Result<()> {
    match backend {
        ResolvedBackend::Cpu => sweep.run(sink, progress),
        #[cfg(feature = "gpu")]
        ResolvedBackend::Gpu(ctx) => {
            if ctx.is_software() {
                // llvmpipe stops a SIMD group's loops after 65,535 iterations in all (its
                // LP_MAX_TGSI_LOOP_ITERATIONS): long lines then lose their last looks silently.
                eprintln!(
                    "penumbra: warning: --backend gpu on a software adapter ({}): lavapipe cuts \
                     shader loops short, so looks along long lines may be wrong (measured on the \
                     1536² LOLA grid: up to 33 deg at 0.01 % of pixel-azimuths); use --backend cpu for \
                     results, see docs/gpu.md",
                    ctx.adapter_kind()
                );
            }
            crate::gpu::line_sweep::sweep_gpu(ctx, sweep, sink, progress)
        }
        #[cfg(not(feature = "gpu"))]
        ResolvedBackend::Gpu(ctx) => match **ctx {},
    }
}

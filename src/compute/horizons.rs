//! Horizons on the resolved backend: sites' profiles, the whole-grid line sweep, and a Fourier
//! horizon map.

use anyhow::Context as _;

use crate::horizon::{
    Horizon, HorizonEngine, HorizonMethod, HorizonParams, HorizonSweep, SweepBand,
};
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

/// The horizons of `sites` (in order) over every layer of `stack`, each `az_step_deg` of azimuth,
/// on the backend `requested` resolves to (`auto`: the CPU scan of `method`, the fast one for a
/// few sites; `gpu`: all sites in one GPU scan, sampled like the exact method), and what ran.
/// Errors name the site.
pub fn site_horizons(
    requested: super::Backend,
    stack: &TerrainStack,
    sites: &[crate::model::Site],
    az_step_deg: f64,
    method: HorizonMethod,
) -> anyhow::Result<(Vec<Horizon>, String)> {
    let engine = HorizonEngine::new(stack);
    match super::resolve(requested, super::OnGpu::WhenAsked)? {
        ResolvedBackend::Cpu => sites
            .iter()
            .map(|s| {
                let params = HorizonParams {
                    observer_height_m: s.height_above_ground_m(),
                    az_step_deg,
                    method,
                    ..HorizonParams::default()
                };
                engine
                    .horizon(s.lat_deg(), s.lon_deg(), &params)
                    .with_context(|| format!("horizon of site '{}'", s.name()))
            })
            .collect::<anyhow::Result<Vec<_>>>()
            .map(|h| (h, "cpu: per-site horizon scan".to_string())),
        #[cfg(feature = "gpu")]
        ResolvedBackend::Gpu(ctx) => {
            let specs: Vec<(f64, f64, f64)> = sites
                .iter()
                .map(|s| (s.lat_deg(), s.lon_deg(), s.height_above_ground_m()))
                .collect();
            for (s, &(lat, lon, h)) in sites.iter().zip(&specs) {
                crate::twins::horizon_scan::site_setup(&engine, lat, lon, h)
                    .with_context(|| format!("horizon of site '{}'", s.name()))?;
            }
            let horizons =
                crate::gpu::horizon::horizons_gpu(&ctx, stack, None, &specs, az_step_deg)?;
            Ok((
                horizons,
                super::site_dp::gpu_note(&ctx, "per-site horizon scan"),
            ))
        }
        #[cfg(not(feature = "gpu"))]
        ResolvedBackend::Gpu(ctx) => match *ctx {},
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

//! A map sweep (statistics over epochs) on the resolved backend.

use crate::map::{MapEngine, MapEngineKind, ObserverPlacement, SweepStats};
use crate::model::{EpochLights, MapGrid};

use super::ResolvedBackend;

/// The statistics of `lights` (one entry per epoch, `step_h` hours apart) over `grid`, and a
/// description of what ran for provenance. The CPU runs `engine` with rays from `placement`;
/// the GPU runs its DP sweep whatever `engine` says (docs/gpu.md), in tiles of
/// `gpu_tile_cells` when given.
#[allow(
    clippy::too_many_arguments,
    reason = "one call site per product; a struct would only rename the arguments"
)]
pub fn map_sweep(
    backend: &ResolvedBackend,
    grid: &MapGrid,
    engine: MapEngineKind,
    observer_height_m: f64,
    placement: ObserverPlacement,
    lights: &[EpochLights],
    step_h: f64,
    gpu_tile_cells: Option<u32>,
    progress: &indicatif::ProgressBar,
) -> anyhow::Result<(SweepStats, String)> {
    match backend {
        ResolvedBackend::Cpu => {
            let engine = MapEngine::new(engine, grid, observer_height_m)?;
            let stats = crate::map::sweep(
                grid,
                &engine,
                observer_height_m,
                placement,
                lights,
                step_h,
                progress,
            )?;
            let note = format!(
                "cpu: {} soft shadows of the discs, rays from the {}",
                engine.describe(),
                placement.describe()
            );
            Ok((stats, note))
        }
        #[cfg(feature = "gpu")]
        ResolvedBackend::Gpu(ctx) => {
            let stats = super::gpu_maps::sweep_gpu_soft(
                ctx,
                grid,
                observer_height_m,
                lights,
                step_h,
                crate::gpu::tiles::DpTiling {
                    tile_cells: gpu_tile_cells,
                },
            )?;
            progress.inc(lights.len() as u64);
            let note = format!(
                "{}: DP max-mipmap soft shadows of the Sun and Earth discs \
                 (GPU-resident sweep; --engine is not used on the GPU)",
                backend.describe()
            );
            Ok((stats, note))
        }
        #[cfg(not(feature = "gpu"))]
        ResolvedBackend::Gpu(ctx) => {
            let _ = gpu_tile_cells;
            match **ctx {}
        }
    }
}

//! One-light maps (the visible fraction of a disc, the hard mask of its centre) on the DEM's own
//! grid, on the resolved backend.
//!
//! Both backends start the rays at each DEM pixel's own surface point by default (or at the
//! model cells, resampled): the CPU runs the chosen engine, the GPU its DP max-mipmap kernel for
//! every engine but Fourier, whose horizon map is built and evaluated by the Fourier kernels
//! (docs/gpu.md), always at the model cells. A grid that needs the GPU's 2-D tiles is mapped
//! from its model cells on the GPU (with a warning).

use crate::map::{MapEngine, MapEngineKind, ObserverPlacement};
use crate::model::MapGrid;
use crate::shadow::Observer;

use super::ResolvedBackend;

/// Where the rays of a map start when `requested` (`None`: the DEM pixels' own surface points,
/// on either backend).
pub fn placement(requested: Option<ObserverPlacement>) -> ObserverPlacement {
    requested.unwrap_or(ObserverPlacement::Pixels)
}

/// A map grid ready for one-light maps on a backend (engine built, a GPU horizon map uploaded).
pub struct OneLightMaps<'a> {
    backend: &'a ResolvedBackend,
    grid: &'a MapGrid,
    observer_height_m: f64,
    placement: ObserverPlacement,
    engine: MapEngine,
    pixel_observers: Vec<Option<Observer>>,
    #[cfg(feature = "gpu")]
    gpu_fourier: Option<crate::gpu::fourier::GpuHorizonMap>,
    #[cfg(feature = "gpu")]
    tiling: crate::gpu::tiles::DpTiling,
    /// The DP kernels from the DEM pixels (GPU, placement pixels, an untiled grid).
    #[cfg(feature = "gpu")]
    gpu_pixels: Option<super::gpu_maps::GpuPixelMaps>,
}

impl<'a> OneLightMaps<'a> {
    /// Builds `engine` for `grid` on `backend` (the Fourier horizon map on the GPU there), with
    /// rays from `placement` (see [`placement`]) and GPU tiles of `gpu_tile_cells` when given.
    pub fn new(
        backend: &'a ResolvedBackend,
        grid: &'a MapGrid,
        engine: MapEngineKind,
        observer_height_m: f64,
        placement: ObserverPlacement,
        gpu_tile_cells: Option<u32>,
    ) -> anyhow::Result<Self> {
        let h_m = observer_height_m;
        #[cfg(not(feature = "gpu"))]
        let _ = gpu_tile_cells;
        let engine = match backend {
            #[cfg(feature = "gpu")]
            ResolvedBackend::Gpu(ctx) if engine == MapEngineKind::Fourier => {
                super::gpu_maps::fourier_engine_gpu(ctx, grid, h_m)?
            }
            _ => MapEngine::new(engine, grid, h_m)?,
        };
        #[cfg(feature = "gpu")]
        let gpu_fourier = match (backend, &engine) {
            (ResolvedBackend::Gpu(ctx), MapEngine::Fourier(map)) => Some({
                use anyhow::Context as _;
                crate::gpu::fourier::GpuHorizonMap::upload(ctx, map, crate::gpu::DEFAULT_BAND_BYTES)
                    .context("uploading the horizon map")?
            }),
            _ => None,
        };
        // Each DEM pixel's own observer (where the engines start their rays by default).
        let pixel_observers = grid.pixel_observers(h_m);
        #[cfg(feature = "gpu")]
        let tiling = crate::gpu::tiles::DpTiling {
            tile_cells: gpu_tile_cells,
        };
        #[cfg(feature = "gpu")]
        let (gpu_pixels, placement) = match backend {
            ResolvedBackend::Gpu(ctx) if gpu_fourier.is_none() => {
                super::gpu_maps::GpuPixelMaps::for_placement(
                    ctx,
                    grid,
                    &pixel_observers,
                    h_m,
                    tiling,
                    placement,
                )?
            }
            _ => (None, placement),
        };
        Ok(OneLightMaps {
            backend,
            grid,
            observer_height_m: h_m,
            placement,
            engine,
            pixel_observers,
            #[cfg(feature = "gpu")]
            gpu_fourier,
            #[cfg(feature = "gpu")]
            tiling,
            #[cfg(feature = "gpu")]
            gpu_pixels,
        })
    }

    /// Where the rays start: the model cells for the Fourier engine (its horizon map is per
    /// model cell) and on the GPU for a grid that needs tiles, else as asked.
    pub fn placement(&self) -> ObserverPlacement {
        match self.engine {
            MapEngine::Fourier(_) => ObserverPlacement::Cells,
            MapEngine::Direct(_) => self.placement,
        }
    }

    /// The observer of each DEM pixel (`None` for nodata pixels).
    pub fn pixel_observers(&self) -> &[Option<Observer>] {
        &self.pixel_observers
    }

    fn observers(&self) -> Option<&[Option<Observer>]> {
        (self.placement == ObserverPlacement::Pixels).then_some(self.pixel_observers.as_slice())
    }

    /// The visible fraction of a disc of angular radius `radius_rad` toward `light_in_model`,
    /// per DEM pixel (`NaN` for nodata).
    pub fn fraction(&self, light_in_model: [f64; 3], radius_rad: f64) -> anyhow::Result<Vec<f32>> {
        let (grid, h_m) = (self.grid, self.observer_height_m);
        #[cfg(feature = "gpu")]
        if let (ResolvedBackend::Gpu(ctx), Some(pixels)) = (self.backend, &self.gpu_pixels) {
            return pixels.fraction(ctx, light_in_model, radius_rad);
        }
        match self.backend {
            ResolvedBackend::Cpu => self.engine.visible_fraction_on_dem(
                grid,
                self.observers(),
                h_m,
                light_in_model,
                radius_rad,
            ),
            // The GPU kernels per model cell: resampled onto the DEM grid.
            #[cfg(feature = "gpu")]
            ResolvedBackend::Gpu(ctx) => Ok(grid.to_output_f32(&match &self.gpu_fourier {
                Some(on_gpu) => {
                    super::gpu_maps::fourier_fraction_gpu(ctx, on_gpu, light_in_model, radius_rad)?
                }
                None => super::gpu_maps::visible_fraction_gpu(
                    ctx,
                    &grid.hf,
                    h_m,
                    light_in_model,
                    radius_rad,
                    self.tiling,
                )?,
            })),
            #[cfg(not(feature = "gpu"))]
            ResolvedBackend::Gpu(ctx) => match **ctx {},
        }
    }

    /// The hard mask of the disc centre toward `light_in_model` per DEM pixel: 1 lit, 0
    /// shadow, 255 nodata.
    pub fn mask(&self, light_in_model: [f64; 3]) -> anyhow::Result<Vec<u8>> {
        let (grid, h_m) = (self.grid, self.observer_height_m);
        #[cfg(feature = "gpu")]
        if let (ResolvedBackend::Gpu(ctx), Some(pixels)) = (self.backend, &self.gpu_pixels) {
            return pixels.mask(ctx, light_in_model);
        }
        match self.backend {
            ResolvedBackend::Cpu => {
                self.engine
                    .hard_mask_on_dem(grid, self.observers(), h_m, light_in_model)
            }
            #[cfg(feature = "gpu")]
            ResolvedBackend::Gpu(ctx) => Ok(grid.to_output_u8(&match &self.gpu_fourier {
                Some(on_gpu) => {
                    use anyhow::Context as _;
                    on_gpu
                        .hard_mask(ctx, light_in_model)
                        .context("evaluating the horizon map on the GPU")?
                }
                None => {
                    super::gpu_maps::hard_mask_gpu(ctx, &grid.hf, h_m, light_in_model, self.tiling)?
                }
            })),
            #[cfg(not(feature = "gpu"))]
            ResolvedBackend::Gpu(ctx) => match **ctx {},
        }
    }
}

//! One-light maps (the visible fraction of a disc, the hard mask of its centre) on the DEM's own
//! grid, on the resolved backend.
//!
//! Both backends start the rays at each DEM pixel's own surface point by default (or at the
//! model cells, resampled). The CPU runs any engine; the GPU runs the two with a GPU kernel
//! ([`super::map_engine_on_gpu`]): DP max-mipmap, and Fourier, whose horizon map is built and
//! evaluated by the Fourier kernels (docs/gpu.md), always at the model cells. A grid that needs
//! the GPU's 2-D tiles is mapped from its model cells on the GPU (with a warning). The GPU
//! helpers of the model-cell kernels live here; the DEM pixels' DP kernels are
//! [`super::gpu_maps::GpuPixelMaps`], shared with the range maps.

#[cfg(feature = "gpu")]
use anyhow::Context as _;
use hifitime::Epoch;

use crate::ephem::{AbCorr, Kernels};
use crate::model::{MapEngine, MapEngineKind, MapGrid, ObserverPlacement, epoch_lights};
use crate::shadow::Observer;
use crate::terrain::TerrainStack;

use super::{MapSettings, ResolvedBackend};

/// A map grid ready for one-light maps on a backend (engine built, a GPU horizon map uploaded).
pub struct Prepared<'a> {
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

impl<'a> Prepared<'a> {
    /// Builds `engine` for `grid` on `backend` (the Fourier horizon map on the GPU there), with
    /// rays from `placement` and GPU tiles of `gpu_tile_cells` when given. On the GPU the engine
    /// is DP or Fourier (the others have no GPU kernel: [`super::map_engine_on_gpu`]).
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
        anyhow::ensure!(
            matches!(backend, ResolvedBackend::Cpu)
                || super::map_engine_on_gpu(engine, false) == super::OnGpu::Preferred,
            "internal: the {} engine has no GPU kernel",
            engine.name()
        );
        let engine = match backend {
            #[cfg(feature = "gpu")]
            ResolvedBackend::Gpu(ctx) if engine == MapEngineKind::Fourier => {
                fourier_engine_gpu(ctx, grid, h_m)?
            }
            _ => MapEngine::new(engine, grid, h_m)?,
        };
        #[cfg(feature = "gpu")]
        let gpu_fourier = match (backend, &engine) {
            (ResolvedBackend::Gpu(ctx), MapEngine::Fourier(map)) => Some({
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
        Ok(Prepared {
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
            return pixels.fraction(ctx, grid, light_in_model, radius_rad);
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
                Some(on_gpu) => fourier_fraction_gpu(ctx, on_gpu, light_in_model, radius_rad)?,
                None => visible_fraction_gpu(
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
            return pixels.mask(ctx, grid, light_in_model);
        }
        match self.backend {
            ResolvedBackend::Cpu => {
                self.engine
                    .hard_mask_on_dem(grid, self.observers(), h_m, light_in_model)
            }
            #[cfg(feature = "gpu")]
            ResolvedBackend::Gpu(ctx) => Ok(grid.to_output_u8(&match &self.gpu_fourier {
                Some(on_gpu) => on_gpu
                    .hard_mask(ctx, light_in_model)
                    .context("evaluating the horizon map on the GPU")?,
                None => hard_mask_gpu(ctx, &grid.hf, h_m, light_in_model, self.tiling)?,
            })),
            #[cfg(not(feature = "gpu"))]
            ResolvedBackend::Gpu(ctx) => match **ctx {},
        }
    }
}

/// One-light maps on the GPU: the DP visible fraction of a disc of angular
/// radius `angular_radius_rad` per model cell (`NaN` for holes), or with `angular_radius_rad` =
/// 0 the hard mask of the disc centre. Every `--engine` except `fourier` maps to this kernel on
/// the GPU (see docs/gpu.md). `tiling` chooses between the whole-grid kernel and 2-D tiles
/// (automatically: tiles when the grid or its mipmap exceed one storage binding; docs/gpu.md,
/// "Large grids").
#[cfg(feature = "gpu")]
fn visible_fraction_gpu(
    ctx: &crate::gpu::GpuContext,
    hf: &crate::terrain::HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    tiling: crate::gpu::tiles::DpTiling,
) -> anyhow::Result<Vec<f32>> {
    use crate::gpu::DEFAULT_BAND_BYTES;
    use crate::gpu::dp::{GpuDpGrid, dp_visible_gpu};
    use crate::gpu::tiles::{DpTileOptions, dp_visible_tiled_gpu};
    use crate::twins::{DpMip, MarchGrid, disc_light_to_f32};
    let march = MarchGrid::from_height_field(hf, observer_height_m)?;
    let light = disc_light_to_f32(&nalgebra::Vector3::from(light_in_model), angular_radius_rad);
    let out = match tiling.resolve(ctx, &march)? {
        Some(tile_cells) => {
            dp_visible_tiled_gpu(ctx, &march, light, DpTileOptions::new(tile_cells))?.values
        }
        None => {
            let mip = DpMip::build(&march);
            let on_gpu = GpuDpGrid::upload(ctx, &march, &mip)?;
            dp_visible_gpu(ctx, &on_gpu, light, DEFAULT_BAND_BYTES)?
        }
    };
    Ok(out
        .into_iter()
        .map(crate::twins::fraction_from_gpu)
        .collect())
}

/// The Fourier engine with its horizon map built on the GPU
/// ([`crate::gpu::fourier::build_horizon_map_gpu`]) with the parameters of
/// [`MapEngine::new`] (64 azimuths, 16 coefficients, rays of `max(rows, cols)` cells).
#[cfg(feature = "gpu")]
fn fourier_engine_gpu(
    ctx: &crate::gpu::GpuContext,
    grid: &MapGrid,
    observer_height_m: f64,
) -> anyhow::Result<MapEngine> {
    let params = crate::shadow::fourier::HorizonMapParams {
        observer_height_m,
        n_azimuths: crate::shadow::fourier::DEFAULT_AZIMUTHS,
        max_distance_cells: grid.hf.rows.max(grid.hf.cols),
        n_coeffs: crate::shadow::fourier::DEFAULT_COEFFS,
    };
    Ok(MapEngine::Fourier(Box::new(
        crate::gpu::fourier::build_horizon_map_gpu(ctx, &grid.hf, &params)
            .context("building the horizon map on the GPU")?,
    )))
}

/// One-light Fourier maps on the GPU: the visible fraction of a disc (radius 0: the hard test
/// as 1 / 0) per model cell from a horizon map resident on the GPU, `NaN` for holes (the GPU
/// twin of [`crate::shadow::fourier::visible_fraction`]).
#[cfg(feature = "gpu")]
fn fourier_fraction_gpu(
    ctx: &crate::gpu::GpuContext,
    on_gpu: &crate::gpu::fourier::GpuHorizonMap,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
) -> anyhow::Result<Vec<f32>> {
    Ok(on_gpu
        .visible_fraction(ctx, light_in_model, angular_radius_rad)
        .context("evaluating the horizon map on the GPU")?
        .into_iter()
        .map(crate::twins::fraction_from_gpu)
        .collect())
}

/// [`visible_fraction_gpu`] at radius 0 as a mask: 1 lit, 0 shadow, 255 nodata.
#[cfg(feature = "gpu")]
fn hard_mask_gpu(
    ctx: &crate::gpu::GpuContext,
    hf: &crate::terrain::HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    tiling: crate::gpu::tiles::DpTiling,
) -> anyhow::Result<Vec<u8>> {
    Ok(
        visible_fraction_gpu(ctx, hf, observer_height_m, light_in_model, 0.0, tiling)?
            .into_iter()
            .map(crate::twins::mask_of_fraction)
            .collect(),
    )
}

/// The light of a one-light map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// The Sun (and the Earth) of an epoch, from the ephemeris.
    Epoch(Epoch),
    /// A Sun direction in `MOON_ME` (any non-zero finite length) and the disc's angular radius.
    DirectionInMoonMe {
        /// The direction.
        dir: [f64; 3],
        /// Angular radius of the disc, degrees.
        radius_deg: f64,
    },
    /// The Sun's azimuth and elevation at the map centre and the disc's angular radius.
    AzElAtCentre {
        /// Azimuth, degrees clockwise from north.
        az_deg: f64,
        /// Elevation, degrees.
        el_deg: f64,
        /// Angular radius of the disc, degrees.
        radius_deg: f64,
    },
}

impl Light {
    /// Checks an explicit light: a finite non-zero direction, an elevation within ±90°, a disc
    /// radius in (0, 10)°.
    pub fn checked(self) -> anyhow::Result<Self> {
        let radius_ok = |r: f64| r > 0.0 && r < 10.0;
        match self {
            Light::Epoch(_) => {}
            Light::DirectionInMoonMe { dir, radius_deg } => {
                let n = nalgebra::Vector3::from(dir).norm();
                anyhow::ensure!(
                    n.is_finite() && n > 0.0,
                    "Sun direction {dir:?}: must be a non-zero vector of finite length"
                );
                anyhow::ensure!(
                    radius_ok(radius_deg),
                    "Sun radius {radius_deg} deg must be in (0, 10)"
                );
            }
            Light::AzElAtCentre {
                az_deg,
                el_deg,
                radius_deg,
            } => {
                anyhow::ensure!(
                    az_deg.is_finite() && (-90.0..=90.0).contains(&el_deg),
                    "Sun azimuth {az_deg} / elevation {el_deg} deg: the azimuth must be finite \
                     and the elevation within -90 .. 90 deg"
                );
                anyhow::ensure!(
                    radius_ok(radius_deg),
                    "Sun radius {radius_deg} deg must be in (0, 10)"
                );
            }
        }
        Ok(self)
    }
}

/// Which maps of one light to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OneLightOutputs {
    /// The Sun's visible fraction.
    pub sun_fraction: bool,
    /// The hard mask of the Sun's disc centre.
    pub sun_mask: bool,
    /// The Earth's visible fraction (with an epoch only).
    pub earth_fraction: bool,
}

/// One light's maps on the DEM's grid: the Sun's fraction and mask, the Earth's fraction with an
/// epoch, and the metadata items every file carries.
pub struct OneLightMaps {
    /// The finest layer's grid with every layer (for writing).
    pub grid: MapGrid,
    /// The Sun's visible fraction per DEM pixel (`NaN` = nodata), when asked for.
    pub sun_fraction: Option<Vec<f32>>,
    /// The hard mask of the Sun's disc centre per DEM pixel (1 lit, 0 shadow, 255 nodata), when
    /// asked for.
    pub sun_mask: Option<Vec<u8>>,
    /// The Earth's visible fraction per DEM pixel, when asked for (with an epoch).
    pub earth_fraction: Option<Vec<f32>>,
    /// The light and the run's parameters, for every file's metadata.
    pub metadata: Vec<(String, String)>,
}

/// The maps of one light over `stack` that `outputs` asks for (the command line's `--utc` /
/// `--sun-*` maps and Python's `map_light`): the light, the kernels for an epoch's light, and the
/// aberration correction.
pub fn one_light(
    settings: &MapSettings,
    stack: &TerrainStack,
    (light, kernels, abcorr): (Light, Option<&Kernels>, AbCorr),
    outputs: OneLightOutputs,
) -> anyhow::Result<OneLightMaps> {
    let grid = MapGrid::new(stack)?;
    grid.announce();
    let (engine, backend) = settings.engine_and_backend(None)?;
    let (sun, sun_radius_rad, earth, epoch) = match (light, kernels) {
        (Light::Epoch(e), Some(k)) => {
            let l = epoch_lights(&grid, k, &[e], abcorr)?[0];
            (
                l.sun,
                l.sun_radius_rad,
                Some((l.earth, l.earth_radius_rad)),
                Some((e, abcorr)),
            )
        }
        (Light::Epoch(_), None) => anyhow::bail!("a light at an epoch needs the kernels"),
        (Light::DirectionInMoonMe { dir, radius_deg }, _) => (
            grid.light_from_moon_me(&nalgebra::Vector3::from(dir)),
            radius_deg.to_radians(),
            None,
            None,
        ),
        (
            Light::AzElAtCentre {
                az_deg,
                el_deg,
                radius_deg,
            },
            _,
        ) => (
            grid.light_from_az_el_deg(az_deg, el_deg),
            radius_deg.to_radians(),
            None,
            None,
        ),
    };
    let h_m = settings.observer_height.m();
    let placement = settings.placement();
    let maps = Prepared::new(
        &backend,
        &grid,
        engine,
        h_m,
        placement,
        settings.gpu_tile_cells,
    )?;
    let metadata = one_light_metadata(
        &grid,
        (engine, h_m, maps.placement()),
        (sun, sun_radius_rad),
        earth.map(|(dir, _)| dir),
        epoch,
    );
    let sun_fraction = match outputs.sun_fraction {
        true => {
            let f = maps.fraction(sun, sun_radius_rad)?;
            grid.below_sphere_exits(maps.pixel_observers(), sun, &f)?
                .warn();
            Some(f)
        }
        false => None,
    };
    let sun_mask = match outputs.sun_mask {
        true => Some(maps.mask(sun)?),
        false => None,
    };
    let earth_fraction = match (outputs.earth_fraction, earth) {
        (true, Some((dir, radius))) => Some(maps.fraction(dir, radius)?),
        _ => None,
    };
    drop(maps);
    Ok(OneLightMaps {
        grid,
        sun_fraction,
        sun_mask,
        earth_fraction,
        metadata,
    })
}

/// The metadata items of a one-light map's GeoTIFFs: the epoch (when the light comes from the
/// ephemeris), the engine, where the rays start, the observer height, the Sun's azimuth and
/// elevation at the map centre, the Sun's angular radius, the aberration correction (with an
/// epoch) and the Earth's azimuth and elevation at the map centre (with an Earth direction).
pub fn one_light_metadata(
    grid: &MapGrid,
    (engine, observer_height_m, placement): (MapEngineKind, f64, ObserverPlacement),
    (sun, sun_radius_rad): ([f64; 3], f64),
    earth: Option<[f64; 3]>,
    epoch: Option<(Epoch, AbCorr)>,
) -> Vec<(String, String)> {
    let (sun_az_deg, sun_el_deg) = grid.az_el_deg_at_centre(sun);
    let mut items: Vec<(&str, String)> = Vec::new();
    if let Some((e, _)) = epoch {
        items.push(("epoch_utc", crate::ephem::time::format_iso(e)));
    }
    items.extend([
        ("engine", engine.name().to_string()),
        ("rays_from", placement.describe().to_string()),
        ("observer_height_m", format!("{observer_height_m}")),
        ("sun_az_deg_at_map_centre", format!("{sun_az_deg:.6}")),
        ("sun_el_deg_at_map_centre", format!("{sun_el_deg:.6}")),
        (
            "sun_radius_deg",
            format!("{:.6}", sun_radius_rad.to_degrees()),
        ),
    ]);
    if let Some((_, abcorr)) = epoch {
        items.push(("abcorr", abcorr.spice_name().to_string()));
    }
    if let Some(dir) = earth {
        let (az, el) = grid.az_el_deg_at_centre(dir);
        items.push(("earth_az_deg_at_map_centre", format!("{az:.6}")));
        items.push(("earth_el_deg_at_map_centre", format!("{el:.6}")));
    }
    items.into_iter().map(|(k, v)| (k.to_string(), v)).collect()
}

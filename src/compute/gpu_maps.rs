//! The GPU side shared by range maps, one-light maps and frames: the DP sweeps over an epoch
//! range, the DEM pixels' own observers on the GPU ([`GpuPixelMaps`]) and the renderer's
//! fractions, their outputs turned into the CPU engines' conventions (`NaN` for holes, fractions
//! in [0, 1]). Only compiled with the `gpu` feature; [`crate::compute`]'s switches call it. The
//! one-light helpers of the model-cell kernels live in [`super::one_light`].

use nalgebra::Vector3;

use crate::model::{EpochLights, MapGrid};
use crate::model::{ObserverPlacement, RangeStats};
use crate::terrain::HeightField;

/// The soft GPU twin of [`crate::model::per_epoch_statistics`]: one GPU-resident sweep
/// ([`crate::gpu::dp::dp_sweep_gpu`]) computes per epoch the DP visible fractions of the Sun's
/// and the Earth's discs (max-mipmap shadow cost `J*` + disc occlusion, as
/// [`crate::shadow::dp::visible_fraction`]) and folds them with the same definitions as [`crate::model::per_epoch_statistics`]
/// (mean visible fraction, "visible" = fraction > [`crate::model::VISIBLE_MIN_FRACTION`], longest Sun-dark
/// run, Earth and Sun-and-Earth counts). The light table goes up once (two f32 discs per epoch);
/// nothing is read back per epoch. Whatever `--engine` says, the GPU runs DP. `tiling` chooses
/// between the whole-grid sweep and the 2-D tiled sweep (docs/gpu.md, "Large grids").
pub fn sweep_gpu_soft(
    ctx: &crate::gpu::GpuContext,
    grid: &MapGrid,
    observer_height_m: f64,
    lights: &[EpochLights],
    step_h: f64,
    tiling: crate::gpu::tiles::DpTiling,
) -> anyhow::Result<RangeStats> {
    use crate::gpu::dp::{DpSweepOptions, GpuDpGrid, dp_sweep_gpu};
    use crate::gpu::tiles::{DpTileSweepOptions, dp_sweep_tiled_gpu};
    use crate::twins::{DpMip, MarchGrid};
    let march = MarchGrid::from_height_field(&grid.hf, observer_height_m)?;
    let table = light_table(lights);
    let stats = match tiling.resolve_sweep(ctx, &march)? {
        Some(tile_cells) => {
            dp_sweep_tiled_gpu(ctx, &march, &table, DpTileSweepOptions::new(tile_cells))?.0
        }
        None => {
            let mip = DpMip::build(&march);
            let on_gpu = GpuDpGrid::upload(ctx, &march, &mip)?;
            dp_sweep_gpu(ctx, &on_gpu, &table, DpSweepOptions::default())?
        }
    };
    Ok(sweep_stats(&stats, lights.len(), step_h, false))
}

/// The DP sweep kernels' light table: per epoch the Sun's then the Earth's disc.
fn light_table(lights: &[EpochLights]) -> Vec<[f32; 4]> {
    use crate::twins::disc_light_to_f32;
    lights
        .iter()
        .flat_map(|l| {
            [
                disc_light_to_f32(&Vector3::from(l.sun), l.sun_radius_rad),
                disc_light_to_f32(&Vector3::from(l.earth), l.earth_radius_rad),
            ]
        })
        .collect()
}

/// The map statistics of the GPU sweeps' per-cell (or per-pixel, `on_dem_grid`) statistics.
fn sweep_stats(
    stats: &[crate::twins::DpCellStats],
    epochs: usize,
    step_h: f64,
    on_dem_grid: bool,
) -> RangeStats {
    RangeStats {
        epochs,
        step_h,
        sun_fraction_sum: stats
            .iter()
            .map(|c| f64::from(c.sun_fraction_sum) - f64::from(c.sun_fraction_comp))
            .collect(),
        sun_visible_count: stats.iter().map(|c| c.sun_visible_epochs).collect(),
        longest_dark_epochs: stats.iter().map(|c| c.longest_dark_run_epochs).collect(),
        earth_visible_count: stats.iter().map(|c| c.earth_visible_epochs).collect(),
        sun_and_earth_count: Some(stats.iter().map(|c| c.sun_and_earth_epochs).collect()),
        below_sphere: None,
        on_dem_grid,
        extra: None,
    }
}

/// The renderer's per-cell Sun and Earth visible fractions on the GPU DP kernel (the GPU twin
/// of what [`crate::render::Scene::new`] computes with the CPU engine, observer on the ground):
/// the height field and its DP mip are uploaded once, then each frame costs two kernel runs.
pub struct GpuSceneFractions {
    grid: crate::gpu::dp::GpuDpGrid,
}

impl GpuSceneFractions {
    /// Uploads `hf` (observer height 0, as in [`crate::render::Scene::new`]).
    pub fn upload(ctx: &crate::gpu::GpuContext, hf: &HeightField) -> anyhow::Result<Self> {
        use crate::twins::{DpMip, MarchGrid};
        let march = MarchGrid::from_height_field(hf, 0.0)?;
        let mip = DpMip::build(&march);
        Ok(Self {
            grid: crate::gpu::dp::GpuDpGrid::upload(ctx, &march, &mip)?,
        })
    }

    /// The (Sun, Earth) visible fractions per model cell for `lights` (`NaN` for holes),
    /// row-major like `hf.z_m`, ready for [`crate::render::Scene::with_fractions`].
    pub fn fractions(
        &self,
        ctx: &crate::gpu::GpuContext,
        lights: &crate::render::Lights,
    ) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
        use crate::gpu::DEFAULT_BAND_BYTES;
        use crate::gpu::dp::dp_visible_gpu;
        use crate::twins::disc_light_to_f32;
        let one = |dir: [f64; 3], radius_rad: f64| -> anyhow::Result<Vec<f32>> {
            let light = disc_light_to_f32(&Vector3::from(dir), radius_rad);
            Ok(dp_visible_gpu(ctx, &self.grid, light, DEFAULT_BAND_BYTES)?
                .into_iter()
                .map(crate::twins::fraction_from_gpu)
                .collect())
        };
        Ok((
            one(lights.sun, lights.sun_radius_rad)?,
            one(lights.earth, lights.earth_radius_rad)?,
        ))
    }
}

/// A map grid on the GPU with its DEM pixels' own observers ([`MapGrid::pixel_observers`]):
/// DP fractions per DEM pixel and light (`shaders/dp_points.wgsl`), each ray starting at the
/// pixel's own surface point and marching the model grid beyond the near field, whose DEM
/// lattice the CPU marches (`src/model/near_field.rs`), as the CPU engines and a series site at
/// the pixel centre. The heights, the mipmap and the observers go up once.
pub struct GpuPixelMaps {
    grid: crate::gpu::dp::GpuDpGrid,
    /// Point records of the pixels with data (the model grid marched beyond the near field,
    /// [`crate::model::NEAR_FIELD_CELLS`]), and the DEM pixel of each.
    points: Vec<[f32; 4]>,
    pixel_of_point: Vec<usize>,
    /// The pixels' observers, for the near field on the DEM's own lattice (CPU).
    observers: Vec<Option<crate::shadow::Observer>>,
}

impl GpuPixelMaps {
    /// The DP kernels of a map whose rays start at `placement`, `grid` and the pixels'
    /// `observers` uploaded: `(None, Cells)` when asked for the cells, or, with one warning line,
    /// when the grid needs the 2-D tiled kernels (the whole grid does not fit one storage
    /// binding, [`crate::gpu::tiles::DpTiling`]), which start their rays at the model cells;
    /// `(Some, Pixels)` otherwise. The second value is where the rays really start.
    pub fn for_placement(
        ctx: &crate::gpu::GpuContext,
        grid: &MapGrid,
        observers: &[Option<crate::shadow::Observer>],
        observer_height_m: f64,
        tiling: crate::gpu::tiles::DpTiling,
        placement: ObserverPlacement,
    ) -> anyhow::Result<(Option<Self>, ObserverPlacement)> {
        use crate::twins::{DpMip, MarchGrid, pixel_point_records_from};
        if placement == ObserverPlacement::Cells {
            return Ok((None, ObserverPlacement::Cells));
        }
        let march = MarchGrid::from_height_field(&grid.hf, observer_height_m)?;
        if tiling.resolve(ctx, &march)?.is_some() {
            eprintln!(
                "penumbra: warning: the map grid needs the GPU's 2-D tiled kernels, which \
                 start their rays at the model grid's cells (resampled onto the DEM grid); \
                 --backend cpu starts them at the DEM pixels' own surface points"
            );
            return Ok((None, ObserverPlacement::Cells));
        }
        let mip = DpMip::build(&march);
        let on_gpu = crate::gpu::dp::GpuDpGrid::upload(ctx, &march, &mip)?;
        let (pixel_of_point, points) =
            pixel_point_records_from(&march, observers, crate::model::NEAR_FIELD_CELLS);
        let maps = GpuPixelMaps {
            grid: on_gpu,
            points,
            pixel_of_point,
            observers: observers.to_vec(),
        };
        Ok((Some(maps), ObserverPlacement::Pixels))
    }

    /// Per DEM pixel, `per_point` scattered back (`nodata` where a pixel has no data).
    fn scatter<T: Copy>(&self, per_point: &[T], nodata: T) -> Vec<T> {
        let mut out = vec![nodata; self.observers.len()];
        for (&pixel, &v) in self.pixel_of_point.iter().zip(per_point) {
            out[pixel] = v;
        }
        out
    }

    /// The visible fraction of a disc of angular radius `radius_rad` toward `light_in_model`
    /// per DEM pixel (`NaN` for nodata); radius 0 gives 1 / 0. The GPU marches the model grid
    /// beyond the near field, the CPU the near field on the DEM's own lattice
    /// ([`MapGrid::with_near_field`]), as the CPU engines: the smaller fraction.
    pub fn fraction(
        &self,
        ctx: &crate::gpu::GpuContext,
        grid: &MapGrid,
        light_in_model: [f64; 3],
        radius_rad: f64,
    ) -> anyhow::Result<Vec<f32>> {
        let beyond = self.fraction_beyond(ctx, light_in_model, radius_rad)?;
        grid.with_near_field(&beyond, &self.observers, light_in_model, radius_rad)
    }

    /// The GPU's part of [`GpuPixelMaps::fraction`]: the model grid beyond the near field.
    fn fraction_beyond(
        &self,
        ctx: &crate::gpu::GpuContext,
        light_in_model: [f64; 3],
        radius_rad: f64,
    ) -> anyhow::Result<Vec<f32>> {
        use crate::gpu::DEFAULT_BAND_BYTES;
        let light = crate::twins::disc_light_to_f32(&Vector3::from(light_in_model), radius_rad);
        let values = crate::gpu::dp::dp_points_gpu(
            ctx,
            &self.grid,
            &self.points,
            light,
            DEFAULT_BAND_BYTES,
        )?;
        let values: Vec<f32> = values.into_iter().map(|f| f.clamp(0.0, 1.0)).collect();
        Ok(self.scatter(&values, f32::NAN))
    }

    /// The hard mask of the disc centre toward `light_in_model` per DEM pixel: 1 lit, 0 shadow,
    /// 255 nodata.
    pub fn mask(
        &self,
        ctx: &crate::gpu::GpuContext,
        grid: &MapGrid,
        light_in_model: [f64; 3],
    ) -> anyhow::Result<Vec<u8>> {
        Ok(self
            .fraction(ctx, grid, light_in_model, 0.0)?
            .into_iter()
            .map(crate::twins::mask_of_fraction)
            .collect())
    }
}

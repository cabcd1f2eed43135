//! Map statistics over an epoch range on the resolved backend: the per-epoch engines (a shadow
//! map per epoch, CPU or GPU) or the horizons engine (whole-grid horizons once, then every epoch
//! per pixel; CPU).

use std::path::PathBuf;

use anyhow::Context as _;
use hifitime::Epoch;

use crate::ephem::{AbCorr, Kernels};
use crate::horizon::statistics::{
    BlockStore, EpochBodies, HorizonFile, HorizonRows, InMemoryHorizons, StatisticsEngine,
    StatisticsParams,
};
use crate::horizon::{HorizonSweep, SweepParams};
use crate::map::{MapEngine, MapEngineKind, ObserverPlacement, SweepStats};
use crate::model::{EpochLights, MapGrid, VISIBLE_MIN_FRACTION, epoch_lights};
use crate::series::LimbLaw;
use crate::terrain::TerrainStack;

use super::ResolvedBackend;

/// Where the horizons engine takes its whole-grid horizons.
#[derive(Debug, Clone, PartialEq)]
pub enum HorizonsFrom {
    /// A horizon GeoTIFF written by `penumbra horizon-map sweep` for the same finest layer and
    /// observer height.
    File(PathBuf),
    /// A line sweep run in memory ([`crate::horizon::sweep`]).
    Sweep {
        /// Requested azimuths.
        azimuths: usize,
        /// Largest step component of a direction.
        max_step: u32,
    },
}

impl Default for HorizonsFrom {
    fn default() -> Self {
        HorizonsFrom::Sweep {
            azimuths: crate::horizon::sweep::DEFAULT_SWEEP_AZIMUTHS,
            max_step: crate::horizon::sweep::DEFAULT_MAX_STEP,
        }
    }
}

/// What a map over an epoch range computes, besides its epochs.
#[derive(Debug, Clone)]
pub struct RangeMap {
    /// The engine.
    pub engine: MapEngineKind,
    /// Observer height above the ground, metres.
    pub observer_height_m: f64,
    /// Where the per-epoch engines' rays start (CPU).
    pub placement: ObserverPlacement,
    /// GPU tiles of this many cells per side instead of the automatic choice.
    pub gpu_tile_cells: Option<u32>,
    /// The horizons of the horizons engine.
    pub horizons: HorizonsFrom,
    /// The Sun's limb darkening in the horizons engine's mean fraction (the per-epoch engines
    /// use a uniform disc).
    pub limb: LimbLaw,
}

/// The statistics of a range, what ran, and the model grid when the arrays are per model cell.
pub struct RangeResult {
    /// The statistics.
    pub stats: SweepStats,
    /// What ran, for provenance.
    pub note: String,
    /// The model grid of model-cell statistics (GPU sweeps), for writing them.
    pub model: Option<MapGrid>,
}

/// A caller's progress report: `(done, total)` of the current stage (the horizons engine: the
/// sweep's directions, then the rows of the statistics); returning `false` stops the run with an
/// "interrupted" error. The per-epoch engines report nothing yet.
pub type Report<'a> = &'a mut (dyn FnMut(usize, usize) -> bool + Send);

/// The statistics of `epochs` (`step_h` hours apart) over `stack` with `map.engine` on
/// `backend`; `report` hears the progress (see [`Report`]). The horizons engine takes finished
/// blocks of rows from `store` and gives it those it computes (a resumable run); the per-epoch
/// engines do not use it.
#[allow(
    clippy::too_many_arguments,
    reason = "the request's parts; two call sites"
)]
pub fn range_statistics(
    backend: &ResolvedBackend,
    stack: &TerrainStack,
    map: &RangeMap,
    kernels: &Kernels,
    epochs: &[Epoch],
    abcorr: AbCorr,
    step_h: f64,
    report: Report<'_>,
    store: &mut dyn BlockStore,
) -> anyhow::Result<RangeResult> {
    if map.engine == MapEngineKind::Horizons {
        return horizon_statistics(
            backend, stack, map, kernels, epochs, abcorr, step_h, report, store,
        );
    }
    let grid = MapGrid::new(stack)?;
    grid.announce();
    let lights = epoch_lights(&grid, kernels, epochs, abcorr)?;
    let progress = crate::output::progress_bar(
        lights.len(),
        "{spinner} map sweep [{bar:30}] {pos}/{len} epochs (eta {eta})",
    );
    let (stats, note) = map_sweep(
        backend,
        &grid,
        map.engine,
        map.observer_height_m,
        map.placement,
        &lights,
        step_h,
        map.gpu_tile_cells,
        &progress,
    )?;
    progress.finish_and_clear();
    let model = (!stats.on_dem_grid).then_some(grid);
    Ok(RangeResult { stats, note, model })
}

/// The horizons engine: whole-grid horizons (from a file or a sweep in memory), then every
/// epoch per pixel ([`crate::horizon::statistics`]; the epoch loop on the GPU with the GPU
/// backend).
#[allow(clippy::too_many_arguments, reason = "range_statistics' arguments")]
fn horizon_statistics(
    backend: &ResolvedBackend,
    stack: &TerrainStack,
    map: &RangeMap,
    kernels: &Kernels,
    epochs: &[Epoch],
    abcorr: AbCorr,
    step_h: f64,
    report: Report<'_>,
    store: &mut dyn BlockStore,
) -> anyhow::Result<RangeResult> {
    let fine = stack.layers.first().context("no DEM layer")?;
    let rows = 0..fine.grid.rows;
    let (stats, note) = horizon_statistics_rows(
        backend, stack, map, kernels, epochs, abcorr, report, store, rows,
    )?;
    Ok(RangeResult {
        stats: SweepStats::from_horizons(stats, step_h, map.limb.name()),
        note,
        model: None,
    })
}

/// The horizons engine's raw statistics of the finest layer's `rows` (all of them, or a shard's:
/// then the sweep keeps only those rows' horizons and memory scales with the rows), and what
/// ran. Pixel `i` of the result is the grid's pixel `rows.start · cols + i`; the values are bit
/// for bit those of a whole-grid run. `map.engine` is not looked at.
#[allow(clippy::too_many_arguments, reason = "range_statistics' arguments")]
pub fn horizon_statistics_rows(
    backend: &ResolvedBackend,
    stack: &TerrainStack,
    map: &RangeMap,
    kernels: &Kernels,
    epochs: &[Epoch],
    abcorr: AbCorr,
    report: Report<'_>,
    store: &mut dyn BlockStore,
    rows: std::ops::Range<usize>,
) -> anyhow::Result<(crate::horizon::statistics::HorizonStatistics, String)> {
    let fine = stack.layers.first().context("no DEM layer")?;
    let engine = StatisticsEngine::new(
        stack,
        StatisticsParams {
            limb: map.limb.law(),
            visible_min_fraction: f64::from(VISIBLE_MIN_FRACTION),
            full_min_fraction: crate::illum::stats::SUN_FULL_MIN_FRACTION,
        },
    )?;
    let t0 = std::time::Instant::now();
    let mut source: Box<dyn HorizonRows> = match &map.horizons {
        HorizonsFrom::File(path) => {
            let file = HorizonFile::open(path)?;
            if file.projection() != fine.projection {
                anyhow::bail!(
                    "horizon map {}: its projection is not the finest layer's ({})",
                    path.display(),
                    fine.name
                );
            }
            Box::new(file)
        }
        HorizonsFrom::Sweep { azimuths, max_step } => {
            let sweep = HorizonSweep::new(
                stack,
                SweepParams {
                    observer_height_m: map.observer_height_m,
                    azimuths: *azimuths,
                    max_step: *max_step,
                },
            )?
            .with_rows(rows.clone())?;
            let progress = crate::output::progress_bar(
                sweep.directions().len(),
                "penumbra: horizons [{bar:40}] {pos}/{len} directions, {elapsed} (eta {eta})",
            );
            let total = sweep.directions().len();
            let h = InMemoryHorizons::sweep_with::<anyhow::Error>(
                &sweep,
                |sink| super::horizons::run_sweep(backend, &sweep, sink, |_| {}),
                |done| {
                    progress.set_position(done as u64);
                    report(done, total)
                },
            )?;
            progress.finish_and_clear();
            crate::note!(
                "penumbra: horizons of {} x {} px toward {} directions in {:.1} s ({:.0} MB)",
                rows.len(),
                fine.grid.cols,
                sweep.directions().len(),
                t0.elapsed().as_secs_f64(),
                h.bytes() as f64 / 1e6
            );
            Box::new(h)
        }
    };
    engine.check_source(source.as_ref())?;
    let h_file = source.observer_height_m();
    if (h_file - map.observer_height_m).abs() > 1e-9 * (1.0 + h_file.abs()) {
        anyhow::bail!(
            "the horizons were computed for an observer {h_file} m above the ground, the map asks \
             for {} m (give --observer-height-m {h_file} or recompute the horizons)",
            map.observer_height_m
        );
    }
    let bodies = EpochBodies::over_dem(fine, kernels, epochs, abcorr)?;
    let t1 = std::time::Instant::now();
    let progress = crate::output::progress_bar(
        rows.len(),
        "penumbra: statistics [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})",
    );
    let rows_total = rows.len();
    // The epoch loop on the GPU (`shaders/horizon_stats.wgsl`) with the GPU backend.
    #[cfg(feature = "gpu")]
    let mut gpu_kernel = match backend {
        ResolvedBackend::Gpu(ctx) => Some(crate::gpu::horizon_stats::GpuHorizonStats::new(ctx)?),
        ResolvedBackend::Cpu => None,
    };
    #[cfg(feature = "gpu")]
    let kernel = gpu_kernel
        .as_mut()
        .map(|k| k as &mut dyn crate::horizon::statistics::CellKernel);
    #[cfg(not(feature = "gpu"))]
    let kernel = None;
    let stats = engine.run_rows_on(
        source.as_mut(),
        &bodies,
        store,
        rows.clone(),
        kernel,
        |done| {
            progress.set_position(done as u64);
            report(done, rows_total)
        },
    )?;
    progress.finish_and_clear();
    let secs = t1.elapsed().as_secs_f64();
    let cell_epochs = (rows.len() * fine.grid.cols) as f64 * epochs.len() as f64;
    crate::note!(
        "penumbra: statistics of {} x {} px over {} epochs in {:.1} s ({:.0} M pixel-epochs/s)",
        rows.len(),
        fine.grid.cols,
        epochs.len(),
        secs,
        cell_epochs / secs.max(1e-9) / 1e6
    );
    let from = match &map.horizons {
        HorizonsFrom::File(p) => format!("horizon map {}", p.display()),
        HorizonsFrom::Sweep { azimuths, max_step } => {
            format!("line sweep in memory ({azimuths} azimuths requested, max step {max_step})")
        }
    };
    let ran = match (backend, &map.horizons) {
        (ResolvedBackend::Gpu(_), HorizonsFrom::Sweep { .. }) => {
            "gpu (the line sweep's hulls and tangents, and the statistics' epoch loop)"
        }
        (ResolvedBackend::Gpu(_), HorizonsFrom::File(_)) => "gpu (the statistics' epoch loop)",
        (ResolvedBackend::Cpu, _) => "cpu",
    };
    let note = format!(
        "{ran}: horizons engine ({from}; {} limb darkening; each pixel's own Sun and Earth \
         directions)",
        map.limb.name()
    );
    Ok((stats, note))
}

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
            // The Fourier horizon map is per model cell whatever the placement.
            let rays = match engine {
                MapEngine::Fourier(_) => ObserverPlacement::Cells,
                MapEngine::Direct(_) => placement,
            };
            let note = format!(
                "cpu: {} soft shadows of the discs, rays from the {}",
                engine.describe(),
                rays.describe()
            );
            Ok((stats, note))
        }
        #[cfg(feature = "gpu")]
        ResolvedBackend::Gpu(ctx) => {
            let tiling = crate::gpu::tiles::DpTiling {
                tile_cells: gpu_tile_cells,
            };
            let (pixels, placement) = super::gpu_maps::GpuPixelMaps::for_placement(
                ctx,
                grid,
                &grid.pixel_observers(observer_height_m),
                observer_height_m,
                tiling,
                placement,
            )?;
            let stats = match pixels {
                Some(pixels) => pixels.sweep(ctx, lights, step_h)?,
                None => super::gpu_maps::sweep_gpu_soft(
                    ctx,
                    grid,
                    observer_height_m,
                    lights,
                    step_h,
                    tiling,
                )?,
            };
            progress.inc(lights.len() as u64);
            let note = format!(
                "{}: DP max-mipmap soft shadows of the Sun and Earth discs \
                 (GPU-resident sweep; --engine is not used on the GPU), rays from the {}",
                backend.describe(),
                placement.describe()
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

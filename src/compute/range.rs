//! Map statistics over an epoch range on the resolved backend: the per-epoch engines (a shadow
//! map per epoch: combined, dp or fourier on the CPU; dp on the GPU) or the horizons engine
//! (whole-grid horizons once, then every epoch per pixel; its epoch loop on the GPU too).

use std::path::PathBuf;

use anyhow::Context as _;

use crate::ephem::{AbCorr, Kernels};
use crate::horizon::statistics::{
    BlockStore, EpochBodies, HorizonFile, HorizonRows, InMemoryHorizons, StatisticsEngine,
    StatisticsParams,
};
use crate::horizon::{HorizonSweep, SweepParams};
use crate::model::{
    EpochLights, EpochRange, MapEngine, MapEngineKind, MapGrid, ObserverPlacement, RangeStats,
    VISIBLE_MIN_FRACTION, epoch_lights,
};
use crate::terrain::TerrainStack;

use super::{MapSettings, ResolvedBackend};

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

/// The inputs of a map over an epoch range: the terrain, the ephemeris and the epochs.
#[derive(Clone, Copy)]
pub struct RangeInputs<'a> {
    /// Every terrain layer, finest first.
    pub stack: &'a TerrainStack,
    /// The SPICE kernels.
    pub kernels: &'a Kernels,
    /// The epochs.
    pub epochs: &'a EpochRange,
    /// The aberration correction.
    pub abcorr: AbCorr,
}

/// The statistics of a range, what ran, and the model grid when the arrays are per model cell.
pub struct RangeResult {
    /// The statistics.
    pub stats: RangeStats,
    /// What ran, for provenance.
    pub note: String,
    /// The model grid of model-cell statistics (the GPU's per-epoch DP), for writing them.
    pub model: Option<MapGrid>,
    /// The engine that ran (`auto` resolved).
    pub engine: MapEngineKind,
}

/// A caller's progress report: `(done, total)` of the current stage (the horizons engine: the
/// sweep's directions, then the rows of the statistics); returning `false` stops the run with an
/// "interrupted" error. The per-epoch engines report nothing yet.
pub type Report<'a> = &'a mut (dyn FnMut(usize, usize) -> bool + Send);

/// What a caller hears and keeps while a range runs: `report` hears the progress (see
/// [`Report`]); the horizons engine takes finished blocks of rows from `store` and gives it those
/// it computes (a resumable run); the per-epoch engines do not use it.
pub struct RangeHooks<'a> {
    /// The progress report.
    pub report: Report<'a>,
    /// The finished blocks of rows.
    pub store: &'a mut dyn BlockStore,
}

/// The statistics of `inputs` with the engine `settings` ask for, on the backend they resolve
/// to ([`MapSettings::engine_and_backend`]); the horizons engine's arrays are checked against
/// the memory budget first.
pub fn range_statistics(
    inputs: RangeInputs<'_>,
    settings: &MapSettings,
    hooks: RangeHooks<'_>,
) -> anyhow::Result<RangeResult> {
    let (engine, backend) = settings.engine_and_backend(Some(inputs.epochs.len()))?;
    if let Some(p) = &settings.power {
        // A load profile that does not cover the epochs fails before any work.
        p.loads(&inputs.epochs.epochs())?;
    }
    let step_h = inputs.epochs.step_s() / 3600.0;
    if engine == MapEngineKind::Horizons {
        let fine = inputs.stack.layers.first().context("no DEM layer")?;
        let rows = 0..fine.grid.rows;
        let bytes = arrays_bytes(inputs.stack, rows.len(), &settings.horizons);
        check_budget(
            "the map's arrays (terrain, whole-grid horizons, statistics)",
            bytes,
            "split the map into shards (--shard I/N, then penumbra merge) or sweep the \
             horizons once into a file (--horizons)",
        )?;
        let (stats, note) = horizon_statistics_rows(&backend, inputs, settings, hooks, rows)?;
        return Ok(RangeResult {
            stats: RangeStats::from_horizons(stats, step_h, settings.limb.name()),
            note,
            model: None,
            engine,
        });
    }
    let grid = MapGrid::new(inputs.stack)?;
    grid.announce();
    let epochs = inputs.epochs.epochs();
    let lights = epoch_lights(&grid, inputs.kernels, &epochs, inputs.abcorr)?;
    let (stats, note) = per_epoch(&backend, &grid, (engine, settings), &lights, step_h)?;
    let model = (!stats.on_dem_grid).then_some(grid);
    Ok(RangeResult {
        stats,
        note,
        model,
        engine,
    })
}

/// `what` needs `bytes` of memory: an error naming `what` and `advice` beyond the budget
/// ([`crate::output::guard::check_budget`]).
pub fn check_budget(what: &str, bytes: u64, advice: &str) -> anyhow::Result<()> {
    crate::output::guard::check_budget(what, u128::from(bytes))
        .map_err(|e| anyhow::anyhow!("{e}; {advice}"))
}

/// The memory the horizons engine holds in arrays for `rows` rows of the finest layer, bytes:
/// every terrain layer (f32), the horizons of those rows (int16 per sweep direction, or a block
/// of rows read from a horizon file), the sweep's per-direction buffers of those rows and the
/// statistics (69 bytes a pixel).
pub fn arrays_bytes(stack: &TerrainStack, rows: usize, horizons: &HorizonsFrom) -> u64 {
    let fine = &stack.layers[0];
    let px = (rows * fine.grid.cols) as u64;
    let terrain: u64 = stack
        .layers
        .iter()
        .map(|l| 4 * l.heights_m.len() as u64)
        .sum();
    let horizons = match horizons {
        HorizonsFrom::Sweep { azimuths, max_step } => {
            let dirs = crate::horizon::sweep::sweep_directions(
                *azimuths,
                *max_step,
                fine.grid.px_x_m,
                fine.grid.px_y_m,
            )
            .len() as u64;
            // Kept int16 bands, plus one direction's looks (12 bytes each way) and its band.
            dirs * px * 2 + px * (2 * 12 + 8)
        }
        HorizonsFrom::File(_) => 64 << 20,
    };
    terrain + horizons + px * 69
}

/// The horizons engine's raw statistics of the finest layer's `rows` (all of them, or a shard's:
/// then the sweep keeps only those rows' horizons and memory scales with the rows), and what
/// ran. Pixel `i` of the result is the grid's pixel `rows.start · cols + i`; the values are bit
/// for bit those of a whole-grid run. `settings.engine` is not looked at.
pub fn horizon_statistics_rows(
    backend: &ResolvedBackend,
    inputs: RangeInputs<'_>,
    map: &MapSettings,
    hooks: RangeHooks<'_>,
    rows: std::ops::Range<usize>,
) -> anyhow::Result<(crate::horizon::statistics::HorizonStatistics, String)> {
    let RangeInputs {
        stack,
        kernels,
        epochs,
        abcorr,
    } = inputs;
    let RangeHooks { report, store } = hooks;
    let epochs = epochs.epochs();
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
                    observer_height_m: map.observer_height.m(),
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
    if (h_file - map.observer_height.m()).abs() > 1e-9 * (1.0 + h_file.abs()) {
        anyhow::bail!(
            "the horizons were computed for an observer {h_file} m above the ground, the map asks \
             for {} m (give --observer-height-m {h_file} or recompute the horizons)",
            map.observer_height
        );
    }
    let bodies = EpochBodies::over_dem(fine, kernels, &epochs, abcorr)?;
    let link = station_flags(map, fine, kernels, &epochs)?;
    let engine = match link {
        Some((flags, stations)) => engine.with_link(flags, stations),
        None => engine,
    };
    let engine = match power_inputs(map, &epochs, inputs.epochs.step_s())? {
        Some(p) => engine.with_power(p),
        None => engine,
    };
    let t1 = std::time::Instant::now();
    let progress = crate::output::progress_bar(
        rows.len(),
        "penumbra: statistics [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})",
    );
    let rows_total = rows.len();
    // The epoch loop on the GPU (`shaders/horizon_stats.wgsl`) with the GPU backend.
    #[cfg(feature = "gpu")]
    let mut gpu_kernel = match backend {
        ResolvedBackend::Gpu(_) if map.epoch_loop_on_cpu() => {
            crate::note!(
                "penumbra: note: the direct-to-Earth and power statistics have no GPU kernel: \
                 the statistics' epoch loop runs on the CPU"
            );
            None
        }
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
    let link_on_cpu = map.epoch_loop_on_cpu();
    let ran = match (backend, &map.horizons) {
        (ResolvedBackend::Gpu(_), HorizonsFrom::Sweep { .. }) if link_on_cpu => {
            "gpu (the line sweep's hulls and tangents; the statistics' epoch loop on the cpu)"
        }
        (ResolvedBackend::Gpu(_), HorizonsFrom::File(_)) if link_on_cpu => "cpu",
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

/// The statistics of `lights` (one entry per epoch, `step_h` hours apart) over `grid` with the
/// per-epoch `engine`, and a description of what ran for provenance. The CPU runs the engine
/// with rays from the settings' placement; the GPU runs the dp engine (the only per-epoch engine
/// with a GPU kernel; [`super::map_engine_on_gpu`] keeps the others on the CPU), in tiles of
/// `gpu_tile_cells` when given.
fn per_epoch(
    backend: &ResolvedBackend,
    grid: &MapGrid,
    (engine, map): (MapEngineKind, &MapSettings),
    lights: &[EpochLights],
    step_h: f64,
) -> anyhow::Result<(RangeStats, String)> {
    let h_m = map.observer_height.m();
    match backend {
        ResolvedBackend::Cpu => {
            let engine = MapEngine::new(engine, grid, h_m)?;
            let stats = crate::model::per_epoch_statistics(
                grid,
                &engine,
                h_m,
                map.placement(),
                lights,
                step_h,
            )?;
            // The Fourier horizon map is per model cell whatever the placement.
            let rays = match engine {
                MapEngine::Fourier(_) => ObserverPlacement::Cells,
                MapEngine::Direct(_) => map.placement(),
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
            anyhow::ensure!(
                engine == MapEngineKind::Direct(crate::shadow::Engine::Dp),
                "internal: the {} engine has no GPU kernel for epoch ranges",
                engine.name()
            );
            let tiling = crate::gpu::tiles::DpTiling {
                tile_cells: map.gpu_tile_cells,
            };
            let observers = grid.pixel_observers(h_m);
            let (pixels, placement) = super::gpu_maps::GpuPixelMaps::for_placement(
                ctx,
                grid,
                &observers,
                h_m,
                tiling,
                map.placement(),
            )?;
            let stats = match pixels {
                // From the DEM pixels: each epoch's fractions on the GPU (the model grid beyond
                // the near field) and the CPU (the near field on the DEM's lattice), folded as
                // on the CPU backend.
                Some(pixels) => crate::model::per_epoch_statistics_with(
                    grid,
                    &observers,
                    true,
                    lights,
                    step_h,
                    |light, radius| pixels.fraction(ctx, grid, light, radius),
                )?,
                None => super::gpu_maps::sweep_gpu_soft(ctx, grid, h_m, lights, step_h, tiling)?,
            };
            let note = format!(
                "{}: DP max-mipmap soft shadows of the Sun and Earth discs, rays from the {}",
                backend.describe(),
                placement.describe()
            );
            Ok((stats, note))
        }
        #[cfg(not(feature = "gpu"))]
        ResolvedBackend::Gpu(ctx) => match **ctx {},
    }
}

/// The settings' panel and load at `epochs` (`step_s` apart), for the power statistics; `None`
/// without a panel.
fn power_inputs(
    map: &MapSettings,
    epochs: &[hifitime::Epoch],
    step_s: f64,
) -> anyhow::Result<Option<crate::horizon::statistics::PowerInputs>> {
    let Some(p) = &map.power else {
        return Ok(None);
    };
    p.validate()?;
    let loads = p.loads(epochs)?;
    let start = epochs.first().copied().unwrap_or_default();
    let effective_area_m2 = epochs
        .iter()
        .map(|&t| {
            let years = (t - start).to_seconds() / (365.25 * 86_400.0);
            p.area_m2 * p.efficiency * (1.0 - p.degradation_pct_per_year / 100.0 * years).max(0.0)
        })
        .collect();
    Ok(Some(crate::horizon::statistics::PowerInputs {
        panel: p.panel,
        effective_area_m2,
        loads,
        step_h: step_s / 3600.0,
        described: p.describe(),
    }))
}

/// Per epoch, whether one of the settings' ground stations sees the centre of `fine` (on the
/// sphere) above its mask, and the stations described; `None` without stations. One flag serves
/// the whole grid: across a polar DEM (≤ 500 km) the parallax moves a station's elevation of the
/// site by < 0.05°.
fn station_flags(
    map: &MapSettings,
    fine: &crate::terrain::Dem,
    kernels: &Kernels,
    epochs: &[hifitime::Epoch],
) -> anyhow::Result<Option<(Vec<bool>, String)>> {
    let Some(stations) = map.stations.resolve(map.station_mask_deg)? else {
        return Ok(None);
    };
    let g = fine.grid;
    let (cx, cy) = g.xy_from_row_col((g.rows as f64 - 1.0) / 2.0, (g.cols as f64 - 1.0) / 2.0);
    let (lat, lon) = fine.projection.lat_lon_from_xy(cx, cy);
    let site = crate::ephem::Site::new(lat, lon, 0.0)?;
    let table = crate::ephem::moon_geometry_table(kernels, epochs)?;
    let at = crate::comms::stations_table(&stations, &table);
    let mut el = vec![0.0; stations.len()];
    let flags = table
        .iter()
        .zip(&at)
        .map(|(geo, a)| {
            crate::comms::site_elevations_deg(geo, a, &site.pos_in_moon_me_km, &mut el);
            crate::comms::best_station(&stations, &el)
                .is_some_and(|(i, e)| e >= stations[i].mask_deg())
        })
        .collect();
    let described = stations
        .iter()
        .map(|s| format!("{} ({:.0} deg mask)", s.name(), s.mask_deg()))
        .collect::<Vec<_>>()
        .join(", ");
    Ok(Some((flags, described)))
}

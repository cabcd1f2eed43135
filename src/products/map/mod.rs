//! `penumbra map`, a scenario's `[map]` and the Python module's maps: illumination maps on the DEM's
//! own grid, for one light ([`one_light`]) or as statistics over an epoch range ([`statistics`]),
//! computed through [`crate::compute`] and written by [`write_range`] (and [`shard`] for one
//! block of rows of a job split across machines).
//!
//! The command line, a scenario and Python build the same [`MapSettings`]; [`run`] is the
//! command line's whole job (inputs, compute, files, `run.json`).

pub mod shard;
mod write;

use std::path::{Path, PathBuf};

use hifitime::Epoch;

use super::{KernelSource, TerrainSource};
use crate::compute::range::{HorizonsFrom, RangeHooks, RangeInputs, RangeMap, RangeResult};
use crate::compute::{Backend, OnGpu, ResolvedBackend};
use crate::ephem::{AbCorr, Kernels};
use crate::illum::LimbLaw;
use crate::model::{
    EpochRange, MapEngineKind, MapGrid, ObserverHeight, ObserverPlacement, epoch_lights,
};
use crate::terrain::TerrainStack;

pub use write::{
    PSR_DESCRIPTION, RangeRaster, geotiff_unit, range_metadata, range_rasters, span_text,
    write_range,
};

/// How a map is computed, whatever it is asked for: the command line, a scenario's `[map]` and
/// the Python module build the same settings.
#[derive(Debug, Clone)]
pub struct MapSettings {
    /// Observer height above the ground.
    pub observer_height: ObserverHeight,
    /// The engine; `None` for `auto` ([`auto_engine`]).
    pub engine: Option<MapEngineKind>,
    /// Where it runs (`--backend`).
    pub backend: Backend,
    /// GPU tiles of this many cells per side (≥ 2) instead of the automatic choice.
    pub gpu_tile_cells: Option<u32>,
    /// Where the rays start; `None` for the DEM pixels' own surface points.
    pub observers: Option<ObserverPlacement>,
    /// The horizons engine: where its whole-grid horizons come from.
    pub horizons: HorizonsFrom,
    /// The horizons engine: the Sun's limb darkening in its mean fraction.
    pub limb: LimbLaw,
}

impl Default for MapSettings {
    fn default() -> Self {
        MapSettings {
            observer_height: ObserverHeight::DEFAULT,
            engine: None,
            backend: Backend::Auto,
            gpu_tile_cells: None,
            observers: None,
            horizons: HorizonsFrom::default(),
            limb: LimbLaw::default(),
        }
    }
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

/// The files of a one-light map (at least one).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OneLightFiles {
    /// The Sun's visible fraction (float32 GeoTIFF).
    pub fraction: Option<PathBuf>,
    /// The hard mask of the Sun's disc centre (uint8 GeoTIFF).
    pub mask: Option<PathBuf>,
    /// The Earth's visible fraction (float32 GeoTIFF; needs an epoch).
    pub earth_fraction: Option<PathBuf>,
}

impl OneLightFiles {
    /// Which maps these files need.
    pub fn outputs(&self) -> OneLightOutputs {
        OneLightOutputs {
            sun_fraction: self.fraction.is_some(),
            sun_mask: self.mask.is_some(),
            earth_fraction: self.earth_fraction.is_some(),
        }
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

/// Where the statistics of an epoch range go.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeFiles {
    /// The folder of the statistics maps.
    pub out_dir: PathBuf,
    /// Carry on an unfinished run in `out_dir` (the horizons engine keeps finished blocks of
    /// rows).
    pub resume: bool,
    /// Compute this shard of the job only and write a partial for `penumbra merge`.
    pub shard: Option<shard::Shard>,
}

/// What a map is asked for: one light and its files, or an epoch range and its folder.
#[derive(Debug, Clone, PartialEq)]
pub enum MapTask {
    /// One light.
    OneLight {
        /// The light.
        light: Light,
        /// The files.
        files: OneLightFiles,
    },
    /// Statistics over an epoch range.
    Range {
        /// The epochs.
        epochs: EpochRange,
        /// The files.
        files: RangeFiles,
    },
}

impl MapTask {
    /// A one-light task, if it writes something and asks for the Earth only with an epoch.
    pub fn one_light(light: Light, files: OneLightFiles) -> anyhow::Result<Self> {
        if files == OneLightFiles::default() {
            anyhow::bail!(
                "nothing to write: give --out-fraction, --out-mask or --out-earth-fraction"
            );
        }
        if files.earth_fraction.is_some() && !matches!(light, Light::Epoch(_)) {
            anyhow::bail!(
                "--out-earth-fraction needs an epoch (--utc): an explicit Sun direction gives no Earth"
            );
        }
        Ok(MapTask::OneLight {
            light: light.checked()?,
            files,
        })
    }
}

/// What `penumbra map` computes and writes.
#[derive(Debug, Clone)]
pub struct MapRequest {
    /// The terrain (every layer).
    pub terrain: TerrainSource,
    /// The kernels.
    pub kernels: KernelSource,
    /// Aberration correction.
    pub abcorr: AbCorr,
    /// How the map is computed.
    pub settings: MapSettings,
    /// What it is asked for.
    pub task: MapTask,
}

/// Runs `penumbra map`.
pub fn run(req: &MapRequest) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    match &req.task {
        MapTask::OneLight { light, files } => {
            check_one_light(&req.settings, files)?;
            let (stack, _) = req.terrain.load()?;
            let kernels = match light {
                Light::Epoch(e) => Some(load_kernels(&req.kernels, &[*e])?),
                _ => None,
            };
            let maps = one_light(
                &req.settings,
                &stack,
                (*light, kernels.as_ref(), req.abcorr),
                files.outputs(),
            )?;
            maps.write(files)?;
            crate::note!(
                "penumbra: map written ({:.1} s)",
                t0.elapsed().as_secs_f64()
            );
            Ok(())
        }
        MapTask::Range { epochs, files } => {
            check_range(&req.settings, files)?;
            range_job(req, epochs, files, t0)
        }
    }
}

/// The kernels of `req`, checked to cover the first and last of `epochs`.
fn load_kernels(kernels: &KernelSource, epochs: &[Epoch]) -> anyhow::Result<Kernels> {
    let k = kernels.load()?;
    let (first, last) = (epochs[0], epochs[epochs.len() - 1]);
    crate::ephem::moon_geometry_table(&k, &[first, last])?;
    Ok(k)
}

/// The checks of a one-light map that need no input read: the engine makes one light, the
/// output files can be written side by side.
fn check_one_light(settings: &MapSettings, files: &OneLightFiles) -> anyhow::Result<()> {
    if settings.engine == Some(MapEngineKind::Horizons) {
        anyhow::bail!(
            "--engine horizons makes statistics over an epoch range (--start/--stop/--step); \
             for one light use combined, dp or fourier"
        );
    }
    let outputs: Vec<(&str, &Path)> = [
        ("--out-fraction", &files.fraction),
        ("--out-mask", &files.mask),
        ("--out-earth-fraction", &files.earth_fraction),
    ]
    .into_iter()
    .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
    .collect();
    for (flag, path) in &outputs {
        crate::output::guard::check_output_target(flag, path, outputs.len() == 1)
            .map_err(anyhow::Error::msg)?;
    }
    crate::output::guard::check_distinct_outputs(&outputs).map_err(anyhow::Error::msg)
}

/// The checks of a range that need no input read: a shard runs the horizons engine on the CPU.
fn check_range(settings: &MapSettings, files: &RangeFiles) -> anyhow::Result<()> {
    if files.shard.is_some() {
        if !matches!(settings.engine, None | Some(MapEngineKind::Horizons)) {
            anyhow::bail!(
                "--shard runs the horizons engine (whole-grid horizons, then every epoch per \
                 pixel): leave --engine at auto or give --engine horizons"
            );
        }
        if settings.backend == Backend::Gpu {
            anyhow::bail!(
                "--shard runs the horizons engine, which runs on the CPU: drop --backend gpu"
            );
        }
    }
    Ok(())
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

impl OneLightMaps {
    /// Writes the files asked for.
    pub fn write(&self, files: &OneLightFiles) -> anyhow::Result<()> {
        let info = |description| crate::model::RasterInfo {
            description,
            unit: "",
            items: self.metadata.clone(),
        };
        if let (Some(path), Some(f)) = (&files.fraction, &self.sun_fraction) {
            self.grid
                .write_f32(path, f, &info(SUN_FRACTION_DESCRIPTION))?;
        }
        if let (Some(path), Some(m)) = (&files.mask, &self.sun_mask) {
            self.grid
                .write_u8(path, m, &info(SUN_MASK_DESCRIPTION))?;
        }
        if let (Some(path), Some(f)) = (&files.earth_fraction, &self.earth_fraction) {
            self.grid
                .write_f32(path, f, &info(EARTH_FRACTION_DESCRIPTION))?;
        }
        Ok(())
    }
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
    let (engine, backend) = choose(settings, None)?;
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
    let placement = settings.observers.unwrap_or(ObserverPlacement::Pixels);
    let maps = crate::compute::one_light::OneLightMaps::new(
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

/// The engine a map runs and the backend it runs on: the engine asked for, on the backend
/// `--backend` resolves to for it ([`crate::compute::range::map_engine_on_gpu`]); for `auto`,
/// the best engine where the map runs ([`auto_engine`]). `range` holds the number of epochs of a
/// range (`None` for one light).
pub fn choose(
    settings: &MapSettings,
    range: Option<usize>,
) -> anyhow::Result<(MapEngineKind, ResolvedBackend)> {
    use crate::compute::range::map_engine_on_gpu;
    if let Some(engine) = settings.engine {
        let on_gpu = map_engine_on_gpu(engine, range.is_some());
        return Ok((engine, crate::compute::resolve(settings.backend, on_gpu)?));
    }
    let backend = crate::compute::resolve(settings.backend, OnGpu::Preferred)?;
    let engine = auto_engine(&backend, range, &settings.horizons);
    if let Some(n) = range {
        crate::note!(
            "penumbra: --engine auto: {} for {n} epochs",
            match engine {
                MapEngineKind::Horizons =>
                    "horizons (whole-grid horizons once, then every epoch per pixel)",
                MapEngineKind::Direct(crate::shadow::Engine::Dp) =>
                    "dp (a soft-shadow map per epoch on the GPU)",
                _ => "combined (a soft-shadow map per epoch)",
            }
        );
    }
    Ok((engine, backend))
}

/// The engine `--engine auto` runs on `backend` for one light (`n_epochs` `None`) or a range of
/// `n_epochs`: one light, `dp` on a GPU, else `combined`. A range: the horizons engine when its
/// horizons are given as a file (`--horizons`: the sweep is paid for, and each epoch then costs
/// it ≈ 35× less than a combined map on the CPU), or on the CPU from
/// [`AUTO_HORIZONS_MIN_EPOCHS`] epochs on (where a whole-grid sweep costs less than the per-epoch
/// maps; `cargo bench --bench statistics`, docs/PERFORMANCE.md); else `dp` on a GPU, `combined`
/// on the CPU. Where a GPU's per-epoch maps overtake a CPU-built sweep has not been measured on
/// a GPU.
pub fn auto_engine(
    backend: &ResolvedBackend,
    n_epochs: Option<usize>,
    horizons: &HorizonsFrom,
) -> MapEngineKind {
    use crate::shadow::Engine;
    let on_gpu = matches!(backend, ResolvedBackend::Gpu(_));
    let per_epoch = if on_gpu {
        MapEngineKind::Direct(Engine::Dp)
    } else {
        MapEngineKind::Direct(Engine::Combined)
    };
    match (n_epochs, horizons) {
        (None, _) => per_epoch,
        (Some(_), HorizonsFrom::File(_)) => MapEngineKind::Horizons,
        (Some(n), HorizonsFrom::Sweep { .. }) if !on_gpu && n >= AUTO_HORIZONS_MIN_EPOCHS => {
            MapEngineKind::Horizons
        }
        (Some(_), HorizonsFrom::Sweep { .. }) => per_epoch,
    }
}

/// Fewest epochs for which `--engine auto` sweeps horizons (see [`auto_engine`]).
pub const AUTO_HORIZONS_MIN_EPOCHS: usize = 1000;

/// The statistics of an epoch range over `inputs` (the command line's `--start/--stop/--step`
/// maps, a scenario's `[map]`, Python's `map_statistics`): the engine and backend chosen as
/// [`choose`] says, the horizons engine's memory checked against the budget first.
pub fn statistics(
    settings: &MapSettings,
    inputs: RangeInputs<'_>,
    hooks: RangeHooks<'_>,
) -> anyhow::Result<RangeResult> {
    let (engine, backend) = choose(settings, Some(inputs.epochs.len()))?;
    if engine == MapEngineKind::Horizons {
        let rows = inputs.stack.layers[0].grid.rows;
        crate::output::guard::check_budget(
            "the map's arrays (terrain, whole-grid horizons, statistics)",
            u128::from(shard::arrays_bytes(inputs.stack, rows, &settings.horizons)),
        )
        .map_err(|e| {
            anyhow::anyhow!(
                "{e}; split the map into shards (--shard I/N, then penumbra merge) or sweep \
                 the horizons once into a file (--horizons)"
            )
        })?;
    }
    crate::compute::range::range_statistics(&backend, inputs, &range_map(settings, engine), hooks)
}

/// The compute layer's description of a range map with `engine`.
fn range_map(settings: &MapSettings, engine: MapEngineKind) -> RangeMap {
    RangeMap {
        engine,
        observer_height: settings.observer_height,
        placement: settings.observers.unwrap_or(ObserverPlacement::Pixels),
        gpu_tile_cells: settings.gpu_tile_cells,
        horizons: settings.horizons.clone(),
        limb: settings.limb,
    }
}

/// The command line's range job: inputs, statistics (or a shard's partial), files, `run.json`.
fn range_job(
    req: &MapRequest,
    epochs: &EpochRange,
    files: &RangeFiles,
    t0: std::time::Instant,
) -> anyhow::Result<()> {
    let (stack, dem_layers) = req.terrain.load()?;
    let epoch_list = epochs.epochs();
    let kernels = load_kernels(&req.kernels, &epoch_list)?;
    let out_dir = &files.out_dir;
    // A shard's manifest, like a run's run.json, goes first and comes back last.
    let manifest = match files.shard {
        Some(_) => shard::MANIFEST,
        None => "run.json",
    };
    let _lock =
        crate::output::cleanup::RunLock::begin(out_dir, manifest).map_err(anyhow::Error::msg)?;
    let mut prov = crate::output::Provenance::new();
    prov.kernels = kernels.files.clone();
    prov.dem_layers = dem_layers;
    prov.dem_files = req.terrain.dem_files()?;
    if let HorizonsFrom::File(path) = &req.settings.horizons
        && req.settings.engine.is_none_or(|e| e == MapEngineKind::Horizons)
    {
        prov.dem_files.push(crate::output::InputFile::of(path)?);
    }
    prov.set_epochs(&epoch_list);
    let (mut cp, note) = crate::output::checkpoint::Checkpoint::open(
        out_dir,
        &range_fingerprint(req, &prov)?,
        files.resume,
    )
    .map_err(anyhow::Error::msg)?;
    if let Some(note) = note {
        crate::note!("{note}");
    }
    let inputs = RangeInputs {
        stack: &stack,
        kernels: &kernels,
        epochs,
        abcorr: req.abcorr,
    };
    let hooks = RangeHooks {
        report: &mut |_, _| true,
        store: &mut cp,
    };
    if let Some(s) = files.shard {
        let job = job_fingerprint(req, &prov)?;
        shard::run(
            shard::ShardJob {
                shard: s,
                job,
                settings: &req.settings,
                inputs,
                out_dir,
                prov: &mut prov,
                t0,
            },
            hooks,
        )?;
        cp.finish();
        return Ok(());
    }
    let result = statistics(&req.settings, inputs, hooks)?;
    prov.outputs = write_range(
        &stack.layers[0],
        result.model.as_ref(),
        &result.stats,
        out_dir,
        &span_text(&epoch_list),
    )?;
    prov.backend = result.note;
    prov.map_rays_blocked_beyond_dem = result.stats.below_sphere;
    if let Some(b) = result.stats.below_sphere {
        b.warn();
    }
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&out_dir.join("run.json"))?;
    cp.finish();
    crate::note!(
        "penumbra: map statistics over {} epochs -> {} ({:.1} s)",
        epochs.len(),
        out_dir.display(),
        prov.wall_time_s
    );
    Ok(())
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

/// The GeoTIFF `content` of a one-light Sun fraction map.
pub const SUN_FRACTION_DESCRIPTION: &str = "visible fraction of the Sun's disc";
/// The GeoTIFF `content` of a one-light hard mask.
pub const SUN_MASK_DESCRIPTION: &str = "Sun disc centre: 1 lit, 0 shadow, 255 no data";
/// The GeoTIFF `content` of a one-epoch Earth fraction map.
pub const EARTH_FRACTION_DESCRIPTION: &str = "visible fraction of the Earth's disc";

/// The fingerprint of a map over an epoch range (what `--resume` checks): penumbra's build, the
/// request (but `--resume`), the kernels' and DEMs' sha256 and a horizons file's size and time.
fn range_fingerprint(req: &MapRequest, prov: &crate::output::Provenance) -> anyhow::Result<String> {
    let mut request = req.clone();
    if let MapTask::Range { files, .. } = &mut request.task {
        files.resume = false;
    }
    let horizons = match &req.settings.horizons {
        HorizonsFrom::File(p) => crate::output::checkpoint::file_stamp(p)
            .map_err(|e| anyhow::anyhow!("--horizons {}: {e}", p.display()))?,
        HorizonsFrom::Sweep { .. } => String::new(),
    };
    Ok(crate::output::checkpoint::fingerprint(&[
        prov.penumbra_version.as_bytes(),
        prov.git_commit.as_bytes(),
        format!("{request:?}").as_bytes(),
        serde_json::to_string(&prov.kernels)?.as_bytes(),
        serde_json::to_string(&prov.dem_files)?.as_bytes(),
        horizons.as_bytes(),
    ]))
}

/// The fingerprint of a sharded job (what `penumbra merge` checks): penumbra's build, every
/// parameter but the shard, its output folder and `--resume` (and the engine and backend, which
/// are the CPU horizons engine for every shard), and the inputs by content (the kernels' and
/// DEMs' sha256, not their paths), so that shards run from other folders or through the Python
/// module merge.
fn job_fingerprint(req: &MapRequest, prov: &crate::output::Provenance) -> anyhow::Result<String> {
    let mut request = req.clone();
    request.settings.engine = Some(MapEngineKind::Horizons);
    request.settings.backend = Backend::Cpu;
    if let TerrainSource::Dems(paths) = &mut request.terrain {
        paths.clear();
    }
    if let HorizonsFrom::File(p) = &mut request.settings.horizons {
        *p = PathBuf::new();
    }
    request.kernels = KernelSource::default();
    if let MapTask::Range { files, .. } = &mut request.task {
        *files = RangeFiles {
            out_dir: PathBuf::new(),
            resume: false,
            shard: None,
        };
    }
    let kernels: Vec<(&str, &str)> = prov
        .kernels
        .iter()
        .map(|k| (k.kind, k.sha256.as_str()))
        .collect();
    let inputs: Vec<&str> = prov.dem_files.iter().map(|f| f.sha256.as_str()).collect();
    Ok(crate::output::checkpoint::fingerprint(&[
        prov.penumbra_version.as_bytes(),
        prov.git_commit.as_bytes(),
        format!("{request:?}").as_bytes(),
        format!("{kernels:?}").as_bytes(),
        format!("{inputs:?}").as_bytes(),
    ]))
}

//! `penumbra map`: illumination maps on the DEM's own grid, for one light or as statistics over
//! an epoch range (average illumination, longest darkness, PSR, Earth visibility).

use std::path::PathBuf;

use super::{EpochSpec, KernelSource, TerrainSource};
use crate::ephem::{self, AbCorr};
use crate::gpu::Backend;
use crate::map::{MapEngineKind, ObserverPlacement};

/// What `penumbra map` computes.
#[derive(Debug, Clone)]
pub struct MapRequest {
    /// The terrain (every layer).
    pub terrain: TerrainSource,
    /// Observer height above the ground, metres.
    pub observer_height_m: f64,
    /// Shadow engine of the CPU maps; `None` chooses (see [`auto_engine`]).
    pub engine: Option<MapEngineKind>,
    /// One epoch (one light) or a range (statistics); `None` with an explicit light.
    pub epochs: Option<EpochSpec>,
    /// An explicit Sun direction in `MOON_ME` (any non-zero length), instead of an epoch.
    pub sun_dir_in_moon_me: Option<nalgebra::Vector3<f64>>,
    /// An explicit Sun azimuth and elevation at the map centre, degrees, instead of an epoch.
    pub sun_az_el_deg: Option<(f64, f64)>,
    /// Angular radius of the Sun's disc for an explicit light, degrees.
    pub sun_radius_deg: f64,
    /// One light: the Sun's visible fraction (float32 GeoTIFF).
    pub out_fraction: Option<PathBuf>,
    /// One light: the hard mask of the disc centre (uint8 GeoTIFF).
    pub out_mask: Option<PathBuf>,
    /// One epoch: the Earth's visible fraction (float32 GeoTIFF).
    pub out_earth_fraction: Option<PathBuf>,
    /// Epoch range: the folder of the statistics maps.
    pub out_dir: Option<PathBuf>,
    /// Epoch range: carry on an unfinished run in `out_dir` (the horizons engine keeps finished
    /// blocks of rows).
    pub resume: bool,
    /// Epoch range: compute this shard of the map only (a block of rows of the finest layer,
    /// horizons engine) and write a partial for `penumbra merge` ([`super::shard`]).
    pub shard: Option<super::shard::Shard>,
    /// Compute backend.
    pub backend: Backend,
    /// GPU tiles of this many cells per side (≥ 2) instead of the automatic choice.
    pub gpu_tile_cells: Option<u32>,
    /// Where the rays start; `None` for the backend's own (pixels on the CPU, cells on the GPU).
    pub observers: Option<ObserverPlacement>,
    /// Epoch ranges with `--engine horizons`: where the whole-grid horizons come from.
    pub horizons: crate::compute::sweep::HorizonsFrom,
    /// Epoch ranges with `--engine horizons`: the Sun's limb darkening in its mean fraction.
    pub limb: crate::series::LimbLaw,
    /// Aberration correction.
    pub abcorr: AbCorr,
    /// The kernels.
    pub kernels: KernelSource,
}

/// Runs `penumbra map`.
pub fn run(req: &MapRequest) -> anyhow::Result<()> {
    use crate::map::write_sweep;
    use crate::model::{MapGrid, epoch_lights};
    if req.engine == Some(MapEngineKind::Horizons) && !req.epochs.is_some_and(|e| e.is_range()) {
        anyhow::bail!(
            "--engine horizons makes statistics over an epoch range (--start/--stop/--step); \
             for one light use brute, smap, dp, combined or fourier"
        );
    }
    if req.shard.is_some() {
        if !req.epochs.is_some_and(|e| e.is_range()) || req.out_dir.is_none() {
            anyhow::bail!(
                "--shard makes one part of a map over an epoch range: give --start/--stop/--step                  and --out-dir"
            );
        }
        if !matches!(req.engine, None | Some(MapEngineKind::Horizons)) {
            anyhow::bail!(
                "--shard runs the horizons engine (whole-grid horizons, then every epoch per                  pixel): leave --engine at auto or give --engine horizons"
            );
        }
        if req.backend == crate::gpu::Backend::Gpu {
            anyhow::bail!(
                "--shard runs the horizons engine, which runs on the CPU: drop --backend gpu"
            );
        }
    }
    let t0 = std::time::Instant::now();
    if !(req.observer_height_m >= 0.0 && req.observer_height_m <= 100_000.0) {
        anyhow::bail!(
            "--observer-height-m {} must lie in 0 .. 100000 m",
            req.observer_height_m
        );
    }
    if !(req.sun_radius_deg > 0.0 && req.sun_radius_deg < 10.0) {
        anyhow::bail!("--sun-radius-deg {} must be in (0, 10)", req.sun_radius_deg);
    }
    let engine_kind = req
        .engine
        .unwrap_or(MapEngineKind::Direct(crate::shadow::Engine::Combined));
    let abcorr = req.abcorr;
    let range = req.epochs.is_some_and(|e| e.is_range());
    if range && req.out_dir.is_none() {
        anyhow::bail!("an epoch range needs --out-dir DIR for the statistics maps");
    }
    if !range
        && req.out_fraction.is_none()
        && req.out_mask.is_none()
        && req.out_earth_fraction.is_none()
    {
        anyhow::bail!("nothing to write: give --out-fraction, --out-mask or --out-earth-fraction");
    }
    if !range && req.epochs.is_none() && req.out_earth_fraction.is_some() {
        anyhow::bail!(
            "--out-earth-fraction needs an epoch (--utc): an explicit Sun direction gives no Earth"
        );
    }
    if let Some((az, el)) = req.sun_az_el_deg
        && !(az.is_finite() && (-90.0..=90.0).contains(&el))
    {
        anyhow::bail!(
            "--sun-az-deg {az} / --sun-el-deg {el}: the azimuth must be finite and the elevation within -90 .. 90 deg"
        );
    }
    if let Some(d) = req.sun_dir_in_moon_me
        && !(d.norm().is_finite() && d.norm() > 0.0)
    {
        anyhow::bail!("--sun-dir-body {d:?}: must be a non-zero vector of finite length");
    }
    let outputs: Vec<(&str, &std::path::Path)> = [
        ("--out-fraction", &req.out_fraction),
        ("--out-mask", &req.out_mask),
        ("--out-earth-fraction", &req.out_earth_fraction),
    ]
    .into_iter()
    .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
    .collect();
    for (flag, path) in &outputs {
        crate::output::guard::check_output_target(flag, path, outputs.len() == 1)
            .map_err(anyhow::Error::msg)?;
    }
    crate::output::guard::check_distinct_outputs(&outputs).map_err(anyhow::Error::msg)?;
    let explicit_dir = req.sun_dir_in_moon_me;
    if !range && explicit_dir.is_none() && req.sun_az_el_deg.is_none() && req.epochs.is_none() {
        anyhow::bail!("give the light: --utc T, --sun-dir-body X,Y,Z or --sun-az-deg/--sun-el-deg");
    }
    let epochs = match &req.epochs {
        Some(spec) => spec.epochs()?,
        None => Vec::new(),
    };
    // The terrain is an input: its errors come before any adapter probe.
    let (stack, dem_layers) = req.terrain.load()?;
    // Resolve after the argument checks (bad input is one error line, with no backend warning)
    // and before any heavy work, so that a missing adapter is one error line (or one warning
    // line with `auto`).
    // The horizons engine is CPU-only: no adapter probe (and no `auto` warning) for it.
    let backend = if (req.engine == Some(MapEngineKind::Horizons) || req.shard.is_some())
        && req.backend != crate::gpu::Backend::Gpu
    {
        crate::compute::ResolvedBackend::Cpu
    } else {
        crate::compute::resolve(req.backend)?
    };
    let placement = crate::compute::one_light::placement(req.observers);
    let kernels = if epochs.is_empty() {
        None
    } else {
        let k = req.kernels.load()?;
        ephem::moon_geometry_table(&k, &[epochs[0], *epochs.last().unwrap_or(&epochs[0])])?;
        Some(k)
    };

    if range {
        let (Some(kernels), Some(out_dir)) = (&kernels, &req.out_dir) else {
            anyhow::bail!("an epoch range needs kernels and --out-dir");
        };
        // A shard's manifest, like a run's run.json, goes first and comes back last.
        let manifest = match req.shard {
            Some(_) => super::shard::MANIFEST,
            None => "run.json",
        };
        let _lock = crate::output::cleanup::RunLock::begin(out_dir, manifest)
            .map_err(anyhow::Error::msg)?;
        let mut dem_files = req.terrain.dem_files()?;
        let (mut cp, note) = crate::output::checkpoint::Checkpoint::open(
            out_dir,
            &range_fingerprint(req, &kernels.files, &dem_files)?,
            req.resume,
        )
        .map_err(anyhow::Error::msg)?;
        if let Some(note) = note {
            crate::note!("{note}");
        }
        let step_h = req.epochs.map_or(3600.0, |e| e.step_s()) / 3600.0;
        let span = crate::map::span_text(&epochs);
        if let crate::compute::sweep::HorizonsFrom::File(path) = &req.horizons
            && (req.engine == Some(MapEngineKind::Horizons) || req.shard.is_some())
        {
            dem_files.push(crate::output::InputFile::of(path)?);
        }
        if let Some(shard) = req.shard {
            let fine = &stack.layers[0];
            let rows = shard.rows(fine.grid.rows).map_err(anyhow::Error::msg)?;
            let range_map = crate::compute::sweep::RangeMap {
                engine: MapEngineKind::Horizons,
                observer_height_m: req.observer_height_m,
                placement,
                gpu_tile_cells: req.gpu_tile_cells,
                horizons: req.horizons.clone(),
                limb: req.limb,
            };
            let arrays_bytes = super::shard::arrays_bytes(&stack, rows.len(), &req.horizons);
            crate::output::guard::check_budget(
                &format!("shard {shard} (rows {}..{}: terrain, horizons, statistics)", rows.start, rows.end),
                u128::from(arrays_bytes),
            )
            .map_err(|e| {
                anyhow::anyhow!("{e}; split the map into more shards or sweep the horizons once into a file (--horizons)")
            })?;
            let (stats, note) = crate::compute::sweep::horizon_statistics_rows(
                &backend,
                &stack,
                &range_map,
                kernels,
                &epochs,
                abcorr,
                &mut |_, _| true,
                &mut cp,
                rows.clone(),
            )?;
            let mut prov = crate::output::Provenance::new();
            prov.kernels = kernels.files.clone();
            prov.dem_layers = dem_layers;
            prov.dem_files = dem_files;
            prov.set_epochs(&epochs);
            prov.backend = note;
            let job = job_fingerprint(req, &kernels.files, &prov.dem_files)?;
            let run = super::shard::ShardRun {
                shard,
                job,
                fine,
                rows: rows.clone(),
                provenance: &prov,
                step_h,
                span,
                limb_law: req.limb.name().to_string(),
                arrays_bytes,
            };
            let manifest =
                super::shard::write_partial(out_dir, &run, &stats, t0.elapsed().as_secs_f64())?;
            cp.finish();
            crate::note!(
                "penumbra: shard {shard} (rows {}..{} of {}) -> {} ({:.1} s, arrays {:.0} MB{}); \
                 combine the shards with `penumbra merge --out-dir OUT DIR...`",
                rows.start,
                rows.end,
                fine.grid.rows,
                out_dir.display(),
                manifest.wall_time_s,
                manifest.arrays_bytes as f64 / 1e6,
                manifest
                    .peak_rss_bytes
                    .map(|b| format!(", peak resident {:.0} MB", b as f64 / 1e6))
                    .unwrap_or_default()
            );
            return Ok(());
        }
        let engine_kind = match req.engine {
            Some(e) => e,
            None => {
                let e = auto_engine(&backend, epochs.len(), &req.horizons);
                crate::note!(
                    "penumbra: --engine auto: {} for {} epochs",
                    if e == MapEngineKind::Horizons {
                        "horizons (whole-grid horizons once, then every epoch per pixel)"
                    } else {
                        "combined (a soft-shadow map per epoch)"
                    },
                    epochs.len()
                );
                e
            }
        };
        if engine_kind == MapEngineKind::Horizons {
            let rows = stack.layers[0].grid.rows;
            crate::output::guard::check_budget(
                "the map's arrays (terrain, whole-grid horizons, statistics)",
                u128::from(super::shard::arrays_bytes(&stack, rows, &req.horizons)),
            )
            .map_err(|e| {
                anyhow::anyhow!(
                    "{e}; split the map into shards (--shard I/N, then penumbra merge) or sweep \
                     the horizons once into a file (--horizons)"
                )
            })?;
        }
        let result = crate::compute::sweep::range_statistics(
            &backend,
            &stack,
            &crate::compute::sweep::RangeMap {
                engine: engine_kind,
                observer_height_m: req.observer_height_m,
                placement,
                gpu_tile_cells: req.gpu_tile_cells,
                horizons: req.horizons.clone(),
                limb: req.limb,
            },
            kernels,
            &epochs,
            abcorr,
            step_h,
            &mut |_, _| true,
            &mut cp,
        )?;
        let files = write_sweep(
            &stack.layers[0],
            result.model.as_ref(),
            &result.stats,
            out_dir,
            &span,
        )?;
        let mut prov = crate::output::Provenance::new();
        prov.kernels = kernels.files.clone();
        prov.dem_layers = dem_layers;
        if let crate::compute::sweep::HorizonsFrom::File(path) = &req.horizons
            && engine_kind == MapEngineKind::Horizons
            && req.engine.is_none()
        {
            dem_files.push(crate::output::InputFile::of(path)?);
        }
        prov.dem_files = dem_files;
        prov.set_epochs(&epochs);
        prov.outputs = files;
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
        return Ok(());
    }

    let grid = MapGrid::new(&stack)?;
    grid.announce();

    // One light.
    let (sun, sun_radius_rad, earth) = match (&kernels, explicit_dir, req.sun_az_el_deg) {
        (Some(k), _, _) => {
            let l = epoch_lights(&grid, k, &epochs, abcorr)?[0];
            (l.sun, l.sun_radius_rad, Some((l.earth, l.earth_radius_rad)))
        }
        (None, Some(d), _) => (
            grid.light_from_moon_me(&d),
            req.sun_radius_deg.to_radians(),
            None,
        ),
        (None, None, Some((az, el))) => (
            grid.light_from_az_el_deg(az, el),
            req.sun_radius_deg.to_radians(),
            None,
        ),
        (None, None, None) => anyhow::bail!("no light given"),
    };
    let maps = crate::compute::one_light::OneLightMaps::new(
        &backend,
        &grid,
        engine_kind,
        req.observer_height_m,
        placement,
        req.gpu_tile_cells,
    )?;
    // The light and the run's parameters, in every file's metadata.
    let items = one_light_metadata(
        &grid,
        engine_kind,
        req.observer_height_m,
        maps.placement(),
        (sun, sun_radius_rad),
        earth.map(|(dir, _)| dir),
        kernels.as_ref().map(|_| (epochs[0], abcorr)),
    );
    let info = |description| crate::model::RasterInfo {
        description,
        unit: "",
        items: items.clone(),
    };
    if let Some(path) = &req.out_fraction {
        let f = maps.fraction(sun, sun_radius_rad)?;
        grid.below_sphere_exits(maps.pixel_observers(), sun, &f)?
            .warn();
        grid.write_f32(path, &f, &info(SUN_FRACTION_DESCRIPTION))?;
    }
    if let Some(path) = &req.out_mask {
        let m = maps.mask(sun)?;
        grid.write_u8(path, &m, &info(SUN_MASK_DESCRIPTION))?;
    }
    if let (Some(path), Some((dir, radius))) = (&req.out_earth_fraction, earth) {
        let f = maps.fraction(dir, radius)?;
        grid.write_f32(path, &f, &info(EARTH_FRACTION_DESCRIPTION))?;
    }
    crate::note!(
        "penumbra: map written ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The metadata items of a one-light map's GeoTIFFs: the epoch (when the light comes from the
/// ephemeris), the engine, where the rays start, the observer height, the Sun's azimuth and elevation at the map centre,
/// the Sun's angular radius, the aberration correction (with an epoch) and the Earth's azimuth
/// and elevation at the map centre (with an Earth direction).
pub fn one_light_metadata(
    grid: &crate::model::MapGrid,
    engine: MapEngineKind,
    observer_height_m: f64,
    placement: crate::map::ObserverPlacement,
    (sun, sun_radius_rad): ([f64; 3], f64),
    earth: Option<[f64; 3]>,
    epoch: Option<(hifitime::Epoch, crate::ephem::AbCorr)>,
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

/// The engine `--engine auto` runs for `n_epochs` epochs of a range on `backend`: the horizons
/// engine when it is faster, else the per-epoch combined engine (the GPU's DP sweep on a GPU).
///
/// Horizons given as a file (`--horizons`) are always used, on any backend: the sweep is paid
/// for, and each epoch then costs the horizons engine ≈ 35× less than a combined map on the CPU
/// (its epoch loop runs on the GPU too). Otherwise, on the CPU, measured on the 2-core VM
/// (`cargo bench --bench statistics`, docs/PERFORMANCE.md): a whole-grid sweep of 552–600
/// directions costs as much as ≈ 750 epochs of per-epoch combined maps on a single layer and
/// ≈ 2,000 with the LOLA far field; so the horizons engine is chosen from 1,000 epochs on. On a
/// GPU the per-epoch DP sweep stays the choice without a file: where a GPU's per-epoch maps
/// overtake a CPU-built sweep has not been measured on a GPU (issue 15).
pub fn auto_engine(
    backend: &crate::compute::ResolvedBackend,
    n_epochs: usize,
    horizons: &crate::compute::sweep::HorizonsFrom,
) -> MapEngineKind {
    use crate::compute::sweep::HorizonsFrom;
    let combined = MapEngineKind::Direct(crate::shadow::Engine::Combined);
    let on_gpu = matches!(backend, crate::compute::ResolvedBackend::Gpu(_));
    match horizons {
        HorizonsFrom::File(_) => MapEngineKind::Horizons,
        HorizonsFrom::Sweep { .. } if !on_gpu && n_epochs >= AUTO_HORIZONS_MIN_EPOCHS => {
            MapEngineKind::Horizons
        }
        HorizonsFrom::Sweep { .. } => combined,
    }
}

/// Fewest epochs for which `--engine auto` sweeps horizons (see [`auto_engine`]).
pub const AUTO_HORIZONS_MIN_EPOCHS: usize = 1000;

/// The fingerprint of a map over an epoch range (what `--resume` checks): penumbra's build, the
/// request (but `--resume`), the kernels' and DEMs' sha256 and a horizons file's size and time.
fn range_fingerprint(
    req: &MapRequest,
    kernels: &[crate::ephem::kernels::KernelFile],
    dems: &[crate::output::InputFile],
) -> anyhow::Result<String> {
    let request = format!(
        "{:?}",
        MapRequest {
            resume: false,
            ..req.clone()
        }
    );
    let horizons = match &req.horizons {
        crate::compute::sweep::HorizonsFrom::File(p) => crate::output::checkpoint::file_stamp(p)
            .map_err(|e| anyhow::anyhow!("--horizons {}: {e}", p.display()))?,
        crate::compute::sweep::HorizonsFrom::Sweep { .. } => String::new(),
    };
    let prov = crate::output::Provenance::new();
    Ok(crate::output::checkpoint::fingerprint(&[
        prov.penumbra_version.as_bytes(),
        prov.git_commit.as_bytes(),
        request.as_bytes(),
        serde_json::to_string(kernels)?.as_bytes(),
        serde_json::to_string(dems)?.as_bytes(),
        horizons.as_bytes(),
    ]))
}

/// The fingerprint of a sharded job (what `penumbra merge` checks): penumbra's build, every
/// parameter but the shard, its output folder and `--resume`, and the inputs by content (the
/// kernels' and DEMs' sha256, not their paths), so that shards run from other folders or
/// through the Python module merge.
fn job_fingerprint(
    req: &MapRequest,
    kernels: &[crate::ephem::kernels::KernelFile],
    inputs: &[crate::output::InputFile],
) -> anyhow::Result<String> {
    let terrain = match &req.terrain {
        TerrainSource::Dems(_) => TerrainSource::Dems(Vec::new()),
        other => other.clone(),
    };
    let horizons = match &req.horizons {
        crate::compute::sweep::HorizonsFrom::File(_) => {
            crate::compute::sweep::HorizonsFrom::File(PathBuf::new())
        }
        other => other.clone(),
    };
    let request = format!(
        "{:?}",
        MapRequest {
            terrain,
            horizons,
            out_dir: None,
            resume: false,
            shard: None,
            kernels: KernelSource::default(),
            ..req.clone()
        }
    );
    let kernels: Vec<(&str, &str)> = kernels
        .iter()
        .map(|k| (k.kind, k.sha256.as_str()))
        .collect();
    let inputs: Vec<&str> = inputs.iter().map(|f| f.sha256.as_str()).collect();
    let prov = crate::output::Provenance::new();
    Ok(crate::output::checkpoint::fingerprint(&[
        prov.penumbra_version.as_bytes(),
        prov.git_commit.as_bytes(),
        request.as_bytes(),
        format!("{kernels:?}").as_bytes(),
        format!("{inputs:?}").as_bytes(),
    ]))
}

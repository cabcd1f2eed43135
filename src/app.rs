//! Runs a parsed command line: the glue between [`crate::cli`] and the library.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use hifitime::Epoch;

use crate::cli::{Cli, Command, EphemArgs, EpochArgs, Format, KernelArgs};
use crate::ephem::{self, AbCorr, Kernels, Site, SunEarth, time::format_utc};

/// Runs one invocation of the tool.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Ephem(args) => run_ephem(&args),
        Command::Kernels(args) => run_kernels(&args),
        Command::Run(args) => crate::scenario::run_file(&args),
        Command::Dem { command } => run_dem(command),
        Command::Series(args) => run_series(&args),
        Command::Map(args) => run_map(&args),
        Command::Horizon(args) => {
            let stack = load_stack(&args.dem)?;
            crate::horizon::cli_run(&args, &stack)
        }
        Command::GpuInfo(args) => run_gpu_info(&args),
        Command::Render(args) => run_render(&args),
        Command::HorizonMap { command } => run_horizon_map(command),
    }
}

/// Formats an error chain on one line (`outer: inner: root cause`), as `main` prints it.
pub fn one_line(err: &anyhow::Error) -> String {
    format!("{err:#}").replace('\n', " ")
}

/// The kernel folder chosen by `--kernels` or the defaults.
pub fn kernel_dir(args: &KernelArgs) -> PathBuf {
    args.kernels
        .clone()
        .unwrap_or_else(ephem::kernels::default_kernel_dir)
}

/// Loads the kernels chosen by `--kernels` or the defaults.
pub fn load_kernels(args: &KernelArgs) -> anyhow::Result<Kernels> {
    let dir = kernel_dir(args);
    Kernels::load(&dir).context("loading SPICE kernels")
}

/// The epochs asked for by `--utc` or `--start/--stop/--step`.
pub fn epochs_from_args(args: &EpochArgs) -> anyhow::Result<Vec<Epoch>> {
    match (&args.utc, &args.start, &args.stop, &args.step) {
        (Some(t), None, None, None) => Ok(vec![ephem::time::parse_utc(t)?]),
        (None, Some(a), Some(b), Some(s)) => Ok(ephem::time::epoch_range(
            ephem::time::parse_utc(a)?,
            ephem::time::parse_utc(b)?,
            ephem::time::parse_step(s)?,
        )?),
        _ => anyhow::bail!("give either --utc T or all of --start T --stop T --step S"),
    }
}

/// Writes to `--out` atomically, or to stdout.
pub fn write_output(
    out: Option<&Path>,
    fill: impl FnOnce(&mut dyn Write) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    match out {
        Some(path) => crate::output::write_atomic(path, fill)
            .with_context(|| format!("writing {}", path.display())),
        None => {
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            fill(&mut lock)?;
            lock.flush().ok();
            Ok(())
        }
    }
}

/// The exact CSV header of `penumbra ephem`.
pub const EPHEM_CSV_HEADER: &str = "utc,sun_az_deg,sun_el_deg,sun_range_km,sun_radius_deg,earth_az_deg,earth_el_deg,earth_range_km,earth_radius_deg";

/// Writes one `ephem` CSV row.
pub fn write_ephem_row(w: &mut dyn Write, epoch: Epoch, v: &SunEarth) -> std::io::Result<()> {
    writeln!(
        w,
        "{},{:.9},{:.9},{:.6},{:.9},{:.9},{:.9},{:.6},{:.9}",
        format_utc(epoch),
        v.sun.az_deg,
        v.sun.el_deg,
        v.sun.range_km,
        v.sun.radius_deg,
        v.earth.az_deg,
        v.earth.el_deg,
        v.earth.range_km,
        v.earth.radius_deg
    )
}

fn run_ephem(args: &EphemArgs) -> anyhow::Result<()> {
    let abcorr = AbCorr::parse(&args.abcorr)?;
    let site = Site::new(args.lat_deg, args.lon_deg, args.height_m)?;
    let epochs = epochs_from_args(&args.epochs)?;
    let kernels = load_kernels(&args.kernels)?;
    let series = ephem::sun_earth_series(&kernels, &[site], &epochs, abcorr)?;
    let rows = &series[0];
    // Sub-solar and sub-Earth points go into the JSON output only (the CSV columns are fixed).
    let sub_points = if args.format == Format::Json {
        use rayon::prelude::*;
        epochs
            .par_iter()
            .map(|&e| {
                let geo = ephem::MoonGeometry::at(&kernels.almanac, e)?;
                Ok((
                    ephem::topo::sub_body_point(&geo, &geo.sun_wrt_moon, abcorr),
                    ephem::topo::sub_body_point(&geo, &geo.earth_wrt_moon, abcorr),
                ))
            })
            .collect::<Result<Vec<_>, ephem::EphemError>>()?
    } else {
        Vec::new()
    };
    write_output(args.out.as_deref(), |w| {
        match args.format {
            Format::Csv => {
                writeln!(w, "{EPHEM_CSV_HEADER}")?;
                for (e, v) in epochs.iter().zip(rows) {
                    write_ephem_row(w, *e, v)?;
                }
            }
            Format::Json => {
                let doc = serde_json::json!({
                    "site": {"lat_deg": args.lat_deg, "lon_deg": args.lon_deg, "height_m": args.height_m},
                    "abcorr": abcorr.spice_name(),
                    "frame": "MOON_ME",
                    "epochs": epochs.iter().zip(rows).zip(&sub_points).map(|((e, v), (ss, se))| serde_json::json!({
                        "utc": format_utc(*e),
                        "sun": v.sun,
                        "earth": v.earth,
                        "subsolar_point": ss,
                        "sub_earth_point": se,
                    })).collect::<Vec<_>>(),
                });
                serde_json::to_writer_pretty(&mut *w, &doc)?;
                writeln!(w)?;
            }
        }
        Ok(())
    })
}

fn run_kernels(args: &KernelArgs) -> anyhow::Result<()> {
    let kernels = load_kernels(args)?;
    let mut out = String::new();
    use std::fmt::Write as _;
    writeln!(out, "kernel folder: {}", kernels.dir.display())?;
    for f in &kernels.files {
        writeln!(
            out,
            "  {:<4} {:>10} B  sha256 {}  {}",
            f.kind,
            f.size_bytes,
            &f.sha256[..16],
            f.path.display()
        )?;
    }
    writeln!(out, "bodies (SPK, NAIF id: span TDB):")?;
    let mut domains: Vec<_> = kernels
        .almanac
        .spk_domains()
        .map(|d| d.into_iter().collect())
        .unwrap_or_default();
    domains.sort_by_key(|(id, _)| *id);
    for (id, (s, e)) in domains.into_iter().filter(|(id, _)| *id != 0) {
        writeln!(out, "  {:>4} {}: {} .. {}", id, body_name(id), s, e)?;
    }
    writeln!(
        out,
        "frames: J2000 (1), MOON_PA_DE421 (31006, binary PCK), MOON_ME = MOON_ME_DE421 (31007, from the frame kernel)"
    )?;
    if let Ok((s, e)) = kernels.almanac.bpc_domain(ephem::kernels::MOON_PA_DE421_ID) {
        writeln!(out, "  MOON_PA_DE421 orientation data: {s} .. {e}")?;
    }
    writeln!(
        out,
        "usable epochs (all bodies and MOON_ME, light-time margin included): {} .. {} UTC",
        format_utc(kernels.coverage.0),
        format_utc(kernels.coverage.1)
    )?;
    writeln!(
        out,
        "time scales: UTC input, leap seconds from hifitime's table (= naif0012), TDB for the kernels"
    )?;
    print!("{out}");
    Ok(())
}

fn body_name(id: i32) -> &'static str {
    match id {
        0 => "solar-system barycentre",
        3 => "Earth-Moon barycentre",
        10 => "Sun",
        301 => "Moon",
        399 => "Earth",
        1 => "Mercury barycentre",
        2 => "Venus barycentre",
        4 => "Mars barycentre",
        5 => "Jupiter barycentre",
        6 => "Saturn barycentre",
        7 => "Uranus barycentre",
        8 => "Neptune barycentre",
        9 => "Pluto barycentre",
        _ => "",
    }
}

/// `penumbra dem info|synth`.
fn run_dem(command: crate::cli::DemCommand) -> anyhow::Result<()> {
    use crate::cli::{DemCommand, InfoFormat};
    use crate::terrain::{self, DemInfo, synth};
    use anyhow::Context as _;
    match command {
        DemCommand::Info { file, format, at } => {
            let dem = terrain::load_dem(&file)?;
            let info = DemInfo::of(&dem);
            let stack = terrain::TerrainStack::new(vec![dem]);
            let mut points = Vec::new();
            for spec in &at {
                let (lat, lon) = spec
                    .split_once(',')
                    .and_then(|(a, b)| {
                        Some((a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?))
                    })
                    .with_context(|| format!("--at {spec:?}: expected LAT,LON in degrees"))?;
                let (h, _) = stack.height_at_lat_lon_m_checked(lat, lon)?;
                points.push((lat, lon, h));
            }
            match format {
                InfoFormat::Text => {
                    print!("{}", info.to_text());
                    for (lat, lon, h) in &points {
                        println!("height at {lat}, {lon}: {h:.3} m");
                    }
                }
                InfoFormat::Json => {
                    let mut v = serde_json::to_value(&info)?;
                    v["points"] = points
                        .iter()
                        .map(|(lat, lon, h)| serde_json::json!({"lat_deg": lat, "lon_deg": lon, "height_m": h}))
                        .collect();
                    println!("{}", serde_json::to_string_pretty(&v)?);
                }
            }
            Ok(())
        }
        DemCommand::Synth {
            size,
            px_m,
            seed,
            out,
        } => {
            let dem = synth::south_polar_dem(&synth::SynthParams {
                size_px: size,
                px_m,
                seed,
            })?;
            let (version, seed_s) = (env!("CARGO_PKG_VERSION").to_string(), seed.to_string());
            let (size_s, px_s) = (size.to_string(), px_m.to_string());
            terrain::write_dem(
                &out,
                &dem,
                &[
                    ("software", &format!("penumbra {version}")),
                    ("synth_seed", &seed_s),
                    ("synth_size_px", &size_s),
                    ("synth_px_m", &px_s),
                    ("units", "m above the 1737.4 km sphere"),
                ],
            )?;
            Ok(())
        }
    }
}

/// Loads DEM layers (GeoTIFF) into a terrain stack, finest first.
pub fn load_stack(paths: &[std::path::PathBuf]) -> anyhow::Result<crate::terrain::TerrainStack> {
    if paths.is_empty() {
        anyhow::bail!("no DEM given (use --dem FILE, repeatable)");
    }
    Ok(crate::terrain::TerrainStack::load(paths)?)
}

/// The built-in synthetic DEM as a one-layer stack, and its description for provenance.
pub fn synthetic_stack(
    params: &crate::terrain::synth::SynthParams,
) -> anyhow::Result<(crate::terrain::TerrainStack, String)> {
    let dem = crate::terrain::synth::south_polar_dem(params)?;
    let what = format!(
        "synthetic south-polar DEM ({} x {} px at {} m, seed {})",
        params.size_px, params.size_px, params.px_m, params.seed
    );
    Ok((crate::terrain::TerrainStack::new(vec![dem]), what))
}

fn run_series(args: &crate::cli::SeriesArgs) -> anyhow::Result<()> {
    use crate::series::{self, SeriesConfig, SeriesSite};
    let t0 = std::time::Instant::now();
    let mut sites: Vec<SeriesSite> = args
        .site
        .iter()
        .map(|s| series::parse_site_flag(s, args.observer_height_m))
        .collect::<anyhow::Result<_>>()?;
    if let (Some(lat_deg), Some(lon_deg)) = (args.lat_deg, args.lon_deg) {
        sites.push(SeriesSite {
            name: "site".into(),
            lat_deg,
            lon_deg,
            height_above_ground_m: args.observer_height_m,
        });
    }
    if sites.is_empty() {
        anyhow::bail!("no site given (use --site NAME,LAT,LON or --lat-deg/--lon-deg)");
    }
    series::validate_sites(&sites)?;
    let config = SeriesConfig {
        abcorr: AbCorr::parse(&args.abcorr)?,
        disc_method: args.disc_method.into(),
        limb_darkening: args.limb_darkening,
        az_step_deg: args.az_step_deg,
        horizon_method: args.horizon_method.into(),
        plots: !args.no_plots,
        write_csv: !args.no_csv,
        backend: args.backend,
        engine: args.engine,
    };
    let epochs = epochs_from_args(&args.epochs)?;
    let step_s = epoch_step_s(&args.epochs)?;
    let (stack, dem_layers) = load_terrain(&args.terrain)?;
    let kernels = load_kernels(&args.kernels)?;
    let run = series::run_series(
        &kernels,
        &stack,
        &sites,
        &epochs,
        step_s,
        &config,
        &args.out_dir,
    )?;
    let mut prov = crate::output::Provenance::new();
    prov.kernels = kernels.files.clone();
    prov.dem_layers = dem_layers;
    prov.set_epochs(&epochs);
    prov.outputs = run.files;
    prov.series_engine = Some(config.engine.name().into());
    prov.series_backend = Some(run.backend);
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&args.out_dir.join("run.json"))?;
    eprintln!(
        "penumbra: {} site(s) x {} epochs -> {} ({:.1} s)",
        sites.len(),
        epochs.len(),
        args.out_dir.display(),
        prov.wall_time_s
    );
    Ok(())
}

/// The step (s) of `--start/--stop/--step`, or 3600 s for a single `--utc` epoch (the weight of one
/// sample in the statistics).
pub fn epoch_step_s(args: &EpochArgs) -> anyhow::Result<f64> {
    Ok(match &args.step {
        Some(s) => ephem::time::parse_step(s)?.to_seconds(),
        None => 3600.0,
    })
}

/// Parses `x,y,z` into a non-zero finite vector.
pub fn parse_vector3(text: &str) -> anyhow::Result<nalgebra::Vector3<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--sun-dir-body '{text}': expected three numbers X,Y,Z"))?;
    if v.len() != 3 {
        anyhow::bail!("--sun-dir-body '{text}': expected three numbers X,Y,Z");
    }
    let v = nalgebra::Vector3::new(v[0], v[1], v[2]);
    if !v.iter().all(|c| c.is_finite()) || v.norm() == 0.0 {
        anyhow::bail!("--sun-dir-body '{text}': the direction must be finite and non-zero");
    }
    Ok(v)
}

fn run_map(args: &crate::cli::MapArgs) -> anyhow::Result<()> {
    use crate::map::{MapGrid, epoch_lights, sweep, write_sweep};
    let t0 = std::time::Instant::now();
    if !(args.observer_height_m >= 0.0 && args.observer_height_m.is_finite()) {
        anyhow::bail!(
            "--observer-height-m {} must be a finite number >= 0",
            args.observer_height_m
        );
    }
    if !(args.sun_radius_deg > 0.0 && args.sun_radius_deg < 10.0) {
        anyhow::bail!(
            "--sun-radius-deg {} must be in (0, 10)",
            args.sun_radius_deg
        );
    }
    let engine_kind: crate::map::MapEngineKind = args.engine.into();
    let abcorr = AbCorr::parse(&args.abcorr)?;
    let range = args.epochs.start.is_some();
    if range && args.out_dir.is_none() {
        anyhow::bail!("an epoch range needs --out-dir DIR for the statistics maps");
    }
    if !range
        && args.out_fraction.is_none()
        && args.out_mask.is_none()
        && args.out_earth_fraction.is_none()
    {
        anyhow::bail!("nothing to write: give --out-fraction, --out-mask or --out-earth-fraction");
    }
    let explicit_dir = match &args.sun_dir_body {
        Some(t) => Some(parse_vector3(t)?),
        None => None,
    };
    if !range && explicit_dir.is_none() && args.sun_az_deg.is_none() && args.epochs.utc.is_none() {
        anyhow::bail!("give the light: --utc T, --sun-dir-body X,Y,Z or --sun-az-deg/--sun-el-deg");
    }
    let epochs = if range || args.epochs.utc.is_some() {
        epochs_from_args(&args.epochs)?
    } else {
        Vec::new()
    };
    // Resolve after the argument checks (bad input is one error line, with no backend warning)
    // and before any heavy work, so that a missing adapter is one error line (or one warning
    // line with `auto`).
    let backend = Some(
        crate::gpu::resolve_backend(args.backend)
            .with_context(|| format!("resolving --backend {}", args.backend.as_str()))?,
    );
    let placement = match (&backend, args.observers) {
        #[cfg(feature = "gpu")]
        (Some(crate::gpu::ResolvedBackend::Gpu(_)), Some(crate::cli::ObserversArg::Pixels)) => {
            anyhow::bail!(
                "--observers pixels needs --backend cpu: the GPU kernels start their rays at the \
                 model grid's cells (--observers cells)"
            )
        }
        (_, Some(o)) => crate::map::ObserverPlacement::from(o),
        (Some(crate::gpu::ResolvedBackend::Cpu), None) => crate::map::ObserverPlacement::Pixels,
        (_, None) => crate::map::ObserverPlacement::Cells,
    };
    let kernels = if epochs.is_empty() {
        None
    } else {
        let k = load_kernels(&args.kernels)?;
        ephem::moon_geometry_table(&k, &[epochs[0], *epochs.last().unwrap_or(&epochs[0])])?;
        Some(k)
    };
    let (stack, dem_layers) = load_terrain(&args.terrain)?;
    let grid = MapGrid::new(&stack)?;
    eprintln!(
        "penumbra: model grid {} x {} at {} m centred on ({:.4}, {:.4}) deg (every layer)",
        grid.hf.rows, grid.hf.cols, grid.hf.px_m, grid.hf.centre_lat_deg, grid.hf.centre_lon_deg
    );
    grid.warn_if_clipped();

    if range {
        let (Some(kernels), Some(out_dir)) = (&kernels, &args.out_dir) else {
            anyhow::bail!("an epoch range needs kernels and --out-dir");
        };
        let step_h = epoch_step_s(&args.epochs)? / 3600.0;
        let lights = epoch_lights(&grid, kernels, &epochs, abcorr)?;
        let progress = indicatif::ProgressBar::new(lights.len() as u64);
        progress.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} map sweep [{bar:30}] {pos}/{len} epochs (eta {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        let Some(backend) = backend else {
            anyhow::bail!("an epoch range needs a resolved backend");
        };
        let (stats, backend_note) = match &backend {
            crate::gpu::ResolvedBackend::Cpu => {
                let engine =
                    crate::map::MapEngine::new(engine_kind, &grid, args.observer_height_m)?;
                let stats = sweep(
                    &grid,
                    &engine,
                    args.observer_height_m,
                    placement,
                    &lights,
                    step_h,
                    &progress,
                )?;
                (
                    stats,
                    format!(
                        "cpu: {} soft shadows of the discs, rays from the {}",
                        engine.describe(),
                        placement.describe()
                    ),
                )
            }
            #[cfg(feature = "gpu")]
            crate::gpu::ResolvedBackend::Gpu(ctx) => {
                let stats = crate::map::sweep_gpu_soft(
                    ctx,
                    &grid,
                    args.observer_height_m,
                    &lights,
                    step_h,
                    crate::gpu::tiles::DpTiling {
                        tile_cells: args.gpu_tile_cells,
                    },
                )?;
                progress.inc(lights.len() as u64);
                (
                    stats,
                    format!(
                        "{}: DP max-mipmap soft shadows of the Sun and Earth discs \
                         (GPU-resident sweep; --engine is not used on the GPU)",
                        backend.describe()
                    ),
                )
            }
            #[cfg(not(feature = "gpu"))]
            crate::gpu::ResolvedBackend::Gpu(ctx) => match **ctx {},
        };
        progress.finish_and_clear();
        std::fs::create_dir_all(out_dir)
            .with_context(|| format!("creating output folder {}", out_dir.display()))?;
        let span = format!(
            "{} .. {} UTC, {} epochs",
            format_utc(epochs[0]),
            format_utc(*epochs.last().unwrap_or(&epochs[0])),
            epochs.len()
        );
        let files = write_sweep(&grid, &stats, out_dir, &span)?;
        let mut prov = crate::output::Provenance::new();
        prov.kernels = kernels.files.clone();
        prov.dem_layers = dem_layers;
        prov.set_epochs(&epochs);
        prov.outputs = files;
        prov.backend = backend_note;
        prov.map_rays_blocked_beyond_dem = stats.below_sphere;
        if let Some(b) = stats.below_sphere {
            b.warn();
        }
        prov.wall_time_s = t0.elapsed().as_secs_f64();
        prov.write(&out_dir.join("run.json"))?;
        eprintln!(
            "penumbra: map statistics over {} epochs -> {} ({:.1} s)",
            epochs.len(),
            out_dir.display(),
            prov.wall_time_s
        );
        return Ok(());
    }

    // One light.
    let (sun, sun_radius_rad, earth) = match (&kernels, explicit_dir, args.sun_az_deg) {
        (Some(k), _, _) => {
            let l = epoch_lights(&grid, k, &epochs, abcorr)?[0];
            (l.sun, l.sun_radius_rad, Some((l.earth, l.earth_radius_rad)))
        }
        (None, Some(d), _) => (
            grid.light_from_moon_me(&d),
            args.sun_radius_deg.to_radians(),
            None,
        ),
        (None, None, Some(az)) => (
            grid.light_from_az_el_deg(az, args.sun_el_deg.unwrap_or(0.0)),
            args.sun_radius_deg.to_radians(),
            None,
        ),
        (None, None, None) => anyhow::bail!("no light given"),
    };
    // The GPU runs the DP max-mipmap kernel for every engine but Fourier, whose horizon map is
    // built and evaluated by the Fourier kernels (docs/gpu.md).
    #[cfg(feature = "gpu")]
    let gpu_ctx = match &backend {
        Some(crate::gpu::ResolvedBackend::Gpu(ctx)) => Some(ctx),
        _ => None,
    };
    #[cfg(not(feature = "gpu"))]
    let gpu_ctx: Option<&crate::gpu::GpuContext> = None;
    #[cfg(feature = "gpu")]
    let tiling = crate::gpu::tiles::DpTiling {
        tile_cells: args.gpu_tile_cells,
    };
    let h_m = args.observer_height_m;
    let engine = match gpu_ctx {
        #[cfg(feature = "gpu")]
        Some(ctx) if engine_kind == crate::map::MapEngineKind::Fourier => {
            crate::map::MapEngine::fourier_gpu(ctx, &grid, h_m)?
        }
        _ => crate::map::MapEngine::new(engine_kind, &grid, h_m)?,
    };
    #[cfg(feature = "gpu")]
    let gpu_fourier = match (gpu_ctx, &engine) {
        (Some(ctx), crate::map::MapEngine::Fourier(map)) => Some(
            crate::gpu::fourier::GpuHorizonMap::upload(
                ctx,
                map,
                crate::gpu::fourier::DEFAULT_BAND_BYTES,
            )
            .context("uploading the horizon map")?,
        ),
        _ => None,
    };
    // Each DEM pixel's own observer (where the CPU engines start their rays by default).
    let pixel_observers = grid.pixel_observers(h_m);
    let observers =
        (placement == crate::map::ObserverPlacement::Pixels).then_some(pixel_observers.as_slice());
    let fraction = |light: [f64; 3], radius: f64| -> anyhow::Result<Vec<f32>> {
        match gpu_ctx {
            #[cfg(feature = "gpu")]
            // The GPU kernels run per model cell: resampled onto the DEM grid.
            Some(ctx) => Ok(grid.to_output_f32(&match &gpu_fourier {
                Some(on_gpu) => crate::map::fourier_fraction_gpu(ctx, on_gpu, light, radius)?,
                None => {
                    crate::map::visible_fraction_gpu(ctx, &grid.hf, h_m, light, radius, tiling)?
                }
            })),
            _ => engine.visible_fraction_on_dem(&grid, observers, h_m, light, radius),
        }
    };
    if let Some(path) = &args.out_fraction {
        let f = fraction(sun, sun_radius_rad)?;
        grid.below_sphere_exits(&pixel_observers, sun, &f)?.warn();
        grid.write_f32(path, &f, "visible fraction of the Sun's disc")?;
    }
    if let Some(path) = &args.out_mask {
        let m = match gpu_ctx {
            #[cfg(feature = "gpu")]
            Some(ctx) => grid.to_output_u8(&match &gpu_fourier {
                Some(on_gpu) => on_gpu
                    .hard_mask(ctx, sun)
                    .context("evaluating the horizon map on the GPU")?,
                None => crate::map::hard_mask_gpu(ctx, &grid.hf, h_m, sun, tiling)?,
            }),
            _ => engine.hard_mask_on_dem(&grid, observers, h_m, sun)?,
        };
        grid.write_u8(path, &m, "Sun disc centre: 1 lit, 0 shadow, 255 no data")?;
    }
    if let (Some(path), Some((dir, radius))) = (&args.out_earth_fraction, earth) {
        let f = fraction(dir, radius)?;
        grid.write_f32(path, &f, "visible fraction of the Earth's disc")?;
    }
    eprintln!(
        "penumbra: map written ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `penumbra gpu-info`: adapters, and optionally the backend that `--backend` resolves to.
fn run_gpu_info(args: &crate::cli::GpuInfoArgs) -> anyhow::Result<()> {
    print_adapters()?;
    if let Some(requested) = args.backend {
        let resolved = crate::gpu::resolve_backend(requested)
            .with_context(|| format!("resolving --backend {}", requested.as_str()))?;
        println!("backend {}: {}", requested.as_str(), resolved.describe());
    }
    Ok(())
}

#[cfg(feature = "gpu")]
fn print_adapters() -> anyhow::Result<()> {
    let adapters = crate::gpu::adapter_report();
    let mut out = String::new();
    use std::fmt::Write as _;
    if adapters.is_empty() {
        writeln!(
            out,
            "no GPU adapter found (WGPU_BACKEND={}); --backend auto will use the CPU",
            std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "unset".into())
        )?;
    }
    for (i, a) in adapters.iter().enumerate() {
        writeln!(out, "adapter {i}: {}", a.name)?;
        writeln!(
            out,
            "  backend: {}, device type: {}, driver: {}",
            a.backend, a.device_type, a.driver
        )?;
        writeln!(
            out,
            "  max_storage_buffer_binding_size: {} B",
            a.max_storage_buffer_binding_size
        )?;
        writeln!(out, "  max_buffer_size: {} B", a.max_buffer_size)?;
        writeln!(
            out,
            "  max_compute_workgroup_size_x: {}",
            a.max_compute_workgroup_size_x
        )?;
        writeln!(
            out,
            "  max_compute_invocations_per_workgroup: {}",
            a.max_compute_invocations_per_workgroup
        )?;
        writeln!(
            out,
            "  max_compute_workgroups_per_dimension: {}",
            a.max_compute_workgroups_per_dimension
        )?;
    }
    print!("{out}");
    Ok(())
}

#[cfg(not(feature = "gpu"))]
fn print_adapters() -> anyhow::Result<()> {
    println!("this penumbra was built without the `gpu` cargo feature: no GPU adapters");
    Ok(())
}

/// The terrain of `--dem FILE…` or `--synthetic`, and its description for provenance.
pub fn load_terrain(
    args: &crate::cli::TerrainArgs,
) -> anyhow::Result<(crate::terrain::TerrainStack, Vec<String>)> {
    if args.synthetic {
        let (stack, what) = synthetic_stack(&crate::terrain::synth::SynthParams::default())?;
        Ok((stack, vec![what]))
    } else {
        Ok((
            load_stack(&args.dem)?,
            args.dem.iter().map(|p| p.display().to_string()).collect(),
        ))
    }
}

/// `penumbra render`: one frame (`--utc`) or numbered frames (`--start/--stop/--step`) from a
/// site or an orbital camera.
pub fn run_render(args: &crate::cli::RenderArgs) -> anyhow::Result<()> {
    let epochs = epochs_from_args(&args.epochs)?;
    let pose = pose_from_args(args)?;
    let frames: Vec<_> = epochs.into_iter().map(|e| (e, pose)).collect();
    render_frames(args, &frames)
}

/// The camera pose of `penumbra render`'s camera options.
pub fn pose_from_args(
    args: &crate::cli::RenderArgs,
) -> anyhow::Result<crate::render::path::CameraPose> {
    use crate::cli::CameraArg;
    use crate::render::path::CameraPose;
    Ok(match args.camera {
        CameraArg::Site => CameraPose::Site {
            lat_deg: args.lat_deg,
            lon_deg: args.lon_deg,
            height_m: args.height_m,
            look_az_deg: args.look_az_deg,
            look_el_deg: args.look_el_deg,
            fov_deg: args.fov_deg,
        },
        CameraArg::Orbit => {
            let Some(altitude_km) = args.altitude_km else {
                anyhow::bail!("--camera orbit needs --altitude-km");
            };
            CameraPose::Orbit {
                lat_deg: args.lat_deg,
                lon_deg: args.lon_deg,
                altitude_km,
                target_lat_deg: args.target_lat_deg.unwrap_or(args.lat_deg),
                target_lon_deg: args.target_lon_deg.unwrap_or(args.lon_deg),
                fov_deg: args.fov_deg,
            }
        }
    })
}

/// A camera placed in model space from a pose: the camera, the (lat, lon) whose local up
/// defines the reported Sun elevation, and a label for the PNG metadata.
struct PlacedCamera {
    camera: crate::render::Camera,
    ref_lat_lon_deg: (f64, f64),
    what: String,
}

/// Checks `pose` against the terrain and places the camera.
fn place_camera(
    pose: &crate::render::path::CameraPose,
    stack: &crate::terrain::TerrainStack,
    hf: &crate::terrain::HeightField,
) -> anyhow::Result<PlacedCamera> {
    use crate::render::Camera;
    use crate::render::path::CameraPose;
    let frame = crate::terrain::model_space::ModelFrame::of(hf);
    let model_from_enu_at = |lat_deg: f64, lon_deg: f64| {
        hf.model_from_moon_me() * crate::frames::enu_from_moon_me(lat_deg, lon_deg).transpose()
    };
    let fov_deg = match *pose {
        CameraPose::Site { fov_deg, .. } | CameraPose::Orbit { fov_deg, .. } => fov_deg,
    };
    if !(fov_deg > 0.0 && fov_deg < 180.0) {
        anyhow::bail!("--fov-deg {fov_deg} must be in (0, 180)");
    }
    Ok(match *pose {
        CameraPose::Site {
            lat_deg,
            lon_deg,
            height_m,
            look_az_deg,
            look_el_deg,
            fov_deg,
        } => {
            if !(height_m >= 0.0 && height_m.is_finite()) {
                anyhow::bail!(
                    "--height-m {height_m} puts the camera below the terrain surface: give a finite height >= 0"
                );
            }
            let (ground_m, _) = stack.height_at_lat_lon_m_checked(lat_deg, lon_deg)?;
            let pos = frame.model_from_lat_lon_height(lat_deg, lon_deg, ground_m + height_m);
            if let Some(z) = crate::render::terrain_z_m(hf, pos.x, pos.y) {
                // The model-space surface is a resampling of the DEM; allow its interpolation error.
                if pos.z < z - 0.5 {
                    anyhow::bail!(
                        "the camera ({height_m:.1} m above the DEM) is below the model-space terrain surface"
                    );
                }
            }
            let camera = Camera::from_az_el_deg(
                pos,
                &model_from_enu_at(lat_deg, lon_deg),
                look_az_deg,
                look_el_deg,
                fov_deg,
            )?;
            PlacedCamera {
                camera,
                ref_lat_lon_deg: (lat_deg, lon_deg),
                what: format!(
                    "site lat_deg={lat_deg} lon_deg={lon_deg} height_m={height_m} \
                     look_az_deg={look_az_deg} look_el_deg={look_el_deg} fov_deg={fov_deg}"
                ),
            }
        }
        CameraPose::Orbit {
            lat_deg,
            lon_deg,
            altitude_km: alt_km,
            target_lat_deg: tlat,
            target_lon_deg: tlon,
            fov_deg,
        } => {
            if !alt_km.is_finite() {
                anyhow::bail!("--altitude-km {alt_km} must be finite");
            }
            let (target_ground_m, _) = stack
                .height_at_lat_lon_m_checked(tlat, tlon)
                .context("the orbit camera's target point")?;
            let pos = frame.model_from_lat_lon_height(lat_deg, lon_deg, alt_km * 1e3);
            let below = match crate::render::terrain_z_m(hf, pos.x, pos.y) {
                Some(z) => pos.z < z,
                None => {
                    // Outside the grid: compare with the DEM there, if any, else with the
                    // highest point of the DEM layers.
                    match stack.height_at_lat_lon_m_checked(lat_deg, lon_deg) {
                        Ok((g, _)) => alt_km * 1e3 < g,
                        Err(_) => {
                            let top_m = stack
                                .layers
                                .iter()
                                .flat_map(|l| l.heights_m.iter())
                                .filter(|h| h.is_finite())
                                .fold(f64::NEG_INFINITY, |a, &h| a.max(f64::from(h)));
                            alt_km * 1e3 < top_m
                        }
                    }
                }
            };
            if below {
                anyhow::bail!(
                    "the camera (--altitude-km {alt_km} above the 1737.4 km sphere) is inside the terrain"
                );
            }
            let target = frame.model_from_lat_lon_height(tlat, tlon, target_ground_m);
            let north = model_from_enu_at(lat_deg, lon_deg) * nalgebra::Vector3::y();
            let camera = Camera::look_at(pos, target, north, fov_deg)?;
            PlacedCamera {
                camera,
                ref_lat_lon_deg: (tlat, tlon),
                what: format!(
                    "orbit lat_deg={lat_deg} lon_deg={lon_deg} altitude_km={alt_km} \
                     target_lat_deg={tlat} target_lon_deg={tlon} fov_deg={fov_deg}"
                ),
            }
        }
    })
}

/// Where the per-cell Sun and Earth visible fractions of a frame come from: the CPU shadow
/// engine, or (when the render backend resolved to the GPU) the GPU DP kernel, so that a GPU
/// frame does not wait on the CPU engine.
enum FractionSource {
    /// `Engine::Combined` on the CPU (what `Scene::new` does).
    Cpu,
    /// The GPU DP kernel on the uploaded grid.
    #[cfg(feature = "gpu")]
    Gpu(crate::map::GpuSceneFractions),
}

/// Everything a frame needs besides its camera and epoch.
struct FrameJob<'a> {
    args: &'a crate::cli::RenderArgs,
    hf: &'a crate::terrain::HeightField,
    brdf: crate::render::Brdf,
    backend: &'a crate::gpu::ResolvedBackend,
    fractions: FractionSource,
}

/// Renders one frame (`index` numbers the output files of a sequence) and writes its PNG (and
/// radiance TIFF); returns the PNG path and the Sun elevation at the reference point, degrees.
fn render_one_frame(
    job: &FrameJob,
    placed: &PlacedCamera,
    epoch: Epoch,
    lights: crate::render::Lights,
    index: Option<usize>,
) -> anyhow::Result<(PathBuf, f64)> {
    use crate::render::Scene;
    let args = job.args;
    let scene = match &job.fractions {
        FractionSource::Cpu => Scene::new(job.hf, lights, crate::shadow::Engine::Combined)?,
        #[cfg(feature = "gpu")]
        FractionSource::Gpu(gpu) => {
            let crate::gpu::ResolvedBackend::Gpu(ctx) = job.backend else {
                anyhow::bail!("internal: GPU fractions without a GPU backend")
            };
            let (sun, earth) = gpu.fractions(ctx, &lights)?;
            Scene::with_fractions(job.hf, lights, sun, earth)
        }
    }
    .with_brdf(job.brdf);
    let camera = &placed.camera;
    let samples = render_samples(&scene, camera, args, job.backend)?;
    let exposure = args
        .exposure
        .unwrap_or_else(|| crate::render::auto_exposure(&samples));
    let mut rgb = crate::render::tone_map(&samples, exposure);
    crate::render::add_sun_glare(&mut rgb, &scene, camera, args.width, args.height);
    // Sun elevation at the site (or the orbit camera's target), above the plane normal to the
    // local up.
    let (lat, lon) = placed.ref_lat_lon_deg;
    let up = job.hf.model_from_moon_me()
        * crate::frames::enu_from_moon_me(lat, lon).transpose()
        * nalgebra::Vector3::z();
    let sun_el_deg = nalgebra::Vector3::from(lights.sun)
        .dot(&up)
        .clamp(-1.0, 1.0)
        .asin()
        .to_degrees();
    let text = [
        (
            "Software",
            format!("penumbra {}", env!("CARGO_PKG_VERSION")),
        ),
        ("penumbra:epoch_utc", format_utc(epoch)),
        ("penumbra:sun_elevation_deg", format!("{sun_el_deg:.4}")),
        ("penumbra:camera", placed.what.clone()),
        ("penumbra:brdf", format!("{:?}", job.brdf)),
        ("penumbra:exposure", format!("{exposure:.6e}")),
    ];
    let png = crate::render::encode_png(&rgb, args.width, args.height, &text)?;
    let numbered = |p: &Path| match index {
        Some(k) => crate::render::numbered_path(p, k),
        None => p.to_path_buf(),
    };
    let out = numbered(&args.out);
    if let Some(tif) = &args.out_radiance {
        let bytes = crate::render::encode_f32_tiff(
            &crate::render::radiance_image(&samples),
            args.width,
            args.height,
        )?;
        crate::output::write_bytes_atomic(&numbered(tif), &bytes)?;
    }
    crate::output::write_bytes_atomic(&out, &png)?;
    Ok((out, sun_el_deg))
}

/// Renders `frames` (epoch, camera pose) with the image, BRDF, exposure, backend, terrain,
/// kernel and output options of `args` (its camera and epoch options are not used): one
/// frame to `--out`, or numbered frames `<stem>_0000.png`, ... Every camera is checked before
/// any file is written.
pub fn render_frames(
    args: &crate::cli::RenderArgs,
    frames: &[(Epoch, crate::render::path::CameraPose)],
) -> anyhow::Result<()> {
    use crate::cli::BrdfArg;
    use crate::render::{Brdf, HapkeParams, Lights};
    let t0 = std::time::Instant::now();
    crate::render::check_size(args.width, args.height)?;
    if frames.is_empty() {
        anyhow::bail!("no frames to render");
    }
    if let Some(e) = args.exposure
        && !(e > 0.0 && e.is_finite())
    {
        anyhow::bail!("--exposure {e} must be a finite number > 0");
    }
    let brdf = match (args.brdf, args.albedo) {
        (BrdfArg::Hapke, None) => Brdf::Hapke(HapkeParams::MOON_643NM),
        (BrdfArg::Hapke, Some(_)) => {
            anyhow::bail!("--albedo applies to --brdf lambert only")
        }
        (BrdfArg::Lambert, a) => {
            let albedo = a.unwrap_or(crate::render::DEFAULT_ALBEDO);
            if !(0.0..=1.0).contains(&albedo) {
                anyhow::bail!("--albedo {albedo} must be in [0, 1]");
            }
            Brdf::Lambert { albedo }
        }
    };
    let abcorr = AbCorr::parse(&args.abcorr)?;
    let (stack, _) = load_terrain(&args.terrain)?;
    let mut grid = crate::map::MapGrid::new(&stack)?;
    grid.warn_if_clipped();
    // A frame may look at any terrain of the grid, far field included: shade all of it.
    grid.hf.window = None;
    let hf = &grid.hf;
    let placed = frames
        .iter()
        .map(|(_, pose)| place_camera(pose, &stack, hf))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let epochs: Vec<Epoch> = frames.iter().map(|(e, _)| *e).collect();
    let kernels = load_kernels(&args.kernels)?;
    let lights_all = crate::map::epoch_lights(&grid, &kernels, &epochs, abcorr)?;
    // Resolved once: `auto` warns once and the GPU device + pipelines are built once.
    let backend = crate::gpu::resolve_backend(args.backend)
        .with_context(|| format!("resolving --backend {}", args.backend.as_str()))?;
    let fractions = match &backend {
        crate::gpu::ResolvedBackend::Cpu => FractionSource::Cpu,
        #[cfg(feature = "gpu")]
        crate::gpu::ResolvedBackend::Gpu(ctx) => {
            FractionSource::Gpu(crate::map::GpuSceneFractions::upload(ctx, hf)?)
        }
        #[cfg(not(feature = "gpu"))]
        crate::gpu::ResolvedBackend::Gpu(ctx) => match **ctx {},
    };
    let job = FrameJob {
        args,
        hf,
        brdf,
        backend: &backend,
        fractions,
    };
    let many = frames.len() > 1;
    let progress = indicatif::ProgressBar::new(frames.len() as u64);
    if many {
        progress.set_style(
            indicatif::ProgressStyle::with_template(
                "rendering {bar:40} {pos}/{len} frames, eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
    } else {
        progress.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    for (k, ((epoch, l), placed)) in epochs.iter().zip(&lights_all).zip(&placed).enumerate() {
        let lights = Lights {
            sun: l.sun,
            sun_radius_rad: l.sun_radius_rad,
            earth: l.earth,
            earth_radius_rad: l.earth_radius_rad,
        };
        let (out, sun_el_deg) = render_one_frame(&job, placed, *epoch, lights, many.then_some(k))?;
        progress.inc(1);
        if !many {
            eprintln!(
                "penumbra: rendered {} x {} px at {} (Sun elevation {sun_el_deg:.3} deg) to {} in {:.2} s",
                args.width,
                args.height,
                format_utc(*epoch),
                out.display(),
                t0.elapsed().as_secs_f64()
            );
        }
    }
    progress.finish_and_clear();
    if many {
        eprintln!(
            "penumbra: rendered {} frames of {} x {} px to {} ... {} in {:.2} s",
            frames.len(),
            args.width,
            args.height,
            crate::render::numbered_path(&args.out, 0).display(),
            crate::render::numbered_path(&args.out, frames.len() - 1).display(),
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// The frame's samples on the backend of `--backend` (see docs/render.md).
fn render_samples(
    scene: &crate::render::Scene,
    camera: &crate::render::Camera,
    args: &crate::cli::RenderArgs,
    backend: &crate::gpu::ResolvedBackend,
) -> anyhow::Result<Vec<crate::render::Sample>> {
    Ok(match backend {
        crate::gpu::ResolvedBackend::Cpu => scene.render(camera, args.width, args.height)?,
        #[cfg(feature = "gpu")]
        crate::gpu::ResolvedBackend::Gpu(ctx) => {
            use crate::gpu::render::{GpuRenderScene, RenderGpuOptions, render_gpu};
            let gpu_scene = GpuRenderScene::upload(ctx, scene)?;
            render_gpu(
                ctx,
                &gpu_scene,
                camera,
                args.width,
                args.height,
                RenderGpuOptions::default(),
            )?
        }
        #[cfg(not(feature = "gpu"))]
        crate::gpu::ResolvedBackend::Gpu(ctx) => match **ctx {},
    })
}

/// `penumbra horizon-map build|info`.
fn run_horizon_map(command: crate::cli::HorizonMapCommand) -> anyhow::Result<()> {
    use crate::shadow::fourier::HorizonMap;
    match command {
        crate::cli::HorizonMapCommand::Build(args) => {
            let (stack, _) = load_terrain(&args.terrain)?;
            let grid = crate::map::MapGrid::new(&stack)?;
            let hf = &grid.hf;
            let params = crate::shadow::fourier::HorizonMapParams {
                observer_height_m: args.observer_height_m,
                n_azimuths: args.azimuths,
                max_distance_cells: args.max_distance_cells.unwrap_or(hf.rows + hf.cols),
                n_coeffs: crate::shadow::fourier::DEFAULT_COEFFS,
            };
            params.check()?;
            // Resolved after the input checks: bad input is one error line, with no warning.
            let backend = crate::gpu::resolve_backend(args.backend)
                .with_context(|| format!("resolving --backend {}", args.backend.as_str()))?;
            let t0 = std::time::Instant::now();
            let map = match &backend {
                crate::gpu::ResolvedBackend::Cpu => HorizonMap::build_with(
                    hf,
                    params.observer_height_m,
                    params.n_azimuths,
                    params.max_distance_cells,
                    params.n_coeffs,
                )?,
                #[cfg(feature = "gpu")]
                crate::gpu::ResolvedBackend::Gpu(ctx) => {
                    crate::gpu::fourier::build_horizon_map_gpu(ctx, hf, &params)?
                }
                #[cfg(not(feature = "gpu"))]
                crate::gpu::ResolvedBackend::Gpu(ctx) => match **ctx {},
            };
            map.write_tiff(&args.out)?;
            eprintln!(
                "penumbra: horizon map {} x {} ({} azimuths, {} coefficients) on {} in {:.1} s -> {}",
                hf.rows,
                hf.cols,
                args.azimuths,
                map.meta.n_coeffs,
                backend.describe(),
                t0.elapsed().as_secs_f64(),
                args.out.display()
            );
            Ok(())
        }
        crate::cli::HorizonMapCommand::Info { file } => {
            let map = HorizonMap::read_tiff(&file)?;
            let m = &map.meta;
            println!("file: {}", file.display());
            println!("grid: {} rows x {} cols at {} m", m.rows, m.cols, m.px_m);
            println!(
                "model origin: lat {:.6} deg, lon {:.6} deg; x_left {} m, y_top {} m",
                m.centre_lat_deg, m.centre_lon_deg, m.x_left_m, m.y_top_m
            );
            println!(
                "observer height: {} m; azimuths: {}; max distance: {} cells",
                m.observer_height_m, m.n_azimuths, m.max_distance_cells
            );
            println!("coefficients: {} complex (f16)", m.n_coeffs);
            let amps: Vec<String> = map
                .mean_amplitudes_rad()
                .iter()
                .map(|a| format!("{:.4}", a.to_degrees()))
                .collect();
            println!("mean |X_k| (deg): {}", amps.join(" "));
            Ok(())
        }
    }
}

//! `penumbra run`: a scenario's series, map and render stages, and its `run.json`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;

use super::{MapSpec, PathSpec, Scenario, TerrainSpec, ViewSpec, parse_map_backend};
use crate::compute::range::{HorizonsFrom, RangeHooks, RangeInputs};
use crate::ephem::{self, Site};
use crate::output::checkpoint::Checkpoint;

/// What `penumbra run` runs: a scenario file and the overrides of the command line.
#[derive(Debug, Clone)]
pub struct RunRequest {
    /// The scenario file (TOML).
    pub scenario: PathBuf,
    /// Overrides the scenario's output folder.
    pub out_dir: Option<PathBuf>,
    /// Overrides the scenario's kernel folder.
    pub kernels: Option<PathBuf>,
    /// Carries on an unfinished run in the output folder (its finished parts are kept).
    pub resume: bool,
}

/// Runs a scenario file (`penumbra run`).
pub fn run_file(args: &RunRequest) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let path = &args.scenario;
    let scenario = Scenario::load(path)?;
    let base = Scenario::base_dir(path);
    let out_dir = args
        .out_dir
        .clone()
        .or_else(|| scenario.output_dir.clone())
        .unwrap_or_else(|| PathBuf::from("out").join(&scenario.name));

    let kernel_dir = match (&args.kernels, &scenario.kernels) {
        (Some(k), _) => k.clone(),
        (None, Some(k)) => base.join(k),
        (None, None) => ephem::kernels::default_kernel_dir(),
    };
    let range = scenario.epochs()?;
    let epochs = range.epochs();
    let kernels = ephem::Kernels::load(&kernel_dir).context("loading SPICE kernels")?;
    crate::products::detail_kernels(&kernels);
    // Fail on coverage before loading terrain or writing anything.
    ephem::moon_geometry_table(&kernels, &[epochs[0], *epochs.last().unwrap_or(&epochs[0])])?;

    let mut prov = crate::output::Provenance::new();
    prov.scenario_file = Some(path.display().to_string());
    prov.scenario = Some(serde_json::to_value(&scenario)?);
    prov.kernels = kernels.files.clone();
    prov.set_epochs(&epochs);
    // What ran where ("series: …; map: …; render: …"), for run.json's `backend`.
    let mut backends: Vec<String> = Vec::new();

    let _lock =
        crate::output::cleanup::RunLock::begin(&out_dir, "run.json").map_err(anyhow::Error::msg)?;
    let stack = match &scenario.terrain {
        None => None,
        Some(t) => Some(load_terrain(t, &base, &out_dir, &mut prov)?),
    };
    std::fs::create_dir_all(&out_dir)
        .with_context(|| format!("creating output folder {}", out_dir.display()))?;
    let fingerprint = run_fingerprint(&scenario, &prov, &base)?;
    let (mut cp, note) =
        Checkpoint::open(&out_dir, &fingerprint, args.resume).map_err(anyhow::Error::msg)?;
    if let Some(note) = note {
        crate::note!("{note}");
    }

    match (&stack, &scenario.series) {
        (Some(_), Some(config)) if cp.is_done("series") => {
            let (files, note) = cp.part("series").expect("done");
            prov.outputs.extend(files);
            prov.series_engine = Some(config.engine.name().into());
            backends.push(format!("series: {note}"));
            prov.series_backend = Some(note.to_string());
            prov.ground_stations = crate::products::series::link_record(config)?;
        }
        (None, _) | (_, None) if cp.is_done("ephem") => {
            prov.outputs.extend(cp.part("ephem").expect("done").0);
        }
        (Some(stack), Some(config)) => {
            let run = crate::products::series::run_series(
                &kernels,
                stack,
                &scenario.sites()?,
                &epochs,
                range.step_s(),
                &crate::products::series::SeriesConfig {
                    abcorr: scenario.abcorr,
                    ..config.clone()
                },
                &out_dir,
            )?;
            let mut run = run;
            if let Some(w) = &scenario.windows {
                // Landing windows of the series (part of its checkpoint: a resumed run keeps them).
                let profile = w.profile().context("[windows]")?;
                let windows = crate::products::windows::run_windows(
                    &run.outcomes,
                    epochs[0],
                    range.step_s(),
                    &profile,
                );
                let sites: Vec<String> = run
                    .outcomes
                    .iter()
                    .map(|o| o.site.name().to_string())
                    .collect();
                let span = crate::products::windows::SeriesSpan {
                    start: epochs[0],
                    step_s: range.step_s(),
                    samples: epochs.len(),
                    sites: &sites,
                };
                run.files.extend(crate::products::windows::write_files(
                    &out_dir,
                    &windows,
                    &profile,
                    span,
                    config.plots,
                )?);
            }
            cp.mark_done("series", &run.files, &run.backend)
                .map_err(anyhow::Error::msg)?;
            prov.outputs.extend(run.files);
            prov.series_engine = Some(config.engine.name().into());
            backends.push(format!("series: {}", run.backend));
            prov.series_backend = Some(run.backend);
            prov.ground_stations = run.stations;
        }
        _ => {
            let sites: Vec<Site> = scenario
                .sites
                .iter()
                .map(|s| {
                    let ground_m = match (&stack, s.ground_height_m) {
                        (_, Some(g)) => g,
                        (Some(stack), None) => {
                            stack.height_at_lat_lon_m_checked(s.lat_deg, s.lon_deg)?.0
                        }
                        (None, None) => 0.0,
                    };
                    Site::new(s.lat_deg, s.lon_deg, ground_m + s.height_above_ground_m)
                        .with_context(|| format!("site '{}'", s.name))
                })
                .collect::<anyhow::Result<_>>()?;
            let series = ephem::sun_earth_series(&kernels, &sites, &epochs, scenario.abcorr)?;
            let first = prov.outputs.len();
            for (spec, rows) in scenario.sites.iter().zip(&series) {
                let name = format!("{}_ephem.csv", spec.name);
                crate::products::write_output(Some(&out_dir.join(&name)), |w| {
                    writeln!(w, "{}", crate::products::ephem::EPHEM_CSV_HEADER)?;
                    for (e, v) in epochs.iter().zip(rows) {
                        crate::products::ephem::write_ephem_row(w, *e, v)?;
                    }
                    Ok(())
                })?;
                prov.outputs.push(name);
            }
            cp.mark_done("ephem", &prov.outputs[first..], "")
                .map_err(anyhow::Error::msg)?;
        }
    }
    if let (Some(stack), Some(spec)) = (&stack, &scenario.map) {
        let (files, below, map_backend) = match cp.part("map") {
            Some((files, note)) if cp.is_done("map") => {
                let (below, backend, made): (
                    Option<crate::output::BelowSphereExits>,
                    String,
                    Option<crate::output::MadeWith>,
                ) = serde_json::from_str(note).context("the checkpoint of [map]")?;
                prov.map_made_with = made;
                (files, below, backend)
            }
            _ => {
                let (files, below, map_backend) = run_map_spec(
                    spec,
                    RangeInputs {
                        stack,
                        kernels: &kernels,
                        epochs: &scenario.map_epochs(spec)?,
                        abcorr: scenario.abcorr,
                    },
                    &base,
                    &out_dir.join("map"),
                    &mut cp,
                    MapContext {
                        prov: &mut prov,
                        marks: &scenario
                            .sites
                            .iter()
                            .map(|s| (s.name.clone(), s.lat_deg, s.lon_deg))
                            .collect::<Vec<_>>(),
                    },
                )?;
                let files: Vec<String> = files.into_iter().map(|f| format!("map/{f}")).collect();
                cp.mark_done(
                    "map",
                    &files,
                    &serde_json::to_string(&(below, &map_backend, &prov.map_made_with))?,
                )
                .map_err(anyhow::Error::msg)?;
                (files, below, map_backend)
            }
        };
        prov.map_rays_blocked_beyond_dem = below;
        prov.outputs.extend(files);
        backends.push(format!("map: {map_backend}"));
    }
    if let Some(spec) = &scenario.render {
        if stack.is_none() {
            anyhow::bail!("scenario {}: [render] needs [terrain]", path.display());
        }
        let terrain = match &scenario.terrain {
            Some(TerrainSpec {
                synthetic: Some(_), ..
            }) => vec![out_dir.join("terrain_synthetic.tif")],
            Some(t) => t.layers.iter().map(|p| base.join(p)).collect(),
            None => Vec::new(),
        };
        let mut render_backends: Vec<String> = Vec::new();
        let render_dir = out_dir.join("render");
        std::fs::create_dir_all(&render_dir)
            .with_context(|| format!("creating {}", render_dir.display()))?;
        let paths: Vec<(ViewSpec, Option<&PathSpec>)> = spec
            .views
            .iter()
            .map(|v| (v.clone(), None))
            .chain(spec.paths.iter().map(|p| (p.as_view(), Some(p))))
            .collect();
        for (i, (view, path_spec)) in paths.iter().enumerate() {
            let key = format!("render {i}");
            if let Some((files, backend)) = cp.part(&key).filter(|_| cp.is_done(&key)) {
                if !render_backends.iter().any(|b| b == backend) {
                    render_backends.push(backend.to_string());
                }
                prov.outputs.extend(files);
                continue;
            }
            let what = if path_spec.is_some() {
                "[[render.paths]]"
            } else {
                "[[render.views]]"
            };
            let options = view.render_options(
                crate::products::TerrainSource::Dems(terrain.clone()),
                crate::products::KernelSource {
                    dir: Some(kernel_dir.clone()),
                },
                scenario.abcorr,
                &render_dir,
            );
            let run = match path_spec {
                None => view.epochs().and_then(|epochs| {
                    crate::products::render::camera_frames(&view.camera(), &epochs)
                }),
                Some(p) => p.frames(),
            }
            .and_then(|frames| {
                crate::products::render::render_frames_kept(
                    &options,
                    &frames,
                    &mut Frames {
                        cp: &mut cp,
                        out_dir: &out_dir,
                        view: i,
                    },
                )
            })
            .with_context(|| format!("{what} '{}'", view.out))?;
            let files: Vec<String> = run.files.iter().map(|f| relative(f, &out_dir)).collect();
            cp.mark_done(&key, &files, &run.backend)
                .map_err(anyhow::Error::msg)?;
            if !render_backends.contains(&run.backend) {
                render_backends.push(run.backend);
            }
            prov.outputs.extend(files);
        }
        if !render_backends.is_empty() {
            backends.push(format!("render: {}", render_backends.join(", ")));
        }
    }
    if !backends.is_empty() {
        prov.backend = backends.join("; ");
    }
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&out_dir.join("run.json"))?;
    let kept = cp.resumed_parts();
    cp.finish();
    if kept > 0 {
        crate::note!("penumbra: resumed: {kept} finished part(s) of the earlier run kept");
    }
    crate::note!(
        "penumbra: {} file(s) and run.json written to {} ({} sites, {} epochs, {:.1} s)",
        prov.outputs.len(),
        out_dir.display(),
        scenario.sites.len(),
        prov.epoch_count,
        prov.wall_time_s
    );
    Ok(())
}

/// A path relative to the run folder, as run.json and the checkpoints name it.
fn relative(f: &Path, out_dir: &Path) -> String {
    f.strip_prefix(out_dir).unwrap_or(f).display().to_string()
}

/// The fingerprint of everything that decides a run's outputs: penumbra's build, the scenario as
/// parsed, the kernels' and DEMs' sha256 and a `[map]` horizons file's size and modification time
/// (not hashed: it can be gigabytes).
fn run_fingerprint(
    scenario: &Scenario,
    prov: &crate::output::Provenance,
    base: &Path,
) -> anyhow::Result<String> {
    let horizons = match scenario.map.as_ref().and_then(|m| m.horizons_file.as_ref()) {
        Some(p) => crate::output::checkpoint::file_stamp(&base.join(p))
            .with_context(|| format!("[map] horizons_file {}", p.display()))?,
        None => String::new(),
    };
    Ok(crate::output::checkpoint::fingerprint(&[
        prov.penumbra_version.as_bytes(),
        prov.git_commit.as_bytes(),
        serde_json::to_string(scenario)?.as_bytes(),
        serde_json::to_string(&prov.kernels)?.as_bytes(),
        serde_json::to_string(&prov.dem_files)?.as_bytes(),
        serde_json::to_string(&prov.dem_layers)?.as_bytes(),
        horizons.as_bytes(),
    ]))
}

/// A render sequence's finished frames, kept as checkpoints.
struct Frames<'a> {
    cp: &'a mut Checkpoint,
    out_dir: &'a Path,
    view: usize,
}

impl crate::products::render::FrameStore for Frames<'_> {
    fn done(&mut self, k: usize) -> Option<Vec<PathBuf>> {
        let key = format!("render {} frame {k}", self.view);
        let (files, _) = self.cp.part(&key)?;
        self.cp
            .is_done(&key)
            .then(|| files.iter().map(|f| self.out_dir.join(f)).collect())
    }
    fn finished(&mut self, k: usize, files: &[PathBuf]) -> anyhow::Result<()> {
        let files: Vec<String> = files.iter().map(|f| relative(f, self.out_dir)).collect();
        self.cp
            .mark_done(&format!("render {} frame {k}", self.view), &files, "")
            .map_err(anyhow::Error::msg)
    }
}

/// Loads a scenario's terrain; the synthetic DEM is also written to the output folder.
fn load_terrain(
    spec: &TerrainSpec,
    base: &Path,
    out_dir: &Path,
    prov: &mut crate::output::Provenance,
) -> anyhow::Result<crate::terrain::TerrainStack> {
    if let Some(s) = spec.synthetic {
        let params = crate::terrain::synth::SynthParams {
            size_px: s.size_px,
            px_m: s.px_m,
            seed: s.seed,
        };
        let (stack, what) = if s.far_field {
            crate::products::synthetic_stack_with_far_field(&params)?
        } else {
            let (stack, what) = crate::products::synthetic_stack(&params)?;
            (stack, vec![what])
        };
        std::fs::create_dir_all(out_dir)
            .with_context(|| format!("creating output folder {}", out_dir.display()))?;
        // Both layers, so that the run can be repeated with `layers = [...]` or by a GIS.
        for (layer, file) in stack
            .layers
            .iter()
            .zip(["terrain_synthetic.tif", "terrain_synthetic_far.tif"])
        {
            crate::terrain::write_dem(
                &out_dir.join(file),
                layer,
                &[(
                    "software",
                    &format!("penumbra {}", env!("CARGO_PKG_VERSION")),
                )],
            )?;
            prov.outputs.push(file.into());
        }
        prov.dem_layers.extend(what);
        return Ok(stack);
    }
    let paths: Vec<PathBuf> = spec.layers.iter().map(|p| base.join(p)).collect();
    prov.dem_layers = paths.iter().map(|p| p.display().to_string()).collect();
    let stack = crate::products::load_stack(&paths)?;
    crate::products::detail_terrain(&stack);
    prov.dem_files = paths
        .iter()
        .map(|p| crate::output::InputFile::of(p))
        .collect::<Result<_, _>>()?;
    Ok(stack)
}

/// What a scenario's `[map]` records and draws besides its statistics: the run's provenance
/// (it adds how the maps were made) and the sites to mark on the previews.
struct MapContext<'a> {
    prov: &'a mut crate::output::Provenance,
    marks: &'a [(String, f64, f64)],
}

/// Runs a scenario's `[map]`: the statistics over the scenario's span at the map's step, written
/// into `dir`.
fn run_map_spec(
    spec: &MapSpec,
    inputs: RangeInputs<'_>,
    base: &Path,
    dir: &Path,
    store: &mut dyn crate::horizon::statistics::BlockStore,
    MapContext { prov, marks }: MapContext<'_>,
) -> anyhow::Result<(Vec<String>, Option<crate::output::BelowSphereExits>, String)> {
    use crate::products::map as pm;
    let settings = pm::MapSettings {
        observer_height: crate::model::ObserverHeight::new(spec.observer_height_m)
            .context("[map] observer_height_m")?,
        engine: crate::model::MapEngineKind::parse_choice(&spec.engine)
            .map_err(anyhow::Error::msg)
            .context("[map]")?,
        backend: parse_map_backend(&spec.backend)
            .with_context(|| format!("[map] backend '{}'", spec.backend))?,
        gpu_tile_cells: None,
        observers: None,
        horizons: match &spec.horizons_file {
            Some(p) => HorizonsFrom::File(base.join(p)),
            None => HorizonsFrom::Sweep {
                azimuths: spec.azimuths,
                max_step: spec.max_step,
            },
        },
        limb: spec.limb_darkening,
        stations: spec.stations.clone(),
        station_mask_deg: spec.station_mask_deg,
        power: spec.power.clone(),
    };
    let hooks = RangeHooks {
        report: &mut |_, _| true,
        store,
    };
    let result = pm::statistics(&settings, inputs, hooks).context("[map]")?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let epochs = inputs.epochs;
    let span = format!(
        "{} .. {}, {} epochs every {}",
        ephem::time::format_iso(epochs.start()),
        ephem::time::format_iso(epochs.epochs()[epochs.len() - 1]),
        epochs.len(),
        spec.step
    );
    let stats = &result.stats;
    let made = crate::output::MadeWith::new(
        prov,
        settings.observer_height.m(),
        result.engine.name(),
        &stats.limb_law(),
        &span,
    );
    let files = pm::write_range(
        &inputs.stack.layers[0],
        result.model.as_ref(),
        stats,
        dir,
        &made,
        marks,
    )?;
    prov.map_made_with = Some(made);
    if let Some(b) = stats.below_sphere {
        b.warn();
    }
    Ok((files, stats.below_sphere, result.note))
}

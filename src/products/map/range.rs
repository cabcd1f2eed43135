//! Statistics over an epoch range ([`statistics`]; the command line's `--start/--stop/--step`
//! maps, a scenario's `[map]`, Python's `map_statistics`), and the command line's range job with
//! its resumable checkpoint and its shards.

use std::path::PathBuf;

use super::{MapEngineKind, MapRequest, MapSettings, MapTask, RangeFiles, shard, span_text};
use crate::compute::Backend;
use crate::compute::range::{HorizonsFrom, RangeHooks, RangeInputs, RangeResult};
use crate::model::EpochRange;
use crate::products::{DemFiles, Inputs, KernelSource, TerrainSource};

/// The command line's range job: inputs, statistics (or a shard's partial), files, `run.json`.
pub(super) fn range_job(
    req: &MapRequest,
    epochs: &EpochRange,
    files: &RangeFiles,
) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    check_range(&req.settings, files)?;
    let keys = JobKeys::of(req)?;
    let epoch_list = epochs.epochs();
    let (terrain, kernels) = (&req.terrain, &req.kernels);
    let inputs = Inputs::load(terrain, kernels, &epoch_list, DemFiles::Record)?;
    let kernels = inputs.kernels.as_ref().expect("a range has epochs");
    let mut prov = inputs.provenance.clone();
    prov.dem_files.extend(keys.horizons_file.clone());
    let (resume_key, merge_key) = keys.fingerprints(&prov)?;
    let out_dir = &files.out_dir;
    // A shard's manifest, like a run's run.json, goes first and comes back last.
    let manifest = match files.shard {
        Some(_) => shard::MANIFEST,
        None => "run.json",
    };
    let _lock =
        crate::output::cleanup::RunLock::begin(out_dir, manifest).map_err(anyhow::Error::msg)?;
    let (mut cp, note) =
        crate::output::checkpoint::Checkpoint::open(out_dir, &resume_key, files.resume)
            .map_err(anyhow::Error::msg)?;
    if let Some(note) = note {
        crate::note!("{note}");
    }
    let range = RangeInputs {
        stack: &inputs.stack,
        kernels,
        epochs,
        abcorr: req.abcorr,
    };
    let hooks = RangeHooks {
        report: &mut |_, _| true,
        store: &mut cp,
    };
    match files.shard {
        Some(s) => shard::run(
            shard::ShardJob {
                shard: s,
                job: merge_key,
                settings: &req.settings,
                inputs: range,
                out_dir,
                prov: &mut prov,
                t0,
            },
            hooks,
        )?,
        None => {
            let result = crate::compute::range::range_statistics(range, &req.settings, hooks)?;
            let made = crate::output::MadeWith::new(
                &prov,
                req.settings.observer_height.m(),
                result.engine.name(),
                &result.stats.limb_law(),
                &span_text(&epoch_list),
            );
            prov.outputs = crate::model::write_range(
                &inputs.stack.layers[0],
                result.model.as_ref(),
                &result.stats,
                out_dir,
                &made,
                &[],
            )?;
            prov.map_made_with = Some(made);
            prov.backend = result.note;
            if let Some(stations) = req
                .settings
                .stations
                .resolve(req.settings.station_mask_deg)?
            {
                prov.ground_stations = Some(crate::comms::stations_record(
                    &req.settings.stations,
                    &stations,
                ));
            }
            prov.map_rays_blocked_beyond_dem = result.stats.below_sphere;
            if let Some(b) = result.stats.below_sphere {
                b.warn();
            }
            prov.wall_time_s = t0.elapsed().as_secs_f64();
            prov.write(&out_dir.join("run.json"))?;
            crate::note!(
                "penumbra: map statistics over {} epochs -> {} ({:.1} s)",
                epochs.len(),
                out_dir.display(),
                prov.wall_time_s
            );
        }
    }
    cp.finish();
    Ok(())
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

/// The statistics of an epoch range over `inputs` (the command line's `--start/--stop/--step`
/// maps, a scenario's `[map]`, Python's `map_statistics`), with the engine and on the backend
/// that `settings` ask for.
pub fn statistics(
    settings: &MapSettings,
    inputs: RangeInputs<'_>,
    hooks: RangeHooks<'_>,
) -> anyhow::Result<RangeResult> {
    crate::compute::range::range_statistics(inputs, settings, hooks)
}

/// What identifies a range job, read off its request before any input is loaded: the request as
/// `--resume` compares it (all but `--resume`) and as `penumbra merge` compares shards (all but
/// the shard, the folders, the paths of the inputs, the engine and the backend, which are the
/// CPU horizons engine for every shard), and a horizons file's provenance, size and time.
struct JobKeys {
    resume_request: String,
    merge_request: String,
    horizons_file: Option<crate::output::InputFile>,
    horizons_stamp: String,
}

impl JobKeys {
    fn of(req: &MapRequest) -> anyhow::Result<Self> {
        let mut request = req.clone();
        if let MapTask::Range { files, .. } = &mut request.task {
            files.resume = false;
        }
        let resume_request = format!("{request:?}");
        if let TerrainSource::Dems(paths) = &mut request.terrain {
            paths.clear();
        }
        request.kernels = KernelSource::default();
        request.settings.engine = Some(MapEngineKind::Horizons);
        request.settings.backend = Backend::Cpu;
        if let MapTask::Range { files, .. } = &mut request.task {
            *files = RangeFiles {
                out_dir: PathBuf::new(),
                resume: false,
                shard: None,
            };
        }
        let (horizons_file, horizons_stamp) = match &mut request.settings.horizons {
            HorizonsFrom::File(p) => {
                let used = req
                    .settings
                    .engine
                    .is_none_or(|e| e == MapEngineKind::Horizons);
                let file = used.then(|| crate::output::InputFile::of(p)).transpose()?;
                let stamp = crate::output::checkpoint::file_stamp(p)
                    .map_err(|e| anyhow::anyhow!("--horizons {}: {e}", p.display()))?;
                *p = PathBuf::new();
                (file, stamp)
            }
            HorizonsFrom::Sweep { .. } => (None, String::new()),
        };
        Ok(JobKeys {
            resume_request,
            merge_request: format!("{request:?}"),
            horizons_file,
            horizons_stamp,
        })
    }

    /// The fingerprints of the job with the inputs of `prov`: the one `--resume` checks
    /// (penumbra's build, the request, the kernels' and DEMs' sha256 and a horizons file's size
    /// and time), and the one `penumbra merge` checks (penumbra's build, the request, and the
    /// inputs by content, the kernels' and DEMs' sha256 but not their paths, so that shards run
    /// from other folders or through the Python module merge).
    fn fingerprints(&self, prov: &crate::output::Provenance) -> anyhow::Result<(String, String)> {
        use crate::output::checkpoint::fingerprint;
        let kernels: Vec<(&str, &str)> = prov
            .kernels
            .iter()
            .map(|k| (k.kind, k.sha256.as_str()))
            .collect();
        let inputs: Vec<&str> = prov.dem_files.iter().map(|f| f.sha256.as_str()).collect();
        let build = [prov.penumbra_version.as_bytes(), prov.git_commit.as_bytes()];
        let resume = fingerprint(&[
            build[0],
            build[1],
            self.resume_request.as_bytes(),
            serde_json::to_string(&prov.kernels)?.as_bytes(),
            serde_json::to_string(&prov.dem_files)?.as_bytes(),
            self.horizons_stamp.as_bytes(),
        ]);
        let merge = fingerprint(&[
            build[0],
            build[1],
            self.merge_request.as_bytes(),
            format!("{kernels:?}").as_bytes(),
            format!("{inputs:?}").as_bytes(),
        ]);
        Ok((resume, merge))
    }
}

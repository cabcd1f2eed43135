//! Sharded maps: `penumbra map … --shard I/N` computes the statistics of one block of rows of the
//! finest layer and writes a partial result; `penumbra merge` combines the partials into the
//! files a single-machine run writes, byte for byte.
//!
//! **Why rows.** A pixel's statistics depend on its own horizon and the epochs only, so a block
//! of rows is a complete unit of work whatever the epochs: the statistics stage, which dominates
//! every run longer than a few months, divides exactly by the number of shards, and a shard holds
//! the horizons of its own rows only (memory ∝ rows / N). The sweep that precedes it skips the
//! lines that miss the shard's rows and stops each line's walk past them. A split by azimuth
//! bins would divide the sweep exactly but leave every shard a slice of every pixel's horizon: a
//! merge would have to gather the whole horizon cube (cells × azimuths × 2 bytes: 1.3 TB for the
//! 20 m south-pole grid at 720 azimuths) before any statistics could start. Measured costs are in
//! docs/SCALING.md.
//!
//! **A partial** is a folder holding `shard.json` (the manifest: the job's fingerprint, the shard
//! id, the rows, the finest layer's grid and projection, the epochs, the inputs' sha256 and the
//! data file's sha256) and `shard.pnbstat` (the raw per-pixel sums and counts of its rows, then
//! the DEM's nodata flags of those rows). The manifest is written last: a folder without one is
//! an unfinished shard, and `merge` refuses it.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use crate::horizon::statistics::HorizonStatistics;
use crate::terrain::{Dem, GridGeometry, Projection};

/// The manifest of a partial.
pub const MANIFEST: &str = "shard.json";
/// The data file of a partial.
pub const DATA_FILE: &str = "shard.pnbstat";
/// The manifest's `format`.
pub const FORMAT: &str = "penumbra map shard 1";
/// Most shards of one job.
pub const MAX_SHARDS: usize = 100_000;

/// Shard `index` of `count` (0-based): rows `index · rows / count .. (index + 1) · rows / count`
/// of the finest layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// Which shard, `0 ..= count - 1`.
    pub index: usize,
    /// How many shards the job has, `1 ..= MAX_SHARDS`.
    pub count: usize,
}

impl Shard {
    /// Parses `I/N` (0 ≤ I < N ≤ [`MAX_SHARDS`]).
    pub fn parse(text: &str) -> Result<Self, String> {
        let bad = || {
            format!(
                "--shard '{text}': expected I/N with 0 <= I < N <= {MAX_SHARDS} (shard I of N, \
                 counted from 0; a Slurm array task gives I = $SLURM_ARRAY_TASK_ID)"
            )
        };
        let (i, n) = text.trim().split_once('/').ok_or_else(bad)?;
        let index: usize = i.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// The rows of a grid of `rows` rows this shard computes; an error when there are more
    /// shards than rows.
    pub fn rows(&self, rows: usize) -> Result<Range<usize>, String> {
        if self.count > rows {
            return Err(format!(
                "{} shards for a finest layer of {rows} rows: give at most one shard per row",
                self.count
            ));
        }
        Ok(self.index * rows / self.count..(self.index + 1) * rows / self.count)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The manifest of a partial (`shard.json`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ShardManifest {
    /// [`FORMAT`].
    pub format: String,
    /// penumbra's version that wrote the partial.
    pub penumbra_version: String,
    /// The git commit of that build.
    pub git_commit: String,
    /// The job's fingerprint: penumbra's build, every parameter but the shard, the kernels' and
    /// DEMs' sha256. Partials merge only with partials of the same job.
    pub job: String,
    /// This shard's index (from 0).
    pub shard: usize,
    /// The job's number of shards.
    pub shards: usize,
    /// The rows of the finest layer held, `[first, end)`.
    pub rows: [usize; 2],
    /// The finest layer's grid.
    pub grid: GridGeometry,
    /// The finest layer's projection.
    pub projection: Projection,
    /// Number of epochs.
    pub epoch_count: usize,
    /// First epoch, UTC.
    pub epoch_start_utc: String,
    /// Last epoch, UTC.
    pub epoch_stop_utc: String,
    /// Hours between epochs.
    pub step_h: f64,
    /// The span line of the map previews.
    pub span: String,
    /// The Sun's limb darkening law.
    pub limb_law: String,
    /// How the maps are made (absent in partials of older versions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub made_with: Option<crate::output::MadeWith>,
    /// The ground stations of the direct-to-Earth maps, described (absent without).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link: Option<String>,
    /// The panel and load of the power maps, described (absent without).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub power: Option<String>,
    /// What ran (the run.json `backend`).
    pub backend: String,
    /// The kernel files with sizes and sha256 (as in run.json).
    pub kernels: serde_json::Value,
    /// The DEM layers (paths or the synthetic DEM's description).
    pub dem_layers: Vec<String>,
    /// The DEM (and horizon) files with sizes and sha256.
    pub dem_files: serde_json::Value,
    /// The shard's command line.
    pub command_line: Vec<String>,
    /// The data file, relative to the partial's folder.
    pub data_file: String,
    /// Its size, bytes.
    pub data_bytes: u64,
    /// Its sha256.
    pub data_sha256: String,
    /// The shard's wall time, seconds.
    pub wall_time_s: f64,
    /// Memory the shard's arrays needed (terrain layers, horizons of its rows, statistics),
    /// bytes.
    pub arrays_bytes: u64,
    /// The process's peak resident memory (Linux `VmHWM`), bytes, where known.
    pub peak_rss_bytes: Option<u64>,
}

/// What a shard's run knows besides its statistics.
pub struct ShardRun<'a> {
    /// The shard.
    pub shard: Shard,
    /// The job's fingerprint.
    pub job: String,
    /// The finest layer.
    pub fine: &'a Dem,
    /// The rows computed.
    pub rows: Range<usize>,
    /// The epochs' provenance (`epoch_*` of run.json) and step.
    pub provenance: &'a crate::output::Provenance,
    /// Hours between epochs.
    pub step_h: f64,
    /// The preview's span line.
    pub span: String,
    /// The limb darkening law's name.
    pub limb_law: String,
    /// Bytes of the arrays held.
    pub arrays_bytes: u64,
    /// The observer's height above the ground, metres.
    pub observer_height_m: f64,
}

/// One shard of a job and what its run needs.
pub struct ShardJob<'a> {
    /// The shard.
    pub shard: Shard,
    /// The job's fingerprint (what `merge` checks).
    pub job: String,
    /// How the map is computed.
    pub settings: &'a super::MapSettings,
    /// The terrain, ephemeris and epochs.
    pub inputs: crate::compute::range::RangeInputs<'a>,
    /// The partial's folder.
    pub out_dir: &'a Path,
    /// The run's provenance so far (inputs and epochs); the shard adds what ran.
    pub prov: &'a mut crate::output::Provenance,
    /// When the run started.
    pub t0: std::time::Instant,
}

/// Runs one shard: the horizons engine's statistics of the shard's rows (on the CPU), then the
/// partial (data file, then manifest).
pub fn run(job: ShardJob<'_>, hooks: crate::compute::range::RangeHooks<'_>) -> anyhow::Result<()> {
    let ShardJob {
        shard,
        job,
        settings,
        inputs,
        out_dir,
        prov,
        t0,
    } = job;
    let fine = &inputs.stack.layers[0];
    let rows = shard.rows(fine.grid.rows).map_err(anyhow::Error::msg)?;
    let arrays_bytes =
        crate::compute::range::arrays_bytes(inputs.stack, rows.len(), &settings.horizons);
    crate::compute::range::check_budget(
        &format!(
            "shard {shard} (rows {}..{}: terrain, horizons, statistics)",
            rows.start, rows.end
        ),
        arrays_bytes,
        "split the map into more shards or sweep the horizons once into a file (--horizons)",
    )?;
    let (stats, note) = crate::compute::range::horizon_statistics_rows(
        &crate::compute::ResolvedBackend::Cpu,
        inputs,
        settings,
        hooks,
        rows.clone(),
    )?;
    prov.backend = note;
    let run = ShardRun {
        shard,
        job,
        fine,
        rows: rows.clone(),
        provenance: prov,
        step_h: inputs.epochs.step_s() / 3600.0,
        span: super::span_text(&inputs.epochs.epochs()),
        limb_law: settings.limb.name().to_string(),
        arrays_bytes,
        observer_height_m: settings.observer_height.m(),
    };
    let manifest = write_partial(out_dir, &run, &stats, t0.elapsed().as_secs_f64())?;
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
    Ok(())
}

/// Writes the partial of `run` with `stats` (its rows' raw statistics) into `out_dir`: the data
/// file, then the manifest. Returns the manifest.
pub fn write_partial(
    out_dir: &Path,
    run: &ShardRun<'_>,
    stats: &HorizonStatistics,
    wall_time_s: f64,
) -> anyhow::Result<ShardManifest> {
    let g = run.fine.grid;
    let px = run.rows.start * g.cols..run.rows.end * g.cols;
    let n_px = px.len();
    let below = (stats.below_sphere.cells, stats.below_sphere.cell_epochs);
    let mut bytes = stats.block_bytes(0, n_px, below);
    bytes.extend(run.fine.heights_m[px].iter().map(|z| u8::from(z.is_nan())));
    let data = out_dir.join(DATA_FILE);
    crate::output::write_bytes_atomic(&data, &bytes)?;
    let digest = sha256_hex(&bytes);
    let p = run.provenance;
    let manifest = ShardManifest {
        format: FORMAT.into(),
        penumbra_version: p.penumbra_version.into(),
        git_commit: p.git_commit.into(),
        job: run.job.clone(),
        shard: run.shard.index,
        shards: run.shard.count,
        rows: [run.rows.start, run.rows.end],
        grid: g,
        projection: run.fine.projection,
        epoch_count: p.epoch_count,
        epoch_start_utc: p.epoch_start_utc.clone(),
        epoch_stop_utc: p.epoch_stop_utc.clone(),
        step_h: run.step_h,
        span: run.span.clone(),
        limb_law: run.limb_law.clone(),
        made_with: Some(crate::output::MadeWith::new(
            p,
            run.observer_height_m,
            "horizons",
            &run.limb_law,
            &run.span,
        )),
        link: stats.link.clone(),
        power: stats.power.clone(),
        backend: p.backend.clone(),
        kernels: serde_json::to_value(&p.kernels)?,
        dem_layers: p.dem_layers.clone(),
        dem_files: serde_json::to_value(&p.dem_files)?,
        command_line: p.command_line.clone(),
        data_file: DATA_FILE.into(),
        data_bytes: bytes.len() as u64,
        data_sha256: digest,
        wall_time_s,
        arrays_bytes: run.arrays_bytes,
        peak_rss_bytes: peak_rss_bytes(),
    };
    let mut json = serde_json::to_vec_pretty(&manifest)?;
    json.push(b'\n');
    crate::output::write_bytes_atomic(&out_dir.join(MANIFEST), &json)?;
    Ok(manifest)
}

/// Lowercase hex sha256 of `bytes` (what `sha256sum` prints for the file).
fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest as _;
    format!("{:x}", sha2::Sha256::digest(bytes))
}

/// The process's peak resident set (Linux `/proc/self/status` `VmHWM`), bytes.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// A partial read back and checked.
struct Partial {
    dir: PathBuf,
    manifest: ShardManifest,
    data: Vec<u8>,
}

/// Largest manifest read, bytes.
const MAX_MANIFEST_BYTES: u64 = 16 << 20;

fn read_partial(dir: &Path) -> anyhow::Result<Partial> {
    let path = dir.join(MANIFEST);
    let meta = match std::fs::metadata(&path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let unfinished = dir.join(crate::output::checkpoint::CHECKPOINT_DIR).exists()
                || dir.join(crate::output::cleanup::LOCK_FILE).exists();
            if !dir.is_dir() {
                anyhow::bail!("{}: no such folder", dir.display());
            }
            anyhow::bail!(
                "{}: no {MANIFEST}: {} (merge refuses holes; re-run that shard{})",
                dir.display(),
                if unfinished {
                    "an unfinished shard (killed or still running)"
                } else {
                    "not the folder of a finished `penumbra map --shard` run"
                },
                if unfinished { " with --resume" } else { "" }
            );
        }
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    if !meta.is_file() || meta.len() > MAX_MANIFEST_BYTES {
        anyhow::bail!(
            "{}: not a shard manifest (not a regular file of at most 16 MiB)",
            path.display()
        );
    }
    let text = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    let manifest: ShardManifest = serde_json::from_slice(&text)
        .map_err(|e| anyhow::anyhow!("{}: not a shard manifest ({e})", path.display()))?;
    if manifest.format != FORMAT {
        anyhow::bail!(
            "{}: format '{}', this penumbra reads '{FORMAT}'",
            path.display(),
            manifest.format
        );
    }
    let data_path = dir.join(DATA_FILE);
    let len = std::fs::metadata(&data_path)
        .with_context(|| format!("shard {}: reading {}", dir.display(), data_path.display()))?
        .len();
    if len != manifest.data_bytes {
        anyhow::bail!(
            "shard {}: {DATA_FILE} has {len} bytes, its manifest says {} (a damaged or \
             unfinished copy: re-run that shard)",
            dir.display(),
            manifest.data_bytes
        );
    }
    let data =
        std::fs::read(&data_path).with_context(|| format!("reading {}", data_path.display()))?;
    if sha256_hex(&data) != manifest.data_sha256 {
        anyhow::bail!(
            "shard {}: {DATA_FILE} does not match the sha256 in its manifest (a damaged copy: \
             re-run that shard)",
            dir.display()
        );
    }
    Ok(Partial {
        dir: dir.to_path_buf(),
        manifest,
        data,
    })
}

/// What differs between two manifests of different jobs, in words.
fn job_difference(a: &ShardManifest, b: &ShardManifest) -> String {
    let mut what = Vec::new();
    if a.penumbra_version != b.penumbra_version || a.git_commit != b.git_commit {
        what.push("penumbra build");
    }
    if a.grid != b.grid || a.projection != b.projection {
        what.push("finest DEM layer's grid");
    }
    if a.dem_files != b.dem_files || a.dem_layers != b.dem_layers {
        what.push("DEM files");
    }
    if a.kernels != b.kernels {
        what.push("kernels");
    }
    if (a.epoch_count, &a.epoch_start_utc, &a.epoch_stop_utc)
        != (b.epoch_count, &b.epoch_start_utc, &b.epoch_stop_utc)
    {
        what.push("epochs");
    }
    if a.shards != b.shards {
        what.push("number of shards");
    }
    if what.is_empty() {
        what.push("parameters");
    }
    what.join(", ")
}

/// `penumbra merge`: combines the partials in `dirs` into the statistics maps of the whole job
/// in `out_dir` (the files of a single-machine `penumbra map` run, byte for byte, and its
/// run.json). Refuses partials of different jobs, repeated shards and missing ones.
pub fn merge(out_dir: &Path, dirs: &[PathBuf]) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    if dirs.is_empty() {
        anyhow::bail!("give the shards' folders to merge");
    }
    let mut parts = Vec::with_capacity(dirs.len());
    for dir in dirs {
        parts.push(read_partial(dir)?);
    }
    let first = &parts[0].manifest;
    for p in &parts[1..] {
        if p.manifest.job != first.job || p.manifest.shards != first.shards {
            anyhow::bail!(
                "shards {} and {} are of different jobs ({} differ): merge only the shards of \
                 one `penumbra map --shard I/N` command",
                parts[0].dir.display(),
                p.dir.display(),
                job_difference(first, &p.manifest)
            );
        }
    }
    let n = first.shards;
    let mut seen: Vec<Option<&Path>> = vec![None; n];
    for p in &parts {
        let m = &p.manifest;
        let expected = Shard {
            index: m.shard,
            count: n,
        }
        .rows(m.grid.rows)
        .ok();
        if m.shard >= n || expected != Some(m.rows[0]..m.rows[1]) {
            anyhow::bail!(
                "shard {}: shard {}/{} with rows {}..{} is inconsistent (a damaged manifest)",
                p.dir.display(),
                m.shard,
                n,
                m.rows[0],
                m.rows[1]
            );
        }
        if let Some(other) = seen[m.shard] {
            anyhow::bail!(
                "shard {}/{n} given twice: {} and {}",
                m.shard,
                other.display(),
                p.dir.display()
            );
        }
        seen[m.shard] = Some(&p.dir);
    }
    let missing: Vec<String> = seen
        .iter()
        .enumerate()
        .filter(|(_, s)| s.is_none())
        .map(|(i, _)| i.to_string())
        .collect();
    if !missing.is_empty() {
        anyhow::bail!(
            "missing shard(s) {} of {n} (merge refuses holes: run them, then merge again)",
            missing.join(", ")
        );
    }
    let g = first.grid;
    let n_px = g.rows * g.cols;
    let mut stats = HorizonStatistics::empty(n_px, first.epoch_count);
    let mut heights = vec![0.0_f32; n_px];
    for p in &parts {
        let m = &p.manifest;
        let first_px = m.rows[0] * g.cols;
        let block_px = (m.rows[1] - m.rows[0]) * g.cols;
        let (block, nodata) = p.data.split_at(p.data.len().saturating_sub(block_px));
        if nodata.len() != block_px || !stats.place_block_bytes_at(0, first_px, block_px, block) {
            anyhow::bail!(
                "shard {}: {DATA_FILE} does not hold the statistics of rows {}..{} over {} epochs",
                p.dir.display(),
                m.rows[0],
                m.rows[1],
                m.epoch_count
            );
        }
        for (h, &nd) in heights[first_px..first_px + block_px]
            .iter_mut()
            .zip(nodata)
        {
            if nd != 0 {
                *h = f32::NAN;
            }
        }
    }
    stats.below_sphere.cells_total = stats.nodata.iter().filter(|&&nd| !nd).count() as u64;
    stats.link = first.link.clone();
    stats.power = first.power.clone();
    let below = stats.below_sphere;
    // The finest layer as the writers see it: its grid, projection and nodata.
    let dem = Dem {
        grid: g,
        projection: first.projection,
        heights_m: heights,
        name: first.dem_layers.first().cloned().unwrap_or_default(),
    };
    let _lock =
        crate::output::cleanup::RunLock::begin(out_dir, "run.json").map_err(anyhow::Error::msg)?;
    let sweep = crate::model::RangeStats::from_horizons(stats, first.step_h, &first.limb_law);
    let made = first
        .made_with
        .clone()
        .unwrap_or_else(|| crate::output::MadeWith {
            engine: "horizons".into(),
            limb_darkening: first.limb_law.clone(),
            span_utc: first.span.clone(),
            layers: first.dem_layers.clone(),
            ..Default::default()
        });
    let files = super::write_range(&dem, None, &sweep, out_dir, &made, &[])?;
    let mut prov = crate::output::Provenance::new();
    prov.dem_layers = first.dem_layers.clone();
    prov.epoch_start_utc = first.epoch_start_utc.clone();
    prov.epoch_stop_utc = first.epoch_stop_utc.clone();
    prov.epoch_count = first.epoch_count;
    prov.backend = format!("{} (merged from {n} shards)", first.backend);
    prov.outputs = files;
    prov.map_rays_blocked_beyond_dem = Some(below);
    prov.map_made_with = Some(made);
    below.warn();
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    let mut record = serde_json::to_value(&prov)?;
    record["kernels"] = first.kernels.clone();
    if first.dem_files.as_array().is_some_and(|a| !a.is_empty()) {
        record["dem_files"] = first.dem_files.clone();
    }
    record["shards"] = serde_json::to_value(
        parts
            .iter()
            .map(|p| {
                serde_json::json!({
                    "shard": p.manifest.shard,
                    "folder": p.dir.display().to_string(),
                    "rows": p.manifest.rows,
                    "wall_time_s": p.manifest.wall_time_s,
                    "peak_rss_bytes": p.manifest.peak_rss_bytes,
                    "command_line": p.manifest.command_line,
                })
            })
            .collect::<Vec<_>>(),
    )?;
    let mut bytes = serde_json::to_vec_pretty(&record)?;
    bytes.push(b'\n');
    crate::output::write_bytes_atomic(&out_dir.join("run.json"), &bytes)?;
    crate::note!(
        "penumbra: merged {n} shards ({} x {} px, {} epochs) -> {} ({:.1} s)",
        g.rows,
        g.cols,
        first.epoch_count,
        out_dir.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_tile_the_rows() {
        assert_eq!(Shard::parse("3/4"), Ok(Shard { index: 3, count: 4 }));
        assert_eq!(Shard::parse(" 0 / 1 "), Ok(Shard { index: 0, count: 1 }));
        for bad in ["4/4", "1/0", "-1/3", "1", "a/b", "1/2/3", "", "0/100001"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        for rows in [1usize, 7, 100, 1537] {
            for count in [1usize, 3, 4, 7] {
                let r: Vec<Range<usize>> = (0..count)
                    .filter_map(|index| Shard { index, count }.rows(rows).ok())
                    .collect();
                if count > rows {
                    assert!(r.is_empty());
                    continue;
                }
                // Contiguous, covering, each at least one row and within one row of the others.
                assert_eq!(r[0].start, 0);
                assert_eq!(r.last().unwrap().end, rows);
                for w in r.windows(2) {
                    assert_eq!(w[0].end, w[1].start);
                }
                let (lo, hi) = r.iter().fold((usize::MAX, 0), |(lo, hi), x| {
                    (lo.min(x.len()), hi.max(x.len()))
                });
                assert!(
                    lo >= 1 && hi - lo <= 1,
                    "{rows} rows, {count} shards: {r:?}"
                );
            }
        }
    }
}

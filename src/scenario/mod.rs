//! Declarative scenarios (`scenarios/*.toml`): sites, epochs, kernels, outputs.
//!
//! A scenario is a TOML file; unknown keys are errors that name the key. Relative paths inside a
//! scenario (kernels, DEMs) are resolved against the scenario file's folder; the output folder is
//! resolved against the working directory. See `scenarios/south-pole-demo.toml` for an annotated
//! example.
//!
//! `penumbra run` writes into the output folder one CSV per site and `run.json` with the
//! provenance of the run (penumbra version, git commit, the scenario, kernels with sha256, epoch
//! range, backend, wall time). Every file is written atomically.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::ephem::AbCorr;

mod render;
pub mod run;

pub use render::{KeyframeSpec, PathSpec, RenderSpec, ViewSpec};
pub use run::{RunRequest, run_file};

/// Errors of scenario files.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("reading scenario {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The TOML is malformed or has unknown keys / wrong types.
    #[error("scenario {path}: {why}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message (names the offending key).
        why: String,
    },
    /// The scenario is well-formed but not meaningful.
    #[error("scenario {path}: {why}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
}

/// A scenario file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name of the scenario (used for the default output folder).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Output folder (default `out/<name>`), relative to the working directory.
    pub output_dir: Option<PathBuf>,
    /// Kernel folder, relative to the scenario file (default: penumbra's default kernels).
    pub kernels: Option<PathBuf>,
    /// Aberration correction, `lt+s` (default) or `none`.
    #[serde(default)]
    pub abcorr: AbCorr,
    /// The epoch range.
    pub time: TimeSpec,
    /// The sites (`[[sites]]` tables and/or `sites_file`).
    #[serde(default)]
    pub sites: Vec<SiteSpec>,
    /// A table of sites, relative to the scenario file: CSV (`name,lat_deg,lon_deg[,height_m]`)
    /// or GeoJSON points (see `penumbra series --sites`); its sites follow the `[[sites]]` ones.
    pub sites_file: Option<PathBuf>,
    /// Terrain: DEM layers or the synthetic DEM. Without it the run is ephemeris-only.
    pub terrain: Option<TerrainSpec>,
    /// Per-site illumination series (needs `[terrain]`); present = enabled.
    pub series: Option<crate::products::series::SeriesConfig>,
    /// Landing windows in the series (needs `[series]`; as `penumbra windows`), written beside
    /// the series' files; present = enabled.
    pub windows: Option<crate::products::windows::WindowsSpec>,
    /// Illumination maps over the scenario's span (needs `[terrain]`); present = enabled.
    pub map: Option<MapSpec>,
    /// Rendered views (needs `[terrain]`), written to `<output_dir>/render/`.
    pub render: Option<RenderSpec>,
}

/// Illumination-map statistics in a scenario (written to `<output_dir>/map/`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSpec {
    /// Time step of the map sweep (maps cost far more per epoch than series), e.g. `1d`.
    pub step: String,
    /// Observer height above the ground, metres (default 2).
    #[serde(default = "default_height_above_ground_m")]
    pub observer_height_m: f64,
    /// Engine, as `penumbra map --engine` (the same names and default): `auto` (default),
    /// `combined`, `dp`, `fourier` or `horizons` (whole-grid horizons once, then every epoch per
    /// pixel: docs/horizon.md).
    #[serde(default = "default_engine")]
    pub engine: String,
    /// `engine = "horizons"`: requested azimuths of the line sweep (default 720).
    #[serde(default = "default_sweep_azimuths")]
    pub azimuths: usize,
    /// `engine = "horizons"`: largest step component of a sweep direction (default 16).
    #[serde(default = "default_sweep_max_step")]
    pub max_step: u32,
    /// `engine = "horizons"`: a horizon GeoTIFF from `penumbra horizon-map sweep` (relative to
    /// this file) instead of a sweep in memory.
    #[serde(default)]
    pub horizons_file: Option<PathBuf>,
    /// `engine = "horizons"`: the Sun's limb darkening in the mean fraction (`none`,
    /// `eddington` (default) or `allen550nm`).
    #[serde(default)]
    pub limb_darkening: crate::illum::LimbLaw,
    /// Where the map runs: `cpu`, `gpu` or `auto` (default), as `penumbra map --backend`: an
    /// engine without a GPU kernel runs on the CPU.
    #[serde(default = "default_map_backend")]
    pub backend: String,
    /// Ground stations of the direct-to-Earth maps (`dte_pct`, `longest_dte_blackout_h`):
    /// `none` (default), `dsn` or a CSV file relative to this file, as `penumbra map --stations`
    /// (the horizons engine).
    #[serde(default = "default_map_stations")]
    pub stations: crate::comms::Stations,
    /// Elevation mask of the DSN stations and of file rows without their own, degrees (10).
    #[serde(default = "default_station_mask_deg")]
    pub station_mask_deg: f64,
    /// A panel and its load (`[map.power]`, the keys of `[series.power]`): adds
    /// `mean_power_w.tif` and `required_battery_wh.tif` (the horizons engine).
    #[serde(default)]
    pub power: Option<crate::illum::power::PowerConfig>,
}

fn default_map_stations() -> crate::comms::Stations {
    crate::comms::Stations::None
}

fn default_station_mask_deg() -> f64 {
    crate::comms::DEFAULT_MASK_DEG
}

fn default_map_backend() -> String {
    "auto".into()
}

/// Parses a `[map] backend` value.
fn parse_map_backend(name: &str) -> Option<crate::gpu::Backend> {
    name.parse().ok()
}

fn default_engine() -> String {
    "auto".into()
}

fn default_sweep_azimuths() -> usize {
    crate::horizon::sweep::DEFAULT_SWEEP_AZIMUTHS
}

fn default_sweep_max_step() -> u32 {
    crate::horizon::sweep::DEFAULT_MAX_STEP
}

/// The terrain of a scenario.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TerrainSpec {
    /// DEM GeoTIFF layers, relative to the scenario file (any order; the finest with data wins).
    #[serde(default)]
    pub layers: Vec<PathBuf>,
    /// The built-in synthetic south-polar DEM, used when `layers` is empty.
    pub synthetic: Option<SynthSpec>,
}

/// Parameters of the synthetic DEM in a scenario.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthSpec {
    /// Grid size, pixels (square).
    pub size_px: usize,
    /// Pixel size, metres.
    pub px_m: f64,
    /// Seed.
    pub seed: u64,
    /// Add the synthetic far field (400 km square at 10 x the pixel, blended into the DEM's
    /// edge), so that no ray leaves the terrain (default false, as `--synthetic`).
    #[serde(default)]
    pub far_field: bool,
}

/// The epoch range of a scenario (UTC).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// First epoch, UTC.
    pub start: String,
    /// Last epoch, UTC.
    pub stop: String,
    /// Step, e.g. `1h`.
    pub step: String,
}

/// A named site.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteSpec {
    /// Name, used as a folder name (letters and digits of any script, inner spaces and
    /// `- _ . ( ) + , '`; see [`crate::model::Site`]).
    pub name: String,
    /// Planetocentric latitude, degrees.
    pub lat_deg: f64,
    /// East longitude, degrees.
    pub lon_deg: f64,
    /// Height of the observer above the ground, metres (default 2).
    #[serde(default = "default_height_above_ground_m")]
    pub height_above_ground_m: f64,
    /// Height of the ground above the 1737.4 km sphere, metres. Without terrain it defaults to 0;
    /// with terrain layers it is read from the DEM unless given here.
    pub ground_height_m: Option<f64>,
}

/// Checks that an output name from a scenario stays inside its folder: relative, no `..`, no
/// folder part that is empty, and the expected extension.
fn confined_name(name: &str, ext: &str) -> anyhow::Result<()> {
    let p = Path::new(name);
    let plain = !name.is_empty()
        && p.is_relative()
        && p.components()
            .all(|c| matches!(c, std::path::Component::Normal(_)));
    if !plain {
        anyhow::bail!(
            "output name '{name}' must be a relative file name inside the output folder (no '..', no absolute path)"
        );
    }
    if !p.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
        anyhow::bail!("output name '{name}' must end in .{ext}");
    }
    Ok(())
}

fn default_height_above_ground_m() -> f64 {
    crate::DEFAULT_OBSERVER_HEIGHT_M
}

/// Largest scenario file read, bytes.
pub const MAX_SCENARIO_BYTES: u64 = 4 << 20;

impl Scenario {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text =
            crate::output::guard::read_small_text(path, MAX_SCENARIO_BYTES).map_err(|source| {
                ScenarioError::Read {
                    path: path.display().to_string(),
                    source,
                }
            })?;
        Self::from_toml(&text, path)
    }

    /// Parses and validates scenario text as if read from `path` (relative paths in it are taken
    /// against `path`'s folder, errors name `path`).
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let scenario: Scenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            path: path.display().to_string(),
            why: e
                .to_string()
                .replace('\n', " ")
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" "),
        })?;
        let mut scenario = scenario;
        if let Some(file) = &scenario.sites_file {
            let base = path.parent().unwrap_or(Path::new("."));
            let table = crate::model::read_sites_file(
                &base.join(file),
                crate::model::ObserverHeight::DEFAULT,
            )
            .map_err(|e| ScenarioError::Invalid {
                path: path.display().to_string(),
                why: format!("sites_file: {e:#}"),
            })?;
            scenario.sites.extend(table.into_iter().map(|s| SiteSpec {
                name: s.name().to_string(),
                lat_deg: s.lat_deg(),
                lon_deg: s.lon_deg(),
                height_above_ground_m: s.height_above_ground_m(),
                ground_height_m: None,
            }));
        }
        let base = path.parent().unwrap_or(Path::new("."));
        if let Some(series) = &mut scenario.series {
            if let crate::comms::Stations::File(f) = &series.stations {
                series.stations = crate::comms::Stations::File(base.join(f));
            }
            for p in &mut series.relay_spks {
                *p = base.join(&*p);
            }
            if let Some(f) = series.power.as_mut().and_then(|p| p.load_profile.as_mut()) {
                *f = base.join(&*f);
            }
        }
        if let Some(map) = &mut scenario.map {
            if let crate::comms::Stations::File(f) = &map.stations {
                map.stations = crate::comms::Stations::File(base.join(f));
            }
            if let Some(f) = map.power.as_mut().and_then(|p| p.load_profile.as_mut()) {
                *f = base.join(&*f);
            }
        }
        scenario.validate(path)?;
        Ok(scenario)
    }

    fn validate(&self, path: &Path) -> Result<(), ScenarioError> {
        let invalid = |why: String| ScenarioError::Invalid {
            path: path.display().to_string(),
            why,
        };
        if self.sites.is_empty() {
            return Err(invalid("no [[sites]] and no sites_file given".into()));
        }
        // A panel's numbers, and its load profile against the scenario's span.
        let check_power = |p: &crate::illum::power::PowerConfig, table: &str| {
            p.validate()
                .map_err(|e| invalid(format!("[{table}] {e}")))?;
            if p.load_profile.is_some() {
                let range = self
                    .epochs()
                    .map_err(|e| invalid(crate::products::one_line(&e)))?;
                p.loads(&range.epochs())
                    .map_err(|e| invalid(format!("[{table}] {e}")))?;
            }
            Ok(())
        };
        if let Some(s) = &self.series {
            s.stations
                .resolve(s.station_mask_deg)
                .map_err(|e| invalid(format!("[series] stations: {e}")))?;
            if let Some(p) = &s.power {
                check_power(p, "series.power")?;
            }
        }
        if let Some(w) = &self.windows {
            let Some(s) = &self.series else {
                return Err(invalid("[windows] needs [series]".into()));
            };
            let has_dte = s
                .stations
                .resolve(s.station_mask_deg)
                .map_err(|e| invalid(format!("[series] stations: {e}")))?
                .is_some();
            let range = self
                .epochs()
                .map_err(|e| invalid(crate::products::one_line(&e)))?;
            w.profile()
                .and_then(|p| {
                    p.validate(has_dte)?;
                    crate::products::windows::check_stay(&p, range.epochs().len(), range.step_s())
                })
                .map_err(|e| invalid(format!("[windows] {}", crate::products::one_line(&e))))?;
        }
        if let Some(m) = &self.map {
            m.stations
                .resolve(m.station_mask_deg)
                .map_err(|e| invalid(format!("[map] stations: {e}")))?;
            if let Some(p) = &m.power {
                check_power(p, "map.power")?;
                if p.battery_wh.is_some() {
                    return Err(invalid(
                        "[map.power] battery_wh: a map gives the smallest battery that survives \
                         (required_battery_wh.tif), not the charge of a given one"
                            .into(),
                    ));
                }
            }
        }
        self.sites()
            .map_err(|e| invalid(crate::products::one_line(&e)))?;
        if let Some(t) = &self.terrain {
            if t.layers.is_empty() && t.synthetic.is_none() {
                return Err(invalid(
                    "[terrain] needs `layers = [...]` or `synthetic = { size_px, px_m, seed }`"
                        .into(),
                ));
            }
            if !t.layers.is_empty() && t.synthetic.is_some() {
                return Err(invalid(
                    "[terrain] takes either `layers` or `synthetic`, not both".into(),
                ));
            }
            if let Some(s) = self.sites.iter().find(|s| s.ground_height_m.is_some()) {
                return Err(invalid(format!(
                    "site '{}': ground_height_m is read from the DEM when [terrain] is given; remove it",
                    s.name
                )));
            }
        }
        if self.map.is_some() && self.terrain.is_none() {
            return Err(invalid("[map] needs [terrain]".into()));
        }
        if let Some(m) = &self.map
            && let Err(e) = crate::model::MapEngineKind::parse_choice(&m.engine)
        {
            return Err(invalid(format!("[map] engine: {e}")));
        }
        if let Some(m) = &self.map
            && parse_map_backend(&m.backend).is_none()
        {
            return Err(invalid(format!(
                "[map] backend '{}': use cpu, gpu or auto",
                m.backend
            )));
        }
        if self.series.is_some() && self.terrain.is_none() {
            return Err(invalid("[series] needs [terrain]".into()));
        }
        self.preflight(path)
            .map_err(|e| invalid(crate::products::one_line(&e)))?;
        // Camera paths are checked before anything runs, so a bad one writes no file.
        for p in self.render.iter().flat_map(|r| &r.paths) {
            p.frames().map_err(|e| {
                invalid(format!(
                    "[[render.paths]] '{}': {}",
                    p.out,
                    format!("{e:#}").replace('\n', " ")
                ))
            })?;
        }
        Ok(())
    }

    /// Everything that can be checked before a stage runs, so that a bad scenario writes no file:
    /// the output folder, the epochs of every table, site bounds, the map's parameters and
    /// horizons file, every camera and image option, and output names that stay inside the
    /// output folder and do not collide.
    fn preflight(&self, path: &Path) -> anyhow::Result<()> {
        use anyhow::Context as _;
        if let Some(dir) = &self.output_dir
            && dir.as_os_str().is_empty()
        {
            anyhow::bail!("output_dir is empty");
        }
        self.epochs()?;
        for s in &self.sites {
            crate::ephem::Site::new(s.lat_deg, s.lon_deg, s.ground_height_m.unwrap_or(0.0))
                .with_context(|| format!("site '{}'", s.name))?;
        }
        if let Some(t) = &self.terrain
            && let Some(synth) = t.synthetic
            && !(synth.size_px >= 16
                && synth.size_px <= 16_384
                && (0.01..=100_000.0).contains(&synth.px_m))
        {
            anyhow::bail!(
                "[terrain] synthetic: size_px {} must lie in 16 .. 16384 and px_m {} in 0.01 .. 100000",
                synth.size_px,
                synth.px_m
            );
        }
        if let Some(cfg) = &self.series {
            crate::horizon::azimuth_count(cfg.az_step_deg).context("[series] az_step_deg")?;
            if let Some(r) = cfg.neighbourhood_m {
                crate::products::series::neighbourhood::check_radius_m(r)
                    .context("[series] neighbourhood_m")?;
            }
        }
        if let Some(m) = &self.map {
            self.map_epochs(m)?;
            crate::model::ObserverHeight::new(m.observer_height_m)
                .context("[map] observer_height_m")?;
            if !(4..=100_000).contains(&m.azimuths) || !(1..=64).contains(&m.max_step) {
                anyhow::bail!(
                    "[map] azimuths {} must lie in 4 .. 100000 and max_step {} in 1 .. 64",
                    m.azimuths,
                    m.max_step
                );
            }
            if let Some(h) = &m.horizons_file {
                let file = Self::base_dir(path).join(h);
                crate::output::guard::check_regular(&file)
                    .with_context(|| format!("[map] horizons_file {}", file.display()))?;
            }
        }
        if let Some(r) = &self.render {
            let mut names: Vec<(String, PathBuf)> = Vec::new();
            let views = r
                .views
                .iter()
                .map(|v| (v.clone(), None))
                .chain(r.paths.iter().map(|p| (p.as_view(), Some(p))));
            for (view, path_spec) in views {
                let what = if path_spec.is_some() {
                    "[[render.paths]]"
                } else {
                    "[[render.views]]"
                };
                let context = || format!("{what} '{}'", view.out);
                confined_name(&view.out, "png").with_context(context)?;
                names.push((format!("{what} out"), PathBuf::from(&view.out)));
                names.push((
                    format!("{what} provenance"),
                    crate::products::render::provenance_path(Path::new(&view.out)),
                ));
                if let Some(r) = &view.out_radiance {
                    confined_name(r, "tif").with_context(context)?;
                    names.push((format!("{what} out_radiance"), PathBuf::from(r)));
                }
                let frames = match path_spec {
                    None => view
                        .epochs()
                        .and_then(|e| crate::products::render::camera_frames(&view.camera(), &e)),
                    Some(p) => p.frames(),
                }
                .with_context(context)?;
                crate::products::render::check_look(&view.render_look(), frames.len())
                    .with_context(context)?;
            }
            let as_flags: Vec<(&str, &Path)> = names
                .iter()
                .map(|(flag, p)| (flag.as_str(), p.as_path()))
                .collect();
            crate::output::guard::check_distinct_outputs(&as_flags)
                .map_err(anyhow::Error::msg)
                .context("[render]")?;
        }
        Ok(())
    }

    /// The scenario's sites, each checked ([`crate::model::Site`]) and their names distinct.
    pub fn sites(&self) -> anyhow::Result<Vec<crate::model::Site>> {
        use anyhow::Context as _;
        let sites = self
            .sites
            .iter()
            .map(|s| {
                let h = crate::model::ObserverHeight::new(s.height_above_ground_m)
                    .with_context(|| format!("site '{}': height_above_ground_m", s.name))?;
                Ok(crate::model::Site::new(&s.name, s.lat_deg, s.lon_deg, h)?)
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        crate::model::check_distinct_sites(&sites)?;
        Ok(sites)
    }

    /// The epochs of `[time]`.
    pub fn epochs(&self) -> anyhow::Result<crate::model::EpochRange> {
        use anyhow::Context as _;
        let step = crate::ephem::time::parse_step(&self.time.step).context("[time] step")?;
        self.epochs_every(step).context("[time]")
    }

    /// The epochs of `[map]`: `[time]`'s span at the map's own step.
    pub fn map_epochs(&self, m: &MapSpec) -> anyhow::Result<crate::model::EpochRange> {
        use anyhow::Context as _;
        let step = crate::ephem::time::parse_step(&m.step).context("[map] step")?;
        self.epochs_every(step).context("[map]")
    }

    /// `[time]`'s span every `step`.
    fn epochs_every(&self, step: hifitime::Duration) -> anyhow::Result<crate::model::EpochRange> {
        use anyhow::Context as _;
        let start = crate::ephem::time::parse_utc(&self.time.start).context("[time] start")?;
        let stop = crate::ephem::time::parse_utc(&self.time.stop).context("[time] stop")?;
        Ok(crate::model::EpochRange::new(start, stop, step)?)
    }

    /// The scenario's folder, against which its relative paths are resolved.
    pub fn base_dir(path: &Path) -> PathBuf {
        path.parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."))
    }
}

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
use std::time::Instant;

use anyhow::Context as _;
use serde::{Deserialize, Serialize};

use crate::ephem::{self, AbCorr, Site};

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
    /// The sites.
    pub sites: Vec<SiteSpec>,
    /// Terrain: DEM layers or the synthetic DEM. Without it the run is ephemeris-only.
    pub terrain: Option<TerrainSpec>,
    /// Per-site illumination series (needs `[terrain]`); present = enabled.
    pub series: Option<crate::series::SeriesConfig>,
    /// Illumination maps over the scenario's span (needs `[terrain]`); present = enabled.
    pub map: Option<MapSpec>,
    /// Rendered views (needs `[terrain]`), written to `<output_dir>/render/`.
    pub render: Option<RenderSpec>,
}

/// The `[render]` table of a scenario: `[[render.views]]` and `[[render.paths]]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSpec {
    /// The views, each one `penumbra render` run (one frame, or numbered frames over a range).
    #[serde(default)]
    pub views: Vec<ViewSpec>,
    /// Camera paths: keyframes interpolated into numbered frames (docs/render.md).
    #[serde(default)]
    pub paths: Vec<PathSpec>,
}

/// One `[[render.paths]]` entry: a camera moving through keyframes, rendered as numbered
/// frames `<stem>_0000.png`, ... (image options as in `[[render.views]]`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Output PNG file name under `<output_dir>/render/` (numbered `<stem>_0000.png`, ...).
    pub out: String,
    /// `site` (default) or `orbit`, for every keyframe.
    pub camera: Option<String>,
    /// The keyframes (at least 2, times strictly increasing).
    pub keyframes: Vec<KeyframeSpec>,
    /// Number of frames, evenly spaced from the first keyframe to the last (or `step`).
    pub frames: Option<usize>,
    /// Time between frames (e.g. `10m`), from the first keyframe (or `frames`).
    pub step: Option<String>,
    /// Image width, pixels.
    pub width: Option<u32>,
    /// Image height, pixels.
    pub height: Option<u32>,
    /// `hapke` (default) or `lambert`.
    pub brdf: Option<String>,
    /// Lambert albedo (with `brdf = "lambert"`).
    pub albedo: Option<f64>,
    /// Fixed exposure, 1/(W m^-2 sr^-1).
    pub exposure: Option<f64>,
    /// Also write float radiance TIFFs under `render/` with this name (numbered).
    pub out_radiance: Option<String>,
}

/// One keyframe of a `[[render.paths]]` entry: an epoch and a camera pose (the `penumbra
/// render` camera options and defaults; site keys for a site camera, orbit keys for an orbit
/// camera).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    /// The keyframe's epoch, UTC.
    pub utc: String,
    /// Camera latitude, degrees.
    pub lat_deg: f64,
    /// Camera east longitude, degrees.
    pub lon_deg: f64,
    /// Site camera: height above the ground, metres (default 2).
    pub height_m: Option<f64>,
    /// Site camera: view azimuth, degrees from north clockwise (default 0).
    pub look_az_deg: Option<f64>,
    /// Site camera: view elevation, degrees (default 0).
    pub look_el_deg: Option<f64>,
    /// Orbit camera: altitude above the 1737.4 km sphere, kilometres (required).
    pub altitude_km: Option<f64>,
    /// Orbit camera: target latitude, degrees (default: the camera's).
    pub target_lat_deg: Option<f64>,
    /// Orbit camera: target east longitude, degrees (default: the camera's).
    pub target_lon_deg: Option<f64>,
    /// Horizontal field of view, degrees (default 60).
    pub fov_deg: Option<f64>,
}

impl PathSpec {
    /// The path's frames: (epoch, camera pose), interpolated between the keyframes.
    pub fn frames(
        &self,
    ) -> anyhow::Result<Vec<(hifitime::Epoch, crate::render::path::CameraPose)>> {
        use crate::render::path::{CameraPose, FrameSampling, Keyframe, path_frames};
        let orbit = match self.camera.as_deref() {
            None | Some("site") => false,
            Some("orbit") => true,
            Some(other) => anyhow::bail!("camera '{other}': use site or orbit"),
        };
        let keyframes = self
            .keyframes
            .iter()
            .enumerate()
            .map(|(k, kf)| {
                let epoch = crate::ephem::time::parse_utc(&kf.utc)
                    .map_err(|e| anyhow::anyhow!("keyframe {k}: {e}"))?;
                let pose = if orbit {
                    if kf.height_m.is_some() || kf.look_az_deg.is_some() || kf.look_el_deg.is_some()
                    {
                        anyhow::bail!(
                            "keyframe {k}: height_m/look_az_deg/look_el_deg are site-camera keys"
                        );
                    }
                    let Some(altitude_km) = kf.altitude_km else {
                        anyhow::bail!("keyframe {k}: an orbit camera needs altitude_km");
                    };
                    CameraPose::Orbit {
                        lat_deg: kf.lat_deg,
                        lon_deg: kf.lon_deg,
                        altitude_km,
                        target_lat_deg: kf.target_lat_deg.unwrap_or(kf.lat_deg),
                        target_lon_deg: kf.target_lon_deg.unwrap_or(kf.lon_deg),
                        fov_deg: kf.fov_deg.unwrap_or(60.0),
                    }
                } else {
                    if kf.altitude_km.is_some()
                        || kf.target_lat_deg.is_some()
                        || kf.target_lon_deg.is_some()
                    {
                        anyhow::bail!(
                            "keyframe {k}: altitude_km/target_lat_deg/target_lon_deg are orbit-camera keys (set camera = \"orbit\")"
                        );
                    }
                    CameraPose::Site {
                        lat_deg: kf.lat_deg,
                        lon_deg: kf.lon_deg,
                        height_m: kf.height_m.unwrap_or(2.0),
                        look_az_deg: kf.look_az_deg.unwrap_or(0.0),
                        look_el_deg: kf.look_el_deg.unwrap_or(0.0),
                        fov_deg: kf.fov_deg.unwrap_or(60.0),
                    }
                };
                Ok(Keyframe { epoch, pose })
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let sampling = match (self.frames, &self.step) {
            (Some(n), None) => FrameSampling::Count(n),
            (None, Some(s)) => FrameSampling::Step(crate::ephem::time::parse_step(s)?),
            _ => anyhow::bail!("give either frames = N or step = \"...\""),
        };
        Ok(path_frames(&keyframes, sampling)?)
    }

    /// The `[[render.views]]` entry with this path's image options and its first keyframe
    /// (its command line carries the options the frames share).
    fn as_view(&self) -> ViewSpec {
        let k0 = self.keyframes.first();
        let g = |f: fn(&KeyframeSpec) -> Option<f64>| k0.and_then(f);
        ViewSpec {
            out: self.out.clone(),
            camera: self.camera.clone(),
            lat_deg: k0.map_or(0.0, |k| k.lat_deg),
            lon_deg: k0.map_or(0.0, |k| k.lon_deg),
            height_m: g(|k| k.height_m),
            look_az_deg: g(|k| k.look_az_deg),
            look_el_deg: g(|k| k.look_el_deg),
            altitude_km: g(|k| k.altitude_km),
            target_lat_deg: g(|k| k.target_lat_deg),
            target_lon_deg: g(|k| k.target_lon_deg),
            fov_deg: g(|k| k.fov_deg),
            utc: k0.map(|k| k.utc.clone()),
            start: None,
            stop: None,
            step: None,
            width: self.width,
            height: self.height,
            brdf: self.brdf.clone(),
            albedo: self.albedo,
            exposure: self.exposure,
            out_radiance: self.out_radiance.clone(),
        }
    }
}

/// One `[[render.views]]` entry: the options of `penumbra render` (same names, same defaults;
/// the terrain, kernels and aberration correction are the scenario's).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewSpec {
    /// Output PNG file name under `<output_dir>/render/` (numbered `<stem>_0000.png`, ... for a
    /// range).
    pub out: String,
    /// `site` (default) or `orbit`.
    pub camera: Option<String>,
    /// Camera latitude, degrees.
    pub lat_deg: f64,
    /// Camera east longitude, degrees.
    pub lon_deg: f64,
    /// Site camera: height above the ground, metres.
    pub height_m: Option<f64>,
    /// Site camera: view azimuth, degrees from north clockwise.
    pub look_az_deg: Option<f64>,
    /// Site camera: view elevation, degrees.
    pub look_el_deg: Option<f64>,
    /// Orbit camera: altitude above the 1737.4 km sphere, kilometres.
    pub altitude_km: Option<f64>,
    /// Orbit camera: target latitude, degrees.
    pub target_lat_deg: Option<f64>,
    /// Orbit camera: target east longitude, degrees.
    pub target_lon_deg: Option<f64>,
    /// Horizontal field of view, degrees.
    pub fov_deg: Option<f64>,
    /// One epoch, UTC (or `start`/`stop`/`step`).
    pub utc: Option<String>,
    /// First epoch of a range, UTC.
    pub start: Option<String>,
    /// Last epoch of a range, UTC.
    pub stop: Option<String>,
    /// Step of the range (e.g. `6h`).
    pub step: Option<String>,
    /// Image width, pixels.
    pub width: Option<u32>,
    /// Image height, pixels.
    pub height: Option<u32>,
    /// `hapke` (default) or `lambert`.
    pub brdf: Option<String>,
    /// Lambert albedo (with `brdf = "lambert"`).
    pub albedo: Option<f64>,
    /// Fixed exposure, 1/(W m^-2 sr^-1).
    pub exposure: Option<f64>,
    /// Also write the float radiance TIFF under `render/` with this name.
    pub out_radiance: Option<String>,
}

impl ViewSpec {
    /// The `penumbra render` command line of this view (after `render`), without the terrain,
    /// kernel and aberration options.
    fn render_argv(&self, render_dir: &Path) -> Vec<String> {
        let mut a: Vec<String> = Vec::new();
        let mut opt = |k: &str, v: Option<String>| {
            if let Some(v) = v {
                a.push(format!("--{k}"));
                a.push(v);
            }
        };
        let f = |x: Option<f64>| x.map(|v| v.to_string());
        opt("camera", self.camera.clone());
        opt("lat-deg", Some(self.lat_deg.to_string()));
        opt("lon-deg", Some(self.lon_deg.to_string()));
        opt("height-m", f(self.height_m));
        opt("look-az-deg", f(self.look_az_deg));
        opt("look-el-deg", f(self.look_el_deg));
        opt("altitude-km", f(self.altitude_km));
        opt("target-lat-deg", f(self.target_lat_deg));
        opt("target-lon-deg", f(self.target_lon_deg));
        opt("fov-deg", f(self.fov_deg));
        opt("utc", self.utc.clone());
        opt("start", self.start.clone());
        opt("stop", self.stop.clone());
        opt("step", self.step.clone());
        opt("width", self.width.map(|v| v.to_string()));
        opt("height", self.height.map(|v| v.to_string()));
        opt("brdf", self.brdf.clone());
        opt("albedo", f(self.albedo));
        opt("exposure", f(self.exposure));
        opt(
            "out",
            Some(render_dir.join(&self.out).display().to_string()),
        );
        opt(
            "out-radiance",
            self.out_radiance
                .as_ref()
                .map(|r| render_dir.join(r).display().to_string()),
        );
        a
    }
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
    /// Shadow engine: `brute`, `smap`, `dp`, `combined` (default) or `fourier`.
    #[serde(default = "default_engine")]
    pub engine: String,
    /// Where the sweep runs: `cpu`, `gpu` or `auto` (default: the GPU when an adapter exists,
    /// else the CPU with one warning line). The GPU sweep is DP soft shadows whatever `engine`
    /// says (docs/gpu.md).
    #[serde(default = "default_map_backend")]
    pub backend: String,
}

fn default_map_backend() -> String {
    "auto".into()
}

/// Parses a `[map] backend` value.
fn parse_map_backend(name: &str) -> Option<crate::gpu::Backend> {
    <crate::gpu::Backend as clap::ValueEnum>::from_str(name, false).ok()
}

fn default_engine() -> String {
    "combined".into()
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
    /// Name, used in file names (letters, digits, `-` and `_`).
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

fn default_height_above_ground_m() -> f64 {
    2.0
}

impl Scenario {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: path.display().to_string(),
            source,
        })?;
        let scenario: Scenario = toml::from_str(&text).map_err(|e| ScenarioError::Parse {
            path: path.display().to_string(),
            why: e
                .to_string()
                .replace('\n', " ")
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" "),
        })?;
        scenario.validate(path)?;
        Ok(scenario)
    }

    fn validate(&self, path: &Path) -> Result<(), ScenarioError> {
        let invalid = |why: String| ScenarioError::Invalid {
            path: path.display().to_string(),
            why,
        };
        if self.sites.is_empty() {
            return Err(invalid("no [[sites]] given".into()));
        }
        let mut seen = std::collections::HashSet::new();
        for s in &self.sites {
            if s.name.is_empty()
                || !s
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
            {
                return Err(invalid(format!(
                    "site name '{}' must be letters, digits, '-' or '_'",
                    s.name
                )));
            }
            if !seen.insert(s.name.clone()) {
                return Err(invalid(format!("site name '{}' is used twice", s.name)));
            }
            if s.height_above_ground_m.is_nan() || s.height_above_ground_m < 0.0 {
                return Err(invalid(format!(
                    "site '{}': height_above_ground_m must be >= 0",
                    s.name
                )));
            }
        }
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
            && crate::map::MapEngineKind::parse(&m.engine).is_none()
        {
            return Err(invalid(format!(
                "[map] engine '{}': use brute, smap, dp, combined or fourier",
                m.engine
            )));
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

    /// The scenario's folder, against which its relative paths are resolved.
    pub fn base_dir(path: &Path) -> PathBuf {
        path.parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."))
    }
}

/// Runs a scenario file (`penumbra run`).
pub fn run_file(args: &crate::cli::RunArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let path = &args.scenario;
    let scenario = Scenario::load(path)?;
    let base = Scenario::base_dir(path);
    let out_dir = args
        .out_dir
        .clone()
        .or_else(|| scenario.output_dir.clone())
        .unwrap_or_else(|| PathBuf::from("out").join(&scenario.name));

    let kernel_dir = match (&args.kernels.kernels, &scenario.kernels) {
        (Some(k), _) => k.clone(),
        (None, Some(k)) => base.join(k),
        (None, None) => ephem::kernels::default_kernel_dir(),
    };
    let start = ephem::time::parse_utc(&scenario.time.start).context("[time] start")?;
    let stop = ephem::time::parse_utc(&scenario.time.stop).context("[time] stop")?;
    let step = ephem::time::parse_step(&scenario.time.step).context("[time] step")?;
    let epochs = ephem::time::epoch_range(start, stop, step)?;
    let kernels = ephem::Kernels::load(&kernel_dir).context("loading SPICE kernels")?;
    // Fail on coverage before loading terrain or writing anything.
    ephem::moon_geometry_table(&kernels, &[epochs[0], *epochs.last().unwrap_or(&epochs[0])])?;

    let mut prov = crate::output::Provenance::new();
    prov.scenario_file = Some(path.display().to_string());
    prov.scenario = Some(serde_json::to_value(&scenario)?);
    prov.kernels = kernels.files.clone();
    prov.set_epochs(&epochs);

    let stack = match &scenario.terrain {
        None => None,
        Some(t) => Some(load_terrain(t, &base, &out_dir, &mut prov)?),
    };
    std::fs::create_dir_all(&out_dir)
        .with_context(|| format!("creating output folder {}", out_dir.display()))?;

    match (&stack, &scenario.series) {
        (Some(stack), Some(config)) => {
            let sites: Vec<crate::series::SeriesSite> = scenario
                .sites
                .iter()
                .map(|s| crate::series::SeriesSite {
                    name: s.name.clone(),
                    lat_deg: s.lat_deg,
                    lon_deg: s.lon_deg,
                    height_above_ground_m: s.height_above_ground_m,
                })
                .collect();
            let run = crate::series::run_series(
                &kernels,
                stack,
                &sites,
                &epochs,
                step.to_seconds(),
                &crate::series::SeriesConfig {
                    abcorr: scenario.abcorr,
                    ..*config
                },
                &out_dir,
            )?;
            prov.outputs.extend(run.files);
            prov.series_engine = Some(config.engine.name().into());
            prov.series_backend = Some(run.backend);
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
            for (spec, rows) in scenario.sites.iter().zip(&series) {
                let name = format!("{}_ephem.csv", spec.name);
                crate::app::write_output(Some(&out_dir.join(&name)), |w| {
                    writeln!(w, "{}", crate::app::EPHEM_CSV_HEADER)?;
                    for (e, v) in epochs.iter().zip(rows) {
                        crate::app::write_ephem_row(w, *e, v)?;
                    }
                    Ok(())
                })?;
                prov.outputs.push(name);
            }
        }
    }
    if let (Some(stack), Some(spec)) = (&stack, &scenario.map) {
        let (files, below) = run_map_spec(
            spec,
            stack,
            &kernels,
            start,
            stop,
            scenario.abcorr,
            &out_dir,
        )?;
        prov.map_rays_blocked_beyond_dem = below;
        prov.outputs
            .extend(files.into_iter().map(|f| format!("map/{f}")));
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
        let abcorr = match scenario.abcorr {
            AbCorr::LtS => "lt+s",
            AbCorr::None => "none",
        };
        let render_dir = out_dir.join("render");
        std::fs::create_dir_all(&render_dir)
            .with_context(|| format!("creating {}", render_dir.display()))?;
        let paths: Vec<(ViewSpec, Option<&PathSpec>)> = spec
            .views
            .iter()
            .map(|v| (v.clone(), None))
            .chain(spec.paths.iter().map(|p| (p.as_view(), Some(p))))
            .collect();
        for (view, path_spec) in &paths {
            let what = if path_spec.is_some() {
                "[[render.paths]]"
            } else {
                "[[render.views]]"
            };
            let mut argv = vec!["penumbra".to_string(), "render".to_string()];
            for t in &terrain {
                argv.push("--dem".into());
                argv.push(t.display().to_string());
            }
            argv.extend(view.render_argv(&render_dir));
            argv.extend([
                "--kernels".to_string(),
                kernel_dir.display().to_string(),
                "--abcorr".to_string(),
                abcorr.to_string(),
            ]);
            let cli = <crate::cli::Cli as clap::Parser>::try_parse_from(&argv).map_err(|e| {
                anyhow::anyhow!(
                    "scenario {}: {what} '{}': {}",
                    path.display(),
                    view.out,
                    e.to_string().lines().next().unwrap_or("bad view")
                )
            })?;
            let crate::cli::Command::Render(args) = cli.command else {
                anyhow::bail!("internal: the view did not parse as `penumbra render`")
            };
            match path_spec {
                None => crate::app::run_render(&args),
                Some(p) => crate::app::render_frames(&args, &p.frames()?),
            }
            .with_context(|| format!("{what} '{}'", view.out))?;
            prov.outputs.push(format!("render/{}", view.out));
        }
    }
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&out_dir.join("run.json"))?;
    eprintln!(
        "penumbra: {} file(s) and run.json written to {} ({} sites, {} epochs, {:.1} s)",
        prov.outputs.len(),
        out_dir.display(),
        scenario.sites.len(),
        prov.epoch_count,
        prov.wall_time_s
    );
    Ok(())
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
        let (stack, what) = crate::app::synthetic_stack(&params)?;
        std::fs::create_dir_all(out_dir)
            .with_context(|| format!("creating output folder {}", out_dir.display()))?;
        crate::terrain::write_dem(
            &out_dir.join("terrain_synthetic.tif"),
            &stack.layers[0],
            &[(
                "software",
                &format!("penumbra {}", env!("CARGO_PKG_VERSION")),
            )],
        )?;
        prov.outputs.push("terrain_synthetic.tif".into());
        prov.dem_layers.push(what);
        return Ok(stack);
    }
    let paths: Vec<PathBuf> = spec.layers.iter().map(|p| base.join(p)).collect();
    prov.dem_layers = paths.iter().map(|p| p.display().to_string()).collect();
    Ok(crate::terrain::TerrainStack::load(&paths)?)
}

/// Runs a scenario's `[map]`: the sweep statistics over the scenario's span at the map's step.
fn run_map_spec(
    spec: &MapSpec,
    stack: &crate::terrain::TerrainStack,
    kernels: &ephem::Kernels,
    start: hifitime::Epoch,
    stop: hifitime::Epoch,
    abcorr: AbCorr,
    out_dir: &Path,
) -> anyhow::Result<(Vec<String>, Option<crate::output::BelowSphereExits>)> {
    let step = ephem::time::parse_step(&spec.step).context("[map] step")?;
    let epochs = ephem::time::epoch_range(start, stop, step)?;
    let kind = crate::map::MapEngineKind::parse(&spec.engine)
        .with_context(|| format!("[map] engine '{}'", spec.engine))?;
    let requested = parse_map_backend(&spec.backend)
        .with_context(|| format!("[map] backend '{}'", spec.backend))?;
    let backend = crate::gpu::resolve_backend(requested)
        .with_context(|| format!("[map] backend '{}'", spec.backend))?;
    let grid = crate::map::MapGrid::new(stack)?;
    grid.warn_if_clipped();
    let lights = crate::map::epoch_lights(&grid, kernels, &epochs, abcorr)?;
    let step_h = step.to_seconds() / 3600.0;
    let progress = indicatif::ProgressBar::new(lights.len() as u64);
    let stats = match &backend {
        crate::gpu::ResolvedBackend::Cpu => {
            let engine = crate::map::MapEngine::new(kind, &grid, spec.observer_height_m)?;
            crate::map::sweep(
                &grid,
                &engine,
                spec.observer_height_m,
                crate::map::ObserverPlacement::Pixels,
                &lights,
                step_h,
                &progress,
            )?
        }
        #[cfg(feature = "gpu")]
        crate::gpu::ResolvedBackend::Gpu(ctx) => crate::map::sweep_gpu_soft(
            ctx,
            &grid,
            spec.observer_height_m,
            &lights,
            step_h,
            crate::gpu::tiles::DpTiling::default(),
        )?,
        #[cfg(not(feature = "gpu"))]
        crate::gpu::ResolvedBackend::Gpu(ctx) => match **ctx {},
    };
    progress.finish_and_clear();
    let dir = out_dir.join("map");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let span = format!(
        "{} .. {} UTC, {} epochs every {}",
        ephem::time::format_utc(epochs[0]),
        ephem::time::format_utc(*epochs.last().unwrap_or(&epochs[0])),
        epochs.len(),
        spec.step
    );
    let files = crate::map::write_sweep(&grid, &stats, &dir, &span)?;
    if let Some(b) = stats.below_sphere {
        b.warn();
    }
    Ok((files, stats.below_sphere))
}

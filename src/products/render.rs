//! `penumbra render`: frames (PNG, optional radiance TIFF) of the terrain seen from a site or an
//! orbital camera at one epoch or a range of epochs.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use hifitime::Epoch;

use super::{KernelSource, TerrainSource};
use crate::ephem::{AbCorr, time::format_utc};
use crate::gpu::Backend;
use crate::model::Epochs;
use crate::render::path::CameraPose;

/// Default image width, pixels.
pub const DEFAULT_WIDTH_PX: u32 = 640;
/// Default image height, pixels.
pub const DEFAULT_HEIGHT_PX: u32 = 480;
/// Default horizontal field of view, degrees.
pub const DEFAULT_FOV_DEG: f64 = 60.0;

/// Surface BRDF choice (`hapke` or `lambert` in scenario files).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BrdfChoice {
    /// Hapke (2012) with the lunar parameters of Sato et al. (2014), 643 nm.
    #[default]
    Hapke,
    /// Lambert with an albedo.
    Lambert,
}

/// Camera kind (`site` or `orbit` in scenario files).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CameraKind {
    /// At a site, a height above the ground, looking along an azimuth and an elevation.
    #[default]
    Site,
    /// In orbit, an altitude above the sphere, looking at a surface point (image up = north).
    Orbit,
}

/// A camera as the command line and the scenario `[[render.views]]` give it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSpec {
    /// Site or orbit.
    pub kind: CameraKind,
    /// Camera latitude (the site, or the point below the orbital camera), degrees.
    pub lat_deg: f64,
    /// Camera east longitude, degrees.
    pub lon_deg: f64,
    /// Site camera: height above the ground (DEM), metres.
    pub height_m: f64,
    /// Site camera: view azimuth, degrees from north clockwise.
    pub look_az_deg: f64,
    /// Site camera: view elevation above the local horizontal, degrees.
    pub look_el_deg: f64,
    /// Orbit camera: altitude above the 1737.4 km sphere, kilometres (required for an orbit).
    pub altitude_km: Option<f64>,
    /// Orbit camera: latitude of the point looked at, degrees (default: `lat_deg`).
    pub target_lat_deg: Option<f64>,
    /// Orbit camera: east longitude of the point looked at, degrees (default: `lon_deg`).
    pub target_lon_deg: Option<f64>,
    /// Horizontal field of view, degrees, in (0, 180).
    pub fov_deg: f64,
}

impl CameraSpec {
    /// A site camera at (`lat_deg`, `lon_deg`) with the defaults: 2 m above the ground, looking
    /// north along the horizontal, 60 deg field of view.
    pub fn site(lat_deg: f64, lon_deg: f64) -> Self {
        CameraSpec {
            kind: CameraKind::Site,
            lat_deg,
            lon_deg,
            height_m: crate::DEFAULT_OBSERVER_HEIGHT_M,
            look_az_deg: 0.0,
            look_el_deg: 0.0,
            altitude_km: None,
            target_lat_deg: None,
            target_lon_deg: None,
            fov_deg: DEFAULT_FOV_DEG,
        }
    }

    /// The camera pose (an orbit camera needs `altitude_km`).
    pub fn pose(&self) -> anyhow::Result<CameraPose> {
        let lat_ok = |v: f64| (-90.0..=90.0).contains(&v);
        let lon_ok = |v: f64| v.is_finite() && v.abs() <= 360.0;
        if !lat_ok(self.lat_deg) || !lon_ok(self.lon_deg) {
            anyhow::bail!(
                "camera at latitude {} / longitude {} deg: latitude must lie in -90 .. 90, longitude in -360 .. 360",
                self.lat_deg,
                self.lon_deg
            );
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            anyhow::bail!("--fov-deg {} must lie in (0, 180)", self.fov_deg);
        }
        match self.kind {
            CameraKind::Site => {
                // A site camera is an observer above the ground: the observer height's bound.
                crate::model::ObserverHeight::new(self.height_m)
                    .map_err(|e| anyhow::anyhow!("site camera: {e}"))?;
                if !self.look_az_deg.is_finite() || !(-90.0..=90.0).contains(&self.look_el_deg) {
                    anyhow::bail!(
                        "view azimuth {} / elevation {} deg: the azimuth must be finite, the elevation within -90 .. 90",
                        self.look_az_deg,
                        self.look_el_deg
                    );
                }
            }
            CameraKind::Orbit => {
                if let Some(alt) = self.altitude_km
                    && !(alt.is_finite() && alt <= MAX_CAMERA_ALTITUDE_KM)
                {
                    // Inside the terrain is refused where the terrain is known (place_camera).
                    anyhow::bail!(
                        "--altitude-km {alt} must be finite and at most {MAX_CAMERA_ALTITUDE_KM} km"
                    );
                }
                if !self.target_lat_deg.is_none_or(lat_ok)
                    || !self.target_lon_deg.is_none_or(lon_ok)
                {
                    anyhow::bail!(
                        "target latitude/longitude out of range (-90 .. 90 / -360 .. 360 deg)"
                    );
                }
            }
        }
        Ok(match self.kind {
            CameraKind::Site => CameraPose::Site {
                lat_deg: self.lat_deg,
                lon_deg: self.lon_deg,
                height_m: self.height_m,
                look_az_deg: self.look_az_deg,
                look_el_deg: self.look_el_deg,
                fov_deg: self.fov_deg,
            },
            CameraKind::Orbit => {
                let Some(altitude_km) = self.altitude_km else {
                    anyhow::bail!("--camera orbit needs --altitude-km");
                };
                CameraPose::Orbit {
                    lat_deg: self.lat_deg,
                    lon_deg: self.lon_deg,
                    altitude_km,
                    target_lat_deg: self.target_lat_deg.unwrap_or(self.lat_deg),
                    target_lon_deg: self.target_lon_deg.unwrap_or(self.lon_deg),
                    fov_deg: self.fov_deg,
                }
            }
        })
    }
}

/// Everything of a render but its cameras and epochs.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// The terrain (every layer is shaded).
    pub terrain: TerrainSource,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Surface BRDF.
    pub brdf: BrdfChoice,
    /// Lambert albedo (only with [`BrdfChoice::Lambert`]), in [0, 1]; default 0.12.
    pub albedo: Option<f64>,
    /// Exposure: fixed physical (`Sun`, the default), per-frame automatic or a given value.
    pub exposure: crate::render::Exposure,
    /// Output PNG (numbered `<stem>_0000.png`, ... for several frames).
    pub out: PathBuf,
    /// Also the terrain radiance as a float32 TIFF (numbered like `out`).
    pub out_radiance: Option<PathBuf>,
    /// Aberration correction.
    pub abcorr: AbCorr,
    /// Compute backend of the ray casting, shading and shadow fractions.
    pub backend: Backend,
    /// The kernels.
    pub kernels: KernelSource,
    /// Burn the epoch, the Sun's and the Earth's elevation and azimuth, the camera and (for a
    /// camera within 45° of level) azimuth ticks into each frame (default); `false` keeps the
    /// picture bare (the same values are always in the PNG's text chunks).
    pub annotate: bool,
}

/// Highest orbit camera above the 1737.4 km sphere, kilometres (the Earth is ≈ 384,000 km away).
pub const MAX_CAMERA_ALTITUDE_KM: f64 = 400_000.0;

/// The image options of a render, checked by [`check_look`] without touching any file.
#[derive(Debug, Clone, Copy)]
pub struct RenderLook {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Surface BRDF.
    pub brdf: BrdfChoice,
    /// Lambert albedo.
    pub albedo: Option<f64>,
    /// Exposure.
    pub exposure: crate::render::Exposure,
}

impl RenderOptions {
    /// The image options.
    pub fn look(&self) -> RenderLook {
        RenderLook {
            width: self.width,
            height: self.height,
            brdf: self.brdf,
            albedo: self.albedo,
            exposure: self.exposure,
        }
    }
}

/// Checks image options and the frame count of a render; the BRDF they choose.
pub fn check_look(look: &RenderLook, n_frames: usize) -> anyhow::Result<crate::render::Brdf> {
    use crate::render::{Brdf, HapkeParams};
    crate::render::check_size(look.width, look.height)?;
    if n_frames > MAX_FRAMES {
        anyhow::bail!(
            "{} frames asked for; at most {MAX_FRAMES} per run (use a coarser --step or split the range)",
            n_frames
        );
    }
    if let crate::render::Exposure::Fixed(e) = look.exposure
        && !(e > 0.0 && e.is_finite())
    {
        anyhow::bail!("--exposure {e} must be a finite number > 0");
    }
    let brdf = match (look.brdf, look.albedo) {
        (BrdfChoice::Hapke, None) => Brdf::Hapke(HapkeParams::MOON_643NM),
        (BrdfChoice::Hapke, Some(_)) => {
            anyhow::bail!("--albedo applies to --brdf lambert only")
        }
        (BrdfChoice::Lambert, a) => {
            let albedo = a.unwrap_or(crate::render::DEFAULT_ALBEDO);
            if !(0.0..=1.0).contains(&albedo) {
                anyhow::bail!("--albedo {albedo} must be in [0, 1]");
            }
            Brdf::Lambert { albedo }
        }
    };
    Ok(brdf)
}

/// Most frames one render run makes.
pub const MAX_FRAMES: usize = 10_000;

/// The frames of one camera at `epochs`.
pub fn camera_frames(
    camera: &CameraSpec,
    epochs: &Epochs,
) -> anyhow::Result<Vec<(Epoch, CameraPose)>> {
    let pose = camera.pose()?;
    Ok(epochs.epochs().into_iter().map(|e| (e, pose)).collect())
}

/// `penumbra render`: one frame (one epoch) or numbered frames (a range) from one camera, and
/// their provenance `<stem>.run.json` beside the PNG.
pub fn run(opts: &RenderOptions, camera: &CameraSpec, epochs: &Epochs) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    let run = render_frames(opts, &camera_frames(camera, epochs)?)?;
    let folder = opts.out.parent().unwrap_or(Path::new(""));
    let mut prov = crate::output::Provenance::new();
    prov.kernels = run.kernels;
    prov.dem_layers = run.dem_layers;
    prov.dem_files = opts.terrain.dem_files()?;
    prov.set_epochs(&run.epochs);
    prov.backend = run.backend;
    prov.outputs = run
        .files
        .iter()
        .map(|f| f.strip_prefix(folder).unwrap_or(f).display().to_string())
        .collect();
    prov.wall_time_s = t0.elapsed().as_secs_f64();
    prov.write(&provenance_path(&opts.out))?;
    Ok(())
}

/// Where `penumbra render --out DIR/NAME.png` writes its provenance: `DIR/NAME.run.json`.
pub fn provenance_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().unwrap_or_default().to_string_lossy();
    out.with_file_name(format!("{stem}.run.json"))
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
    let (camera, ref_lat_lon_deg, what) = match *pose {
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
                    "camera height {height_m} m above the ground (--observer-height-m, or height_m \
                     in a scenario) puts it below the terrain surface: give a finite height >= 0"
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
            let what = format!(
                "site lat_deg={lat_deg} lon_deg={lon_deg} height_m={height_m} \
                 look_az_deg={look_az_deg} look_el_deg={look_el_deg} fov_deg={fov_deg}"
            );
            (camera, (lat_deg, lon_deg), what)
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
            let what = format!(
                "orbit lat_deg={lat_deg} lon_deg={lon_deg} altitude_km={alt_km} \
                 target_lat_deg={tlat} target_lon_deg={tlon} fov_deg={fov_deg}"
            );
            (camera, (tlat, tlon), what)
        }
    };
    Ok(PlacedCamera {
        camera,
        ref_lat_lon_deg,
        what,
    })
}

/// Azimuth ticks along the top edge of a frame: (column, label) where the horizontal centre
/// row's rays cross multiples of 10° (30° for a field of view over 120°), for a camera within
/// 45° of level (none for a camera looking down from orbit). `az_el_deg` gives a model-space
/// direction's azimuth and elevation at the frame's reference point.
fn azimuth_ticks(
    camera: &crate::render::Camera,
    az_el_deg: &dyn Fn(&nalgebra::Vector3<f64>) -> (f64, f64),
    width: u32,
    height: u32,
) -> Vec<(u32, String)> {
    if az_el_deg(&camera.forward_model).1.abs() > 45.0 {
        return Vec::new();
    }
    let step = if camera.fov_deg > 120.0 { 30.0 } else { 10.0 };
    let row = height / 2;
    let mut ticks = Vec::new();
    let mut prev = az_el_deg(&camera.ray_dir(row, 0, width, height)).0;
    for col in 1..width {
        let az = az_el_deg(&camera.ray_dir(row, col, width, height)).0;
        // The azimuth from the previous column, unwrapped across north.
        let next = prev + (az - prev + 180.0).rem_euclid(360.0) - 180.0;
        let (lo, hi) = (prev.min(next), prev.max(next));
        let mut k = (lo / step).floor() + 1.0;
        while k * step <= hi {
            let deg = (k * step).rem_euclid(360.0).round() as i64 % 360;
            ticks.push((col, format!("{deg}°")));
            k += 1.0;
        }
        prev = az;
    }
    ticks
}

/// Everything a frame needs besides its camera and epoch.
struct FrameJob<'a> {
    opts: &'a RenderOptions,
    hf: &'a crate::terrain::HeightField,
    brdf: crate::render::Brdf,
    backend: &'a crate::compute::ResolvedBackend,
    fractions: crate::compute::render::SceneFractions<'a>,
}

/// Renders one frame (`index` numbers the output files of a sequence) and writes its PNG (and
/// radiance TIFF); returns the files written (the PNG last) and the Sun elevation at the
/// reference point, degrees.
fn render_one_frame(
    job: &FrameJob,
    placed: &PlacedCamera,
    epoch: Epoch,
    lights: crate::render::Lights,
    index: Option<usize>,
    exposure: Option<f64>,
) -> anyhow::Result<(Vec<PathBuf>, f64)> {
    let opts = job.opts;
    let scene = job.fractions.scene(lights)?.with_brdf(job.brdf);
    let camera = &placed.camera;
    let samples = crate::compute::render::render_samples(
        job.backend,
        &scene,
        camera,
        opts.width,
        opts.height,
    )?;
    // The run's exposure, or this frame's own (a single frame, or `auto`).
    let exposure = exposure.unwrap_or_else(|| opts.exposure.value(&samples));
    let mut rgb = crate::render::tone_map(&samples, exposure);
    crate::render::add_sun_glare(&mut rgb, &scene, camera, opts.width, opts.height);
    // Sun elevation at the site (or the orbit camera's target), above the plane normal to the
    // local up.
    let (lat, lon) = placed.ref_lat_lon_deg;
    let enu_to_model =
        job.hf.model_from_moon_me() * crate::frames::enu_from_moon_me(lat, lon).transpose();
    let (east, north, up) = (
        enu_to_model * nalgebra::Vector3::x(),
        enu_to_model * nalgebra::Vector3::y(),
        enu_to_model * nalgebra::Vector3::z(),
    );
    let az_el_deg = |v: &nalgebra::Vector3<f64>| {
        (
            v.dot(&east)
                .atan2(v.dot(&north))
                .to_degrees()
                .rem_euclid(360.0),
            v.dot(&up).clamp(-1.0, 1.0).asin().to_degrees(),
        )
    };
    let (sun_az_deg, sun_el_deg) = az_el_deg(&nalgebra::Vector3::from(lights.sun));
    let (earth_az_deg, earth_el_deg) = az_el_deg(&nalgebra::Vector3::from(lights.earth));
    if opts.annotate {
        let lines = [
            format!("{} UTC", format_utc(epoch)),
            format!(
                "Sun el {sun_el_deg:.2}°, az {sun_az_deg:.1}°   Earth el {earth_el_deg:.2}°, az \
                 {earth_az_deg:.1}°"
            ),
            placed.what.clone(),
        ];
        let ticks = azimuth_ticks(camera, &az_el_deg, opts.width, opts.height);
        crate::illum::plot::annotate_frame(&mut rgb, (opts.width, opts.height), &lines, &ticks)?;
    }
    let text = [
        (
            "Software",
            format!("penumbra {}", env!("CARGO_PKG_VERSION")),
        ),
        ("penumbra:epoch_utc", crate::ephem::time::format_iso(epoch)),
        ("penumbra:sun_elevation_deg", format!("{sun_el_deg:.4}")),
        ("penumbra:sun_azimuth_deg", format!("{sun_az_deg:.4}")),
        ("penumbra:earth_elevation_deg", format!("{earth_el_deg:.4}")),
        ("penumbra:earth_azimuth_deg", format!("{earth_az_deg:.4}")),
        ("penumbra:camera", placed.what.clone()),
        ("penumbra:brdf", format!("{:?}", job.brdf)),
        ("penumbra:exposure", format!("{exposure:.6e}")),
        ("penumbra:exposure_mode", opts.exposure.to_string()),
    ];
    let png = crate::render::encode_png(&rgb, opts.width, opts.height, &text)?;
    let numbered = |p: &Path| match index {
        Some(k) => crate::render::numbered_path(p, k),
        None => p.to_path_buf(),
    };
    let out = numbered(&opts.out);
    let mut written = Vec::new();
    if let Some(tif) = &opts.out_radiance {
        let items: Vec<(&str, &str)> = text.iter().map(|(k, v)| (*k, v.as_str())).collect();
        let bytes = crate::render::encode_f32_tiff(
            &crate::render::radiance_image(&samples),
            opts.width,
            opts.height,
            &items,
        )?;
        let tif = numbered(tif);
        crate::output::write_bytes_atomic(&tif, &bytes)?;
        written.push(tif);
    }
    crate::output::write_bytes_atomic(&out, &png)?;
    written.push(out);
    Ok((written, sun_el_deg))
}

/// What [`render_frames`] did: for provenance.
#[derive(Debug, Clone)]
pub struct RenderRun {
    /// The files written, in order (each frame's radiance TIFF, then its PNG).
    pub files: Vec<PathBuf>,
    /// The backend that ran (`cpu` or `gpu (adapter)`).
    pub backend: String,
    /// The kernels read.
    pub kernels: Vec<crate::ephem::kernels::KernelFile>,
    /// The DEM layers (paths or the synthetic DEM's description).
    pub dem_layers: Vec<String>,
    /// The frames' epochs.
    pub epochs: Vec<Epoch>,
}

/// Renders `frames` (epoch, camera pose) with the image, BRDF, exposure, backend, terrain,
/// kernel and output options of `opts`: one frame to `opts.out`, or numbered frames
/// `<stem>_0000.png`, ... Every camera is checked before any file is written.
pub fn render_frames(
    opts: &RenderOptions,
    frames: &[(Epoch, crate::render::path::CameraPose)],
) -> anyhow::Result<RenderRun> {
    render_frames_kept(opts, frames, &mut NoFrameStore)
}

/// Frames of a sequence that a resumable run has already rendered (each frame depends on its own
/// epoch and pose only, so a frame rendered by a killed run is the frame a whole run renders).
pub trait FrameStore {
    /// The files of frame `k`, when it is already rendered (and still intact).
    fn done(&mut self, k: usize) -> Option<Vec<PathBuf>>;
    /// Frame `k` has been rendered into `files`.
    fn finished(&mut self, k: usize, files: &[PathBuf]) -> anyhow::Result<()>;
}

/// A store that keeps nothing.
pub struct NoFrameStore;

impl FrameStore for NoFrameStore {
    fn done(&mut self, _k: usize) -> Option<Vec<PathBuf>> {
        None
    }
    fn finished(&mut self, _k: usize, _files: &[PathBuf]) -> anyhow::Result<()> {
        Ok(())
    }
}

/// A frame's lights from an epoch's.
fn frame_lights(l: &crate::model::EpochLights) -> crate::render::Lights {
    crate::render::Lights {
        sun: l.sun,
        sun_radius_rad: l.sun_radius_rad,
        earth: l.earth,
        earth_radius_rad: l.earth_radius_rad,
    }
}

/// [`render_frames`], skipping the frames `store` has and telling it each frame rendered.
pub fn render_frames_kept(
    opts: &RenderOptions,
    frames: &[(Epoch, crate::render::path::CameraPose)],
    store: &mut dyn FrameStore,
) -> anyhow::Result<RenderRun> {
    let t0 = std::time::Instant::now();
    if frames.is_empty() {
        anyhow::bail!("no frames to render");
    }
    let brdf = check_look(&opts.look(), frames.len())?;
    let prov_path = provenance_path(&opts.out);
    let mut outputs: Vec<(&str, &Path)> = vec![("--out", &opts.out)];
    if let Some(r) = &opts.out_radiance {
        outputs.push(("--out-radiance", r));
    }
    for (flag, path) in &outputs {
        crate::output::guard::check_output_target(flag, path, false).map_err(anyhow::Error::msg)?;
    }
    outputs.push(("the provenance file", &prov_path));
    crate::output::guard::check_distinct_outputs(&outputs).map_err(anyhow::Error::msg)?;
    let abcorr = opts.abcorr;
    let (stack, dem_layers) = opts.terrain.load()?;
    let mut grid = crate::model::MapGrid::new(&stack)?;
    grid.warn_if_clipped();
    // A frame may look at any terrain of the grid, far field included: shade all of it.
    grid.hf.window = None;
    let hf = &grid.hf;
    let placed = frames
        .iter()
        .map(|(_, pose)| place_camera(pose, &stack, hf))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let epochs: Vec<Epoch> = frames.iter().map(|(e, _)| *e).collect();
    let kernels = opts.kernels.load()?;
    let lights_all = crate::model::epoch_lights(&grid, &kernels, &epochs, abcorr)?;
    // Resolved once: `auto` warns once and the GPU device + pipelines are built once.
    let backend = crate::compute::resolve(opts.backend, crate::compute::OnGpu::Preferred)?;
    let fractions = crate::compute::render::SceneFractions::new(&backend, hf)?;
    let job = FrameJob {
        opts,
        hf,
        brdf,
        backend: &backend,
        fractions,
    };
    let many = frames.len() > 1;
    // One exposure for all frames of a sequence: from a pre-render of every frame at a quarter of
    // the width (at least 128 px, at most the frame's; a single frame sets its own from its
    // full-size samples).
    let exposure = match opts.exposure {
        crate::render::Exposure::Fixed(e) => Some(e),
        crate::render::Exposure::Auto => None,
        crate::render::Exposure::Sequence if !many => None,
        crate::render::Exposure::Sequence => {
            let w = opts.width.min((opts.width / 4).max(128));
            let h = ((u64::from(opts.height) * u64::from(w) / u64::from(opts.width)) as u32).max(1);
            let mut brightest: Option<f64> = None;
            for (l, placed) in lights_all.iter().zip(&placed) {
                let scene = job.fractions.scene(frame_lights(l))?.with_brdf(job.brdf);
                let samples = crate::compute::render::render_samples(
                    job.backend,
                    &scene,
                    &placed.camera,
                    w,
                    h,
                )?;
                if let Some(p99) = crate::render::terrain_radiance_p99(&samples) {
                    brightest = Some(brightest.map_or(p99, |b| b.max(p99)));
                }
            }
            Some(crate::render::sequence_exposure(brightest))
        }
    };
    let progress = super::progress_bar(
        frames.len(),
        "rendering {bar:40} {pos}/{len} frames, eta {eta}",
    );
    if !many {
        progress.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let mut files = Vec::new();
    for (k, ((epoch, l), placed)) in epochs.iter().zip(&lights_all).zip(&placed).enumerate() {
        if let Some(kept) = store.done(k) {
            progress.inc(1);
            files.extend(kept);
            continue;
        }
        let (written, sun_el_deg) = render_one_frame(
            &job,
            placed,
            *epoch,
            frame_lights(l),
            many.then_some(k),
            exposure,
        )?;
        store.finished(k, &written)?;
        progress.inc(1);
        if let (false, Some(out)) = (many, written.last()) {
            crate::note!(
                "penumbra: rendered {} x {} px at {} (Sun elevation {sun_el_deg:.3} deg) to {} in {:.2} s",
                opts.width,
                opts.height,
                format_utc(*epoch),
                out.display(),
                t0.elapsed().as_secs_f64()
            );
        }
        files.extend(written);
    }
    progress.finish_and_clear();
    if many {
        crate::note!(
            "penumbra: rendered {} frames of {} x {} px to {} ... {} in {:.2} s",
            frames.len(),
            opts.width,
            opts.height,
            crate::render::numbered_path(&opts.out, 0).display(),
            crate::render::numbered_path(&opts.out, frames.len() - 1).display(),
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(RenderRun {
        files,
        backend: backend.describe(),
        kernels: kernels.files.clone(),
        dem_layers,
        epochs,
    })
}

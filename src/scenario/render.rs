//! The `[render]` table of a scenario: `[[render.views]]` and `[[render.paths]]`, and the typed
//! render requests they make.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::ephem::AbCorr;

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
    pub camera: Option<crate::products::render::CameraKind>,
    /// The keyframes (at least 2, times strictly increasing).
    pub keyframes: Vec<KeyframeSpec>,
    /// Number of frames, evenly spaced from the first keyframe to the last (or `step`).
    pub frames: Option<usize>,
    /// Time between frames (e.g. `10m`), from the first keyframe (or `frames`).
    pub step: Option<String>,
    /// Image width, pixels (`width_px`, as the command line's `--width-px`, or `width`).
    #[serde(alias = "width_px")]
    pub width: Option<u32>,
    /// Image height, pixels (`height_px` or `height`).
    #[serde(alias = "height_px")]
    pub height: Option<u32>,
    /// `hapke` (default) or `lambert`.
    pub brdf: Option<crate::products::render::BrdfChoice>,
    /// Lambert albedo (with `brdf = "lambert"`).
    pub albedo: Option<f64>,
    /// Exposure: `"sequence"` (default: one for all frames), `"auto"` (per frame) or a number in
    /// 1/(W m^-2 sr^-1).
    pub exposure: Option<crate::render::Exposure>,
    /// Also write float radiance TIFFs under `render/` with this name (numbered).
    pub out_radiance: Option<String>,
    /// Draw the epoch, the Sun's and the Earth's elevation and azimuth and azimuth ticks into
    /// the frames (default `true`; the command line's `--no-annotation` is `false`).
    pub annotate: Option<bool>,
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
    #[serde(alias = "observer_height_m")]
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
        let orbit = self.camera == Some(crate::products::render::CameraKind::Orbit);
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
                        fov_deg: kf.fov_deg.unwrap_or(crate::products::render::DEFAULT_FOV_DEG),
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
                        height_m: kf.height_m.unwrap_or(crate::DEFAULT_OBSERVER_HEIGHT_M),
                        look_az_deg: kf.look_az_deg.unwrap_or(0.0),
                        look_el_deg: kf.look_el_deg.unwrap_or(0.0),
                        fov_deg: kf.fov_deg.unwrap_or(crate::products::render::DEFAULT_FOV_DEG),
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
    pub(super) fn as_view(&self) -> ViewSpec {
        let k0 = self.keyframes.first();
        let g = |f: fn(&KeyframeSpec) -> Option<f64>| k0.and_then(f);
        ViewSpec {
            out: self.out.clone(),
            camera: self.camera,
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
            brdf: self.brdf,
            albedo: self.albedo,
            exposure: self.exposure,
            out_radiance: self.out_radiance.clone(),
            annotate: self.annotate,
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
    pub camera: Option<crate::products::render::CameraKind>,
    /// Camera latitude, degrees.
    pub lat_deg: f64,
    /// Camera east longitude, degrees.
    pub lon_deg: f64,
    /// Site camera: height above the ground, metres.
    #[serde(alias = "observer_height_m")]
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
    /// Image width, pixels (`width_px`, as the command line's `--width-px`, or `width`).
    #[serde(alias = "width_px")]
    pub width: Option<u32>,
    /// Image height, pixels (`height_px` or `height`).
    #[serde(alias = "height_px")]
    pub height: Option<u32>,
    /// `hapke` (default) or `lambert`.
    pub brdf: Option<crate::products::render::BrdfChoice>,
    /// Lambert albedo (with `brdf = "lambert"`).
    pub albedo: Option<f64>,
    /// Exposure: `"sequence"` (default: one for all frames), `"auto"` (per frame) or a number in
    /// 1/(W m^-2 sr^-1).
    pub exposure: Option<crate::render::Exposure>,
    /// Also write the float radiance TIFF under `render/` with this name.
    pub out_radiance: Option<String>,
    /// Draw the epoch, the Sun's and the Earth's elevation and azimuth and azimuth ticks into
    /// the frame (default `true`; the command line's `--no-annotation` is `false`).
    pub annotate: Option<bool>,
}

impl ViewSpec {
    /// The camera of this view (the defaults of `penumbra render` where a key is absent).
    pub(super) fn camera(&self) -> crate::products::render::CameraSpec {
        use crate::products::render::CameraSpec;
        let defaults = CameraSpec::site(self.lat_deg, self.lon_deg);
        CameraSpec {
            kind: self.camera.unwrap_or_default(),
            height_m: self.height_m.unwrap_or(defaults.height_m),
            look_az_deg: self.look_az_deg.unwrap_or(defaults.look_az_deg),
            look_el_deg: self.look_el_deg.unwrap_or(defaults.look_el_deg),
            altitude_km: self.altitude_km,
            target_lat_deg: self.target_lat_deg,
            target_lon_deg: self.target_lon_deg,
            fov_deg: self.fov_deg.unwrap_or(defaults.fov_deg),
            ..defaults
        }
    }

    /// The epochs of this view (`utc`, or `start`/`stop`/`step`).
    pub(super) fn epochs(&self) -> anyhow::Result<crate::model::Epochs> {
        Ok(crate::model::Epochs::parse_required(
            self.utc.as_deref(),
            self.start.as_deref(),
            self.stop.as_deref(),
            self.step.as_deref(),
        )?)
    }

    /// The image, BRDF and output options of this view, with the scenario's terrain, kernels
    /// and aberration correction; outputs under `render_dir`.
    pub(super) fn render_look(&self) -> crate::products::render::RenderLook {
        use crate::products::render as r;
        r::RenderLook {
            width: self.width.unwrap_or(r::DEFAULT_WIDTH_PX),
            height: self.height.unwrap_or(r::DEFAULT_HEIGHT_PX),
            brdf: self.brdf.unwrap_or_default(),
            albedo: self.albedo,
            exposure: self.exposure.unwrap_or_default(),
        }
    }

    pub(super) fn render_options(
        &self,
        terrain: crate::products::TerrainSource,
        kernels: crate::products::KernelSource,
        abcorr: AbCorr,
        render_dir: &Path,
    ) -> crate::products::render::RenderOptions {
        use crate::products::render as r;
        r::RenderOptions {
            terrain,
            width: self.width.unwrap_or(r::DEFAULT_WIDTH_PX),
            height: self.height.unwrap_or(r::DEFAULT_HEIGHT_PX),
            brdf: self.brdf.unwrap_or_default(),
            albedo: self.albedo,
            exposure: self.exposure.unwrap_or_default(),
            out: render_dir.join(&self.out),
            out_radiance: self.out_radiance.as_ref().map(|r| render_dir.join(r)),
            abcorr,
            backend: crate::gpu::Backend::Auto,
            kernels,
            annotate: self.annotate.unwrap_or(true),
        }
    }
}

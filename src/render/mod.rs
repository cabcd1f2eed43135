//! A CPU reference renderer: the terrain height field seen from a camera at one epoch, lit by
//! the Sun and by earthshine, tone mapped to an 8-bit sRGB PNG.
//!
//! Everything happens in model space (see [`crate::terrain::HeightField`]): each pixel's view ray
//! is cast through the height field's maximum mipmap to its exact first hit on the bilinear
//! surface ([`cast`]; uniform stepping stays available as [`TraceMethod::Uniform`]), and the hit
//! point is shaded with a [`Brdf`] (Hapke 2012 with lunar parameters, or Lambert with albedo
//! [`DEFAULT_ALBEDO`]; see [`brdf`]). The Sun's and the Earth's visible fractions come from a
//! shadow engine run ONCE per frame for the whole grid
//! ([`crate::shadow::Engine::visible_fraction`]) and are looked up bilinearly at the hit point.
//! Earthshine models the Earth as a Lambert sphere of Bond albedo [`EARTH_BOND_ALBEDO`]
//! ([`Lights::earth_irradiance_w_m2`]). The GPU twin is `crate::gpu::render`; see
//! docs/render.md for the assumptions and what is missing.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::SOLAR_CONSTANT_W_M2;
use crate::shadow::{Engine, ShadowError};
use crate::terrain::HeightField;

pub mod brdf;
pub use brdf::{Brdf, HapkeParams};
pub mod cast;
pub mod path;
pub use cast::{RayCaster, TraceMethod};

/// Lambert albedo of the regolith (a typical mean for the lunar highlands).
pub const DEFAULT_ALBEDO: f64 = 0.12;

/// The Earth's Bond albedo, 0.306 (NASA Earth Fact Sheet, Williams 2024; CERES-era value ~0.29-0.31).
pub const EARTH_BOND_ALBEDO: f64 = 0.306;

/// Irradiance of a full Earth at the Moon's mean distance (384,400 km), W/m²: a Lambert sphere
/// of Bond albedo `A` has geometric albedo `p = 2A/3`, so `E = p * S * (R_earth / d)^2` =
/// 0.204 * 1360.8 * (6378.1 / 384400)^2 = 0.0764 W/m² ([`Lights::earth_irradiance_w_m2`] uses
/// the actual distance and phase).
pub const FULL_EARTH_IRRADIANCE_W_M2: f64 = 0.076_4;

/// Errors of the renderer.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The camera parameters are not usable (field of view, position, direction).
    #[error("bad camera: {0}")]
    BadCamera(String),
    /// A camera path is not usable (too few keyframes, times not increasing, mixed kinds).
    #[error("bad camera path: {0}")]
    BadPath(String),
    /// The image has a zero or absurd size.
    #[error("bad image size {width} x {height} px: both must be in 1..=16384")]
    BadImageSize {
        /// Width asked for, pixels.
        width: u32,
        /// Height asked for, pixels.
        height: u32,
    },
    /// A shadow engine failed.
    #[error(transparent)]
    Shadow(#[from] ShadowError),
    /// PNG encoding failed.
    #[error("encoding PNG: {0}")]
    Png(String),
    /// TIFF encoding failed.
    #[error("encoding TIFF: {0}")]
    Tiff(String),
}

/// Result alias for the renderer.
pub type Result<T, E = RenderError> = std::result::Result<T, E>;

/// A pinhole camera in model space.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    /// Position, model space, metres.
    pub pos_model_m: Vector3<f64>,
    /// Unit view direction, model space.
    pub forward_model: Vector3<f64>,
    /// Unit right vector, model space.
    pub right_model: Vector3<f64>,
    /// Unit up vector of the image, model space.
    pub up_model: Vector3<f64>,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
}

impl Camera {
    /// A camera at `pos_model_m` looking at azimuth / elevation (deg, azimuth from north
    /// clockwise) in a local ENU frame whose axes in model space are the columns of
    /// `model_from_enu`; the image's up is the local up.
    pub fn from_az_el_deg(
        pos_model_m: Vector3<f64>,
        model_from_enu: &Matrix3<f64>,
        look_az_deg: f64,
        look_el_deg: f64,
        fov_deg: f64,
    ) -> Result<Self> {
        if !(fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(RenderError::BadCamera(format!(
                "field of view {fov_deg} deg must be in (0, 180)"
            )));
        }
        if !(look_el_deg.abs() < 89.9 && look_az_deg.is_finite()) {
            return Err(RenderError::BadCamera(format!(
                "look elevation {look_el_deg} deg must be in (-89.9, 89.9) and the azimuth finite"
            )));
        }
        if !pos_model_m.iter().all(|v| v.is_finite()) {
            return Err(RenderError::BadCamera("position is not finite".into()));
        }
        let forward = model_from_enu * crate::frames::enu_from_az_el_deg(look_az_deg, look_el_deg);
        let up_hint = model_from_enu * Vector3::new(0.0, 0.0, 1.0);
        let right = forward.cross(&up_hint).normalize();
        let up = right.cross(&forward).normalize();
        Ok(Camera {
            pos_model_m,
            forward_model: forward.normalize(),
            right_model: right,
            up_model: up,
            fov_deg,
        })
    }

    /// A camera at `pos_model_m` looking at `target_model_m`, the image's up as close as possible
    /// to `up_hint_model` (e.g. local north for an orbital camera looking down).
    pub fn look_at(
        pos_model_m: Vector3<f64>,
        target_model_m: Vector3<f64>,
        up_hint_model: Vector3<f64>,
        fov_deg: f64,
    ) -> Result<Self> {
        if !(fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(RenderError::BadCamera(format!(
                "field of view {fov_deg} deg must be in (0, 180)"
            )));
        }
        if !(pos_model_m
            .iter()
            .chain(target_model_m.iter())
            .all(|v| v.is_finite()))
        {
            return Err(RenderError::BadCamera("position is not finite".into()));
        }
        let d = target_model_m - pos_model_m;
        if d.norm() < 1e-6 {
            return Err(RenderError::BadCamera(
                "the camera is at its target point".into(),
            ));
        }
        let forward = d.normalize();
        let mut right = forward.cross(&up_hint_model);
        if right.norm() < 1e-9 {
            // Looking along the hint: take any perpendicular.
            let alt = if forward.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            right = forward.cross(&alt);
        }
        let right = right.normalize();
        Ok(Camera {
            pos_model_m,
            forward_model: forward,
            right_model: right,
            up_model: right.cross(&forward).normalize(),
            fov_deg,
        })
    }

    /// Unit ray direction (model space) through the centre of pixel (`px_row`, `px_col`) of a
    /// `width` x `height` image (row 0 at the top).
    pub fn ray_dir(&self, px_row: u32, px_col: u32, width: u32, height: u32) -> Vector3<f64> {
        let t = (self.fov_deg.to_radians() / 2.0).tan();
        let u = (2.0 * (f64::from(px_col) + 0.5) / f64::from(width) - 1.0) * t;
        let v = (1.0 - 2.0 * (f64::from(px_row) + 0.5) / f64::from(height)) * t * f64::from(height)
            / f64::from(width);
        (self.forward_model + u * self.right_model + v * self.up_model).normalize()
    }
}

/// The light sources of a frame, model space.
#[derive(Debug, Clone, Copy)]
pub struct Lights {
    /// Unit vector to the Sun.
    pub sun: [f64; 3],
    /// The Sun's angular radius, radians.
    pub sun_radius_rad: f64,
    /// Unit vector to the Earth.
    pub earth: [f64; 3],
    /// The Earth's angular radius, radians.
    pub earth_radius_rad: f64,
}

impl Lights {
    /// Earthshine irradiance on a surface facing the Earth, W/m²: the Earth as a Lambert sphere
    /// of Bond albedo [`EARTH_BOND_ALBEDO`] (geometric albedo `p = 2A/3`) lit by the solar
    /// constant `S`: `E = p * S * sin^2(rho) * Phi(alpha)`, with `sin(rho) = R_earth / d` from the
    /// Earth's angular radius and the Lambert-sphere phase law
    /// `Phi(alpha) = (sin alpha + (pi - alpha) cos alpha) / pi` (Russell 1916), where the phase
    /// angle alpha (Sun-Earth-Moon) is taken as `pi - elongation` (Sun-Moon-Earth angle), exact
    /// to the Moon's parallax (~0.15 deg).
    pub fn earth_irradiance_w_m2(&self) -> f64 {
        let cos_elong = dot(self.sun, self.earth).clamp(-1.0, 1.0);
        let alpha = std::f64::consts::PI - cos_elong.acos();
        let phi =
            (alpha.sin() + (std::f64::consts::PI - alpha) * alpha.cos()) / std::f64::consts::PI;
        let p = 2.0 / 3.0 * EARTH_BOND_ALBEDO;
        p * SOLAR_CONSTANT_W_M2 * self.earth_radius_rad.sin().powi(2) * phi.max(0.0)
    }
}

/// What a view ray sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sample {
    /// Terrain with its radiance, W/(m² sr).
    Terrain {
        /// Reflected radiance, W/(m² sr).
        radiance_w_m2_sr: f32,
    },
    /// The Sun's disc.
    Sun,
    /// The day side of the Earth's disc.
    Earth,
    /// The night side of the Earth's disc (the part of the disc facing away from the Sun).
    EarthNight,
    /// Black sky.
    Sky,
}

/// A height field with its lights and per-cell visible fractions, ready to render.
pub struct Scene<'a> {
    hf: &'a HeightField,
    lights: Lights,
    sun_fraction: Vec<f32>,
    earth_fraction: Vec<f32>,
    brdf: Brdf,
    caster: RayCaster<'a>,
    trace_method: TraceMethod,
}

impl<'a> Scene<'a> {
    /// Runs `engine` once for the Sun and once for the Earth (ground level, observer height 0)
    /// over the whole grid.
    pub fn new(hf: &'a HeightField, lights: Lights, engine: Engine) -> Result<Self> {
        let sun_fraction = engine.visible_fraction(hf, 0.0, lights.sun, lights.sun_radius_rad)?;
        let earth_fraction =
            engine.visible_fraction(hf, 0.0, lights.earth, lights.earth_radius_rad)?;
        Ok(Self::with_fractions(
            hf,
            lights,
            sun_fraction,
            earth_fraction,
        ))
    }

    /// A scene with given per-cell visible fractions (row-major like `hf.z_m`).
    pub fn with_fractions(
        hf: &'a HeightField,
        lights: Lights,
        sun_fraction: Vec<f32>,
        earth_fraction: Vec<f32>,
    ) -> Self {
        Scene {
            hf,
            lights,
            sun_fraction,
            earth_fraction,
            brdf: Brdf::Lambert {
                albedo: DEFAULT_ALBEDO,
            },
            caster: RayCaster::new(hf),
            trace_method: TraceMethod::default(),
        }
    }

    /// The same scene shaded with `brdf` (the default of [`Scene::new`] and
    /// [`Scene::with_fractions`] is Lambert with [`DEFAULT_ALBEDO`]).
    pub fn with_brdf(mut self, brdf: Brdf) -> Self {
        self.brdf = brdf;
        self
    }

    /// The BRDF of the scene.
    pub fn brdf(&self) -> &Brdf {
        &self.brdf
    }

    /// The same scene tracing view rays with `method` (default: [`TraceMethod::MaxMipmap`]).
    pub fn with_trace_method(mut self, method: TraceMethod) -> Self {
        self.trace_method = method;
        self
    }

    /// The ray caster (height field, its maximum mipmap and height range).
    pub fn caster(&self) -> &RayCaster<'a> {
        &self.caster
    }

    /// The per-cell visible fractions of the Sun and of the Earth (row-major like `hf.z_m`).
    pub fn fractions(&self) -> (&[f32], &[f32]) {
        (&self.sun_fraction, &self.earth_fraction)
    }

    /// The Lambert albedo ([`DEFAULT_ALBEDO`] when the BRDF is Hapke).
    pub fn albedo(&self) -> f64 {
        match self.brdf {
            Brdf::Lambert { albedo } => albedo,
            Brdf::Hapke(_) => DEFAULT_ALBEDO,
        }
    }

    /// The lights of the scene.
    pub fn lights(&self) -> &Lights {
        &self.lights
    }

    /// Bilinear terrain height (m) at model x/y; `None` outside the grid or next to a hole.
    pub fn surface_z_m(&self, x_m: f64, y_m: f64) -> Option<f64> {
        bilinear(self.hf, &self.hf.z_m, x_m, y_m, false)
    }

    /// Unit surface normal at model x/y from central differences (one cell each side).
    fn normal_at(&self, x_m: f64, y_m: f64) -> Option<Vector3<f64>> {
        let d = self.hf.px_m;
        let zx0 = self.surface_z_m(x_m - d, y_m);
        let zx1 = self.surface_z_m(x_m + d, y_m);
        let zy0 = self.surface_z_m(x_m, y_m - d);
        let zy1 = self.surface_z_m(x_m, y_m + d);
        let z = self.surface_z_m(x_m, y_m)?;
        // One-sided differences at the grid edge.
        let dzdx = match (zx0, zx1) {
            (Some(a), Some(b)) => (b - a) / (2.0 * d),
            (None, Some(b)) => (b - z) / d,
            (Some(a), None) => (z - a) / d,
            (None, None) => 0.0,
        };
        let dzdy = match (zy0, zy1) {
            (Some(a), Some(b)) => (b - a) / (2.0 * d),
            (None, Some(b)) => (b - z) / d,
            (Some(a), None) => (z - a) / d,
            (None, None) => 0.0,
        };
        Some(Vector3::new(-dzdx, -dzdy, 1.0).normalize())
    }

    /// Radiance (W/(m² sr)) of the terrain at model x/y towards the unit vector `to_viewer`:
    /// `f(i_sun, e, g_sun) * S * f_sun * cos i_sun + f(i_earth, e, g_earth) * E_earth * f_earth *
    /// cos i_earth` with `f` the scene's BRDF ([`Brdf::per_sr`]), `S` the solar constant and
    /// `E_earth` the earthshine irradiance ([`Lights::earth_irradiance_w_m2`]).
    fn radiance_toward(&self, x_m: f64, y_m: f64, to_viewer: &Vector3<f64>) -> Option<f64> {
        let n = self.normal_at(x_m, y_m)?;
        let f_sun = bilinear(self.hf, &self.sun_fraction, x_m, y_m, true).unwrap_or(0.0);
        let f_earth = bilinear(self.hf, &self.earth_fraction, x_m, y_m, true).unwrap_or(0.0);
        let sun = Vector3::from(self.lights.sun);
        let earth = Vector3::from(self.lights.earth);
        let cos_e = n.dot(to_viewer);
        let mut l = 0.0;
        for (dir, e_normal, frac) in [
            (sun, SOLAR_CONSTANT_W_M2, f_sun),
            (earth, self.lights.earth_irradiance_w_m2(), f_earth),
        ] {
            let cos_i = n.dot(&dir);
            if cos_i > 0.0 && frac > 0.0 {
                let f = self.brdf.per_sr(cos_i, cos_e, dir.dot(to_viewer));
                l += f * e_normal * frac * cos_i;
            }
        }
        Some(l)
    }

    /// The first terrain crossing of the ray `origin + t * dir` (t > 0): model point, or `None`
    /// (by the scene's [`TraceMethod`], see [`cast`]).
    fn trace(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Option<Vector3<f64>> {
        self.caster.cast(origin, dir, self.trace_method)
    }

    /// What the ray `origin + t * dir` sees: terrain radiance, the Sun's or the Earth's disc, or
    /// black sky.
    pub fn sample(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Sample {
        if let Some(p) = self.trace(origin, dir)
            && let Some(l) = self.radiance_toward(p.x, p.y, &(-dir))
        {
            return Sample::Terrain {
                radiance_w_m2_sr: l as f32,
            };
        }
        let ang = |v: [f64; 3]| dir.dot(&Vector3::from(v)).clamp(-1.0, 1.0).acos();
        if ang(self.lights.sun) <= self.lights.sun_radius_rad {
            Sample::Sun
        } else if ang(self.lights.earth) <= self.lights.earth_radius_rad {
            if self.earth_point_is_day(dir) {
                Sample::Earth
            } else {
                Sample::EarthNight
            }
        } else {
            Sample::Sky
        }
    }

    /// Whether the point of the Earth's disc seen along the unit `dir` is on the day side: the
    /// ray meets the Earth's sphere (centre along `lights.earth` at unit distance, radius
    /// `sin(earth_radius_rad)`) at `t = d.e - sqrt((d.e)^2 - cos^2 rho)`, where the outward normal
    /// `n = (t d - e) / sin rho` is lit when `n . sun > 0` (the Sun's direction from the Earth
    /// equals the one from the Moon within the Moon's parallax, ~0.15 deg).
    fn earth_point_is_day(&self, dir: &Vector3<f64>) -> bool {
        let e = Vector3::from(self.lights.earth);
        let (sin_r, cos_r) = self.lights.earth_radius_rad.sin_cos();
        let de = dir.dot(&e);
        let disc = (de * de - cos_r * cos_r).max(0.0);
        let t = de - disc.sqrt();
        let n = (t * dir - e) / sin_r;
        n.dot(&Vector3::from(self.lights.sun)) > 0.0
    }

    /// Renders a `width` x `height` image (row-major, row 0 at the top), one ray per pixel centre,
    /// rows in parallel (rayon).
    pub fn render(&self, camera: &Camera, width: u32, height: u32) -> Result<Vec<Sample>> {
        check_size(width, height)?;
        Ok((0..height * width)
            .into_par_iter()
            .map(|i| {
                let (r, c) = (i / width, i % width);
                self.sample(&camera.pos_model_m, &camera.ray_dir(r, c, width, height))
            })
            .collect())
    }
}

/// Bilinear terrain height (m) of `hf` at model x/y; `None` outside the grid or next to a hole.
pub fn terrain_z_m(hf: &HeightField, x_m: f64, y_m: f64) -> Option<f64> {
    bilinear(hf, &hf.z_m, x_m, y_m, false)
}

/// The terrain radiance of each sample, W/(m² sr); 0 for the sky, the Sun's and the Earth's
/// discs (row-major like the samples).
pub fn radiance_image(samples: &[Sample]) -> Vec<f32> {
    samples
        .iter()
        .map(|s| match s {
            Sample::Terrain { radiance_w_m2_sr } => *radiance_w_m2_sr,
            // Sky (and the discs of the Sun and the Earth): no terrain, not a dark terrain.
            _ => f32::NAN,
        })
        .collect()
}

/// Encodes a `width` x `height` f32 image (row-major, row 0 at the top) as a single-band 32-bit
/// float TIFF: NaN declared as nodata (GDAL_NODATA, the sky), the band's description and unit
/// (W m-2 sr-1) and `items` (the frame's epoch, camera, …) in GDAL_METADATA.
pub fn encode_f32_tiff(
    values: &[f32],
    width: u32,
    height: u32,
    items: &[(&str, &str)],
) -> Result<Vec<u8>> {
    let err = |e: tiff::TiffError| RenderError::Tiff(e.to_string());
    let xml = crate::terrain::gdal_metadata_xml_with_band(
        items,
        crate::terrain::BandInfo {
            description: "terrain radiance toward the camera (NaN: sky, no terrain)",
            unit: "W m-2 sr-1",
        },
    );
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut enc = tiff::encoder::TiffEncoder::new(&mut buf).map_err(err)?;
        let mut image = enc
            .new_image::<tiff::encoder::colortype::Gray32Float>(width, height)
            .map_err(err)?;
        let tags = image.encoder();
        tags.write_tag(tiff::tags::Tag::Unknown(42112), xml.as_str())
            .map_err(err)?;
        tags.write_tag(tiff::tags::Tag::Unknown(42113), "nan")
            .map_err(err)?;
        image.write_data(values).map_err(err)?;
    }
    Ok(buf.into_inner())
}

/// The path of frame `index` of a sequence: `<dir>/<stem>_<index:04>.<ext>`.
pub fn numbered_path(path: &std::path::Path, index: usize) -> std::path::PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}_{index:04}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{index:04}"),
    };
    path.with_file_name(name)
}

/// Checks an image size.
pub fn check_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 || width > 16384 || height > 16384 {
        return Err(RenderError::BadImageSize { width, height });
    }
    Ok(())
}

/// The dimmest daylight an automatic exposure is set for, W m⁻² sr⁻¹: a level Lambert surface of
/// albedo 0.12 (the Moon's typical normal albedo) under the Sun 1° high at 1 au,
/// `0.12 · S0 · sin 1° / π` ≈ 0.91. An exposure never brightens a scene beyond what it would give
/// this surface, so a frame lit only by the Earth (≈ 10⁻⁶–10⁻⁴ W m⁻² sr⁻¹) stays dark.
pub const DAYLIGHT_FLOOR_RADIANCE_W_M2_SR: f64 =
    0.12 * crate::SOLAR_CONSTANT_W_M2 * 0.017_452_406_437_283_51 / std::f64::consts::PI;

/// Exposed radiance `x` at which an automatic exposure puts a frame's 99th-percentile lit terrain
/// radiance (≈ 90 % of white, level 229 after the tone curve and sRGB).
pub const AUTO_EXPOSED_P99: f64 = 1.4;

/// White point of the tone curve: `x = exposure · L` at or above it is white.
pub const TONE_WHITE_POINT: f64 = 2.0;

/// How the radiance of a frame becomes grey levels.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Exposure {
    /// One exposure for every frame of a run (the default): the brightest frame's 99th-percentile
    /// lit terrain radiance maps to `x` = [`AUTO_EXPOSED_P99`], never brighter than for
    /// [`DAYLIGHT_FLOOR_RADIANCE_W_M2_SR`]. Brightness is comparable between the frames of a
    /// sequence (no flicker), and a frame lit only by the Earth is dark.
    #[default]
    Sequence,
    /// Per frame: each frame's own 99th percentile maps to `x` = [`AUTO_EXPOSED_P99`], with no
    /// floor: every frame looks lit, brightness is not comparable between frames.
    Auto,
    /// A given exposure, 1/(W m⁻² sr⁻¹).
    Fixed(f64),
}

/// The exposure of a sequence whose brightest frame has 99th-percentile lit terrain radiance
/// `p99` (`None`: no terrain lit in any frame), 1/(W m⁻² sr⁻¹).
pub fn sequence_exposure(p99: Option<f64>) -> f64 {
    AUTO_EXPOSED_P99 / p99.unwrap_or(0.0).max(DAYLIGHT_FLOOR_RADIANCE_W_M2_SR)
}

impl Exposure {
    /// The exposure of one frame rendered alone, 1/(W m⁻² sr⁻¹).
    pub fn value(&self, samples: &[Sample]) -> f64 {
        match self {
            Exposure::Sequence => sequence_exposure(terrain_radiance_p99(samples)),
            Exposure::Auto => auto_exposure(samples),
            Exposure::Fixed(e) => *e,
        }
    }
}

impl std::str::FromStr for Exposure {
    type Err = String;
    /// `sequence`, `auto` (or `frame`), or a number > 0 (1/(W m⁻² sr⁻¹)).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "sequence" => Ok(Exposure::Sequence),
            "auto" | "frame" => Ok(Exposure::Auto),
            t => match t.parse::<f64>() {
                Ok(e) if e > 0.0 && e.is_finite() => Ok(Exposure::Fixed(e)),
                _ => Err(format!(
                    "exposure '{s}': use sequence (one per run, the default), auto (per frame) or a number > 0 in 1/(W m-2 sr-1)"
                )),
            },
        }
    }
}

impl serde::Serialize for Exposure {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            Exposure::Fixed(e) => s.serialize_f64(*e),
            other => s.serialize_str(&other.to_string()),
        }
    }
}

/// Scenarios write `exposure = "sun"`, `"auto"` or a number.
impl<'de> serde::Deserialize<'de> for Exposure {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(f64),
            Text(String),
        }
        let text = match Raw::deserialize(d)? {
            Raw::Number(e) => e.to_string(),
            Raw::Text(t) => t,
        };
        text.parse().map_err(serde::de::Error::custom)
    }
}

impl std::fmt::Display for Exposure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Exposure::Sequence => f.write_str("sequence"),
            Exposure::Auto => f.write_str("auto"),
            Exposure::Fixed(e) => write!(f, "{e}"),
        }
    }
}

/// The 99th percentile of the lit terrain radiance of a frame, W m⁻² sr⁻¹ (`None` when no terrain
/// is lit).
pub fn terrain_radiance_p99(samples: &[Sample]) -> Option<f64> {
    let mut l: Vec<f32> = samples
        .iter()
        .filter_map(|s| match s {
            Sample::Terrain { radiance_w_m2_sr } if *radiance_w_m2_sr > 0.0 => {
                Some(*radiance_w_m2_sr)
            }
            _ => None,
        })
        .collect();
    if l.is_empty() {
        return None;
    }
    l.sort_by(f32::total_cmp);
    Some(f64::from(l[((l.len() - 1) as f64 * 0.99).round() as usize]))
}

/// Exposure (1/(W m⁻² sr⁻¹)) that maps the 99th percentile of the terrain radiance to `x` =
/// [`AUTO_EXPOSED_P99`] on the tone curve ([`tone_curve`]); 1 when no terrain is lit.
fn auto_exposure(samples: &[Sample]) -> f64 {
    terrain_radiance_p99(samples).map_or(1.0, |p99| AUTO_EXPOSED_P99 / p99)
}

/// The tone curve from exposed radiance `x = exposure · L` to linear display value in [0, 1]:
/// extended Reinhard `x (1 + x / W²) / (1 + x)` with white point `W` = [`TONE_WHITE_POINT`]. It is
/// nearly linear in the shadows and mid-tones (slope 1 at 0, 0.375 at `x` = 0.5) and rolls off to
/// white at `W`, so lit terrain keeps its shading (plain Reinhard `x/(1+x)` at the old automatic
/// exposure squeezed it into grey levels 178–205).
pub fn tone_curve(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    let w2 = TONE_WHITE_POINT * TONE_WHITE_POINT;
    (x * (1.0 + x / w2) / (1.0 + x)).min(1.0)
}

/// Tone maps samples to 8-bit sRGB (RGB, row-major): terrain grey `srgb(tone_curve(exposure ·
/// L))`, the Sun's disc near-white, the Earth's disc blue-grey, sky black.
pub fn tone_map(samples: &[Sample], exposure: f64) -> Vec<u8> {
    let mut rgb = Vec::with_capacity(samples.len() * 3);
    for s in samples {
        let px = match s {
            Sample::Terrain { radiance_w_m2_sr } => {
                let v = srgb_u8(tone_curve(exposure * f64::from(*radiance_w_m2_sr)));
                [v, v, v]
            }
            Sample::Sun => [255, 250, 230],
            Sample::Earth => [120, 140, 170],
            Sample::EarthNight => [12, 14, 20],
            Sample::Sky => [0, 0, 0],
        };
        rgb.extend_from_slice(&px);
    }
    rgb
}

/// sRGB-encoded 8-bit value of a linear display value (for tests and documentation).
pub fn srgb_level(linear: f64) -> u8 {
    srgb_u8(linear)
}

/// Cosmetic veiling glare of the Sun (PNG only, not in the radiance): when the Sun's disc is
/// visible from the camera (fraction `v` of 9 points over the disc not hidden by the terrain),
/// every pixel at angle `theta` from the Sun's centre gets `255 * v * 0.5 * (rho / theta)^1.5`
/// added (warm white), with `rho` the Sun's angular radius; pixels inside the disc are left as
/// they are. The Sun may lie outside the image: its halo still shows at the edge.
pub fn add_sun_glare(rgb: &mut [u8], scene: &Scene, camera: &Camera, width: u32, height: u32) {
    let l = scene.lights();
    let sun = Vector3::from(l.sun);
    let rho = l.sun_radius_rad;
    // A frame perpendicular to the Sun's direction for the disc sample points.
    let (u, w) = crate::frames::perpendicular_pair(&sun);
    let mut visible = 0;
    let mut total = 0;
    for (du, dw) in [
        (0.0, 0.0),
        (0.7, 0.0),
        (-0.7, 0.0),
        (0.0, 0.7),
        (0.0, -0.7),
        (0.5, 0.5),
        (-0.5, 0.5),
        (0.5, -0.5),
        (-0.5, -0.5),
    ] {
        let d = (sun + rho * (du * u + dw * w)).normalize();
        total += 1;
        if scene.trace(&camera.pos_model_m, &d).is_none() {
            visible += 1;
        }
    }
    let v = f64::from(visible) / f64::from(total);
    if v == 0.0 {
        return;
    }
    for row in 0..height {
        for col in 0..width {
            let d = camera.ray_dir(row, col, width, height);
            let theta = d.dot(&sun).clamp(-1.0, 1.0).acos();
            if theta <= rho {
                continue;
            }
            let g = v * 0.5 * (rho / theta).powf(1.5);
            let i = 3 * (row * width + col) as usize;
            for (k, tint) in [1.0, 0.97, 0.88].iter().enumerate() {
                let add = 255.0 * g * tint;
                rgb[i + k] = (f64::from(rgb[i + k]) + add).min(255.0).round() as u8;
            }
        }
    }
}

/// Encodes an RGB8 image as PNG with `text` as tEXt chunks (keyword, value).
pub fn encode_png(rgb: &[u8], width: u32, height: u32, text: &[(&str, String)]) -> Result<Vec<u8>> {
    let mut buf = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut buf, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        for (k, v) in text {
            enc.add_text_chunk((*k).to_string(), v.clone())
                .map_err(|e| RenderError::Png(e.to_string()))?;
        }
        let mut w = enc
            .write_header()
            .map_err(|e| RenderError::Png(e.to_string()))?;
        w.write_image_data(rgb)
            .map_err(|e| RenderError::Png(e.to_string()))?;
    }
    Ok(buf)
}

fn srgb_u8(linear: f64) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Ray / box intersection: the `t` interval inside the box, or `None`.
fn slab(o: &Vector3<f64>, d: &Vector3<f64>, lo: [f64; 3], hi: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if d[k].abs() < 1e-15 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
        } else {
            let a = (lo[k] - o[k]) / d[k];
            let b = (hi[k] - o[k]) / d[k];
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t1 >= t0.max(0.0)).then_some((t0, t1))
}

/// Bilinear interpolation of per-cell values at model x/y. With `skip_nan`, NaN corners are
/// left out (weights renormalised); else any NaN corner gives `None`. Outside the cell-centre
/// hull the nearest edge cells are used (clamped).
fn bilinear(hf: &HeightField, v: &[f32], x_m: f64, y_m: f64, skip_nan: bool) -> Option<f64> {
    let (r, c) = hf.row_col_from_xy(x_m, y_m);
    let (rows, cols) = (hf.rows as f64, hf.cols as f64);
    if !(r >= -0.5 && c >= -0.5 && r <= rows - 0.5 && c <= cols - 0.5) {
        return None;
    }
    let r = r.clamp(0.0, rows - 1.0);
    let c = c.clamp(0.0, cols - 1.0);
    let (r0, c0) = (r.floor() as usize, c.floor() as usize);
    let (r1, c1) = ((r0 + 1).min(hf.rows - 1), (c0 + 1).min(hf.cols - 1));
    let (fr, fc) = (r - r0 as f64, c - c0 as f64);
    let mut acc = 0.0;
    let mut wsum = 0.0;
    for (rr, cc, w) in [
        (r0, c0, (1.0 - fr) * (1.0 - fc)),
        (r0, c1, (1.0 - fr) * fc),
        (r1, c0, fr * (1.0 - fc)),
        (r1, c1, fr * fc),
    ] {
        let z = v[rr * hf.cols + cc];
        if z.is_nan() {
            if !skip_nan && w > 0.0 {
                return None;
            }
            continue;
        }
        acc += w * f64::from(z);
        wsum += w;
    }
    (wsum > 0.0).then(|| acc / wsum)
}

//! Shadow engines on the model-space height field (CPU reference implementations).
//!
//! Every engine answers two questions per cell of a [`crate::terrain::HeightField`], for an
//! observer `observer_height_m` above the cell's surface point along
//! [`HeightField::up_at`](crate::terrain::HeightField::up_at) and a light at infinity given by one
//! unit direction `light_in_model`: [`Engine::hard_mask`] (is the disc's centre visible? `1` lit,
//! `0` shadow, `255` nodata) and [`Engine::visible_fraction`] (which fraction of a uniform disc of
//! radius `angular_radius_rad` is visible? `NaN` for nodata). Engines: [`brute`] (the reference
//! ray march, and the uniform-stepping baseline), [`smap`] (hard shadows, paper 004), [`dp`]
//! (soft shadows by the DP max-mipmap search of papers 000/003, and [`dp::soft_combined`]: SMap
//! at the disc's two vertical limbs, DP only in the penumbra), [`fourier`] (Fourier-compressed
//! horizon maps, paper 001); [`accuracy`] compares them.
//!
//! Shared conventions, so that the engines agree pixel by pixel: the surface is bilinear between
//! cell centres, sampled where a ray crosses the lines joining them (a hole is no terrain); a ray
//! is blocked where the surface is strictly above it; only terrain blocks, whatever the sign of
//! the light's elevation; a ray that leaves the grid is lit, and one that would meet the sphere
//! beyond it is counted ([`lit_exits_below_sphere`]). Details: `docs/shadow.md`, "Model shared by
//! all engines"; the rule for every engine: `docs/ARCHITECTURE.md`.

pub mod accuracy;
pub mod brute;
pub mod dp;
pub mod fourier;
pub mod smap;

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::terrain::HeightField;

/// Apparent angular radius of the Sun's disc at 1 au, radians (696,000 km / 1 au = 0.2666°).
pub const SUN_ANGULAR_RADIUS_RAD: f64 = crate::SUN_RADIUS_KM / crate::AU_KM;
/// Typical apparent angular radius of the Earth's disc seen from the Moon, radians (0.95°).
pub const EARTH_ANGULAR_RADIUS_RAD: f64 = 0.0166;
/// Terrain nearer than this (horizontal, cells) to an observer placed at a DEM pixel's own
/// surface point is not sampled: the observer's own half pixel, as the per-site horizon engine
/// starts its scan at half a pixel ([`Observers::Points`]).
pub const OWN_HALF_PIXEL_CELLS: f64 = 0.5;
/// Mask value for a lit cell.
pub const MASK_LIT: u8 = 1;
/// Mask value for a shadowed cell.
pub const MASK_SHADOW: u8 = 0;
/// Mask value for a cell without data.
pub const MASK_NODATA: u8 = 255;

/// Errors of the shadow engines.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ShadowError {
    /// A result would exceed the memory budget.
    #[error("{0}")]
    Budget(String),
    /// The light direction is zero, not finite, or otherwise unusable.
    #[error("invalid light direction {light:?}: {reason}")]
    InvalidLight {
        /// The offending vector (model space).
        light: [f64; 3],
        /// Why it was rejected.
        reason: &'static str,
    },
    /// The angular radius of the disc is negative, not finite, or not below 90°.
    #[error("invalid angular radius {0} rad (must be finite, >= 0 and < pi/2)")]
    InvalidAngularRadius(f64),
    /// The observer height is negative or not finite.
    #[error("invalid observer height {0} m (must be finite and >= 0)")]
    InvalidObserverHeight(f64),
    /// A configuration parameter (sample count, mip levels) is out of range.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter {
        /// Which parameter.
        name: &'static str,
        /// Why it was rejected.
        reason: &'static str,
    },
}

/// Result alias for the shadow engines.
pub type Result<T, E = ShadowError> = std::result::Result<T, E>;

/// The shadow engines behind one interface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Engine {
    /// Brute-force ray marching (the reference); soft fraction by disc sampling
    /// ([`brute::DEFAULT_DISC_SAMPLES`] directions).
    Brute,
    /// DP maximum mipmaps (papers 000/003) for every pixel; the hard mask is `J* > 0`.
    Dp,
    /// SMap at the disc's upper and lower limbs + DP for the penumbra pixels only; the hard mask
    /// is SMap's.
    Combined,
}

impl Engine {
    /// Hard lit/shadow mask of the light disc's centre: `1` lit, `0` shadow, `255` nodata. Brute
    /// force marches the centre ray; combined takes SMap's mask (paper 004); DP says lit when no
    /// terrain lies above the centre ray (`J* >= 0`).
    pub fn hard_mask<'a>(
        self,
        hf: &HeightField,
        observers: impl Into<Observers<'a>>,
        light_in_model: [f64; 3],
    ) -> Result<Vec<u8>> {
        let (observers, light) = (observers.into(), light_in_model);
        match self {
            Engine::Brute => hard_mask_by(hf, observers, light, |dir, min_s_cells| {
                let z_max_m = max_height_m(hf);
                move |obs: &Observer| brute::ray_blocked(hf, obs, &dir, z_max_m, min_s_cells)
            }),
            Engine::Combined => hard_mask_by(hf, observers, light, |dir, _| {
                let map = smap::SMap::build(hf, dir);
                move |obs: &Observer| smap::shadowed(map.as_ref(), &dir, obs)
            }),
            Engine::Dp => hard_mask_by(hf, observers, light, |dir, min_s_cells| {
                let (mip, cfg) = (dp::MaxMipmap::new(hf), dp::DpConfig::default());
                let z_max_m = max_height_m(hf);
                move |obs: &Observer| {
                    let scene = dp::DpScene {
                        hf,
                        mip: &mip,
                        z_max_m,
                        cfg: &cfg,
                    };
                    dp::dp_cost_beyond(&scene, obs, &dir, 0.0, min_s_cells) < 0.0
                }
            }),
        }
    }

    /// Visible fraction (0..=1) of a uniform disc of angular radius `angular_radius_rad` centred
    /// on `light_in_model`; `NaN` for nodata cells.
    pub fn visible_fraction<'a>(
        self,
        hf: &HeightField,
        observers: impl Into<Observers<'a>>,
        light_in_model: [f64; 3],
        angular_radius_rad: f64,
    ) -> Result<Vec<f32>> {
        let observers = observers.into();
        match self {
            Engine::Brute => brute::visible_fraction(
                hf,
                observers,
                light_in_model,
                angular_radius_rad,
                brute::DEFAULT_DISC_SAMPLES,
            ),
            Engine::Combined => {
                dp::soft_combined(hf, observers, light_in_model, angular_radius_rad).map(|(f, _)| f)
            }
            Engine::Dp => dp::visible_fraction(
                hf,
                observers,
                light_in_model,
                angular_radius_rad,
                &dp::DpConfig::default(),
            ),
        }
    }
}

/// Validates and normalises a light direction.
pub(crate) fn unit_light(light_in_model: [f64; 3]) -> Result<Vector3<f64>> {
    let v = Vector3::from(light_in_model);
    if !v.iter().all(|c| c.is_finite()) {
        return Err(ShadowError::InvalidLight {
            light: light_in_model,
            reason: "not finite",
        });
    }
    let n = v.norm();
    if n.is_nan() || n <= 1e-12 {
        return Err(ShadowError::InvalidLight {
            light: light_in_model,
            reason: "zero length",
        });
    }
    Ok(v / n)
}

/// Validates an observer height.
pub(crate) fn check_observer_height(observer_height_m: f64) -> Result<()> {
    if observer_height_m.is_finite() && observer_height_m >= 0.0 {
        Ok(())
    } else {
        Err(ShadowError::InvalidObserverHeight(observer_height_m))
    }
}

/// Validates a disc angular radius.
pub(crate) fn check_radius(angular_radius_rad: f64) -> Result<()> {
    if (0.0..std::f64::consts::FRAC_PI_2).contains(&angular_radius_rad) {
        Ok(())
    } else {
        Err(ShadowError::InvalidAngularRadius(angular_radius_rad))
    }
}

/// A light direction decomposed for marching over the grid.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LightDir {
    /// Unit vector, model space.
    pub unit: Vector3<f64>,
    /// Horizontal (model x/y) length of `unit`.
    pub hor: f64,
    /// Change of `col` per cell size (`px_m`) of horizontal travel toward the light.
    pub dcol: f64,
    /// Change of `row` per cell size of horizontal travel toward the light (rows grow south).
    pub drow: f64,
    /// Rise of the ray (model z) per metre of horizontal travel: `tan(elevation)`.
    pub tan_el: f64,
}

impl LightDir {
    /// Decomposes a unit vector. `hor` may be 0 (light at the model zenith or nadir).
    pub fn new(unit: Vector3<f64>) -> Self {
        let hor = (unit.x * unit.x + unit.y * unit.y).sqrt();
        if hor < 1e-12 {
            return LightDir {
                unit,
                hor: 0.0,
                dcol: 0.0,
                drow: 0.0,
                tan_el: if unit.z > 0.0 {
                    f64::INFINITY
                } else {
                    f64::NEG_INFINITY
                },
            };
        }
        LightDir {
            unit,
            hor,
            dcol: unit.x / hor,
            drow: -unit.y / hor,
            tan_el: unit.z / hor,
        }
    }

    /// Elevation above the model x/y plane, radians.
    pub fn elevation_rad(&self) -> f64 {
        self.unit.z.atan2(self.hor)
    }
}

/// An observer in model space: the start of every ray of one map cell or pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observer {
    /// Fractional row of the observer (centre coordinates: integers are cell centres).
    pub row: f64,
    /// Fractional column of the observer.
    pub col: f64,
    /// Model z of the observer, metres.
    pub z_m: f64,
}

/// The observer standing `observer_height_m` above the surface point of cell (row, col), or
/// `None` for a hole.
#[inline]
pub(crate) fn observer_at(
    hf: &HeightField,
    row: usize,
    col: usize,
    observer_height_m: f64,
) -> Option<Observer> {
    let z = hf.z_at(row as isize, col as isize)? as f64;
    let (x, y) = hf.xy_from_row_col(row as f64, col as f64);
    let up = hf.up_at(x, y, z);
    let p = Vector3::new(x, y, z) + observer_height_m * up;
    // Offset from the cell's own (integer) position, not a round trip through x/y: a round trip
    // leaves a 1e-12-cell error with a non-round cell size, and the first line crossing of a
    // ray then lands on the observer's own cell (as the GPU's u0 = col + h up_x / px).
    let (r, c) = (
        row as f64 - observer_height_m * up.y / hf.px_m,
        col as f64 + observer_height_m * up.x / hf.px_m,
    );
    // The radial offset moves an edge cell's observer off the grid by at most
    // h * sin(tilt) (1 cm for 2 m at 6° tilt); keep rays starting inside the grid.
    Some(Observer {
        row: r.clamp(0.0, (hf.rows - 1) as f64),
        col: c.clamp(0.0, (hf.cols - 1) as f64),
        z_m: p.z,
    })
}

/// Whether the ray from `obs` toward `light`, after it leaves the grid's terrain, is
/// below the reference sphere there or meets it further on: the DEM is too small for that cell
/// and that light, since the real Moon would block the ray. A ray that goes straight up never
/// does; one straight down always does.
fn exits_below_sphere(hf: &HeightField, obs: &Observer, light: &LightDir) -> bool {
    if light.hor == 0.0 {
        return light.unit.z < 0.0;
    }
    // Where the ray leaves the terrain: the last centre line it crosses.
    let s = dp::exit_distance(hf, obs, light);
    let (row, col) = (obs.row + s * light.drow, obs.col + s * light.dcol);
    let (x, y) = hf.xy_from_row_col(row, col);
    let z_ray = obs.z_m + s * hf.px_m * light.tan_el;
    // The sphere's centre is (0, 0, -R) in model space. With w = exit point - centre, the ray
    // w + t L (t >= 0) meets the sphere iff |w| < R, or b = w.L < 0 and b² >= |w|² - R².
    let r = crate::MOON_RADIUS_M;
    let w = Vector3::new(x, y, z_ray + r);
    let c = w.norm_squared() - r * r;
    if c < 0.0 {
        return true;
    }
    let b = w.dot(&light.unit);
    b < 0.0 && b * b >= c
}

/// For every observer (see [`Observers`]) for which `lit(index)` holds:
/// whether its ray toward `light_in_model`, once it leaves the grid, is below the reference
/// sphere or meets it further on (the DEM is too small there). Other cells are `false`.
pub fn lit_exits_below_sphere<'a, F>(
    hf: &HeightField,
    observers: impl Into<Observers<'a>>,
    light_in_model: [f64; 3],
    lit: F,
) -> Result<Vec<bool>>
where
    F: Fn(usize) -> bool + Sync,
{
    let observers = observers.into();
    observers.check()?;
    let dir = LightDir::new(unit_light(light_in_model)?);
    Ok(map_observers(hf, &observers, false, |i, obs| {
        lit(i) && exits_below_sphere(hf, obs, &dir)
    }))
}

/// Hard mask of every observer (see [`Observers`]): [`MASK_SHADOW`] where `shadowed(observer)`,
/// else [`MASK_LIT`]; [`MASK_NODATA`] for the others. `engine(light, min_s_cells)` builds the
/// test once the inputs are checked, from the light's direction and the nearest terrain sample
/// (cells, [`Observers::min_s_cells`]).
pub(crate) fn hard_mask_by<S>(
    hf: &HeightField,
    observers: Observers,
    light_in_model: [f64; 3],
    engine: impl FnOnce(LightDir, f64) -> S,
) -> Result<Vec<u8>>
where
    S: Fn(&Observer) -> bool + Sync,
{
    observers.check()?;
    let dir = LightDir::new(unit_light(light_in_model)?);
    let shadowed = engine(dir, observers.min_s_cells());
    Ok(map_observers(hf, &observers, MASK_NODATA, |_, obs| {
        if shadowed(obs) { MASK_SHADOW } else { MASK_LIT }
    }))
}

/// Largest valid height of the field (model z, m); `-inf` if all cells are holes.
pub(crate) fn max_height_m(hf: &HeightField) -> f64 {
    hf.z_m
        .iter()
        .filter(|z| !z.is_nan())
        .fold(f64::NEG_INFINITY, |m, &z| m.max(z as f64))
}

/// Visible fraction of a uniform disc of angular radius `r` whose centre is `clearance_rad`
/// above a straight horizon edge (negative: centre hidden). This is the circular-segment formula
/// of paper 000/003 eq. 7, `(pi - acos d + d sqrt(1 - d^2)) / pi` with `d = clearance / r` clamped
/// to [-1, 1] (d = 1: the edge touches the lower limb, fully visible). Paper eq. 6 writes `d`
/// through J* and the normal N·N_L; here `d` is derived directly from the angular clearance
/// (see [`dp`]), which is the same quantity without the small-angle factors.
#[inline]
pub fn disc_fraction_above_edge(clearance_rad: f64, angular_radius_rad: f64) -> f64 {
    if angular_radius_rad <= 0.0 {
        return if clearance_rad > 0.0 { 1.0 } else { 0.0 };
    }
    let d = (clearance_rad / angular_radius_rad).clamp(-1.0, 1.0);
    (std::f64::consts::PI - d.acos() + d * (1.0 - d * d).sqrt()) / std::f64::consts::PI
}

/// Visible fraction of the disc from the minimum shadow cost `j_min = min over the ray of
/// Δh / t` (tan units; `+inf` when nothing is along the ray) under the prism assumption of paper
/// 000/003 §3.4: the occluder's edge is horizontal across the disc. With `tan(e_c)` the centre's
/// elevation, the horizon along the centre azimuth has `tan(e_h) = tan(e_c) - J*`. Only terrain
/// makes a horizon (no local-horizontal lower bound: see the module docs).
#[inline]
pub(crate) fn fraction_from_cost(j_min: f64, light: &LightDir, angular_radius_rad: f64) -> f64 {
    if light.hor == 0.0 {
        // Straight up: nothing above; straight down: the observer's own ground.
        return if light.unit.z > 0.0 { 1.0 } else { 0.0 };
    }
    let e_c = light.elevation_rad();
    let e_h = if j_min.is_finite() {
        (light.tan_el - j_min).atan()
    } else {
        f64::NEG_INFINITY
    };
    disc_fraction_above_edge(e_c - e_h, angular_radius_rad)
}

/// Light direction of the disc's upper (`sign = +1`) or lower (`-1`) limb: the centre rotated
/// by the angular radius in the vertical plane (model z) that contains it.
pub(crate) fn limb_direction(light: &LightDir, angular_radius_rad: f64, sign: f64) -> [f64; 3] {
    let e = light.elevation_rad() + sign * angular_radius_rad;
    if light.hor == 0.0 {
        // Zenith / nadir: tilt toward +x (any azimuth is as good).
        let e = light.unit.z.signum() * std::f64::consts::FRAC_PI_2 + sign * angular_radius_rad;
        return [e.cos(), 0.0, e.sin()];
    }
    let ax = light.unit.x / light.hor;
    let ay = light.unit.y / light.hor;
    [e.cos() * ax, e.cos() * ay, e.sin()]
}

/// Where an engine puts its observers.
#[derive(Debug, Clone, Copy)]
pub enum Observers<'a> {
    /// One per cell of the height field, `height_m` above the cell's surface point along the
    /// radial direction (results in the grid's row-major order; holes and cells outside
    /// [`HeightField::window`] give nodata). A plain number converts into this.
    Cells {
        /// Observer height above the ground, metres (finite, >= 0).
        height_m: f64,
    },
    /// Given observers (results in the list's order; `None` gives nodata), e.g. the exact
    /// positions of a DEM's own pixels ([`crate::model::MapGrid::pixel_observers`]). Terrain
    /// closer than `min_s_cells` (horizontal distance, cells) is not sampled, as the per-site
    /// horizon engine leaves out the observer's own half pixel.
    Points {
        /// The observers.
        list: &'a [Option<Observer>],
        /// Nearest terrain sample, cells.
        min_s_cells: f64,
    },
}

impl From<f64> for Observers<'_> {
    fn from(height_m: f64) -> Self {
        Observers::Cells { height_m }
    }
}

impl Observers<'_> {
    /// Checks the observer height of [`Observers::Cells`].
    pub(crate) fn check(&self) -> Result<()> {
        match *self {
            Observers::Cells { height_m } => check_observer_height(height_m),
            Observers::Points { .. } => Ok(()),
        }
    }

    /// Nearest terrain sample (cells) an engine takes: `min_s_cells` for points, 0 for cells.
    pub(crate) fn min_s_cells(&self) -> f64 {
        match *self {
            Observers::Cells { .. } => 0.0,
            Observers::Points { min_s_cells, .. } => min_s_cells,
        }
    }
}

/// Runs `f(index, observer)` for every observer of `observers` in parallel (`index` into the
/// result); the others give `nodata` (see [`Observers`]).
pub(crate) fn map_observers<T, F>(
    hf: &HeightField,
    observers: &Observers,
    nodata: T,
    f: F,
) -> Vec<T>
where
    T: Copy + Send + Sync,
    F: Fn(usize, &Observer) -> T + Sync,
{
    match *observers {
        Observers::Cells { height_m } => {
            let cols = hf.cols;
            map_cells(hf, height_m, nodata, |row, col, obs| {
                f(row * cols + col, obs)
            })
        }
        Observers::Points { list, .. } => list
            .par_iter()
            .enumerate()
            .map(|(i, o)| o.as_ref().map_or(nodata, |obs| f(i, obs)))
            .collect(),
    }
}

/// Runs `f(row, col, observer)` for every cell in parallel over rows; holes and cells outside
/// [`HeightField::window`] give `nodata`.
pub(crate) fn map_cells<T, F>(hf: &HeightField, observer_height_m: f64, nodata: T, f: F) -> Vec<T>
where
    T: Copy + Send + Sync,
    F: Fn(usize, usize, &Observer) -> T + Sync,
{
    let mut out = vec![nodata; hf.rows * hf.cols];
    if hf.cols == 0 {
        return out;
    }
    out.par_chunks_mut(hf.cols)
        .enumerate()
        .for_each(|(row, line)| {
            for (col, v) in line.iter_mut().enumerate() {
                if !hf.evaluates(row, col) {
                    continue;
                }
                if let Some(obs) = observer_at(hf, row, col, observer_height_m) {
                    *v = f(row, col, &obs);
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disc_fraction_limits_and_half() {
        let r = 0.01;
        assert_eq!(disc_fraction_above_edge(r, r), 1.0);
        assert_eq!(disc_fraction_above_edge(-r, r), 0.0);
        assert!((disc_fraction_above_edge(0.0, r) - 0.5).abs() < 1e-12);
        // Segment area, independent formula: area above a chord at distance d below the centre
        // of a unit disc = pi - (acos(d) - d sqrt(1-d^2)).
        let d: f64 = 0.3;
        let seg_below = d.acos() - d * (1.0 - d * d).sqrt();
        let expected = (std::f64::consts::PI - seg_below) / std::f64::consts::PI;
        assert!((disc_fraction_above_edge(0.3 * r, r) - expected).abs() < 1e-12);
    }

    #[test]
    fn invalid_lights_are_errors() {
        assert!(matches!(
            unit_light([0.0, 0.0, 0.0]),
            Err(ShadowError::InvalidLight { .. })
        ));
        assert!(matches!(
            unit_light([f64::NAN, 0.0, 1.0]),
            Err(ShadowError::InvalidLight { .. })
        ));
        assert!(unit_light([0.0, 3.0, 4.0]).is_ok());
    }

    #[test]
    fn limbs_are_radius_away_from_centre() {
        let l = LightDir::new(Vector3::new(0.3, -0.9, 0.05).normalize());
        let r = SUN_ANGULAR_RADIUS_RAD;
        for s in [-1.0, 1.0] {
            let limb = Vector3::from(limb_direction(&l, r, s));
            assert!((limb.norm() - 1.0).abs() < 1e-12);
            assert!((limb.dot(&l.unit).clamp(-1.0, 1.0).acos() - r).abs() < 1e-9);
        }
    }
}

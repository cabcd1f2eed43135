//! The per-site horizon scan of the GPU backend: the data it reads (layers, sites, azimuths, in
//! the layout of `shaders/horizon_scan.wgsl`) and its CPU twin, in f32, line by line with the
//! WGSL ([`scan_azimuth`]).
//!
//! The kernel runs over the same terrain as the CPU [`HorizonEngine`]: every layer of the
//! [`TerrainStack`] in its own polar stereographic grid (at most [`MAX_LAYERS`]), the finest layer
//! with a surface winning at each point, and samples the path like the exact scan (grid-line and
//! outer-edge crossings, finer layers' outer-edge crossings, patch midpoints, tangent points of
//! the quadratic profile), in segments of 8 cells of the finest layer at the segment start.
//! What differs from the exact scan is the
//! arithmetic (f32, see the precision budget at the top of the shader) and three details: the
//! sample parameters come from a DDA over the lines instead of a sorted list (pieces shorter than
//! the f64 scan's 1e-12 dedup are kept; harmless), the nearest-centre test of the bilinear
//! surface rounds halves up, and a fractional index within 1e-3 cell outside an outer edge is
//! snapped onto it (1e-9 in f64). Measured differences: `docs/gpu.md`.
//!
//! The twin is the parity oracle of the GPU kernel (`tests/it/gpu/horizon.rs`); the f64
//! [`HorizonEngine`] exact scan is the accuracy oracle of both.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::HOLE_TEST_M;
pub use super::{HOLE_Z_M, NO_SAMPLE};
use crate::MOON_RADIUS_M;
use crate::frames::enu_from_moon_me;
use crate::horizon::{
    Horizon, HorizonEngine, HorizonError, HorizonMethod, HorizonParams, azimuth_count,
};
use crate::terrain::{Projection, TerrainStack};

/// Most layers the kernel takes (the uniform holds a fixed array).
pub const MAX_LAYERS: usize = 4;
const MOON_RADIUS_F32_M: f32 = MOON_RADIUS_M as f32;
const SEGMENT_CELLS: f32 = 8.0;
const SNAP_EPS: f32 = 1.0e-3;
const MAX_SEGMENTS: u32 = 1_000_000;
const MAX_PIECES: u32 = 1_000_000;
const FAR_T: f32 = 1.0e30;
const SERIES_MAX_RAD: f32 = 0.6;

/// One layer as the kernel sees it. Keep in sync with `Layer` in shaders/horizon_scan.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
pub struct LayerParams {
    /// Rows of the layer.
    pub rows: u32,
    /// Columns of the layer.
    pub cols: u32,
    /// Index of the layer's first cell in the concatenated heights.
    pub offset: u32,
    /// 1: south polar stereographic; 0: north.
    pub south: u32,
    /// Cell width, metres.
    pub px_x_m: f32,
    /// Cell height, metres.
    pub px_y_m: f32,
    /// Map x of the left edge of column 0, metres.
    pub x_left_m: f32,
    /// Map y of the top edge of row 0, metres.
    pub y_top_m: f32,
    /// `sin(lon0)` of the projection.
    pub sin_lon0: f32,
    /// `cos(lon0)` of the projection.
    pub cos_lon0: f32,
    /// `2 R k0` of the projection, metres.
    pub two_r_k0_m: f32,
    /// `min(px_x_m, px_y_m)`: sets the segment length.
    pub px_min_m: f32,
}
const _: () = assert!(size_of::<LayerParams>() == 48);

/// The kernel's uniform. Keep in sync with `ScanParams` in shaders/horizon_scan.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ScanParams {
    /// Number of layers in use (1..=[`MAX_LAYERS`]).
    pub n_layers: u32,
    /// Number of sites in this dispatch.
    pub n_sites: u32,
    /// Number of azimuths per site.
    pub n_az: u32,
    /// First site of this dispatch (index into the sites buffer).
    pub site0: u32,
    /// The layers, finest first; unused entries zero.
    pub layers: [LayerParams; MAX_LAYERS],
}
const _: () = assert!(size_of::<ScanParams>() == 208);

/// One site. Keep in sync with `Site` in shaders/horizon_scan.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
pub struct SiteParams {
    /// `MOON_ME` radial unit vector (w unused).
    pub up: [f32; 4],
    /// `MOON_ME` local north unit vector (w unused).
    pub north: [f32; 4],
    /// `MOON_ME` local east unit vector (w unused).
    pub east: [f32; 4],
    /// Observer height above the 1737.4 km sphere (ground + observer height), metres.
    pub obs_m: f32,
    /// First ground angle scanned (end of the observer's own cell), radians.
    pub theta_min_rad: f32,
    /// Last ground angle that can hold terrain, radians.
    pub theta_max_rad: f32,
    /// Padding.
    pub _pad: f32,
}
const _: () = assert!(size_of::<SiteParams>() == 64);

/// A terrain stack in the kernel's layout: layer parameters and the concatenated heights.
#[derive(Debug, Clone)]
pub struct ScanTerrain {
    /// The uniform (with `n_sites = n_az = 0`; set per dispatch).
    pub params: ScanParams,
    /// Every layer's heights, row-major, finest layer first; holes as [`HOLE_Z_M`].
    pub heights_m: Vec<f32>,
}

impl ScanTerrain {
    /// Converts `stack`. Errors when it has no layer, more than [`MAX_LAYERS`], a layer that is
    /// not polar stereographic, or more cells than 32-bit indices allow.
    pub fn new(stack: &TerrainStack) -> Result<Self, HorizonError> {
        let unsupported = |reason: String| HorizonError::GpuUnsupported { reason };
        if stack.layers.is_empty() {
            return Err(HorizonError::NoLayers);
        }
        if stack.layers.len() > MAX_LAYERS {
            return Err(unsupported(format!(
                "{} layers, at most {MAX_LAYERS}",
                stack.layers.len()
            )));
        }
        let total: usize = stack.layers.iter().map(|d| d.heights_m.len()).sum();
        if total >= u32::MAX as usize {
            return Err(unsupported(format!("{total} cells exceed 32-bit indices")));
        }
        let mut layers = [LayerParams::default(); MAX_LAYERS];
        let mut heights_m = Vec::with_capacity(total);
        for (slot, dem) in layers.iter_mut().zip(&stack.layers) {
            let Projection::PolarStereographic {
                south,
                lon0_deg,
                k0,
                radius_m,
            } = dem.projection
            else {
                return Err(unsupported(format!(
                    "layer {} is not polar stereographic",
                    dem.name
                )));
            };
            let g = &dem.grid;
            let (sin_lon0, cos_lon0) = lon0_deg.to_radians().sin_cos();
            *slot = LayerParams {
                rows: g.rows as u32,
                cols: g.cols as u32,
                offset: heights_m.len() as u32,
                south: u32::from(south),
                px_x_m: g.px_x_m as f32,
                px_y_m: g.px_y_m as f32,
                x_left_m: g.x_left_m as f32,
                y_top_m: g.y_top_m as f32,
                sin_lon0: sin_lon0 as f32,
                cos_lon0: cos_lon0 as f32,
                two_r_k0_m: (2.0 * radius_m * k0) as f32,
                px_min_m: dem.px_m() as f32,
            };
            heights_m.extend(
                dem.heights_m
                    .iter()
                    .map(|&h| if h.is_nan() { HOLE_Z_M } else { h }),
            );
        }
        Ok(ScanTerrain {
            params: ScanParams {
                n_layers: stack.layers.len() as u32,
                n_sites: 0,
                n_az: 0,
                site0: 0,
                layers,
            },
            heights_m,
        })
    }
}

/// A site ready for the kernel, with what the [`Horizon`] needs besides the scan.
#[derive(Debug, Clone)]
pub struct SiteSetup {
    /// The kernel's site record.
    pub site: SiteParams,
    /// Site latitude, degrees.
    pub lat_deg: f64,
    /// Site east longitude, degrees.
    pub lon_deg: f64,
    /// Ground height (m above the sphere) from the finest layer with data there.
    pub ground_height_m: f64,
    /// Observer height above the ground, metres.
    pub observer_height_m: f64,
    /// Name of the layer that carries the observer.
    pub ground_layer: String,
    /// Terrain nearer than this is ignored (half a cell of the ground layer), metres.
    pub min_distance_m: f64,
}

/// Validates a site like [`HorizonEngine::horizon`] and builds its kernel record (the same
/// observer, `min_distance_m` and last ground angle as the CPU scan).
pub fn site_setup(
    engine: &HorizonEngine,
    lat_deg: f64,
    lon_deg: f64,
    observer_height_m: f64,
) -> Result<SiteSetup, HorizonError> {
    if !(lat_deg.is_finite() && lon_deg.is_finite() && lat_deg.abs() <= 90.0) {
        return Err(HorizonError::BadSite { lat_deg, lon_deg });
    }
    if !(observer_height_m.is_finite() && observer_height_m >= 0.0) {
        return Err(HorizonError::BadObserverHeight { observer_height_m });
    }
    let (ground_m, layer_idx) = engine.ground_at(lat_deg, lon_deg)?;
    let dem = &engine.stack().layers[layer_idx];
    let min_distance_m = 0.5 * dem.px_m();
    let enu = enu_from_moon_me(lat_deg, lon_deg);
    let up = enu.row(2).transpose();
    let v4 = |r: usize| {
        let v = enu.row(r);
        [v[0] as f32, v[1] as f32, v[2] as f32, 0.0]
    };
    Ok(SiteSetup {
        site: SiteParams {
            up: v4(2),
            north: v4(1),
            east: v4(0),
            obs_m: (ground_m + observer_height_m) as f32,
            theta_min_rad: (min_distance_m / MOON_RADIUS_M) as f32,
            theta_max_rad: engine.theta_max_rad(&up) as f32,
            _pad: 0.0,
        },
        lat_deg,
        lon_deg,
        ground_height_m: ground_m,
        observer_height_m,
        ground_layer: dem.name.clone(),
        min_distance_m,
    })
}

/// `(sin az, cos az)` of the `360 / az_step_deg` azimuths, computed in f64.
pub fn azimuth_table(az_step_deg: f64) -> Result<Vec<[f32; 2]>, HorizonError> {
    let n = azimuth_count(az_step_deg)?;
    Ok((0..n)
        .map(|i| {
            let (s, c) = (i as f64 * az_step_deg).to_radians().sin_cos();
            [s as f32, c as f32]
        })
        .collect())
}

/// Turns the kernel's `(tan el, ground angle)` per azimuth into a [`Horizon`] (`atan` in f64;
/// `-90°` and `NaN` distance where there was no terrain). The method is recorded as
/// [`HorizonMethod::Exact`]: the GPU scan samples like the exact scan.
pub fn to_horizon(setup: &SiteSetup, az_step_deg: f64, scan: &[[f32; 2]]) -> Horizon {
    let (elevation_deg, distance_m) = scan
        .iter()
        .map(|&[t, th]| {
            if t < HOLE_TEST_M {
                (-90.0, f64::NAN)
            } else {
                (
                    f64::from(t).atan().to_degrees(),
                    f64::from(th) * MOON_RADIUS_M,
                )
            }
        })
        .unzip();
    Horizon {
        lat_deg: setup.lat_deg,
        lon_deg: setup.lon_deg,
        ground_height_m: setup.ground_height_m,
        observer_height_m: setup.observer_height_m,
        ground_layer: setup.ground_layer.clone(),
        min_distance_m: setup.min_distance_m,
        method: HorizonMethod::Exact,
        az_step_deg,
        az_deg: (0..scan.len()).map(|i| i as f64 * az_step_deg).collect(),
        elevation_deg,
        distance_m,
    }
}

/// The CPU twin over every (site, azimuth), rayon; the same output layout as the kernel
/// (`site * n_az + az`).
pub fn horizon_scan(
    terrain: &ScanTerrain,
    sites: &[SiteParams],
    azimuths: &[[f32; 2]],
) -> Vec<[f32; 2]> {
    let n_az = azimuths.len();
    (0..sites.len() * n_az)
        .into_par_iter()
        .map(|i| scan_azimuth(terrain, &sites[i / n_az], azimuths[i % n_az]))
        .collect()
}

/// Horizons of several sites with the CPU twin (same validation as the CPU engine).
pub fn horizons_twin(
    stack: &TerrainStack,
    sites: &[(f64, f64)],
    params: &HorizonParams,
) -> Result<Vec<Horizon>, HorizonError> {
    let terrain = ScanTerrain::new(stack)?;
    let engine = HorizonEngine::new(stack);
    let azimuths = azimuth_table(params.az_step_deg)?;
    let setups = sites
        .iter()
        .map(|&(lat, lon)| site_setup(&engine, lat, lon, params.observer_height_m))
        .collect::<Result<Vec<_>, _>>()?;
    let recs: Vec<SiteParams> = setups.iter().map(|s| s.site).collect();
    let out = horizon_scan(&terrain, &recs, &azimuths);
    Ok(setups
        .iter()
        .zip(out.chunks(azimuths.len().max(1)))
        .map(|(s, scan)| to_horizon(s, params.az_step_deg, scan))
        .collect())
}

// ---- The twin of shaders/horizon_scan.wgsl, line by line. ----

fn sin_small(t: f32) -> f32 {
    if t >= SERIES_MAX_RAD {
        return t.sin();
    }
    let t2 = t * t;
    t * (1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))))
}

fn one_minus_cos_small(t: f32) -> f32 {
    if t >= SERIES_MAX_RAD {
        return 1.0 - t.cos();
    }
    let t2 = t * t;
    t2 / 2.0 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0 * (1.0 - t2 / 90.0))))
}

/// Per-invocation state (the shader's `var<private>`s).
struct Scan<'a> {
    params: &'a ScanParams,
    heights: &'a [f32],
    seg_a: [[f32; 2]; MAX_LAYERS],
    seg_b: [[f32; 2]; MAX_LAYERS],
    obs_m: f32,
    best_tan: f32,
    best_theta: f32,
}

impl Scan<'_> {
    fn cell_height(&self, l: usize, row: i32, col: i32) -> f32 {
        let layer = &self.params.layers[l];
        if row < 0 || col < 0 || row >= layer.rows as i32 || col >= layer.cols as i32 {
            return NO_SAMPLE;
        }
        self.heights[(layer.offset + row as u32 * layer.cols + col as u32) as usize]
    }

    fn height_at(&self, l: usize, row: f32, col: f32) -> f32 {
        let layer = &self.params.layers[l];
        super::bilinear_with_holes(layer.rows, layer.cols, row, col, |r, c| {
            self.cell_height(l, r, c)
        })
    }

    fn row_col(&self, l: usize, u: [f32; 3]) -> [f32; 2] {
        let layer = &self.params.layers[l];
        let e = u[1] * layer.cos_lon0 - u[0] * layer.sin_lon0;
        let n = u[0] * layer.cos_lon0 + u[1] * layer.sin_lon0;
        let (x, y) = if layer.south == 1 {
            let f = layer.two_r_k0_m / (1.0 - u[2]);
            (f * e, f * n)
        } else {
            let f = layer.two_r_k0_m / (1.0 + u[2]);
            (f * e, -f * n)
        };
        [
            (layer.y_top_m - y) / layer.px_y_m - 0.5,
            (x - layer.x_left_m) / layer.px_x_m - 0.5,
        ]
    }

    fn inside_extent(&self, l: usize, rc: [f32; 2]) -> bool {
        let layer = &self.params.layers[l];
        rc[0] >= -0.5
            && rc[1] >= -0.5
            && rc[0] <= layer.rows as f32 - 0.5
            && rc[1] <= layer.cols as f32 - 0.5
    }

    fn segment_misses(&self, l: usize) -> bool {
        let layer = &self.params.layers[l];
        let (a, b) = (self.seg_a[l], self.seg_b[l]);
        a[0].max(b[0]) < -0.5
            || a[1].max(b[1]) < -0.5
            || a[0].min(b[0]) > layer.rows as f32 - 0.5
            || a[1].min(b[1]) > layer.cols as f32 - 0.5
    }

    fn tan_elevation(&self, h_m: f32, theta: f32) -> f32 {
        let rho = MOON_RADIUS_F32_M + h_m;
        ((h_m - self.obs_m) - rho * one_minus_cos_small(theta)) / (rho * sin_small(theta))
    }

    fn offer(&mut self, tan_el: f32, theta: f32) {
        if tan_el > self.best_tan {
            self.best_tan = tan_el;
            self.best_theta = theta;
        }
    }

    fn lerp(&self, k: usize, t: f32) -> [f32; 2] {
        let (a, b) = (self.seg_a[k], self.seg_b[k]);
        [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
    }

    fn sample(&self, l: usize, finer: u32, t: f32) -> f32 {
        for k in 0..l {
            if finer & (1 << k) != 0 {
                let rc = self.lerp(k, t);
                if self.height_at(k, rc[0], rc[1]) >= HOLE_TEST_M {
                    return NO_SAMPLE;
                }
            }
        }
        let layer = &self.params.layers[l];
        let rc = self.lerp(l, t);
        self.height_at(
            l,
            snap_to_edge(rc[0], layer.rows as f32),
            snap_to_edge(rc[1], layer.cols as f32),
        )
    }

    /// The first crossing after `t` (and before 1) of the outer edge of a finer layer (bit k of
    /// `finer`), [`FAR_T`] when none (`next_finer_edge` of horizon_scan.wgsl).
    fn next_finer_edge(&self, l: usize, finer: u32, t: f32) -> f32 {
        let mut best = FAR_T;
        for k in 0..l {
            if finer & (1 << k) != 0 {
                let (va, vb) = (self.seg_a[k], self.seg_b[k]);
                let layer = &self.params.layers[k];
                let n = [layer.rows as f32, layer.cols as f32];
                for axis in 0..2 {
                    let dv = vb[axis] - va[axis];
                    for edge in [-0.5, n[axis] - 0.5] {
                        let te = line_t(edge, va[axis], dv);
                        if te > t && te < 1.0 && te < best {
                            best = te;
                        }
                    }
                }
            }
        }
        best
    }

    fn scan_layer_segment(&mut self, l: usize, theta_a: f32, theta_b: f32, include_start: bool) {
        if self.segment_misses(l) {
            return;
        }
        let mut finer = 0u32;
        for k in 0..l {
            if !self.segment_misses(k) {
                finer |= 1 << k;
            }
        }
        let layer = &self.params.layers[l];
        let rows = layer.rows as f32;
        let cols = layer.cols as f32;
        let va = self.seg_a[l];
        let dv = [self.seg_b[l][0] - va[0], self.seg_b[l][1] - va[1]];
        let d_theta = theta_b - theta_a;
        let dir = [wgsl_sign(dv[0]), wgsl_sign(dv[1])];
        let mut line_r = next_line(va[0], dir[0], rows);
        let mut line_c = next_line(va[1], dir[1], cols);
        let mut t_r = line_t(line_r, va[0], dv[0]);
        let mut t_c = line_t(line_c, va[1], dv[1]);
        let mut t_e = self.next_finer_edge(l, finer, 0.0);
        let mut t0 = 0.0_f32;
        let mut prev = self.sample(l, finer, 0.0);
        if include_start && prev >= HOLE_TEST_M {
            self.offer(self.tan_elevation(prev, theta_a), theta_a);
        }
        for _ in 0..MAX_PIECES {
            let mut t1 = 1.0_f32;
            if t_r < t1 {
                t1 = t_r;
            }
            if t_c < t1 {
                t1 = t_c;
            }
            if t_e < t1 {
                t1 = t_e;
            }
            let at_edge = t_e == t1;
            if at_edge {
                t_e = self.next_finer_edge(l, finer, t1);
            }
            if t_r == t1 {
                line_r = next_line(line_r, dir[0], rows);
                t_r = line_t(line_r, va[0], dv[0]);
            }
            if t_c == t1 {
                line_c = next_line(line_c, dir[1], cols);
                t_c = line_t(line_c, va[1], dv[1]);
            }
            if t1 > t0 {
                let mut next = self.sample(l, finer, t1);
                if at_edge && next < HOLE_TEST_M {
                    // The finer layer's border is clamped, so it has a surface at its edge.
                    next = self.sample(l, 0, t1);
                }
                let th1 = theta_a + t1 * d_theta;
                if next >= HOLE_TEST_M {
                    self.offer(self.tan_elevation(next, th1), th1);
                }
                let tm = 0.5 * (t0 + t1);
                let hm = self.sample(l, finer, tm);
                if hm >= HOLE_TEST_M {
                    let thm = theta_a + tm * d_theta;
                    let tan_m = self.tan_elevation(hm, thm);
                    self.offer(tan_m, thm);
                    if prev >= HOLE_TEST_M && next >= HOLE_TEST_M {
                        let q = 2.0 * (prev - 2.0 * hm + next);
                        if q < 0.0 {
                            let p = next - prev - q;
                            let ds_m = (t1 - t0) * d_theta * MOON_RADIUS_F32_M;
                            let m = ds_m * (tan_m + thm);
                            let u = (m - p) / (2.0 * q);
                            if u > 0.0 && u < 1.0 && (u - 0.5).abs() > 1.0e-3 {
                                let tv = t0 + u * (t1 - t0);
                                let hv = self.sample(l, finer, tv);
                                if hv >= HOLE_TEST_M {
                                    let thv = theta_a + tv * d_theta;
                                    self.offer(self.tan_elevation(hv, thv), thv);
                                }
                            }
                        }
                    }
                }
                prev = next;
                t0 = t1;
            }
            if t1 >= 1.0 {
                break;
            }
        }
    }

    fn place(&mut self, site: &SiteParams, d: [f32; 3], theta: f32, to_b: bool) {
        let up = [site.up[0], site.up[1], site.up[2]];
        let (s, omc) = (sin_small(theta), one_minus_cos_small(theta));
        let u = [
            up[0] + d[0] * s - up[0] * omc,
            up[1] + d[1] * s - up[1] * omc,
            up[2] + d[2] * s - up[2] * omc,
        ];
        for l in 0..self.params.n_layers as usize {
            let rc = self.row_col(l, u);
            if to_b {
                self.seg_b[l] = rc;
            } else {
                self.seg_a[l] = rc;
            }
        }
    }

    fn segment_length_rad(&self) -> f32 {
        let mut px = self.params.layers[self.params.n_layers as usize - 1].px_min_m;
        for l in 0..self.params.n_layers as usize {
            if self.inside_extent(l, self.seg_a[l]) {
                px = self.params.layers[l].px_min_m;
                break;
            }
        }
        SEGMENT_CELLS * px / MOON_RADIUS_F32_M
    }
}

/// WGSL `sign`: -1, 0 or 1.
fn wgsl_sign(v: f32) -> f32 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

fn snap_to_edge(v: f32, n: f32) -> f32 {
    if v < -0.5 && v > -0.5 - SNAP_EPS {
        return -0.5;
    }
    if v > n - 0.5 && v < n - 0.5 + SNAP_EPS {
        return n - 0.5;
    }
    v
}

fn next_line(v: f32, dir: f32, n: f32) -> f32 {
    if dir > 0.0 {
        if v < -0.5 {
            return -0.5;
        }
        if v < 0.0 {
            return 0.0;
        }
        if v < n - 1.0 {
            return v.floor() + 1.0;
        }
        if v < n - 0.5 {
            return n - 0.5;
        }
        return FAR_T;
    }
    if v > n - 0.5 {
        return n - 0.5;
    }
    if v > n - 1.0 {
        return n - 1.0;
    }
    if v > 0.0 {
        return v.ceil() - 1.0;
    }
    if v > -0.5 {
        return -0.5;
    }
    -FAR_T
}

fn line_t(line: f32, va: f32, dv: f32) -> f32 {
    if dv == 0.0 || line.abs() >= FAR_T {
        return FAR_T;
    }
    (line - va) / dv
}

/// The twin of the `horizon_scan` entry point for one (site, azimuth): `(tan el, ground angle
/// rad)`, `tan el` = [`NO_SAMPLE`] when the path met no terrain.
#[expect(
    clippy::neg_cmp_op_on_partial_ord,
    reason = "line by line with the WGSL, where a NaN ground angle also ends the loop"
)]
pub fn scan_azimuth(terrain: &ScanTerrain, site: &SiteParams, sin_cos_az: [f32; 2]) -> [f32; 2] {
    let [sa, ca] = sin_cos_az;
    let d = [
        site.north[0] * ca + site.east[0] * sa,
        site.north[1] * ca + site.east[1] * sa,
        site.north[2] * ca + site.east[2] * sa,
    ];
    let mut scan = Scan {
        params: &terrain.params,
        heights: &terrain.heights_m,
        seg_a: [[0.0; 2]; MAX_LAYERS],
        seg_b: [[0.0; 2]; MAX_LAYERS],
        obs_m: site.obs_m,
        best_tan: NO_SAMPLE,
        best_theta: 0.0,
    };
    let mut theta = site.theta_min_rad;
    scan.place(site, d, theta, false);
    let mut first = true;
    for _ in 0..MAX_SEGMENTS {
        if !(theta < site.theta_max_rad) {
            break;
        }
        let theta_b = (theta + scan.segment_length_rad()).min(site.theta_max_rad);
        scan.place(site, d, theta_b, true);
        for l in 0..terrain.params.n_layers as usize {
            scan.scan_layer_segment(l, theta, theta_b, first);
        }
        first = false;
        scan.seg_a = scan.seg_b;
        theta = theta_b;
    }
    [scan.best_tan, scan.best_theta]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_match_the_f64_functions() {
        for t in [1e-6_f32, 1e-3, 0.05, 0.3, 0.59, 0.61, 1.2] {
            let t64 = f64::from(t);
            assert!((f64::from(sin_small(t)) - t64.sin()).abs() <= 1e-7 * t64.sin());
            let omc = 1.0 - t64.cos();
            assert!((f64::from(one_minus_cos_small(t)) - omc).abs() <= 2e-7 * omc.max(1e-7));
        }
    }

    #[test]
    fn next_line_walks_edges_and_centres() {
        let n = 3.0;
        let mut v = -1.0;
        let mut up = Vec::new();
        while v < FAR_T {
            v = next_line(v, 1.0, n);
            up.push(v);
        }
        assert_eq!(up, [-0.5, 0.0, 1.0, 2.0, 2.5, FAR_T]);
        let mut v = 3.0;
        let mut down = Vec::new();
        while v > -FAR_T {
            v = next_line(v, -1.0, n);
            down.push(v);
        }
        assert_eq!(down, [2.5, 2.0, 1.0, 0.0, -0.5, -FAR_T]);
        assert_eq!(next_line(1.0, 1.0, n), 2.0);
        assert_eq!(next_line(1.0, -1.0, n), 0.0);
    }
}

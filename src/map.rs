//! Illumination maps (`penumbra map`): shadow engines run on the model-space height field, results
//! resampled back onto the DEM's own grid so that every GeoTIFF carries the DEM's georeferencing.
//!
//! ```text
//!  DEM layers ──resample──► HeightField (model space: tangent plane at the DEM centre,
//!      ▲                    curvature in z; the finest layer's extent + margin, its pixel size)
//!      │                                  │ shadow engine per light direction
//!      │                                  ▼
//!  output grid = finest layer ◄──bilinear/nearest── per-cell values in model space
//! ```
//!
//! The Sun is one direction over the whole grid (its parallax over 184 km is 1.2e-6 rad). For the
//! Earth the direction is taken at the map centre; over ±184 km it varies by up to
//! 184 km / 384,400 km = 4.8e-4 rad = 0.027°, about 3% of the Earth's angular radius, which bounds
//! the Earth-visibility error at the map edges.
//!
//! **Every layer.** The model grid covers the union of all layers' extents at the finest layer's
//! pixel size (each model cell takes the finest layer with data there, [`resample_to_model_space`]),
//! so far-field layers cast shadows exactly as in the per-site horizon engine
//! ([`crate::horizon`]); only the cells under the output raster are evaluated
//! ([`HeightField::window`]). Beyond [`MAX_MODEL_CELLS`] the grid is clipped around the map and
//! [`MapGrid::clipped_to_km`] says where (the caller warns).

use std::path::Path;

use anyhow::Context as _;
use hifitime::Epoch;
use nalgebra::Vector3;
use rayon::prelude::*;

use crate::ephem::{self, AbCorr, Kernels, Site};
use crate::illum::plot::{MapLegend, write_map_preview};
use crate::output::BelowSphereExits;
use crate::shadow::{Engine, MASK_NODATA, Observer, Observers};
use crate::terrain::model_space::{ModelFrame, ModelGridSpec, resample_to_model_space};
use crate::terrain::{Dem, HeightField, TerrainStack};

/// A disc counts as visible when its fraction exceeds this (as in [`crate::illum::stats`]).
pub const VISIBLE_MIN_FRACTION: f32 = 1e-6;

/// Largest model grid a map builds (cells; 4 bytes each, plus the engines' mipmaps): 40 M cells
/// hold the 1536² 240 m LOLA grid with its ±457 km far field (3,752² cells).
pub const MAX_MODEL_CELLS: usize = 40_000_000;

/// The model-space height field of a map and the way back to the output (DEM) grid.
pub struct MapGrid {
    /// The output grid: the finest DEM layer (its heights mark nodata).
    pub dem: Dem,
    /// The model-space height field the engines run on.
    pub hf: HeightField,
    /// For each output pixel, its fractional (row, col) in `hf`; NaN for nodata pixels.
    rc_in_model: Vec<[f32; 2]>,
    /// For each output pixel, its surface point in model space (`None` for nodata pixels).
    surface_in_model: Vec<Option<Vector3<f64>>>,
    /// `Some(half-width km)` when the coarser layers reach beyond [`MAX_MODEL_CELLS`] and the
    /// grid was clipped to that half-width around the map centre.
    pub clipped_to_km: Option<f64>,
}

impl MapGrid {
    /// Builds the model-space height field for the finest layer of `stack` (with every layer
    /// resampled into it) and the mapping back to that layer's grid.
    pub fn new(stack: &TerrainStack) -> anyhow::Result<Self> {
        let dem = stack.layers.first().context("no DEM layer")?.clone();
        let g = dem.grid;
        let (cx, cy) = g.xy_from_row_col((g.rows as f64 - 1.0) / 2.0, (g.cols as f64 - 1.0) / 2.0);
        let (centre_lat_deg, centre_lon_deg) = dem.projection.lat_lon_from_xy(cx, cy);
        // The model grid follows the DEM's: its axes turned onto the DEM's rows and columns at
        // the centre, its cell the DEM's pixel measured there, and the centre on the same kind of
        // point (a pixel centre or a pixel corner). So near the centre the model cells are the
        // DEM's pixels and resampling is (almost) the identity; away from it they drift apart by
        // the projection's scale change and the tilt of the local vertical (docs/terrain.md).
        let (rotation_rad, px_m) = {
            let enu = ModelFrame::new(centre_lat_deg, centre_lon_deg);
            let d = dem.px_m();
            let step = |dx: f64, dy: f64| {
                let (lat, lon) = dem.projection.lat_lon_from_xy(cx + dx, cy + dy);
                enu.model_from_lat_lon_height(lat, lon, 0.0)
            };
            let (east, north) = (step(d, 0.0), step(0.0, d));
            (
                north.x.atan2(north.y),
                0.5 * (east.x.hypot(east.y) + north.x.hypot(north.y)),
            )
        };
        let frame = ModelFrame::rotated(centre_lat_deg, centre_lon_deg, rotation_rad);
        // Model-space position of every output pixel centre (on its own surface).
        let surface_in_model: Vec<Option<Vector3<f64>>> = (0..g.rows * g.cols)
            .into_par_iter()
            .map(|i| {
                let (row, col) = (i / g.cols, i % g.cols);
                let h = dem.heights_m[i];
                if h.is_nan() {
                    return None;
                }
                let (x, y) = g.xy_from_row_col(row as f64, col as f64);
                let (lat, lon) = dem.projection.lat_lon_from_xy(x, y);
                Some(frame.model_from_lat_lon_height(lat, lon, f64::from(h)))
            })
            .collect();
        let (max_x, max_y) = surface_in_model
            .iter()
            .flatten()
            .fold((0.0_f64, 0.0_f64), |(mx, my), p| {
                (mx.max(p.x.abs()), my.max(p.y.abs()))
            });
        if max_x == 0.0 && max_y == 0.0 {
            anyhow::bail!("the DEM {} has no valid heights", dem.name);
        }
        // The output raster's half-extent, and that of every layer (their outer edges on the
        // sphere, sampled densely: the model frame is a rotation of the projection's axes).
        let out_half_cols = (max_x / px_m).ceil() as usize + 2;
        let out_half_rows = (max_y / px_m).ceil() as usize + 2;
        let (mut all_x, mut all_y) = (max_x, max_y);
        for layer in &stack.layers[1..] {
            for (x, y) in layer.grid.edge_points_m(256) {
                let (lat, lon) = layer.projection.lat_lon_from_xy(x, y);
                let p = frame.model_from_lat_lon_height(lat, lon, 0.0);
                if p.x.is_finite() && p.y.is_finite() {
                    all_x = all_x.max(p.x.abs());
                    all_y = all_y.max(p.y.abs());
                }
            }
        }
        let mut half_cols = ((all_x / px_m).ceil() as usize + 2).max(out_half_cols);
        let mut half_rows = ((all_y / px_m).ceil() as usize + 2).max(out_half_rows);
        let mut clipped_to_km = None;
        if 4 * half_rows * half_cols > MAX_MODEL_CELLS {
            // Clip the far field (never the output raster) to the cell budget.
            let scale = (MAX_MODEL_CELLS as f64 / (4 * half_rows * half_cols) as f64).sqrt();
            half_cols = ((half_cols as f64 * scale) as usize).max(out_half_cols);
            half_rows = ((half_rows as f64 * scale) as usize).max(out_half_rows);
            clipped_to_km = Some(half_cols.min(half_rows) as f64 * px_m / 1e3);
        }
        // An odd DEM has a pixel centre at its centre, an even one a pixel corner: so does the
        // model grid, so that their cells coincide there.
        let (rows, cols) = (2 * half_rows + g.rows % 2, 2 * half_cols + g.cols % 2);
        let spec = ModelGridSpec {
            centre_lat_deg,
            centre_lon_deg,
            rows,
            cols,
            px_m,
            rotation_rad,
        };
        let (mut hf, _) = resample_to_model_space(stack, &spec)?;
        // Evaluate only the cells under the output raster (and the bilinear neighbours of its
        // pixels): the rest of the grid is terrain that blocks, not results anyone reads.
        let (dr, dc) = (half_rows - out_half_rows, half_cols - out_half_cols);
        hf.window = Some(crate::terrain::CellWindow {
            rows: (dr, rows - dr),
            cols: (dc, cols - dc),
        });
        let rc_in_model = surface_in_model
            .iter()
            .map(|p| match p {
                Some(p) => {
                    let (r, c) = hf.row_col_from_xy(p.x, p.y);
                    [r as f32, c as f32]
                }
                None => [f32::NAN, f32::NAN],
            })
            .collect();
        Ok(MapGrid {
            dem,
            hf,
            rc_in_model,
            surface_in_model,
            clipped_to_km,
        })
    }

    /// The observer of every DEM pixel with data (row-major on the DEM grid): exactly at the
    /// pixel centre's own surface point (not the model grid's resampled surface),
    /// `observer_height_m` above it along its radial direction. The CPU map engines run from
    /// these with [`Observers::Points`] (terrain within [`crate::shadow::OWN_HALF_PIXEL_CELLS`]
    /// left out, as the per-site horizon engine leaves out the site's own half pixel), so a map
    /// pixel and a series site at its centre stand at the same point.
    pub fn pixel_observers(&self, observer_height_m: f64) -> Vec<Option<Observer>> {
        let hf = &self.hf;
        let (max_r, max_c) = ((hf.rows - 1) as f64, (hf.cols - 1) as f64);
        self.surface_in_model
            .par_iter()
            .map(|s| {
                let s = s.as_ref()?;
                let p = s + observer_height_m * hf.up_at(s.x, s.y, s.z);
                let (row, col) = hf.row_col_from_xy(p.x, p.y);
                Some(Observer {
                    row: row.clamp(0.0, max_r),
                    col: col.clamp(0.0, max_c),
                    z_m: p.z,
                })
            })
            .collect()
    }

    /// [`MapGrid::pixel_observers`] as the engines take them.
    pub fn pixel_points<'a>(&self, observers: &'a [Option<Observer>]) -> Observers<'a> {
        Observers::Points {
            list: observers,
            min_s_cells: crate::shadow::OWN_HALF_PIXEL_CELLS,
        }
    }

    /// Prints a one-line warning when the far field was clipped to [`MAX_MODEL_CELLS`].
    pub fn warn_if_clipped(&self) {
        if let Some(km) = self.clipped_to_km {
            eprintln!(
                "penumbra: warning: the map grid holds terrain only within {km:.0} km of the map \
                 centre ({MAX_MODEL_CELLS} cells at {} m); coarser layers beyond cast no shadow \
                 in maps (the per-site series use them)",
                self.hf.px_m
            );
        }
    }

    /// How many DEM pixels lit per `fraction` (per pixel, `> VISIBLE_MIN_FRACTION`) rest on a
    /// ray toward `light_in_model` from their `observers` that leaves the DEM toward the
    /// reference sphere.
    pub fn below_sphere_exits(
        &self,
        observers: &[Option<Observer>],
        light_in_model: [f64; 3],
        fraction: &[f32],
    ) -> anyhow::Result<BelowSphereExits> {
        let mut tally = BelowSphereTally::new(observers);
        tally.add(self, light_in_model, fraction)?;
        Ok(tally.finish())
    }
}

/// Accumulates [`BelowSphereExits`] over the epochs of a map of the DEM's pixels: which pixels
/// were ever lit by such a ray, and how many (pixel, epoch) results were.
struct BelowSphereTally<'a> {
    observers: &'a [Option<Observer>],
    any: Vec<bool>,
    cell_epochs: u64,
}

impl<'a> BelowSphereTally<'a> {
    /// A tally for the pixels' `observers` ([`MapGrid::pixel_observers`]).
    fn new(observers: &'a [Option<Observer>]) -> Self {
        BelowSphereTally {
            observers,
            any: vec![false; observers.len()],
            cell_epochs: 0,
        }
    }

    /// Adds one epoch's Sun `fraction` (per pixel) for the light `light_in_model`.
    fn add(
        &mut self,
        grid: &MapGrid,
        light_in_model: [f64; 3],
        fraction: &[f32],
    ) -> anyhow::Result<()> {
        let below = crate::shadow::lit_exits_below_sphere(
            &grid.hf,
            grid.pixel_points(self.observers),
            light_in_model,
            |i| fraction[i] > VISIBLE_MIN_FRACTION,
        )?;
        self.cell_epochs += below.iter().filter(|&&b| b).count() as u64;
        self.any
            .par_iter_mut()
            .zip(&below)
            .for_each(|(any, &b)| *any |= b);
        Ok(())
    }

    fn finish(self) -> BelowSphereExits {
        BelowSphereExits {
            cells: self.any.iter().filter(|&&b| b).count() as u64,
            cell_epochs: self.cell_epochs,
            cells_total: self.observers.iter().flatten().count() as u64,
        }
    }
}

impl MapGrid {
    /// A unit light direction in model space from a direction in `MOON_ME`.
    pub fn light_from_moon_me(&self, dir_in_moon_me: &Vector3<f64>) -> [f64; 3] {
        let v = self.hf.model_from_moon_me() * dir_in_moon_me;
        let v = v / v.norm();
        [v.x, v.y, v.z]
    }

    /// A unit light direction in model space from azimuth / elevation (deg) at the map centre.
    pub fn light_from_az_el_deg(&self, az_deg: f64, el_deg: f64) -> [f64; 3] {
        let v = self.hf.model_from_enu() * crate::frames::enu_from_az_el_deg(az_deg, el_deg);
        [v.x, v.y, v.z]
    }

    /// The map centre as a site on the sphere (for the ephemeris of the light directions).
    pub fn centre_site(&self) -> anyhow::Result<Site> {
        Ok(Site::new(
            self.hf.centre_lat_deg,
            self.hf.centre_lon_deg,
            0.0,
        )?)
    }

    /// Resamples model-space values onto the output grid: bilinear, NaN-aware (NaN neighbours are
    /// left out and the weights of the others renormalised; if all four are NaN, the nearest
    /// valid cell of the 4 x 4 around the pixel). Every output pixel with data gets a value.
    pub fn to_output_f32(&self, model: &[f32]) -> Vec<f32> {
        let (rows, cols) = (self.hf.rows, self.hf.cols);
        let at = |r: isize, c: isize| -> f32 {
            if r < 0 || c < 0 || r as usize >= rows || c as usize >= cols {
                f32::NAN
            } else {
                model[r as usize * cols + c as usize]
            }
        };
        self.rc_in_model
            .par_iter()
            .map(|&[r, c]| {
                if r.is_nan() {
                    return f32::NAN;
                }
                let (r0, c0) = (r.floor(), c.floor());
                let (fr, fc) = (r - r0, c - c0);
                let (r0, c0) = (r0 as isize, c0 as isize);
                let v = [
                    at(r0, c0),
                    at(r0, c0 + 1),
                    at(r0 + 1, c0),
                    at(r0 + 1, c0 + 1),
                ];
                if v.iter().any(|x| x.is_nan()) {
                    let w = [
                        (1.0 - fr) * (1.0 - fc),
                        (1.0 - fr) * fc,
                        fr * (1.0 - fc),
                        fr * fc,
                    ];
                    let (mut sum, mut wsum) = (0.0_f32, 0.0_f32);
                    for (x, w) in v.iter().zip(w) {
                        if !x.is_nan() && w > 0.0 {
                            sum += x * w;
                            wsum += w;
                        }
                    }
                    if wsum > 0.0 {
                        return sum / wsum;
                    }
                    return nearest_valid(r, c, |r, c| {
                        let x = at(r, c);
                        (!x.is_nan()).then_some(x)
                    })
                    .unwrap_or(f32::NAN);
                }
                (v[0] * (1.0 - fc) + v[1] * fc) * (1.0 - fr) + (v[2] * (1.0 - fc) + v[3] * fc) * fr
            })
            .collect()
    }

    /// Resamples model-space bytes onto the output grid (nearest cell with data, among the 4 x 4
    /// around the pixel; `MASK_NODATA` only for nodata pixels).
    pub fn to_output_u8(&self, model: &[u8]) -> Vec<u8> {
        let (rows, cols) = (self.hf.rows, self.hf.cols);
        let at = |r: isize, c: isize| -> Option<u8> {
            if r < 0 || c < 0 || r as usize >= rows || c as usize >= cols {
                return None;
            }
            let v = model[r as usize * cols + c as usize];
            (v != MASK_NODATA).then_some(v)
        };
        self.rc_in_model
            .par_iter()
            .map(|&[r, c]| {
                if r.is_nan() {
                    return MASK_NODATA;
                }
                nearest_valid(r, c, at).unwrap_or(MASK_NODATA)
            })
            .collect()
    }

    /// Writes an f32 raster on the output grid (NaN = nodata) with provenance metadata.
    pub fn write_f32(&self, path: &Path, values: &[f32], what: &str) -> anyhow::Result<()> {
        crate::terrain::write_geotiff_f32(
            path,
            &self.dem.grid,
            &self.dem.projection,
            values,
            Some(f32::NAN),
            &metadata(what),
        )
        .with_context(|| format!("writing {}", path.display()))
    }

    /// Writes a u8 raster on the output grid (255 = nodata) with provenance metadata.
    pub fn write_u8(&self, path: &Path, values: &[u8], what: &str) -> anyhow::Result<()> {
        crate::terrain::write_geotiff_u8(
            path,
            &self.dem.grid,
            &self.dem.projection,
            values,
            Some(MASK_NODATA),
            &metadata(what),
        )
        .with_context(|| format!("writing {}", path.display()))
    }
}

/// The value of the cell nearest to fractional (row, col) among the 4 x 4 cells around it for
/// which `at` has one.
fn nearest_valid<T>(r: f32, c: f32, at: impl Fn(isize, isize) -> Option<T>) -> Option<T> {
    let (r0, c0) = (r.floor() as isize, c.floor() as isize);
    let mut best: Option<(f32, T)> = None;
    for dr in -1..=2 {
        for dc in -1..=2 {
            let (rr, cc) = (r0 + dr, c0 + dc);
            if let Some(v) = at(rr, cc) {
                let d = (rr as f32 - r).powi(2) + (cc as f32 - c).powi(2);
                if best.as_ref().is_none_or(|(bd, _)| d < *bd) {
                    best = Some((d, v));
                }
            }
        }
    }
    best.map(|(_, v)| v)
}

fn metadata(what: &str) -> Vec<(&'static str, &str)> {
    vec![
        ("software", concat!("penumbra ", env!("CARGO_PKG_VERSION"))),
        ("git_commit", env!("PENUMBRA_GIT_COMMIT")),
        ("content", what),
    ]
}

/// Per-cell statistics of an epoch sweep, on the model grid.
#[derive(Debug, Clone)]
pub struct SweepStats {
    /// Number of epochs.
    pub epochs: usize,
    /// Time step, hours.
    pub step_h: f64,
    /// Sum of the Sun's visible fraction over the epochs.
    pub sun_fraction_sum: Vec<f64>,
    /// Epochs with any part of the Sun visible.
    pub sun_visible_count: Vec<u32>,
    /// Longest run of consecutive epochs with the Sun entirely hidden.
    pub longest_dark_epochs: Vec<u32>,
    /// Epochs with any part of the Earth visible.
    pub earth_visible_count: Vec<u32>,
    /// Epochs with both the Sun and the Earth (partly) visible; `None` when the sweep cannot tell
    /// (the GPU sweep folds each light separately), written as an all-NaN map.
    pub sun_and_earth_count: Option<Vec<u32>>,
    /// Sun-lit results resting on rays that leave the DEM below the reference sphere (counted
    /// by the CPU sweep; `None` on the GPU).
    pub below_sphere: Option<BelowSphereExits>,
    /// Whether the arrays are per DEM pixel (the CPU sweep, from the pixels' own observers)
    /// rather than per model cell (the GPU sweeps).
    pub on_dem_grid: bool,
}

/// Where a map's rays start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObserverPlacement {
    /// At each DEM pixel's own surface point ([`MapGrid::pixel_observers`]); results per pixel.
    Pixels,
    /// At the model grid's cells; results resampled back onto the DEM grid (the GPU's method).
    Cells,
}

impl ObserverPlacement {
    /// Words for provenance.
    pub fn describe(self) -> &'static str {
        match self {
            ObserverPlacement::Pixels => "DEM pixels' own surface points",
            ObserverPlacement::Cells => "model grid's cells (resampled onto the DEM grid)",
        }
    }
}

/// Which shadow engine a map uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapEngineKind {
    /// A per-light engine of [`crate::shadow::Engine`].
    Direct(Engine),
    /// A Fourier-compressed horizon map built once for the grid ([`crate::shadow::fourier`]).
    Fourier,
}

impl MapEngineKind {
    /// Parses a scenario's engine name (`brute`, `smap`, `dp`, `combined`, `fourier`).
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "brute" => MapEngineKind::Direct(Engine::Brute),
            "smap" => MapEngineKind::Direct(Engine::Smap),
            "dp" => MapEngineKind::Direct(Engine::Dp),
            "combined" => MapEngineKind::Direct(Engine::Combined),
            "fourier" => MapEngineKind::Fourier,
            _ => return None,
        })
    }
}

/// A shadow engine ready for a map grid: per-light engines run on the height field for each light;
/// the Fourier engine builds its horizon map once (the expensive part) and evaluates it per light.
pub enum MapEngine {
    /// A per-light engine.
    Direct(Engine),
    /// A horizon map of the grid.
    Fourier(Box<crate::shadow::fourier::HorizonMap>),
}

impl MapEngine {
    /// Prepares `kind` for `grid` (builds the horizon map for [`MapEngineKind::Fourier`]).
    pub fn new(
        kind: MapEngineKind,
        grid: &MapGrid,
        observer_height_m: f64,
    ) -> anyhow::Result<Self> {
        Ok(match kind {
            MapEngineKind::Direct(e) => MapEngine::Direct(e),
            MapEngineKind::Fourier => {
                let max_cells = grid.hf.rows.max(grid.hf.cols);
                MapEngine::Fourier(Box::new(crate::shadow::fourier::HorizonMap::build(
                    &grid.hf,
                    observer_height_m,
                    crate::shadow::fourier::DEFAULT_AZIMUTHS,
                    max_cells,
                )?))
            }
        })
    }

    /// Visible fraction of a disc per model cell (`NaN` for holes).
    pub fn visible_fraction(
        &self,
        hf: &HeightField,
        observer_height_m: f64,
        light_in_model: [f64; 3],
        angular_radius_rad: f64,
    ) -> anyhow::Result<Vec<f32>> {
        Ok(match self {
            MapEngine::Direct(e) => {
                e.visible_fraction(hf, observer_height_m, light_in_model, angular_radius_rad)?
            }
            MapEngine::Fourier(map) => {
                crate::shadow::fourier::visible_fraction(map, light_in_model, angular_radius_rad)?
            }
        })
    }

    /// Hard mask of the disc centre per model cell (1 lit, 0 shadow, 255 nodata).
    pub fn hard_mask(
        &self,
        hf: &HeightField,
        observer_height_m: f64,
        light_in_model: [f64; 3],
    ) -> anyhow::Result<Vec<u8>> {
        Ok(match self {
            MapEngine::Direct(e) => e.hard_mask(hf, observer_height_m, light_in_model)?,
            MapEngine::Fourier(map) => crate::shadow::fourier::hard_mask(map, light_in_model)?,
        })
    }

    /// Visible fraction of a disc per DEM pixel (row-major on the output grid, `NaN` for
    /// nodata): the per-light engines from the pixels' own observers (`observers`, from
    /// [`MapGrid::pixel_observers`], or `None`: from the model cells, resampled); the Fourier
    /// horizon map per model cell, resampled.
    pub fn visible_fraction_on_dem(
        &self,
        grid: &MapGrid,
        observers: Option<&[Option<Observer>]>,
        observer_height_m: f64,
        light_in_model: [f64; 3],
        angular_radius_rad: f64,
    ) -> anyhow::Result<Vec<f32>> {
        let Some(observers) = observers else {
            return Ok(grid.to_output_f32(&self.visible_fraction(
                &grid.hf,
                observer_height_m,
                light_in_model,
                angular_radius_rad,
            )?));
        };
        Ok(match self {
            MapEngine::Direct(e) => e.visible_fraction(
                &grid.hf,
                grid.pixel_points(observers),
                light_in_model,
                angular_radius_rad,
            )?,
            MapEngine::Fourier(map) => grid.to_output_f32(
                &crate::shadow::fourier::visible_fraction(map, light_in_model, angular_radius_rad)?,
            ),
        })
    }

    /// Hard mask of the disc centre per DEM pixel (1 lit, 0 shadow, 255 nodata), as
    /// [`MapEngine::visible_fraction_on_dem`].
    pub fn hard_mask_on_dem(
        &self,
        grid: &MapGrid,
        observers: Option<&[Option<Observer>]>,
        observer_height_m: f64,
        light_in_model: [f64; 3],
    ) -> anyhow::Result<Vec<u8>> {
        let Some(observers) = observers else {
            return Ok(grid.to_output_u8(&self.hard_mask(
                &grid.hf,
                observer_height_m,
                light_in_model,
            )?));
        };
        Ok(match self {
            MapEngine::Direct(e) => {
                e.hard_mask(&grid.hf, grid.pixel_points(observers), light_in_model)?
            }
            MapEngine::Fourier(map) => {
                grid.to_output_u8(&crate::shadow::fourier::hard_mask(map, light_in_model)?)
            }
        })
    }

    /// A short description for provenance.
    pub fn describe(&self) -> String {
        match self {
            MapEngine::Direct(e) => format!("{e:?}"),
            MapEngine::Fourier(_) => {
                "Fourier horizon map (paper 001, 64 azimuths, 16 coefficients)".into()
            }
        }
    }
}

/// Runs the engine for every epoch and accumulates the map statistics per DEM pixel (CPU, rayon
/// inside the engines), with the rays from `placement`. `progress` is advanced once per epoch.
pub fn sweep(
    grid: &MapGrid,
    engine: &MapEngine,
    observer_height_m: f64,
    placement: ObserverPlacement,
    lights: &[EpochLights],
    step_h: f64,
    progress: &indicatif::ProgressBar,
) -> anyhow::Result<SweepStats> {
    // Per DEM pixel from the pixels' own observers, or per model cell (resampled at the end, as
    // the GPU sweeps).
    let on_dem_grid = placement == ObserverPlacement::Pixels;
    let observers = grid.pixel_observers(observer_height_m);
    let n = if on_dem_grid {
        observers.len()
    } else {
        grid.hf.rows * grid.hf.cols
    };
    let mut s = SweepStats {
        epochs: lights.len(),
        step_h,
        sun_fraction_sum: vec![0.0; n],
        sun_visible_count: vec![0; n],
        longest_dark_epochs: vec![0; n],
        earth_visible_count: vec![0; n],
        sun_and_earth_count: None,
        below_sphere: None,
        on_dem_grid,
    };
    let mut sun_and_earth_count = vec![0_u32; n];
    let mut current_dark = vec![0_u32; n];
    let mut below = BelowSphereTally::new(&observers);
    for l in lights {
        let fraction = |light, radius| {
            if on_dem_grid {
                engine.visible_fraction_on_dem(
                    grid,
                    Some(&observers),
                    observer_height_m,
                    light,
                    radius,
                )
            } else {
                engine.visible_fraction(&grid.hf, observer_height_m, light, radius)
            }
        };
        let sun = fraction(l.sun, l.sun_radius_rad)?;
        if on_dem_grid {
            below.add(grid, l.sun, &sun)?;
        }
        let earth = fraction(l.earth, l.earth_radius_rad)?;
        s.sun_fraction_sum
            .par_iter_mut()
            .zip(s.sun_visible_count.par_iter_mut())
            .zip(s.longest_dark_epochs.par_iter_mut())
            .zip(s.earth_visible_count.par_iter_mut())
            .zip(sun_and_earth_count.par_iter_mut())
            .zip(current_dark.par_iter_mut())
            .enumerate()
            .for_each(|(i, (((((sum, vis), longest), ev), both), dark))| {
                let (fs, fe) = (sun[i], earth[i]);
                if fs.is_nan() {
                    return;
                }
                *sum += f64::from(fs);
                let sun_up = fs > VISIBLE_MIN_FRACTION;
                let earth_up = fe > VISIBLE_MIN_FRACTION;
                if sun_up {
                    *vis += 1;
                    *dark = 0;
                } else {
                    *dark += 1;
                    *longest = (*longest).max(*dark);
                }
                if earth_up {
                    *ev += 1;
                }
                if sun_up && earth_up {
                    *both += 1;
                }
            });
        progress.inc(1);
    }
    s.sun_and_earth_count = Some(sun_and_earth_count);
    s.below_sphere = on_dem_grid.then(|| below.finish());
    Ok(s)
}

/// The GPU twin of [`sweep`]: two GPU-resident sweeps
/// ([`crate::gpu::sweep_accumulate::sweep_stats_gpu`], brute-force march), one over the Sun's
/// directions and one over the Earth's, each a hard shadow of the disc centre. So, unlike the
/// CPU sweep, `sun_fraction_sum` is the count of epochs with the Sun's centre visible, a cell is
/// "visible" when the disc centre is (not any part of the disc), and `sun_and_earth_count` is
/// `None` (the sweep keeps no per-epoch masks to combine). Holes (NaN heights) are left untouched
/// by the kernel and masked by [`write_sweep`].
#[cfg(feature = "gpu")]
pub fn sweep_gpu(
    ctx: &crate::gpu::GpuContext,
    grid: &MapGrid,
    observer_height_m: f64,
    lights: &[EpochLights],
    step_h: f64,
) -> anyhow::Result<SweepStats> {
    use crate::gpu::shadow_march::GpuMarchGrid;
    use crate::gpu::sweep_accumulate::{SweepOptions, sweep_stats_gpu};
    use crate::shadow::gpu_twins::{MarchGrid, light_to_f32};
    let march = MarchGrid::from_height_field(&grid.hf, observer_height_m)?;
    let on_gpu = GpuMarchGrid::upload(ctx, &march)?;
    let table = |pick: fn(&EpochLights) -> [f64; 3]| -> Vec<[f32; 4]> {
        lights
            .iter()
            .map(|l| light_to_f32(&Vector3::from(pick(l))))
            .collect()
    };
    let sun = sweep_stats_gpu(ctx, &on_gpu, &table(|l| l.sun), SweepOptions::default())?;
    let earth = sweep_stats_gpu(ctx, &on_gpu, &table(|l| l.earth), SweepOptions::default())?;
    Ok(SweepStats {
        epochs: lights.len(),
        step_h,
        sun_fraction_sum: sun.iter().map(|c| f64::from(c.lit_epochs)).collect(),
        sun_visible_count: sun.iter().map(|c| c.lit_epochs).collect(),
        longest_dark_epochs: sun.iter().map(|c| c.longest_dark_run_epochs).collect(),
        earth_visible_count: earth.iter().map(|c| c.lit_epochs).collect(),
        sun_and_earth_count: None,
        below_sphere: None,
        on_dem_grid: false,
    })
}

/// The soft GPU twin of [`sweep`] (issue 7 item 3): one GPU-resident sweep
/// ([`crate::gpu::dp::dp_sweep_gpu`]) computes per epoch the DP visible fractions of the Sun's
/// and the Earth's discs (max-mipmap shadow cost `J*` + disc occlusion, as
/// [`crate::shadow::dp::visible_fraction`]) and folds them with the same definitions as [`sweep`]
/// (mean visible fraction, "visible" = fraction > [`VISIBLE_MIN_FRACTION`], longest Sun-dark
/// run, Earth and Sun-and-Earth counts). The light table goes up once (two f32 discs per epoch);
/// nothing is read back per epoch. Whatever `--engine` says, the GPU runs DP. `tiling` chooses
/// between the whole-grid sweep and the 2-D tiled sweep (docs/gpu.md, "Large grids").
#[cfg(feature = "gpu")]
pub fn sweep_gpu_soft(
    ctx: &crate::gpu::GpuContext,
    grid: &MapGrid,
    observer_height_m: f64,
    lights: &[EpochLights],
    step_h: f64,
    tiling: crate::gpu::tiles::DpTiling,
) -> anyhow::Result<SweepStats> {
    use crate::gpu::dp::{DpSweepOptions, GpuDpGrid, dp_sweep_gpu};
    use crate::gpu::tiles::{DpTileSweepOptions, dp_sweep_tiled_gpu};
    use crate::shadow::gpu_twins::{DpMip, MarchGrid, disc_light_to_f32};
    let march = MarchGrid::from_height_field(&grid.hf, observer_height_m)?;
    let table: Vec<[f32; 4]> = lights
        .iter()
        .flat_map(|l| {
            [
                disc_light_to_f32(&Vector3::from(l.sun), l.sun_radius_rad),
                disc_light_to_f32(&Vector3::from(l.earth), l.earth_radius_rad),
            ]
        })
        .collect();
    let stats = match tiling.resolve_sweep(ctx, &march)? {
        Some(tile_cells) => {
            dp_sweep_tiled_gpu(ctx, &march, &table, DpTileSweepOptions::new(tile_cells))?.0
        }
        None => {
            let mip = DpMip::build(&march);
            let on_gpu = GpuDpGrid::upload(ctx, &march, &mip)?;
            dp_sweep_gpu(ctx, &on_gpu, &table, DpSweepOptions::default())?
        }
    };
    Ok(SweepStats {
        epochs: lights.len(),
        step_h,
        sun_fraction_sum: stats
            .iter()
            .map(|c| f64::from(c.sun_fraction_sum) - f64::from(c.sun_fraction_comp))
            .collect(),
        sun_visible_count: stats.iter().map(|c| c.sun_visible_epochs).collect(),
        longest_dark_epochs: stats.iter().map(|c| c.longest_dark_run_epochs).collect(),
        earth_visible_count: stats.iter().map(|c| c.earth_visible_epochs).collect(),
        sun_and_earth_count: Some(stats.iter().map(|c| c.sun_and_earth_epochs).collect()),
        below_sphere: None,
        on_dem_grid: false,
    })
}

/// A soft-shadow kernel output as a fraction: `NaN` for a hole
/// ([`crate::shadow::gpu_twins::NODATA_FRACTION`], -1), else clamped to [0, 1] (f32 rounding
/// leaves a few lit-edge cells at -1e-7, which a `< 0` hole test would turn into holes).
#[cfg(feature = "gpu")]
fn fraction_from_gpu(f: f32) -> f32 {
    if f < crate::shadow::gpu_twins::NODATA_FRACTION + 0.5 {
        f32::NAN
    } else {
        f.clamp(0.0, 1.0)
    }
}

/// One-light maps on the GPU (issue 7 item 2): the DP visible fraction of a disc of angular
/// radius `angular_radius_rad` per model cell (`NaN` for holes), or with `angular_radius_rad` =
/// 0 the hard mask of the disc centre. Every `--engine` except `fourier` maps to this kernel on
/// the GPU (see docs/gpu.md). `tiling` chooses between the whole-grid kernel and 2-D tiles
/// (automatically: tiles when the grid or its mipmap exceed one storage binding; docs/gpu.md,
/// "Large grids").
#[cfg(feature = "gpu")]
pub fn visible_fraction_gpu(
    ctx: &crate::gpu::GpuContext,
    hf: &HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
    tiling: crate::gpu::tiles::DpTiling,
) -> anyhow::Result<Vec<f32>> {
    use crate::gpu::dp::{GpuDpGrid, dp_visible_gpu};
    use crate::gpu::shadow_march::DEFAULT_BAND_BYTES;
    use crate::gpu::tiles::{DpTileOptions, dp_visible_tiled_gpu};
    use crate::shadow::gpu_twins::{DpMip, MarchGrid, disc_light_to_f32};
    let march = MarchGrid::from_height_field(hf, observer_height_m)?;
    let light = disc_light_to_f32(&Vector3::from(light_in_model), angular_radius_rad);
    let out = match tiling.resolve(ctx, &march)? {
        Some(tile_cells) => {
            dp_visible_tiled_gpu(ctx, &march, light, DpTileOptions::new(tile_cells))?.values
        }
        None => {
            let mip = DpMip::build(&march);
            let on_gpu = GpuDpGrid::upload(ctx, &march, &mip)?;
            dp_visible_gpu(ctx, &on_gpu, light, DEFAULT_BAND_BYTES)?
        }
    };
    Ok(out.into_iter().map(fraction_from_gpu).collect())
}

/// The renderer's per-cell Sun and Earth visible fractions on the GPU DP kernel (the GPU twin
/// of what [`crate::render::Scene::new`] computes with the CPU engine, observer on the ground):
/// the height field and its DP mip are uploaded once, then each frame costs two kernel runs.
#[cfg(feature = "gpu")]
pub struct GpuSceneFractions {
    grid: crate::gpu::dp::GpuDpGrid,
}

#[cfg(feature = "gpu")]
impl GpuSceneFractions {
    /// Uploads `hf` (observer height 0, as in [`crate::render::Scene::new`]).
    pub fn upload(ctx: &crate::gpu::GpuContext, hf: &HeightField) -> anyhow::Result<Self> {
        use crate::shadow::gpu_twins::{DpMip, MarchGrid};
        let march = MarchGrid::from_height_field(hf, 0.0)?;
        let mip = DpMip::build(&march);
        Ok(Self {
            grid: crate::gpu::dp::GpuDpGrid::upload(ctx, &march, &mip)?,
        })
    }

    /// The (Sun, Earth) visible fractions per model cell for `lights` (`NaN` for holes),
    /// row-major like `hf.z_m`, ready for [`crate::render::Scene::with_fractions`].
    pub fn fractions(
        &self,
        ctx: &crate::gpu::GpuContext,
        lights: &crate::render::Lights,
    ) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
        use crate::gpu::dp::dp_visible_gpu;
        use crate::gpu::shadow_march::DEFAULT_BAND_BYTES;
        use crate::shadow::gpu_twins::disc_light_to_f32;
        let one = |dir: [f64; 3], radius_rad: f64| -> anyhow::Result<Vec<f32>> {
            let light = disc_light_to_f32(&Vector3::from(dir), radius_rad);
            Ok(dp_visible_gpu(ctx, &self.grid, light, DEFAULT_BAND_BYTES)?
                .into_iter()
                .map(fraction_from_gpu)
                .collect())
        };
        Ok((
            one(lights.sun, lights.sun_radius_rad)?,
            one(lights.earth, lights.earth_radius_rad)?,
        ))
    }
}

impl MapEngine {
    /// The Fourier engine with its horizon map built on the GPU
    /// ([`crate::gpu::fourier::build_horizon_map_gpu`]) with the parameters of
    /// [`MapEngine::new`] (64 azimuths, 16 coefficients, rays of `max(rows, cols)` cells).
    #[cfg(feature = "gpu")]
    pub fn fourier_gpu(
        ctx: &crate::gpu::GpuContext,
        grid: &MapGrid,
        observer_height_m: f64,
    ) -> anyhow::Result<Self> {
        let params = crate::shadow::fourier::HorizonMapParams {
            observer_height_m,
            n_azimuths: crate::shadow::fourier::DEFAULT_AZIMUTHS,
            max_distance_cells: grid.hf.rows.max(grid.hf.cols),
            n_coeffs: crate::shadow::fourier::DEFAULT_COEFFS,
        };
        Ok(MapEngine::Fourier(Box::new(
            crate::gpu::fourier::build_horizon_map_gpu(ctx, &grid.hf, &params)
                .context("building the horizon map on the GPU")?,
        )))
    }
}

/// One-light Fourier maps on the GPU: the visible fraction of a disc (radius 0: the hard test
/// as 1 / 0) per model cell from a horizon map resident on the GPU, `NaN` for holes (the GPU
/// twin of [`crate::shadow::fourier::visible_fraction`]).
#[cfg(feature = "gpu")]
pub fn fourier_fraction_gpu(
    ctx: &crate::gpu::GpuContext,
    on_gpu: &crate::gpu::fourier::GpuHorizonMap,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
) -> anyhow::Result<Vec<f32>> {
    Ok(on_gpu
        .visible_fraction(ctx, light_in_model, angular_radius_rad)
        .context("evaluating the horizon map on the GPU")?
        .into_iter()
        .map(fraction_from_gpu)
        .collect())
}

/// [`visible_fraction_gpu`] at radius 0 as a mask: 1 lit, 0 shadow, 255 nodata.
#[cfg(feature = "gpu")]
pub fn hard_mask_gpu(
    ctx: &crate::gpu::GpuContext,
    hf: &HeightField,
    observer_height_m: f64,
    light_in_model: [f64; 3],
    tiling: crate::gpu::tiles::DpTiling,
) -> anyhow::Result<Vec<u8>> {
    Ok(
        visible_fraction_gpu(ctx, hf, observer_height_m, light_in_model, 0.0, tiling)?
            .into_iter()
            .map(|f| {
                if f.is_nan() {
                    crate::shadow::MASK_NODATA
                } else if f > 0.5 {
                    crate::shadow::MASK_LIT
                } else {
                    crate::shadow::MASK_SHADOW
                }
            })
            .collect(),
    )
}

/// The light directions (model space) and angular radii of one epoch.
#[derive(Debug, Clone, Copy)]
pub struct EpochLights {
    /// The epoch.
    pub epoch: Epoch,
    /// Unit vector to the Sun, model space.
    pub sun: [f64; 3],
    /// The Sun's angular radius, radians.
    pub sun_radius_rad: f64,
    /// Unit vector to the Earth, model space.
    pub earth: [f64; 3],
    /// The Earth's angular radius, radians.
    pub earth_radius_rad: f64,
}

/// Light directions for every epoch, seen from the map centre (f64 ephemeris reduced to unit
/// vectors in model space).
pub fn epoch_lights(
    grid: &MapGrid,
    kernels: &Kernels,
    epochs: &[Epoch],
    abcorr: AbCorr,
) -> anyhow::Result<Vec<EpochLights>> {
    let site = grid.centre_site()?;
    let sky = ephem::sun_earth_series(kernels, &[site], epochs, abcorr)?;
    Ok(epochs
        .iter()
        .zip(&sky[0])
        .map(|(&epoch, v)| EpochLights {
            epoch,
            sun: grid.light_from_moon_me(&v.sun.pos_in_moon_me_km),
            sun_radius_rad: v.sun.radius_deg.to_radians(),
            earth: grid.light_from_moon_me(&v.earth.pos_in_moon_me_km),
            earth_radius_rad: v.earth.radius_deg.to_radians(),
        })
        .collect())
}

/// Writes the statistics of a sweep as GeoTIFFs and PNG previews into `out_dir`; returns the file
/// names.
pub fn write_sweep(
    grid: &MapGrid,
    s: &SweepStats,
    out_dir: &Path,
    span: &str,
) -> anyhow::Result<Vec<String>> {
    let n_epochs = s.epochs.max(1) as f64;
    let pct = |count: &[u32]| -> Vec<f32> {
        count
            .iter()
            .map(|&c| (100.0 * f64::from(c) / n_epochs) as f32)
            .collect()
    };
    // Nodata of the arrays' own grid: the DEM's pixels or the model cells (see `on_dem_grid`).
    let nodata_model: Vec<bool> = if s.on_dem_grid {
        grid.dem.heights_m.iter().map(|z| z.is_nan()).collect()
    } else {
        grid.hf.z_m.iter().map(|z| z.is_nan()).collect()
    };
    let mask_nodata = |v: Vec<f32>| -> Vec<f32> {
        v.into_iter()
            .zip(&nodata_model)
            .map(|(x, &nd)| if nd { f32::NAN } else { x })
            .collect()
    };
    let sun_mean_pct = mask_nodata(
        s.sun_fraction_sum
            .iter()
            .map(|&x| (100.0 * x / n_epochs) as f32)
            .collect(),
    );
    let longest_dark_h = mask_nodata(
        s.longest_dark_epochs
            .iter()
            .map(|&k| (f64::from(k) * s.step_h) as f32)
            .collect(),
    );
    let earth_pct = mask_nodata(pct(&s.earth_visible_count));
    let sun_visible_pct = mask_nodata(pct(&s.sun_visible_count));
    let both_what = if s.sun_and_earth_count.is_some() {
        "Sun and Earth both (partly) visible, % of time"
    } else {
        "Sun and Earth both visible, % of time: not computed by the GPU sweep (all NaN)"
    };
    let both_pct = match &s.sun_and_earth_count {
        Some(count) => mask_nodata(pct(count)),
        None => vec![f32::NAN; nodata_model.len()],
    };
    let psr: Vec<u8> = s
        .sun_visible_count
        .iter()
        .zip(&nodata_model)
        .map(|(&c, &nd)| if nd { MASK_NODATA } else { u8::from(c == 0) })
        .collect();

    let mut files = Vec::new();
    let (rows, cols) = (grid.dem.grid.rows, grid.dem.grid.cols);
    let span_h = n_epochs * s.step_h;
    let continuous: [(&str, &str, Vec<f32>, f64, String); 5] = [
        (
            "sun_illumination_pct",
            "average Sun illumination (time-mean visible fraction of the disc), %",
            sun_mean_pct,
            100.0,
            "% of time (disc-weighted)".into(),
        ),
        (
            "sun_visible_pct",
            "Sun visible (any part of the disc), % of time",
            sun_visible_pct,
            100.0,
            "% of time".into(),
        ),
        (
            "longest_dark_h",
            "longest continuous darkness (Sun entirely hidden), hours",
            longest_dark_h,
            span_h,
            "hours".into(),
        ),
        (
            "earth_visible_pct",
            "Earth visible (any part of the disc), % of time",
            earth_pct,
            100.0,
            "% of time".into(),
        ),
        (
            "sun_and_earth_pct",
            both_what,
            both_pct,
            100.0,
            "% of time".into(),
        ),
    ];
    for (name, what, model, max, unit) in continuous {
        let out = if s.on_dem_grid {
            model
        } else {
            grid.to_output_f32(&model)
        };
        // Colour bar up to the data's maximum, rounded up to a tenth of the full scale.
        let data_max = out
            .iter()
            .filter(|v| v.is_finite())
            .fold(0.0_f32, |a, &b| a.max(b));
        let tenth = max / 10.0;
        let max = ((f64::from(data_max) / tenth).ceil() * tenth).clamp(tenth, max);
        let tif = format!("{name}.tif");
        grid.write_f32(&out_dir.join(&tif), &out, what)?;
        let png = format!("{name}.png");
        write_map_preview(
            &out_dir.join(&png),
            &format!("{what} — {span}"),
            &out,
            rows,
            cols,
            &MapLegend::Continuous {
                min: 0.0,
                max,
                unit,
            },
        )?;
        files.extend([tif, png]);
    }
    let psr_out = if s.on_dem_grid {
        psr
    } else {
        grid.to_output_u8(&psr)
    };
    grid.write_u8(
        &out_dir.join("psr_mask.tif"),
        &psr_out,
        "permanently shadowed over the span: 1 never lit, 0 lit at least once, 255 no data",
    )?;
    let psr_f: Vec<f32> = psr_out
        .iter()
        .map(|&v| {
            if v == MASK_NODATA {
                f32::NAN
            } else {
                f32::from(v)
            }
        })
        .collect();
    write_map_preview(
        &out_dir.join("psr_mask.png"),
        &format!("Never lit (PSR over the span) — {span}"),
        &psr_f,
        rows,
        cols,
        &MapLegend::Categories(vec![
            (
                1.0,
                plotters::style::RGBColor(20, 20, 60),
                "never lit".into(),
            ),
            (
                0.0,
                plotters::style::RGBColor(250, 220, 90),
                "lit at least once".into(),
            ),
        ]),
    )?;
    files.extend(["psr_mask.tif".to_string(), "psr_mask.png".to_string()]);
    Ok(files)
}

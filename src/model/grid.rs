//! The model grid of a map, a frame or a site DP search: every DEM layer resampled into the
//! curvature-exact model space ([`crate::terrain::model_space`]) on the DEM's own grid, and the
//! way back to the output (DEM) grid.
//!
//! **Every layer.** The model grid covers the union of all layers' extents at the finest layer's
//! pixel size (each model cell takes the finest layer with data there, [`resample_to_model_space`]),
//! so far-field layers cast shadows exactly as in the per-site horizon engine
//! ([`crate::horizon`]); only the cells under the output raster are evaluated
//! ([`HeightField::window`]). Beyond [`MAX_MODEL_CELLS`] the grid is clipped around the map and
//! [`MapGrid::clipped_to_km`] says where (the caller warns).

use std::path::Path;

use anyhow::Context as _;
use nalgebra::Vector3;
use rayon::prelude::*;

use crate::ephem::Site;
use crate::output::BelowSphereExits;
use crate::shadow::{MASK_NODATA, Observer, Observers};
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
    pub(super) surface_in_model: Vec<Option<Vector3<f64>>>,
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

    /// [`MapGrid::pixel_points`] whose rays march the model grid only beyond the near field
    /// ([`super::near_field::NEAR_FIELD_CELLS`]): the near field is the DEM's own lattice's
    /// ([`MapGrid::near_field_costs`]).
    pub fn pixel_points_beyond_near_field<'a>(
        &self,
        observers: &'a [Option<Observer>],
    ) -> Observers<'a> {
        Observers::Points {
            list: observers,
            min_s_cells: super::near_field::NEAR_FIELD_CELLS,
        }
    }

    /// Says what the grid is (one note line: size, spacing, centre) and warns in one line when
    /// the far field was clipped to [`MAX_MODEL_CELLS`].
    pub fn announce(&self) {
        crate::note!(
            "penumbra: model grid {} x {} at {} m centred on ({:.4}, {:.4}) deg (every layer)",
            self.hf.rows,
            self.hf.cols,
            self.hf.px_m,
            self.hf.centre_lat_deg,
            self.hf.centre_lon_deg
        );
        self.warn_if_clipped();
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
pub(crate) struct BelowSphereTally<'a> {
    observers: &'a [Option<Observer>],
    any: Vec<bool>,
    cell_epochs: u64,
}

impl<'a> BelowSphereTally<'a> {
    /// A tally for the pixels' `observers` ([`MapGrid::pixel_observers`]).
    pub(crate) fn new(observers: &'a [Option<Observer>]) -> Self {
        BelowSphereTally {
            observers,
            any: vec![false; observers.len()],
            cell_epochs: 0,
        }
    }

    /// Adds one epoch's Sun `fraction` (per pixel) for the light `light_in_model`.
    pub(crate) fn add(
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

    pub(crate) fn finish(self) -> BelowSphereExits {
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

    /// Writes a raster of f32 (NaN = nodata) or u8 (255 = nodata) on the output grid with
    /// provenance metadata.
    pub fn write<T: MapSample>(
        &self,
        path: &Path,
        values: &[T],
        info: &RasterInfo<'_>,
    ) -> anyhow::Result<()> {
        write_on(&self.dem, path, values, info)
    }

    /// The azimuth and elevation (degrees) of a model-space light direction at the map centre.
    pub fn az_el_deg_at_centre(&self, light: [f64; 3]) -> (f64, f64) {
        let enu = self.hf.model_from_enu().transpose() * nalgebra::Vector3::from(light);
        crate::frames::az_el_deg_from_enu(&enu)
    }
}

/// What a map raster holds, for its GeoTIFF: the band's description and unit, and the run's
/// parameters as metadata items (epoch, Sun direction, observer height, engine, span, …).
#[derive(Debug, Clone, Default)]
pub struct RasterInfo<'a> {
    /// What the values are (band description and the `content` item).
    pub description: &'a str,
    /// Their unit (`%`, `h`, `W m-2`; empty for fractions and classes).
    pub unit: &'a str,
    /// Further metadata items (`name`, value).
    pub items: Vec<(String, String)>,
}

impl<'a> RasterInfo<'a> {
    /// A raster described by `description`, in `unit`.
    pub fn new(description: &'a str, unit: &'a str) -> Self {
        Self {
            description,
            unit,
            items: Vec::new(),
        }
    }
}

/// Writes a raster of f32 (NaN = nodata) or u8 (255 = nodata) on `dem`'s grid with provenance
/// metadata.
pub fn write_on<T: MapSample>(
    dem: &Dem,
    path: &Path,
    values: &[T],
    info: &RasterInfo<'_>,
) -> anyhow::Result<()> {
    crate::terrain::write_geotiff(
        path,
        &dem.grid,
        &dem.projection,
        values,
        Some(T::NODATA),
        &metadata(info),
        band(info),
    )
    .with_context(|| format!("writing {}", path.display()))
}

/// The sample types of maps, with their nodata value.
pub trait MapSample: crate::terrain::WriteSample {
    /// The value of a pixel without data.
    const NODATA: Self;
}

impl MapSample for f32 {
    const NODATA: f32 = f32::NAN;
}

impl MapSample for u8 {
    const NODATA: u8 = MASK_NODATA;
}

fn band<'a>(info: &RasterInfo<'a>) -> crate::terrain::BandInfo<'a> {
    crate::terrain::BandInfo {
        description: info.description,
        unit: info.unit,
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

fn metadata<'a>(info: &'a RasterInfo<'_>) -> Vec<(&'a str, &'a str)> {
    let mut items = vec![
        ("software", concat!("penumbra ", env!("CARGO_PKG_VERSION"))),
        ("git_commit", env!("PENUMBRA_GIT_COMMIT")),
        ("content", info.description),
    ];
    items.extend(info.items.iter().map(|(k, v)| (k.as_str(), v.as_str())));
    items
}

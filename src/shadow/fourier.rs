//! Fourier-compressed horizon maps after paper 001 (Fritsch et al., "Fast Planetary Shadows
//! using Fourier-Compressed Horizon Maps").
//!
//! For every cell of a model-space [`HeightField`] the horizon `α_h(θ)` is sampled at
//! `n_azimuths` azimuths `θ_n = 2πn/N` (from model north `+y`, clockwise toward east `+x`): an
//! angle in radians above the model x/y plane, the largest `atan((z_s − z_obs) / t_s)` over the
//! crossings of the horizontal ray with the centre lines (the surface of [`crate::shadow`],
//! marched by [`crate::shadow::brute`]), never below the bare sphere's dip. So
//! `light elevation > α_h(light azimuth)` is brute force's "not blocked" test, up to ties.
//!
//! The real DFT is truncated to `K` complex coefficients (default 16, stored as `half::f16`)
//! with the weights folded in, so paper eq. 3 holds verbatim:
//! `α_h(θ) = Σ_k (Re X_k cos kθ − Im X_k sin kθ)`. [`HorizonMap::mipmapped`] keeps coefficients
//! `4l … 4l+3` at `1/2^l` of the resolution (paper §3.2). Soft shadows use the circular segment
//! through the horizon at the disc's edge azimuths
//! ([`crate::illum::disc::chord_visible_fraction`]). Files: [`HorizonMap::write_tiff`],
//! [`HorizonMap::read_tiff`]. Why the dip floor, the file layout and the accuracy:
//! `docs/shadow.md`, "Fourier-compressed horizon maps".

use std::io::{BufReader, Cursor};
use std::path::Path;

use half::f16;
use nalgebra::Vector3;
use rayon::prelude::*;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::encoder::{TiffEncoder, colortype};
use tiff::tags::Tag;

use super::{
    LightDir, MASK_LIT, MASK_NODATA, MASK_SHADOW, ShadowError, brute, check_observer_height,
    check_radius, max_height_m, observer_at, unit_light,
};
use crate::illum::disc::{LimbDarkening, chord_visible_fraction};
use crate::terrain::HeightField;

/// Number of complex coefficients kept by default (paper 001: 16).
pub const DEFAULT_COEFFS: usize = 16;
/// Coefficients per mip level (paper 001: four complex coefficients per RGBA32 texel).
pub const COEFFS_PER_LEVEL: usize = 4;
/// Default number of sampled azimuths (the GPU target in `docs/PERFORMANCE.md` uses 720).
pub const DEFAULT_AZIMUTHS: usize = 64;
/// Value of the `format` field of the TIFF metadata.
const FORMAT_NAME: &str = "penumbra-fourier-horizon-map";

/// Errors of the Fourier horizon maps.
#[derive(Debug, thiserror::Error)]
pub enum FourierError {
    /// An input of the shadow engines (observer height, light, radius, parameter) is invalid.
    #[error(transparent)]
    Shadow(#[from] ShadowError),
    /// Reading or writing the TIFF failed (I/O or encoding).
    #[error("{path}: {detail}")]
    Tiff {
        /// The file.
        path: String,
        /// What went wrong.
        detail: String,
    },
    /// The TIFF is readable but not a horizon map of this format.
    #[error("{path}: not a penumbra Fourier horizon map: {detail}")]
    Format {
        /// The file.
        path: String,
        /// What is wrong with it.
        detail: String,
    },
}

/// Geometry and parameters of a horizon map (the TIFF's JSON metadata).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HorizonMapMeta {
    /// Always `penumbra-fourier-horizon-map`.
    pub format: String,
    /// Number of rows of the height field.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Cell size, metres.
    pub px_m: f64,
    /// Model x of the left edge of column 0, metres.
    pub x_left_m: f64,
    /// Model y of the top edge of row 0, metres.
    pub y_top_m: f64,
    /// Latitude of the model origin, degrees.
    pub centre_lat_deg: f64,
    /// East longitude of the model origin, degrees.
    pub centre_lon_deg: f64,
    /// Rotation of the model axes from east/north at the origin, degrees (counter-clockwise seen
    /// from above; 0 in maps written before it was recorded).
    #[serde(default)]
    pub rotation_deg: f64,
    /// Observer height above the ground, metres.
    pub observer_height_m: f64,
    /// Number of sampled azimuths before the DFT.
    pub n_azimuths: usize,
    /// Longest ray, cells.
    pub max_distance_cells: usize,
    /// Number of complex coefficients kept.
    pub n_coeffs: usize,
}

/// A Fourier-compressed horizon map (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct HorizonMap {
    /// Geometry and parameters.
    pub meta: HorizonMapMeta,
    /// Coefficients, row-major per cell, `2 * n_coeffs` values per cell: `Re X_0, Im X_0,
    /// Re X_1, …` (radians); all `NaN` for holes.
    pub coeffs: Vec<f16>,
}

/// The parameters of a horizon-map build (the CPU engine's [`HorizonMap::build_with`] arguments,
/// shared with the GPU build `crate::gpu::fourier::build_horizon_map_gpu`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HorizonMapParams {
    /// Observer height above the ground (radial), metres.
    pub observer_height_m: f64,
    /// Number of sampled azimuths before the DFT.
    pub n_azimuths: usize,
    /// Longest ray, cells.
    pub max_distance_cells: usize,
    /// Number of complex coefficients kept.
    pub n_coeffs: usize,
}

impl HorizonMapParams {
    /// Checks the parameters as [`HorizonMap::build_with`] does.
    pub fn check(&self) -> Result<(), ShadowError> {
        check_observer_height(self.observer_height_m)?;
        check_params(self.n_azimuths, self.n_coeffs, self.max_distance_cells)
    }
}

impl HorizonMapMeta {
    /// The metadata of a map of `hf` built with `params`.
    pub fn for_height_field(hf: &HeightField, params: &HorizonMapParams) -> Self {
        HorizonMapMeta {
            format: FORMAT_NAME.to_string(),
            rows: hf.rows,
            cols: hf.cols,
            px_m: hf.px_m,
            x_left_m: hf.x_left_m,
            y_top_m: hf.y_top_m,
            centre_lat_deg: hf.centre_lat_deg,
            centre_lon_deg: hf.centre_lon_deg,
            rotation_deg: hf.rotation_rad.to_degrees(),
            observer_height_m: params.observer_height_m,
            n_azimuths: params.n_azimuths,
            max_distance_cells: params.max_distance_cells,
            n_coeffs: params.n_coeffs,
        }
    }
}

/// Checks the build parameters.
/// Most azimuths sampled per cell (0.05° apart).
pub const MAX_AZIMUTHS: usize = 7200;

fn check_params(
    n_azimuths: usize,
    n_coeffs: usize,
    max_distance_cells: usize,
) -> Result<(), ShadowError> {
    if n_coeffs == 0 {
        return Err(ShadowError::InvalidParameter {
            name: "n_coeffs",
            reason: "must be at least 1",
        });
    }
    if n_azimuths > MAX_AZIMUTHS {
        return Err(ShadowError::InvalidParameter {
            name: "n_azimuths",
            reason: "must be at most 7200 (0.05 deg apart)",
        });
    }
    if n_azimuths < 2 * n_coeffs {
        return Err(ShadowError::InvalidParameter {
            name: "n_azimuths",
            reason: "must be at least twice the number of coefficients (Nyquist)",
        });
    }
    if max_distance_cells == 0 {
        return Err(ShadowError::InvalidParameter {
            name: "max_distance_cells",
            reason: "must be at least 1",
        });
    }
    Ok(())
}

/// What the horizon sampling of every row shares: the height field, the observers' height
/// above the ground (m), the horizontal directions of the sampled azimuths, the rays' reach
/// (cells) and the field's highest cell (model z, m).
struct HorizonSampler<'a> {
    hf: &'a HeightField,
    observer_height_m: f64,
    dirs: Vec<LightDir>,
    max_distance_cells: usize,
    z_max_m: f64,
}

impl<'a> HorizonSampler<'a> {
    fn new(
        hf: &'a HeightField,
        observer_height_m: f64,
        n_azimuths: usize,
        max_distance_cells: usize,
    ) -> Self {
        HorizonSampler {
            hf,
            observer_height_m,
            dirs: azimuth_dirs(n_azimuths),
            max_distance_cells,
            z_max_m: max_height_m(hf),
        }
    }

    /// Horizon elevations (radians above the model x/y plane) of every cell of one row at the
    /// `n_az` azimuths into `out` (`cols * n_az`, cell-major); `NaN` for holes.
    fn row(&self, row: usize, out: &mut [f32]) {
        let (hf, dirs, z_max_m) = (self.hf, &self.dirs, self.z_max_m);
        let n_az = dirs.len();
        let max_s = self.max_distance_cells as f64;
        for col in 0..hf.cols {
            let cell = &mut out[col * n_az..(col + 1) * n_az];
            let observer = if hf.evaluates(row, col) {
                observer_at(hf, row, col, self.observer_height_m)
            } else {
                None
            };
            let Some(obs) = observer else {
                cell.fill(f32::NAN);
                continue;
            };
            for (v, dir) in cell.iter_mut().zip(dirs) {
                let mut best = sphere_floor_tan(hf, &obs, dir);
                brute::march(hf, &obs, dir, |s, z| {
                    if s > max_s {
                        return false;
                    }
                    let t_m = s * hf.px_m;
                    if let Some(z) = z {
                        best = best.max((z - obs.z_m) / t_m);
                    }
                    // Beyond t no sample rises above (z_max - z_obs) / t' (t' >= t): the bound at
                    // t when the top is above the observer, else 0 (approached as t' grows).
                    ((z_max_m - obs.z_m) / t_m).max(0.0) > best
                });
                *v = best.atan() as f32;
            }
        }
    }
}

/// The floor of a sampled horizon (`tan` above the model x/y plane) toward the horizontal `dir`:
/// the bare sphere's horizon, the dip `sqrt(2h/R)` below the observer's local horizontal (`h` its
/// height above the sphere, to second order `z + (x² + y²)/2R`). See the module docs.
fn sphere_floor_tan(hf: &HeightField, obs: &super::Observer, dir: &LightDir) -> f64 {
    let r = crate::MOON_RADIUS_M;
    let (x, y) = hf.xy_from_row_col(obs.row, obs.col);
    let up = hf.up_at(x, y, obs.z_m);
    let tan_local = -(up.x * dir.unit.x + up.y * dir.unit.y) / up.z;
    let h = obs.z_m + (x * x + y * y) / (2.0 * r);
    let dip = (2.0 * h.max(0.0) / r).sqrt();
    (tan_local.atan() - dip).tan()
}

/// Horizontal unit directions of the `n_az` azimuths `2πn/N` (from north, clockwise).
fn azimuth_dirs(n_az: usize) -> Vec<LightDir> {
    (0..n_az)
        .map(|n| {
            let az = std::f64::consts::TAU * n as f64 / n_az as f64;
            LightDir::new(Vector3::new(az.sin(), az.cos(), 0.0))
        })
        .collect()
}

/// The untruncated sampled horizons of every cell: `rows * cols * n_azimuths` angles (radians
/// above the model x/y plane, azimuth `2πn/N` from north clockwise), cell-major; `NaN` for holes.
/// The reference that [`HorizonMap`] compresses.
pub fn sampled_horizons_rad(
    hf: &HeightField,
    observer_height_m: f64,
    n_azimuths: usize,
    max_distance_cells: usize,
) -> Result<Vec<f32>, ShadowError> {
    check_observer_height(observer_height_m)?;
    check_params(n_azimuths, 1, max_distance_cells)?;
    let sampler = HorizonSampler::new(hf, observer_height_m, n_azimuths, max_distance_cells);
    let mut out = vec![f32::NAN; hf.rows * hf.cols * n_azimuths];
    if hf.cols == 0 {
        return Ok(out);
    }
    out.par_chunks_mut(hf.cols * n_azimuths)
        .enumerate()
        .for_each(|(row, line)| sampler.row(row, line));
    Ok(out)
}

/// Truncated real DFT of one sampled horizon with the eq. 3 weights folded in: `2 * n_coeffs`
/// values `Re X_0, Im X_0, Re X_1, …` (see the module docs).
fn truncated_dft(samples: &[f32], n_coeffs: usize) -> Vec<f64> {
    let n = samples.len() as f64;
    let mut out = vec![0.0; 2 * n_coeffs];
    for k in 0..n_coeffs {
        let w = if k == 0 { 1.0 / n } else { 2.0 / n };
        let (mut re, mut im) = (0.0, 0.0);
        for (j, &a) in samples.iter().enumerate() {
            let ang = std::f64::consts::TAU * (k * j) as f64 / n;
            re += a as f64 * ang.cos();
            im -= a as f64 * ang.sin();
        }
        out[2 * k] = w * re;
        out[2 * k + 1] = w * im;
    }
    out
}

/// Paper 001 eq. 3: `α_h(θ) = Σ_k (Re X_k cos kθ − Im X_k sin kθ)` over `coeffs` pairs.
#[inline]
fn eval_series(coeffs: impl Iterator<Item = (f32, f32)>, azimuth_rad: f64) -> f32 {
    let mut sum = 0.0f64;
    for (k, (re, im)) in coeffs.enumerate() {
        let (s, c) = (k as f64 * azimuth_rad).sin_cos();
        sum += re as f64 * c - im as f64 * s;
    }
    sum as f32
}

impl HorizonMap {
    /// Builds the map of `hf` with [`DEFAULT_COEFFS`] coefficients: samples each cell's horizon
    /// at `n_azimuths` azimuths (rays up to `max_distance_cells` cells; rayon over rows), then
    /// keeps the truncated DFT as f16.
    pub fn build(
        hf: &HeightField,
        observer_height_m: f64,
        n_azimuths: usize,
        max_distance_cells: usize,
    ) -> Result<Self, ShadowError> {
        Self::build_with(
            hf,
            observer_height_m,
            n_azimuths,
            max_distance_cells,
            DEFAULT_COEFFS,
        )
    }

    /// As [`HorizonMap::build`] with `n_coeffs` complex coefficients.
    pub fn build_with(
        hf: &HeightField,
        observer_height_m: f64,
        n_azimuths: usize,
        max_distance_cells: usize,
        n_coeffs: usize,
    ) -> Result<Self, ShadowError> {
        check_observer_height(observer_height_m)?;
        check_params(n_azimuths, n_coeffs, max_distance_cells)?;
        crate::output::guard::check_budget(
            "the horizon map",
            hf.rows as u128 * hf.cols as u128 * 4 * n_coeffs as u128,
        )
        .map_err(ShadowError::Budget)?;
        let sampler = HorizonSampler::new(hf, observer_height_m, n_azimuths, max_distance_cells);
        let per_cell = 2 * n_coeffs;
        let mut coeffs = vec![f16::NAN; hf.rows * hf.cols * per_cell];
        if hf.cols > 0 {
            coeffs
                .par_chunks_mut(hf.cols * per_cell)
                .enumerate()
                .for_each(|(row, line)| {
                    let mut samples = vec![0.0f32; hf.cols * n_azimuths];
                    sampler.row(row, &mut samples);
                    for col in 0..hf.cols {
                        let s = &samples[col * n_azimuths..(col + 1) * n_azimuths];
                        if s[0].is_nan() {
                            continue;
                        }
                        let x = truncated_dft(s, n_coeffs);
                        for (dst, v) in line[col * per_cell..(col + 1) * per_cell].iter_mut().zip(x)
                        {
                            *dst = f16::from_f64(v);
                        }
                    }
                });
        }
        let params = HorizonMapParams {
            observer_height_m,
            n_azimuths,
            max_distance_cells,
            n_coeffs,
        };
        Ok(HorizonMap {
            meta: HorizonMapMeta::for_height_field(hf, &params),
            coeffs,
        })
    }

    /// The coefficients of cell (row, col): `2 * n_coeffs` f16 values.
    #[inline]
    pub fn cell(&self, row: usize, col: usize) -> &[f16] {
        let per = 2 * self.meta.n_coeffs;
        let i = (row * self.meta.cols + col) * per;
        &self.coeffs[i..i + per]
    }

    /// Horizon elevation (radians above the model x/y plane) of cell (row, col) at `azimuth_rad`
    /// (from north, clockwise): the inverse truncated DFT, eq. 3. `NaN` for holes.
    pub fn elevation_rad(&self, row: usize, col: usize, azimuth_rad: f64) -> f32 {
        let c = self.cell(row, col);
        eval_series(
            c.chunks_exact(2).map(|p| (p[0].to_f32(), p[1].to_f32())),
            azimuth_rad,
        )
    }

    /// The paper's mip pyramid, expanded back to full resolution: coefficient `k` of every cell
    /// is replaced by the mean (holes left out) of its `2^l × 2^l` block, `l = k / 4` (4
    /// coefficients per level). Evaluating the result equals nearest-texel sampling of the
    /// pyramid.
    pub fn mipmapped(&self) -> HorizonMap {
        let (rows, cols, nk) = (self.meta.rows, self.meta.cols, self.meta.n_coeffs);
        let per = 2 * nk;
        let mut out = self.clone();
        for k in COEFFS_PER_LEVEL..nk {
            let b = 1usize << (k / COEFFS_PER_LEVEL);
            for br in (0..rows).step_by(b) {
                for bc in (0..cols).step_by(b) {
                    for part in 0..2 {
                        let (mut sum, mut n) = (0.0f64, 0usize);
                        for r in br..(br + b).min(rows) {
                            for c in bc..(bc + b).min(cols) {
                                let v = self.coeffs[(r * cols + c) * per + 2 * k + part];
                                if !v.is_nan() {
                                    sum += v.to_f64();
                                    n += 1;
                                }
                            }
                        }
                        if n == 0 {
                            continue;
                        }
                        let mean = f16::from_f64(sum / n as f64);
                        for r in br..(br + b).min(rows) {
                            for c in bc..(bc + b).min(cols) {
                                let i = (r * cols + c) * per + 2 * k + part;
                                if !out.coeffs[i].is_nan() {
                                    out.coeffs[i] = mean;
                                }
                            }
                        }
                    }
                }
            }
        }
        out
    }

    /// Mean absolute amplitude `|X_k|` (radians) of each coefficient over the valid cells (the
    /// quantity of paper 001 fig. 8).
    pub fn mean_amplitudes_rad(&self) -> Vec<f64> {
        let nk = self.meta.n_coeffs;
        let mut sum = vec![0.0; nk];
        let mut n = 0usize;
        for c in self.coeffs.chunks_exact(2 * nk) {
            if c[0].is_nan() {
                continue;
            }
            n += 1;
            for (k, s) in sum.iter_mut().enumerate() {
                *s += c[2 * k].to_f64().hypot(c[2 * k + 1].to_f64());
            }
        }
        sum.iter().map(|s| s / n.max(1) as f64).collect()
    }

    /// Writes the map as a multi-page TIFF (see the module docs), atomically.
    pub fn write_tiff(&self, path: &Path) -> Result<(), FourierError> {
        let name = path.display().to_string();
        let err = |e: &dyn std::fmt::Display| FourierError::Tiff {
            path: name.clone(),
            detail: e.to_string(),
        };
        let (w, h) = (
            u32::try_from(self.meta.cols).map_err(|e| err(&e))?,
            u32::try_from(self.meta.rows).map_err(|e| err(&e))?,
        );
        let json = serde_json::to_string(&self.meta).map_err(|e| err(&e))?;
        let per = 2 * self.meta.n_coeffs;
        let m = &self.meta;
        let (transform, dir, doubles, ascii) = crate::terrain::orthographic_model_tags(
            m.centre_lat_deg,
            m.centre_lon_deg,
            m.rotation_deg.to_radians(),
            m.x_left_m,
            m.y_top_m,
            m.px_m,
        );
        let mut bytes = Cursor::new(Vec::new());
        {
            let mut enc = TiffEncoder::new(&mut bytes).map_err(|e| err(&e))?;
            for page in 0..per {
                let data: Vec<u16> = self
                    .coeffs
                    .iter()
                    .skip(page)
                    .step_by(per)
                    .map(|v| v.to_bits())
                    .collect();
                let mut image = enc
                    .new_image::<colortype::Gray16>(w, h)
                    .map_err(|e| err(&e))?;
                if page == 0 {
                    image
                        .encoder()
                        .write_tag(Tag::ImageDescription, json.as_str())
                        .map_err(|e| err(&e))?;
                }
                // Every page georeferenced (GDAL opens each as GTIFF_DIR:n:file).
                let e = image.encoder();
                e.write_tag(Tag::ModelTransformationTag, &transform[..])
                    .map_err(|e| err(&e))?;
                e.write_tag(Tag::GeoKeyDirectoryTag, &dir[..])
                    .map_err(|e| err(&e))?;
                e.write_tag(Tag::GeoDoubleParamsTag, &doubles[..])
                    .map_err(|e| err(&e))?;
                e.write_tag(Tag::GeoAsciiParamsTag, ascii.as_str())
                    .map_err(|e| err(&e))?;
                image.write_data(&data).map_err(|e| err(&e))?;
            }
        }
        crate::output::write_bytes_atomic(path, &bytes.into_inner()).map_err(|e| err(&e))
    }

    /// Reads a map written by [`HorizonMap::write_tiff`].
    pub fn read_tiff(path: &Path) -> Result<Self, FourierError> {
        let name = path.display().to_string();
        let err = |e: &dyn std::fmt::Display| FourierError::Tiff {
            path: name.clone(),
            detail: e.to_string(),
        };
        let file = crate::output::guard::open_regular(path).map_err(|e| err(&e))?;
        let file_len = file.metadata().map_err(|e| err(&e))?.len();
        Self::read_tiff_from(BufReader::new(file), file_len, &name)
    }

    /// Reads a map written by [`HorizonMap::write_tiff`] from `reader`, which holds `file_len`
    /// bytes; `name` names the source in errors. (The fuzz target reads from memory.)
    pub fn read_tiff_from<R: std::io::Read + std::io::Seek>(
        reader: R,
        file_len: u64,
        name: &str,
    ) -> Result<Self, FourierError> {
        let err = |e: &dyn std::fmt::Display| FourierError::Tiff {
            path: name.to_string(),
            detail: e.to_string(),
        };
        let fmt = |d: String| FourierError::Format {
            path: name.to_string(),
            detail: d,
        };
        let mut dec = Decoder::new(reader).map_err(|e| err(&e))?;
        let json = dec
            .find_tag(Tag::ImageDescription)
            .map_err(|e| err(&e))?
            .ok_or_else(|| fmt("no ImageDescription metadata".into()))?
            .into_string()
            .map_err(|e| err(&e))?;
        let meta: HorizonMapMeta =
            serde_json::from_str(&json).map_err(|e| fmt(format!("metadata: {e}")))?;
        if meta.format != FORMAT_NAME {
            return Err(fmt(format!("format is '{}'", meta.format)));
        }
        check_params(
            meta.n_azimuths,
            meta.n_coeffs,
            meta.max_distance_cells.max(1),
        )
        .map_err(|e| fmt(format!("metadata: {e}")))?;
        if meta.rows == 0 || meta.cols == 0 {
            return Err(fmt(format!(
                "metadata: {} x {} cells",
                meta.cols, meta.rows
            )));
        }
        let per = 2 * meta.n_coeffs;
        let n_cells = meta.rows as u128 * meta.cols as u128;
        // Pages are stored uncompressed: the file must hold every f16 value it declares.
        if n_cells * per as u128 * 2 > u128::from(file_len) {
            return Err(fmt(format!(
                "metadata declares {} x {} cells x {per} values, more than the file's {file_len} bytes hold",
                meta.cols, meta.rows
            )));
        }
        crate::output::guard::check_budget("the horizon map", n_cells * per as u128 * 2)
            .map_err(fmt)?;
        let n_cells = n_cells as usize;
        let mut coeffs = vec![f16::NAN; n_cells * per];
        for page in 0..per {
            if page > 0 {
                if !dec.more_images() {
                    return Err(fmt(format!("{page} pages, expected {per}")));
                }
                dec.next_image().map_err(|e| err(&e))?;
            }
            let (w, h) = dec.dimensions().map_err(|e| err(&e))?;
            if (w as usize, h as usize) != (meta.cols, meta.rows) {
                return Err(fmt(format!("page {page} is {w} x {h}")));
            }
            let DecodingResult::U16(v) = dec.read_image().map_err(|e| err(&e))? else {
                return Err(fmt(format!("page {page} is not 16-bit")));
            };
            if v.len() != n_cells {
                return Err(fmt(format!(
                    "page {page} holds {} values for {n_cells} cells (one 16-bit sample per cell expected)",
                    v.len()
                )));
            }
            for (cell, bits) in v.into_iter().enumerate() {
                coeffs[cell * per + page] = f16::from_bits(bits);
            }
        }
        Ok(HorizonMap { meta, coeffs })
    }
}

/// Azimuth (from north, clockwise) and elevation (above the model x/y plane) of a unit vector,
/// radians.
pub(crate) fn az_el(l: &Vector3<f64>) -> (f64, f64) {
    (l.x.atan2(l.y), l.z.atan2(l.x.hypot(l.y)))
}

/// Half-width in azimuth (radians) of a disc of angular radius `r` whose centre is at elevation
/// `el`: `r / cos el`, capped at π (paper 001's disc edge azimuths `θ_s ± r / cos α_s`).
pub(crate) fn half_span_rad(el: f64, r: f64) -> f64 {
    if el.cos() * std::f64::consts::PI <= r {
        std::f64::consts::PI
    } else {
        r / el.cos()
    }
}

/// Hard mask from the horizon map: `1` where the light's elevation is above `α_h` at its
/// azimuth, `0` else, `255` for holes.
pub fn hard_mask(map: &HorizonMap, light_in_model: [f64; 3]) -> Result<Vec<u8>, ShadowError> {
    let l = unit_light(light_in_model)?;
    let (az, el) = az_el(&l);
    let cols = map.meta.cols.max(1);
    let mut out = vec![MASK_NODATA; map.meta.rows * map.meta.cols];
    out.par_chunks_mut(cols)
        .enumerate()
        .for_each(|(row, line)| {
            for (col, v) in line.iter_mut().enumerate() {
                let h = map.elevation_rad(row, col, az);
                if !h.is_nan() {
                    *v = if el > h as f64 { MASK_LIT } else { MASK_SHADOW };
                }
            }
        });
    Ok(out)
}

/// Visible fraction of a uniform disc of angular radius `angular_radius_rad` centred on
/// `light_in_model`, by the circular-segment approximation of paper 001 eqs. 6–7 (see the module
/// docs); `NaN` for holes. A zero radius gives the hard mask as 0/1.
pub fn visible_fraction(
    map: &HorizonMap,
    light_in_model: [f64; 3],
    angular_radius_rad: f64,
) -> Result<Vec<f32>, ShadowError> {
    check_radius(angular_radius_rad)?;
    let l = unit_light(light_in_model)?;
    let (az, el) = az_el(&l);
    let r = angular_radius_rad;
    let half_span = half_span_rad(el, r);
    let cols = map.meta.cols.max(1);
    let mut out = vec![f32::NAN; map.meta.rows * map.meta.cols];
    out.par_chunks_mut(cols)
        .enumerate()
        .for_each(|(row, line)| {
            for (col, v) in line.iter_mut().enumerate() {
                let mid = map.elevation_rad(row, col, az);
                if mid.is_nan() {
                    continue;
                }
                if r == 0.0 {
                    *v = if el > mid as f64 { 1.0 } else { 0.0 };
                    continue;
                }
                let left = map.elevation_rad(row, col, az - half_span) as f64 - el;
                let right = map.elevation_rad(row, col, az + half_span) as f64 - el;
                // Line through L = (−r, left), R = (r, right); its signed distance from the
                // centre is the apothem d (positive: line above the centre), eq. 6.
                let m = 0.5 * (left + right);
                let k = (right - left) / (2.0 * r);
                let d = m / (1.0 + k * k).sqrt();
                *v = chord_visible_fraction(d / r, &LimbDarkening::UNIFORM) as f32;
            }
        });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dft_of_a_band_limited_horizon_is_exact() {
        let n = 64;
        let f = |t: f64| 0.1 + 0.05 * t.cos() - 0.02 * (3.0 * t).sin() + 0.01 * (15.0 * t).cos();
        let s: Vec<f32> = (0..n)
            .map(|j| f(std::f64::consts::TAU * j as f64 / n as f64) as f32)
            .collect();
        let x = truncated_dft(&s, DEFAULT_COEFFS);
        for t in [0.0, 0.3, 1.7, 4.0, 6.1] {
            let v = eval_series(x.chunks(2).map(|p| (p[0] as f32, p[1] as f32)), t);
            assert!((v as f64 - f(t)).abs() < 1e-6, "t {t}: {v} vs {}", f(t));
        }
    }

    #[test]
    fn bad_parameters_are_errors() {
        let hf = HeightField::flat(4, 4, 10.0);
        assert!(HorizonMap::build(&hf, 2.0, 16, 10).is_err());
        assert!(HorizonMap::build(&hf, -1.0, 64, 10).is_err());
        assert!(HorizonMap::build(&hf, 2.0, 64, 0).is_err());
        let m = HorizonMap::build(&hf, 2.0, 64, 10).unwrap();
        assert!(visible_fraction(&m, [0.0, 1.0, 0.1], -0.1).is_err());
        assert!(hard_mask(&m, [0.0, 0.0, 0.0]).is_err());
    }
}

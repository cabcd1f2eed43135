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
//! The grid itself, with every layer, is [`crate::model::MapGrid`]; the CPU|GPU switch of maps
//! and sweeps is [`crate::compute`]. This module holds the CPU map engines, the CPU sweep and
//! the writers of a sweep's statistics.

use std::path::Path;

use rayon::prelude::*;

use crate::illum::plot::{MapLegend, write_map_preview};
use crate::model::{BelowSphereTally, EpochLights, MapGrid, VISIBLE_MIN_FRACTION};
use crate::output::BelowSphereExits;
use crate::shadow::{Engine, MASK_NODATA, Observer};
use crate::terrain::HeightField;

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

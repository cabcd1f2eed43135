//! The map engines on the model grid (CPU): a per-light engine of [`crate::shadow`] or a Fourier
//! horizon map built once ([`MapEngine`]), and the statistics of a range of epochs from one map
//! per epoch ([`per_epoch_statistics`]), per DEM pixel (rays from each pixel's own surface point)
//! or per model cell.
//!
//! The Sun is one direction over the whole grid (its parallax over 184 km is 1.2e-6 rad). For the
//! Earth the direction is taken at the map centre; over ±184 km it varies by up to
//! 184 km / 384,400 km = 4.8e-4 rad = 0.027°, about 3% of the Earth's angular radius, which bounds
//! the Earth-visibility error at the map edges.

use rayon::prelude::*;

use super::{BelowSphereTally, EpochLights, MapGrid, VISIBLE_MIN_FRACTION};
use crate::output::BelowSphereExits;
use crate::shadow::{Engine, Observer};
use crate::terrain::HeightField;

/// Per-pixel (or per model cell) statistics over a range of epochs.
#[derive(Debug, Clone)]
pub struct RangeStats {
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
    /// Epochs with both the Sun and the Earth (partly) visible; `None` when the engine cannot tell
    /// (the GPU per-epoch DP folds each light separately), written as an all-NaN map.
    pub sun_and_earth_count: Option<Vec<u32>>,
    /// Sun-lit results resting on rays that leave the DEM below the reference sphere (counted
    /// by the CPU per-epoch engines and the horizons engine; `None` on the GPU).
    pub below_sphere: Option<BelowSphereExits>,
    /// Whether the arrays are per DEM pixel (the CPU per-epoch engines, from the pixels' own observers, and
    /// the horizons engine) rather than per model cell (the GPU per-epoch DP).
    pub on_dem_grid: bool,
    /// Statistics only the horizons engine computes (`None` for the per-epoch engines).
    pub extra: Option<HorizonExtras>,
}

/// The statistics the horizons engine adds to the per-epoch engines' (per DEM pixel).
#[derive(Debug, Clone)]
pub struct HorizonExtras {
    /// Epochs with the Sun fully visible.
    pub sun_full_count: Vec<u32>,
    /// Longest run of consecutive epochs with the Earth entirely hidden.
    pub longest_earth_hidden_epochs: Vec<u32>,
    /// Time-mean irradiance on a level surface, W/m².
    pub irradiance_horizontal_mean_w_m2: Vec<f32>,
    /// Time-mean irradiance on a vertical panel turned to the Sun's azimuth, W/m².
    pub irradiance_tracking_mean_w_m2: Vec<f32>,
    /// Limb-darkening law of the Sun's mean fraction, for the file descriptions.
    pub limb_law: String,
    /// Direct-to-Earth statistics, with ground stations.
    pub dte: Option<DteCounts>,
    /// Power statistics, with a panel and its load.
    pub power: Option<PowerMaps>,
}

/// A panel's power per pixel ([`crate::illum::power`]).
#[derive(Debug, Clone)]
pub struct PowerMaps {
    /// Time-mean power, W.
    pub mean_power_w: Vec<f32>,
    /// The smallest battery that, starting full, carries the load through every epoch, Wh.
    pub required_battery_wh: Vec<f32>,
    /// The panel and load, described.
    pub described: String,
}

/// Direct-to-Earth per pixel: any part of the Earth above the terrain horizon while a ground
/// station sees the DEM above its mask.
#[derive(Debug, Clone)]
pub struct DteCounts {
    /// Epochs with direct-to-Earth.
    pub dte_count: Vec<u32>,
    /// Longest run of consecutive epochs without.
    pub longest_dte_blackout_epochs: Vec<u32>,
    /// The stations, described.
    pub stations: String,
}

impl RangeStats {
    /// The Sun's limb darkening in the mean fraction: the horizons engine's law, else a uniform
    /// disc (the per-epoch engines).
    pub fn limb_law(&self) -> String {
        self.extra
            .as_ref()
            .map_or_else(|| "none (uniform disc)".to_string(), |e| e.limb_law.clone())
    }

    /// The statistics from the horizons engine's (`step_h` hours apart).
    pub fn from_horizons(
        h: crate::horizon::statistics::HorizonStatistics,
        step_h: f64,
        limb_law: &str,
    ) -> Self {
        let n = h.epochs.max(1) as f64;
        let mean = |v: &[f64]| v.iter().map(|&x| (x / n) as f32).collect::<Vec<f32>>();
        RangeStats {
            epochs: h.epochs,
            step_h,
            extra: Some(HorizonExtras {
                sun_full_count: h.sun_full_count,
                longest_earth_hidden_epochs: h.longest_earth_hidden_epochs,
                irradiance_horizontal_mean_w_m2: mean(&h.irradiance_horizontal_sum_w_m2),
                irradiance_tracking_mean_w_m2: mean(&h.irradiance_tracking_sum_w_m2),
                limb_law: limb_law.to_string(),
                power: h.power.map(|described| PowerMaps {
                    mean_power_w: mean(&h.power_sum_w),
                    required_battery_wh: h.required_battery_wh.iter().map(|&x| x as f32).collect(),
                    described,
                }),
                dte: h.link.map(|stations| DteCounts {
                    dte_count: h.dte_count,
                    longest_dte_blackout_epochs: h.longest_dte_blackout_epochs,
                    stations,
                }),
            }),
            sun_fraction_sum: h.sun_fraction_sum,
            sun_visible_count: h.sun_visible_count,
            longest_dark_epochs: h.longest_dark_epochs,
            earth_visible_count: h.earth_visible_count,
            sun_and_earth_count: Some(h.sun_and_earth_count),
            below_sphere: Some(h.below_sphere),
            on_dem_grid: true,
        }
    }
}

/// Where a map's rays start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObserverPlacement {
    /// At each DEM pixel's own surface point ([`MapGrid::pixel_observers`]); results per pixel.
    Pixels,
    /// At the model grid's cells; results resampled back onto the DEM grid (the GPU's 2-D tiled
    /// kernels and the Fourier engine always).
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
    /// Statistics over an epoch range from exact whole-grid horizons
    /// ([`crate::horizon::statistics`]); epoch ranges only.
    Horizons,
}

impl MapEngineKind {
    /// The engine's name, as `--engine` takes it.
    pub fn name(self) -> &'static str {
        match self {
            MapEngineKind::Direct(Engine::Brute) => "brute",
            MapEngineKind::Direct(Engine::Dp) => "dp",
            MapEngineKind::Direct(Engine::Combined) => "combined",
            MapEngineKind::Fourier => "fourier",
            MapEngineKind::Horizons => "horizons",
        }
    }

    /// The engine of a user-facing name (`combined`, `dp`, `fourier`, `horizons`), or `None` for
    /// `auto`; the error lists the names. The command line, scenarios and Python take these.
    pub fn parse_choice(name: &str) -> Result<Option<Self>, String> {
        Ok(Some(match name {
            "auto" => return Ok(None),
            "combined" => MapEngineKind::Direct(Engine::Combined),
            "dp" => MapEngineKind::Direct(Engine::Dp),
            "fourier" => MapEngineKind::Fourier,
            "horizons" => MapEngineKind::Horizons,
            _ => {
                return Err(format!(
                    "engine '{name}': use auto, combined, dp, fourier or horizons"
                ));
            }
        }))
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
            MapEngineKind::Horizons => anyhow::bail!(
                "--engine horizons makes statistics over an epoch range (--start/--stop/--step); \
                 for one light use brute, smap, dp, combined or fourier"
            ),
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
            // The DEM's own lattice near each pixel, the model grid beyond
            // (src/model/near_field.rs): the fraction of the smaller cost.
            MapEngine::Direct(e) => {
                let beyond = e.visible_fraction(
                    &grid.hf,
                    grid.pixel_points_beyond_near_field(observers),
                    light_in_model,
                    angular_radius_rad,
                )?;
                grid.with_near_field(&beyond, observers, light_in_model, angular_radius_rad)?
            }
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
                let beyond = e.hard_mask(
                    &grid.hf,
                    grid.pixel_points_beyond_near_field(observers),
                    light_in_model,
                )?;
                let near = grid.near_field_costs(observers, light_in_model)?;
                beyond
                    .iter()
                    .zip(&near)
                    .map(|(&b, &j)| {
                        if b == crate::shadow::MASK_LIT && j < 0.0 {
                            crate::shadow::MASK_SHADOW
                        } else {
                            b
                        }
                    })
                    .collect()
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
/// inside the engines), with the rays from `placement`, showing a progress bar of the epochs.
pub fn per_epoch_statistics(
    grid: &MapGrid,
    engine: &MapEngine,
    observer_height_m: f64,
    placement: ObserverPlacement,
    lights: &[EpochLights],
    step_h: f64,
) -> anyhow::Result<RangeStats> {
    let on_dem_grid = placement == ObserverPlacement::Pixels;
    let observers = grid.pixel_observers(observer_height_m);
    per_epoch_statistics_with(
        grid,
        &observers,
        on_dem_grid,
        lights,
        step_h,
        |light, radius| {
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
        },
    )
}

/// [`per_epoch_statistics`] with the fractions of each light from `fraction(light, radius)`:
/// per DEM pixel (`on_dem_grid`, the pixels' `observers`) or per model cell. The GPU's DP from
/// the DEM pixels folds its fractions here too, so both backends count the same way.
pub fn per_epoch_statistics_with(
    grid: &MapGrid,
    observers: &[Option<Observer>],
    on_dem_grid: bool,
    lights: &[EpochLights],
    step_h: f64,
    mut fraction: impl FnMut([f64; 3], f64) -> anyhow::Result<Vec<f32>>,
) -> anyhow::Result<RangeStats> {
    let progress = crate::output::progress_bar(
        lights.len(),
        "{spinner} map [{bar:30}] {pos}/{len} epochs (eta {eta})",
    );
    // Per DEM pixel from the pixels' own observers, or per model cell (resampled at the end, as
    // the GPU per-epoch DP).
    let n = if on_dem_grid {
        observers.len()
    } else {
        grid.hf.rows * grid.hf.cols
    };
    let mut s = RangeStats {
        epochs: lights.len(),
        step_h,
        sun_fraction_sum: vec![0.0; n],
        sun_visible_count: vec![0; n],
        longest_dark_epochs: vec![0; n],
        earth_visible_count: vec![0; n],
        sun_and_earth_count: None,
        below_sphere: None,
        on_dem_grid,
        extra: None,
    };
    let mut sun_and_earth_count = vec![0_u32; n];
    let mut current_dark = vec![0_u32; n];
    let mut below = BelowSphereTally::new(observers);
    for l in lights {
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
    progress.finish_and_clear();
    s.sun_and_earth_count = Some(sun_and_earth_count);
    s.below_sphere = on_dem_grid.then(|| below.finish());
    Ok(s)
}

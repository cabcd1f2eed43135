//! The per-cell epoch loop run elsewhere: what [`super::StatisticsEngine::run_rows_on`] hands a
//! [`CellKernel`] (the GPU's `shaders/horizon_stats.wgsl`, or its f32 CPU twin
//! `crate::twins::horizon_stats`), in the kernel's layout.
//!
//! The kernel sees no sector tables and no per-cell bounds: per epoch and body it places the
//! body at the cell, decides a disc entirely above the cell's highest horizon or below its lowest
//! without an azimuth, and takes the others through the same circular segment (the Sun) and
//! horizon polyline (the Earth) as the CPU engine's exact path. Sums are f32 per chunk of
//! [`EPOCH_CHUNK`] epochs (aligned to the run's first epoch, as the CPU engine's), added to f32
//! totals (the CPU engine keeps f64 totals: the totals differ by at most ½ ulp per chunk, ≤ 2e-5
//! relative over 163,000 epochs).
//!
//! Rays the Moon beyond the DEM would block are not decided by the kernel: it counts a cell's
//! *candidate* epochs (Sun visible while its centre is below the cell's geometric horizon on the
//! sphere, [`KernelCell::sin_dip_bound`]), and the engine re-runs the few cells with any on the
//! CPU for the exact tally.

use std::sync::Arc;

use super::HorizonError;
use super::kernel::CHUNK;
use super::lookup::{AzimuthLookup, ChordTable};

/// Epochs per f32 partial sum (the CPU engine's chunk).
pub const EPOCH_CHUNK: usize = CHUNK;

/// One cell as the kernel reads it (64 B, four `vec4<f32>` in WGSL): its frame (unit vectors
/// in `MOON_ME`), the observer's distance from the Moon's centre, the range of its horizon.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct KernelCell {
    /// Radial up.
    pub up: [f32; 3],
    /// Observer's distance from the Moon's centre, km.
    pub r_obs_km: f32,
    /// Map +x in the tangent plane.
    pub grid_east: [f32; 3],
    /// The lowest horizon over every band, degrees.
    pub h_min_deg: f32,
    /// Map +y in the tangent plane.
    pub grid_north: [f32; 3],
    /// The highest horizon over every band, degrees.
    pub h_max_deg: f32,
    /// `sin` of the observer's geometric horizon on the sphere, plus room for f32 rounding: a
    /// lit epoch whose Sun's sine of elevation is below it is a below-sphere candidate.
    pub sin_dip_bound: f32,
    /// Padding to 64 B.
    pub pad: [f32; 3],
}

/// Running statistics of one cell as the kernel keeps them (48 B; the counts of
/// [`super::HorizonStatistics`], f32 sums).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct KernelAcc {
    /// Σ of the Sun's visible (flux) fraction.
    pub sun_fraction_sum: f32,
    /// Σ irradiance on a level surface, W/m².
    pub irradiance_horizontal_sum: f32,
    /// Σ irradiance on a vertical panel facing the Sun, W/m².
    pub irradiance_tracking_sum: f32,
    /// Epochs with any part of the Sun visible.
    pub sun_visible: u32,
    /// Epochs with the Sun fully visible.
    pub sun_full: u32,
    /// Epochs with any part of the Earth visible.
    pub earth_visible: u32,
    /// Epochs with both.
    pub sun_and_earth: u32,
    /// The current run of epochs with the Sun hidden.
    pub dark_run: u32,
    /// The longest run of epochs with the Sun hidden.
    pub dark_max: u32,
    /// The current run of epochs with the Earth hidden.
    pub earth_hidden_run: u32,
    /// The longest run of epochs with the Earth hidden.
    pub earth_hidden_max: u32,
    /// Below-sphere candidates (see the module's text).
    pub low_lit: u32,
}

/// One epoch as the kernel reads it (48 B): the bodies' centres relative to the Moon's centre
/// (`MOON_ME`, km) with their angular radii (degrees), the Sun's normal irradiance (W/m²).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct KernelEpoch {
    /// The Sun's centre, km.
    pub sun_km: [f32; 3],
    /// The Sun's angular radius, degrees.
    pub sun_radius_deg: f32,
    /// The Earth's centre, km.
    pub earth_km: [f32; 3],
    /// The Earth's angular radius, degrees.
    pub earth_radius_deg: f32,
    /// The Sun's normal irradiance (whole disc), W/m².
    pub sun_normal_w_m2: f32,
    /// Padding to 48 B.
    pub pad: [f32; 3],
}

/// What every block of a run shares: the epochs in time order, the azimuth lookup and the chord
/// tables as flat arrays, the thresholds.
#[derive(Debug, Clone)]
pub struct KernelShared {
    /// The epochs, in time order.
    pub epochs: Vec<KernelEpoch>,
    /// Band azimuths relative to the first band, degrees (`n + 1` values, the last 360).
    pub rel_deg: Vec<f32>,
    /// `1 / (rel[k + 1] − rel[k])` (`n` values).
    pub inv_width: Vec<f32>,
    /// The bands' grid azimuths, degrees (`n` values).
    pub band_az_deg: Vec<f32>,
    /// Azimuth index: the segment at the start of each bin.
    pub index: Vec<u32>,
    /// The first band's grid azimuth, degrees.
    pub a0_deg: f32,
    /// Index bins per degree.
    pub bins_per_deg: f32,
    /// The chord tables of the Sun (limb-darkened) and the Earth (uniform), `CHORD_BINS + 1`
    /// values each over `d / r` in [−1, 1]: the Sun's.
    pub chord_sun: Vec<f32>,
    /// The Earth's chord table.
    pub chord_earth: Vec<f32>,
    /// A disc is "visible" above this fraction.
    pub visible_min: f32,
    /// The Sun is "full" from this fraction.
    pub full_min: f32,
}

impl KernelShared {
    pub(super) fn new(
        epochs: Vec<KernelEpoch>,
        lookup: &AzimuthLookup,
        chords: (&ChordTable, &ChordTable),
        (visible_min, full_min): (f32, f32),
    ) -> Self {
        let p = lookup.parts();
        KernelShared {
            epochs,
            rel_deg: p.rel_deg.to_vec(),
            inv_width: p.inv_width.to_vec(),
            band_az_deg: lookup.band_az_deg().to_vec(),
            index: p.index.to_vec(),
            a0_deg: p.a0_deg,
            bins_per_deg: p.bins_per_deg,
            chord_sun: chords.0.values().to_vec(),
            chord_earth: chords.1.values().to_vec(),
            visible_min,
            full_min,
        }
    }

    /// Number of bands.
    pub fn n_bands(&self) -> usize {
        self.inv_width.len()
    }
}

/// Runs the per-cell epoch loop of blocks of cells.
pub trait CellKernel {
    /// Takes what every block of the run shares (called once, before any block; the epochs
    /// are ≈ 8 MB over 18.6 years hourly, so they are shared, not copied).
    fn begin(&mut self, shared: Arc<KernelShared>) -> Result<(), HorizonError>;

    /// Every epoch of the run for `cells`, whose horizons are `horizons` (`n + 1` values per
    /// cell, degrees: the bands, then the first again): one accumulator per cell.
    fn run(
        &mut self,
        cells: &[KernelCell],
        horizons: &[f32],
    ) -> Result<Vec<KernelAcc>, HorizonError>;

    /// What ran, for notes ("gpu: NVIDIA H200", "cpu twin").
    fn name(&self) -> String;
}

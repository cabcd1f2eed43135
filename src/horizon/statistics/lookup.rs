//! Tables of the statistics kernel: the horizon at any grid azimuth from non-uniform bands, and
//! the visible fraction of a disc above a chord.

use crate::illum::{LimbDarkening, chord_visible_fraction};

/// Bins of the azimuth index (0.044° each: narrower than any two band azimuths are apart, so one
/// comparison finds the band after the table).
const INDEX_BINS: usize = 8192;

/// The horizon at any grid azimuth, by linear interpolation between the bands (non-uniform grid
/// azimuths, sorted, periodic): an index table of [`INDEX_BINS`] bins, then at most a few
/// comparisons.
#[derive(Debug, Clone)]
pub struct AzimuthLookup {
    band_az_deg: Vec<f32>,
    a0_deg: f32,
    /// Band azimuths relative to the first, degrees; `rel[n] = 360`.
    rel_deg: Vec<f32>,
    inv_width: Vec<f32>,
    index: Vec<u32>,
}

impl AzimuthLookup {
    /// A lookup over bands at `grid_az_deg` (strictly increasing, in [0, 360)); `None` if they
    /// are not.
    pub fn new(grid_az_deg: &[f64]) -> Option<Self> {
        let n = grid_az_deg.len();
        if n < 2
            || grid_az_deg.iter().any(|a| !(0.0..360.0).contains(a))
            || grid_az_deg.windows(2).any(|w| w[1] <= w[0])
        {
            return None;
        }
        let a0 = grid_az_deg[0];
        let mut rel_deg: Vec<f32> = grid_az_deg.iter().map(|a| (a - a0) as f32).collect();
        rel_deg.push(360.0);
        let inv_width = rel_deg
            .windows(2)
            .map(|w| 1.0 / (w[1] - w[0]).max(1e-6))
            .collect();
        let mut index = Vec::with_capacity(INDEX_BINS);
        let mut k = 0_usize;
        for j in 0..INDEX_BINS {
            let start = (j as f64 * 360.0 / INDEX_BINS as f64) as f32;
            while k + 1 < n && rel_deg[k + 1] <= start {
                k += 1;
            }
            index.push(k as u32);
        }
        Some(AzimuthLookup {
            band_az_deg: grid_az_deg.iter().map(|&a| a as f32).collect(),
            a0_deg: a0 as f32,
            rel_deg,
            inv_width,
            index,
        })
    }

    /// Number of bands.
    pub fn n_bands(&self) -> usize {
        self.inv_width.len()
    }

    /// The bands' grid azimuths, degrees.
    pub fn band_az_deg(&self) -> &[f32] {
        &self.band_az_deg
    }

    /// The horizon (deg) at grid azimuth `az_deg` (any real value) from the band values `h`
    /// (`n + 1` values: the `n` bands then the first again).
    #[inline(always)]
    pub fn horizon_deg(&self, h: &[f32], az_deg: f32) -> f32 {
        let mut r = az_deg - self.a0_deg;
        if !(0.0..360.0).contains(&r) {
            r -= 360.0 * (r / 360.0).floor();
            if r >= 360.0 {
                r = 0.0;
            }
        }
        let j = ((r * (INDEX_BINS as f32 / 360.0)) as usize).min(INDEX_BINS - 1);
        let mut k = self.index[j] as usize;
        let n = self.inv_width.len();
        while k + 1 < n && r >= self.rel_deg[k + 1] {
            k += 1;
        }
        let w = (r - self.rel_deg[k]) * self.inv_width[k];
        let (a, b) = (h[k], h[k + 1]);
        a + w * (b - a)
    }
}

/// Intervals of the chord table over `d / r` in [−1, 1].
const CHORD_BINS: usize = 4096;

/// The visible (flux) fraction of a disc above a straight chord at signed distance `x = d / r`
/// from its centre ([`chord_visible_fraction`]), tabulated and interpolated linearly (error
/// < 1e-5: `tests::chord_table_matches`).
#[derive(Debug, Clone)]
pub struct ChordTable {
    values: Vec<f32>,
}

impl ChordTable {
    /// The table of `limb`.
    pub fn new(limb: &LimbDarkening) -> Self {
        let values = (0..=CHORD_BINS)
            .map(|i| {
                let x = -1.0 + 2.0 * i as f64 / CHORD_BINS as f64;
                chord_visible_fraction(x, limb) as f32
            })
            .collect();
        ChordTable { values }
    }

    /// The fraction at `x = d / r` (positive: chord above the centre).
    #[inline(always)]
    pub fn fraction(&self, x: f32) -> f32 {
        if x >= 1.0 {
            return 0.0;
        }
        if x <= -1.0 || x.is_nan() {
            return if x.is_nan() { 0.0 } else { 1.0 };
        }
        let t = (x + 1.0) * (CHORD_BINS as f32 / 2.0);
        let i = (t as usize).min(CHORD_BINS - 1);
        let f = t - i as f32;
        let (a, b) = (self.values[i], self.values[i + 1]);
        a + f * (b - a)
    }
}

//! Tables of the statistics kernel: the horizon at any grid azimuth from non-uniform bands, and
//! the visible fraction of a disc above a chord; a branch-free `atan2` in degrees.

use crate::illum::{LimbDarkening, chord_visible_fraction};

/// Fewest bins of the azimuth index (0.044° each); more when two bands are closer than two bins.
const MIN_INDEX_BINS: usize = 8192;
/// Most bins of the azimuth index.
const MAX_INDEX_BINS: usize = 1 << 22;

/// The horizon at any grid azimuth, by linear interpolation between the bands (non-uniform grid
/// azimuths, sorted, periodic): an index table whose bins are narrower than any two bands are
/// apart, so that one comparison after the table finds the band (branch-free: the lookup
/// vectorises).
#[derive(Debug, Clone)]
pub struct AzimuthLookup {
    band_az_deg: Vec<f32>,
    a0_deg: f32,
    /// Band azimuths relative to the first, degrees; `rel[n] = 360`.
    rel_deg: Vec<f32>,
    inv_width: Vec<f32>,
    index: Vec<u32>,
    /// Index bins per degree.
    bins_per_deg: f32,
}

/// [`AzimuthLookup`]'s arrays (see its fields).
pub(super) struct LookupParts<'a> {
    pub rel_deg: &'a [f32],
    pub inv_width: &'a [f32],
    pub index: &'a [u32],
    pub a0_deg: f32,
    pub bins_per_deg: f32,
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
        let min_gap = rel_deg
            .windows(2)
            .map(|w| f64::from(w[1] - w[0]))
            .fold(f64::INFINITY, f64::min);
        if min_gap < 720.0 / MAX_INDEX_BINS as f64 {
            return None;
        }
        let bins = ((720.0 / min_gap).ceil() as usize)
            .next_power_of_two()
            .clamp(MIN_INDEX_BINS, MAX_INDEX_BINS);
        let mut index = Vec::with_capacity(bins);
        let mut k = 0_usize;
        for j in 0..bins {
            let start = (j as f64 * 360.0 / bins as f64) as f32;
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
            bins_per_deg: (bins as f64 / 360.0) as f32,
        })
    }

    /// Number of bands.
    pub fn n_bands(&self) -> usize {
        self.inv_width.len()
    }

    /// The lookup's arrays, for a kernel that mirrors [`AzimuthLookup::segment`] elsewhere.
    pub(super) fn parts(&self) -> LookupParts<'_> {
        LookupParts {
            rel_deg: &self.rel_deg,
            inv_width: &self.inv_width,
            index: &self.index,
            a0_deg: self.a0_deg,
            bins_per_deg: self.bins_per_deg,
        }
    }

    /// The bands' grid azimuths, degrees.
    pub fn band_az_deg(&self) -> &[f32] {
        &self.band_az_deg
    }

    /// The horizon (deg) at grid azimuth `az_deg` (any real value) from the band values `h`
    /// (`n + 1` values: the `n` bands then the first again).
    #[inline(always)]
    pub fn horizon_deg(&self, h: &[f32], az_deg: f32) -> f32 {
        let (k, r) = self.segment(az_deg);
        self.horizon_in_segment(h, k, r)
    }

    /// The horizon (deg) at azimuth `r` relative to the first band, in band segment `k` (both
    /// from [`AzimuthLookup::segment`]).
    #[inline(always)]
    pub(super) fn horizon_in_segment(&self, h: &[f32], k: usize, r: f32) -> f32 {
        let w = (r - self.rel_deg[k]) * self.inv_width[k];
        let (a, b) = (h[k], h[k + 1]);
        a + w * (b - a)
    }

    /// The band segment `k` (from band `k` to band `k + 1`, the last to the first) holding grid
    /// azimuth `az_deg`, and the azimuth relative to the first band, degrees in [0, 360).
    #[inline(always)]
    pub fn segment(&self, az_deg: f32) -> (usize, f32) {
        let r0 = az_deg - self.a0_deg;
        let r = r0 - 360.0 * (r0 * (1.0 / 360.0)).floor();
        let last = self.index.len() as i32 - 1;
        let j = ((r * self.bins_per_deg) as i32).clamp(0, last) as usize;
        let k0 = self.index[j] as usize;
        let n = self.inv_width.len();
        // The bins are narrower than the bands' gaps: at most one band boundary per bin.
        let k = (k0 + usize::from(r >= self.rel_deg[k0 + 1])).min(n - 1);
        (k, r)
    }

    /// Segments holding grid azimuths from `from_deg` over `width_deg` (≥ 0), in order.
    pub fn segments_over(&self, from_deg: f32, width_deg: f32) -> impl Iterator<Item = usize> {
        let n = self.inv_width.len();
        let (k0, r0) = self.segment(from_deg);
        let end = r0 + width_deg;
        let rel = &self.rel_deg;
        (0..n)
            .map(move |i| (k0 + i) % n)
            .enumerate()
            .take_while(move |&(i, k)| {
                // Start of segment k, unwrapped past the first lap.
                let turns = if k < k0 { 360.0 } else { 0.0 };
                i == 0 || rel[k] + turns <= end
            })
            .map(|(_, k)| k)
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

    /// The table's `CHORD_BINS + 1` values over `x` in [−1, 1].
    pub(super) fn values(&self) -> &[f32] {
        &self.values
    }

    /// The fraction at `x = d / r` (positive: chord above the centre); branch-free.
    #[inline(always)]
    pub fn fraction(&self, x: f32) -> f32 {
        let t = (x.clamp(-1.0, 1.0) + 1.0) * (CHORD_BINS as f32 / 2.0);
        let i = (t as i32).clamp(0, CHORD_BINS as i32 - 1) as usize;
        let f = t - i as f32;
        let (a, b) = (self.values[i], self.values[i + 1]);
        a + f * (b - a)
    }
}

/// `atan(a)` for `a` in [0, 1]: a least-squares minimax polynomial in `a²` (degree 7), error
/// < 4e-8 rad (2.2e-6°; `tests::atan2_deg_matches_f64`).
#[inline(always)]
fn atan_unit(a: f32) -> f32 {
    const C: [f32; 8] = [
        9.999_993_4e-1,
        -3.332_986e-1,
        1.994_656e-1,
        -1.390_860_7e-1,
        9.642_142e-2,
        -5.591_159e-2,
        2.186_245_7e-2,
        -4.054_43e-3,
    ];
    // Plain multiply-adds: `mul_add` is a libm call without the FMA target feature.
    let t = a * a;
    let p = C[7];
    let p = p * t + C[6];
    let p = p * t + C[5];
    let p = p * t + C[4];
    let p = p * t + C[3];
    let p = p * t + C[2];
    let p = p * t + C[1];
    let p = p * t + C[0];
    a * p
}

/// `atan2(y, x)` in degrees, in [−180, 180], branch-free (0 for `(0, 0)`).
#[inline(always)]
pub fn atan2_deg(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let lo = ax.min(ay);
    let hi = ax.max(ay).max(f32::MIN_POSITIVE);
    let r = atan_unit(lo / hi);
    let r = if ay > ax {
        std::f32::consts::FRAC_PI_2 - r
    } else {
        r
    };
    let r = if x < 0.0 { std::f32::consts::PI - r } else { r };
    let r = if y < 0.0 { -r } else { r };
    r * (180.0 / std::f32::consts::PI)
}

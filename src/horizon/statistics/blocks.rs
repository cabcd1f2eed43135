//! Blocks of rows of the statistics, kept apart: what a killed map run has finished and a
//! resumed one takes back (a pixel's statistics depend on its own horizon and the epochs only, so
//! a block computed in another process is the same bytes).

use std::ops::Range;

use super::HorizonStatistics;
use crate::output::BelowSphereExits;

/// Where [`super::StatisticsEngine::run_rows_on`] keeps finished row blocks.
pub trait BlockStore {
    /// The finished block of `rows`, if there is one (`None` → compute it).
    fn load(&mut self, rows: Range<usize>) -> Option<Vec<u8>>;
    /// Keeps the finished block of `rows` (a block of rows as bytes: first pixel, pixel and epoch counts, the arrays).
    fn store(&mut self, rows: Range<usize>, bytes: &[u8]) -> Result<(), String>;
}

/// A store that keeps nothing.
pub struct NoStore;

impl BlockStore for NoStore {
    fn load(&mut self, _rows: Range<usize>) -> Option<Vec<u8>> {
        None
    }
    fn store(&mut self, _rows: Range<usize>, _bytes: &[u8]) -> Result<(), String> {
        Ok(())
    }
}

/// A run folder's checkpoints keep the blocks (as parts `map rows A-B`).
impl BlockStore for crate::output::checkpoint::Checkpoint {
    fn load(&mut self, rows: Range<usize>) -> Option<Vec<u8>> {
        self.load_blob(&format!("map rows {}-{}", rows.start, rows.end))
    }
    fn store(&mut self, rows: Range<usize>, bytes: &[u8]) -> Result<(), String> {
        self.store_blob(&format!("map rows {}-{}", rows.start, rows.end), bytes)
    }
}

const MAGIC: &[u8; 8] = b"PNBSTAT2";

impl HorizonStatistics {
    /// Statistics of `n_px` pixels, all nodata, over `epochs` epochs.
    pub fn empty(n_px: usize, epochs: usize) -> Self {
        HorizonStatistics {
            epochs,
            nodata: vec![true; n_px],
            sun_fraction_sum: vec![0.0; n_px],
            sun_visible_count: vec![0; n_px],
            sun_full_count: vec![0; n_px],
            longest_dark_epochs: vec![0; n_px],
            earth_visible_count: vec![0; n_px],
            longest_earth_hidden_epochs: vec![0; n_px],
            sun_and_earth_count: vec![0; n_px],
            dte_count: vec![0; n_px],
            longest_dte_blackout_epochs: vec![0; n_px],
            link: None,
            irradiance_horizontal_sum_w_m2: vec![0.0; n_px],
            irradiance_tracking_sum_w_m2: vec![0.0; n_px],
            power_sum_w: vec![0.0; n_px],
            required_battery_wh: vec![0.0; n_px],
            power: None,
            below_sphere: BelowSphereExits::default(),
        }
    }

    /// The pixels `first_px..first_px + n_px` and their below-sphere counts as bytes
    /// (little-endian; read back by [`Self::place_block_bytes`]).
    pub(crate) fn block_bytes(&self, first_px: usize, n_px: usize, below: (u64, u64)) -> Vec<u8> {
        let r = first_px..first_px + n_px;
        let mut b = Vec::with_capacity(64 + n_px * 69);
        b.extend_from_slice(MAGIC);
        for v in [
            first_px as u64,
            n_px as u64,
            self.epochs as u64,
            below.0,
            below.1,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend(self.nodata[r.clone()].iter().map(|&n| u8::from(n)));
        for a in [
            &self.sun_fraction_sum,
            &self.irradiance_horizontal_sum_w_m2,
            &self.irradiance_tracking_sum_w_m2,
            &self.power_sum_w,
            &self.required_battery_wh,
        ] {
            a[r.clone()].iter().for_each(|v| b.extend(v.to_le_bytes()));
        }
        for a in [
            &self.sun_visible_count,
            &self.sun_full_count,
            &self.longest_dark_epochs,
            &self.earth_visible_count,
            &self.longest_earth_hidden_epochs,
            &self.sun_and_earth_count,
            &self.dte_count,
            &self.longest_dte_blackout_epochs,
        ] {
            a[r.clone()].iter().for_each(|v| b.extend(v.to_le_bytes()));
        }
        b
    }

    /// Places a block of [`Self::block_bytes`] for pixels `first_px..first_px + n_px`; `false`
    /// (and nothing changed) when the bytes are not such a block.
    pub(crate) fn place_block_bytes(&mut self, first_px: usize, n_px: usize, bytes: &[u8]) -> bool {
        self.place_block_bytes_at(first_px, first_px, n_px, bytes)
    }

    /// [`Self::place_block_bytes`] for a block written as pixels `block_first_px..` of other
    /// statistics (a shard's own), placed at pixels `first_px..` of these.
    pub(crate) fn place_block_bytes_at(
        &mut self,
        block_first_px: usize,
        first_px: usize,
        n_px: usize,
        bytes: &[u8],
    ) -> bool {
        let header = 8 + 5 * 8;
        if bytes.len() != header + n_px * (1 + 5 * 8 + 8 * 4) || &bytes[..8] != MAGIC {
            return false;
        }
        let word = |i: usize| {
            let s = 8 + 8 * i;
            u64::from_le_bytes(bytes[s..s + 8].try_into().expect("8 bytes"))
        };
        if word(0) != block_first_px as u64
            || word(1) != n_px as u64
            || word(2) != self.epochs as u64
            || first_px + n_px > self.nodata.len()
        {
            return false;
        }
        let mut at = header;
        for (i, &n) in bytes[at..at + n_px].iter().enumerate() {
            self.nodata[first_px + i] = n != 0;
        }
        at += n_px;
        let px = first_px..first_px + n_px;
        for a in [
            &mut self.sun_fraction_sum,
            &mut self.irradiance_horizontal_sum_w_m2,
            &mut self.irradiance_tracking_sum_w_m2,
            &mut self.power_sum_w,
            &mut self.required_battery_wh,
        ] {
            read_le(bytes, &mut at, &mut a[px.clone()], f64::from_le_bytes);
        }
        for a in [
            &mut self.sun_visible_count,
            &mut self.sun_full_count,
            &mut self.longest_dark_epochs,
            &mut self.earth_visible_count,
            &mut self.longest_earth_hidden_epochs,
            &mut self.sun_and_earth_count,
            &mut self.dte_count,
            &mut self.longest_dte_blackout_epochs,
        ] {
            read_le(bytes, &mut at, &mut a[px.clone()], u32::from_le_bytes);
        }
        self.below_sphere.cells += word(3);
        self.below_sphere.cell_epochs += word(4);
        true
    }
}

/// Reads `out.len()` little-endian values of `N` bytes each from `bytes` at `*at`, and moves
/// `at` past them.
fn read_le<const N: usize, T>(
    bytes: &[u8],
    at: &mut usize,
    out: &mut [T],
    from_le_bytes: fn([u8; N]) -> T,
) {
    let end = *at + N * out.len();
    for (o, c) in out.iter_mut().zip(bytes[*at..end].chunks_exact(N)) {
        *o = from_le_bytes(c.try_into().expect("N bytes"));
    }
    *at = end;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_block_round_trips_bit_for_bit() {
        let mut a = HorizonStatistics::empty(10, 7);
        for i in 0..10 {
            a.nodata[i] = i % 3 == 0;
            a.sun_fraction_sum[i] = 0.1 * i as f64 + 1e-17;
            a.irradiance_tracking_sum_w_m2[i] = -(i as f64).sqrt();
            a.longest_dark_epochs[i] = i as u32 * 7;
            a.sun_and_earth_count[i] = u32::MAX - i as u32;
        }
        let bytes = a.block_bytes(3, 5, (2, 9));
        let mut b = HorizonStatistics::empty(10, 7);
        assert!(b.place_block_bytes(3, 5, &bytes));
        for i in 3..8 {
            assert_eq!(a.nodata[i], b.nodata[i]);
            assert_eq!(
                a.sun_fraction_sum[i].to_bits(),
                b.sun_fraction_sum[i].to_bits()
            );
            assert_eq!(
                a.irradiance_tracking_sum_w_m2[i].to_bits(),
                b.irradiance_tracking_sum_w_m2[i].to_bits()
            );
            assert_eq!(a.longest_dark_epochs[i], b.longest_dark_epochs[i]);
            assert_eq!(a.sun_and_earth_count[i], b.sun_and_earth_count[i]);
        }
        assert!(b.nodata[0] && b.nodata[9]);
        assert_eq!((b.below_sphere.cells, b.below_sphere.cell_epochs), (2, 9));
        // Another place, size, epoch count or a truncated block is refused.
        assert!(!b.place_block_bytes(4, 5, &bytes));
        assert!(!b.place_block_bytes(3, 4, &bytes));
        assert!(!HorizonStatistics::empty(10, 8).place_block_bytes(3, 5, &bytes));
        assert!(!b.place_block_bytes(3, 5, &bytes[..bytes.len() - 1]));
    }
}

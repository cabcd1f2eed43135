//! Where the whole-grid horizons come from: a horizon GeoTIFF written by `penumbra horizon-map
//! sweep` (read a block of rows at a time), or a sweep run in memory.

use std::ops::Range;
use std::path::{Path, PathBuf};

use super::super::{HorizonError, HorizonSweep, SweepBand};
use crate::terrain::geotiff::{BandSample, MultiBandTiffReader};
use crate::terrain::{GridGeometry, Projection};

/// Nodata of the int16 horizon bands.
pub const HORIZON_NODATA_I16: i16 = i16::MIN;
/// The `penumbra_product` metadata item of a horizon GeoTIFF.
pub const HORIZON_PRODUCT: &str = "horizon elevation (line sweep)";

/// A horizon elevation (deg, NaN = nodata) in the files' int16 centi-degrees (−90° … 90°).
pub fn horizon_centideg(el_deg: f32) -> i16 {
    if el_deg.is_nan() {
        HORIZON_NODATA_I16
    } else {
        (el_deg * 100.0).round().clamp(-9000.0, 9000.0) as i16
    }
}

/// Whole-grid horizons read by blocks of rows.
pub trait HorizonRows {
    /// The horizons' grid (the finest layer's).
    fn grid(&self) -> GridGeometry;
    /// The band azimuths: grid azimuths, degrees, strictly increasing.
    fn grid_az_deg(&self) -> &[f64];
    /// The observer height above the ground the horizons were computed for, metres.
    fn observer_height_m(&self) -> f64;
    /// Rows `rows` of every band in centi-degrees ([`HORIZON_NODATA_I16`] = nodata), band-major:
    /// `out[band * n + i]` with `n = rows.len() * cols`.
    fn read_rows(&mut self, rows: Range<usize>, out: &mut Vec<i16>) -> Result<(), HorizonError>;
}

/// Horizons held in memory, one band per direction (from [`InMemoryHorizons::sweep`]).
pub struct InMemoryHorizons {
    grid: GridGeometry,
    grid_az_deg: Vec<f64>,
    observer_height_m: f64,
    /// The rows held ([`HorizonSweep::rows`]).
    rows: Range<usize>,
    bands: Vec<Vec<i16>>,
}

impl InMemoryHorizons {
    /// Runs `sweep` and keeps its bands, quantised as in the horizon GeoTIFF (so a statistics
    /// map from memory and one from the file are identical). `progress` gets the bands done;
    /// when it returns `false` the sweep stops with [`HorizonError::Interrupted`].
    pub fn sweep(
        sweep: &HorizonSweep<'_>,
        progress: impl FnMut(usize) -> bool,
    ) -> Result<Self, HorizonError> {
        Self::sweep_with(sweep, |sink| sweep.run(sink, |_| {}), progress)
    }

    /// As [`Self::sweep`], with the bands produced by `run` (which hands every band of `sweep`
    /// to the sink it gets: the CPU sweep, or its looks on the GPU).
    pub fn sweep_with<E: From<HorizonError>>(
        sweep: &HorizonSweep<'_>,
        run: impl FnOnce(&mut dyn FnMut(SweepBand<'_>) -> Result<(), E>) -> Result<(), E>,
        mut progress: impl FnMut(usize) -> bool,
    ) -> Result<Self, E> {
        let dirs = sweep.directions();
        let mut bands = vec![Vec::new(); dirs.len()];
        let mut done = 0;
        run(&mut |band| {
            bands[band.index] = band
                .elevation_deg
                .iter()
                .map(|&e| horizon_centideg(e))
                .collect();
            done += 1;
            if progress(done) {
                Ok(())
            } else {
                Err(E::from(HorizonError::Interrupted))
            }
        })?;
        Ok(InMemoryHorizons {
            grid: sweep.grid_dem().grid,
            grid_az_deg: dirs.iter().map(|d| d.grid_az_deg).collect(),
            observer_height_m: sweep.params().observer_height_m,
            rows: sweep.rows(),
            bands,
        })
    }

    /// Memory held, bytes.
    pub fn bytes(&self) -> usize {
        self.bands.iter().map(|b| 2 * b.len()).sum()
    }
}

impl HorizonRows for InMemoryHorizons {
    fn grid(&self) -> GridGeometry {
        self.grid
    }
    fn grid_az_deg(&self) -> &[f64] {
        &self.grid_az_deg
    }
    fn observer_height_m(&self) -> f64 {
        self.observer_height_m
    }
    fn read_rows(&mut self, rows: Range<usize>, out: &mut Vec<i16>) -> Result<(), HorizonError> {
        let cols = self.grid.cols;
        if rows.start < self.rows.start || rows.end > self.rows.end {
            return Err(HorizonError::SweepUnsupported {
                reason: format!(
                    "rows {}..{} asked of horizons held for rows {}..{}",
                    rows.start, rows.end, self.rows.start, self.rows.end
                ),
            });
        }
        let (a, b) = (rows.start - self.rows.start, rows.end - self.rows.start);
        out.clear();
        for band in &self.bands {
            out.extend_from_slice(&band[a * cols..b * cols]);
        }
        Ok(())
    }
}

/// A horizon GeoTIFF from `penumbra horizon-map sweep`, checked: int16 bands whose descriptions
/// give their grid azimuths, and the observer height it was computed for.
pub struct HorizonFile {
    reader: MultiBandTiffReader,
    path: PathBuf,
    grid_az_deg: Vec<f64>,
    observer_height_m: f64,
    words: Vec<u16>,
}

impl HorizonFile {
    /// Opens and checks `path`.
    pub fn open(path: &Path) -> Result<Self, HorizonError> {
        let bad = |detail: String| HorizonError::BadHorizonFile {
            path: path.display().to_string(),
            detail,
        };
        let reader = MultiBandTiffReader::open(path).map_err(|e| match e {
            crate::terrain::DemError::NotPenumbraMultiBand { detail, .. } => bad(format!(
                "{detail}: not a penumbra horizon map (write one with `penumbra horizon-map sweep`)"
            )),
            other => bad(other.to_string()),
        })?;
        if reader.sample != BandSample::I16
            || reader.metadata_item("penumbra_product") != Some(HORIZON_PRODUCT)
        {
            return Err(bad(format!(
                "not a penumbra horizon map (write one with `penumbra horizon-map sweep`; its \
                 product is {:?})",
                reader
                    .metadata_item("penumbra_product")
                    .unwrap_or("not recorded")
            )));
        }
        let observer_height_m = reader
            .metadata_item("observer_height_m")
            .and_then(|v| v.trim().parse::<f64>().ok())
            .filter(|h| h.is_finite() && *h >= 0.0)
            .ok_or_else(|| bad("no valid observer_height_m metadata item".into()))?;
        let grid_az_deg = reader
            .descriptions
            .iter()
            .enumerate()
            .map(|(i, d)| {
                d.split_whitespace()
                    .find_map(|w| w.strip_prefix("grid_az_deg="))
                    .and_then(|v| v.parse::<f64>().ok())
                    .ok_or_else(|| {
                        bad(format!(
                            "band {} has no grid azimuth in its description {d:?}",
                            i + 1
                        ))
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if super::AzimuthLookup::new(&grid_az_deg).is_none() {
            return Err(bad(
                "its band azimuths are not strictly increasing in [0, 360)".into(),
            ));
        }
        Ok(HorizonFile {
            reader,
            path: path.to_path_buf(),
            grid_az_deg,
            observer_height_m,
            words: Vec::new(),
        })
    }

    /// The file's projection.
    pub fn projection(&self) -> Projection {
        self.reader.projection
    }
}

impl HorizonRows for HorizonFile {
    fn grid(&self) -> GridGeometry {
        self.reader.grid
    }
    fn grid_az_deg(&self) -> &[f64] {
        &self.grid_az_deg
    }
    fn observer_height_m(&self) -> f64 {
        self.observer_height_m
    }
    fn read_rows(&mut self, rows: Range<usize>, out: &mut Vec<i16>) -> Result<(), HorizonError> {
        out.clear();
        for band in 0..self.grid_az_deg.len() {
            self.reader
                .read_rows(band, rows.clone(), &mut self.words)
                .map_err(|e| HorizonError::BadHorizonFile {
                    path: self.path.display().to_string(),
                    detail: e.to_string(),
                })?;
            out.extend(self.words.iter().map(|&w| w as i16));
        }
        Ok(())
    }
}

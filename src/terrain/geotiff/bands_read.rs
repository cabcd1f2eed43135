//! Reading the streaming multi-band GeoTIFFs of [`super::MultiBandTiff`] (penumbra's whole-grid
//! horizon files) by row blocks: any rows of any band, straight from the file, without decoding
//! the whole raster (a 1536² × 552-band horizon map is 2.6 GB; a statistics pass reads it a block
//! of rows at a time).
//!
//! Only the layout penumbra writes is accepted (checked, with a one-line error otherwise):
//! uncompressed 16-bit samples, one band per strip (`PlanarConfiguration = 2`,
//! `RowsPerStrip = rows`), GeoTIFF georeferencing, GDAL band descriptions and metadata.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::*;

/// An open multi-band GeoTIFF; see the module docs.
pub struct MultiBandTiffReader {
    file: File,
    path: PathBuf,
    /// The raster grid (pixel-is-area).
    pub grid: GridGeometry,
    /// The map projection.
    pub projection: Projection,
    /// The sample type of every band.
    pub sample: BandSample,
    /// GDAL band descriptions, one per band (empty strings where there is none).
    pub descriptions: Vec<String>,
    /// Dataset metadata items (`name`, value) of the GDAL_METADATA tag.
    pub metadata: Vec<(String, String)>,
    /// File offset of each band's strip.
    band_offsets: Vec<u64>,
}

impl MultiBandTiffReader {
    /// Opens `path` and checks its layout.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let file = File::open(path).map_err(|source| DemError::Io {
            path: name.clone(),
            source,
        })?;
        if file.metadata().map(|m| !m.is_file()).unwrap_or(true) {
            return Err(DemError::Decode {
                path: name,
                detail: "not a regular file".into(),
            });
        }
        let tiff_err = |e: TiffError| map_tiff_error(&name, e);
        let bad = |detail: String| DemError::NotPenumbraMultiBand {
            path: name.clone(),
            detail,
        };
        let mut decoder = Decoder::new(std::io::BufReader::new(file.try_clone().map_err(
            |source| DemError::Io {
                path: name.clone(),
                source,
            },
        )?))
        .map_err(tiff_err)?;
        let (cols, rows) = decoder.dimensions().map_err(tiff_err)?;
        let (rows, cols) = (rows as usize, cols as usize);
        let n_bands: u16 = decoder
            .find_tag_unsigned(Tag::SamplesPerPixel)
            .map_err(tiff_err)?
            .unwrap_or(1);
        let n = usize::from(n_bands);
        let ints = |decoder: &mut Decoder<_>, tag: Tag| -> Result<Vec<u64>> {
            match decoder.find_tag(tag).map_err(tiff_err)? {
                Some(v) => v.into_u64_vec().map_err(tiff_err),
                None => Ok(Vec::new()),
            }
        };
        let bits = ints(&mut decoder, Tag::BitsPerSample)?;
        let formats = ints(&mut decoder, Tag::SampleFormat)?;
        let compression = ints(&mut decoder, Tag::Compression)?;
        let planar = ints(&mut decoder, Tag::PlanarConfiguration)?;
        let rows_per_strip = ints(&mut decoder, Tag::RowsPerStrip)?;
        let offsets = ints(&mut decoder, Tag::StripOffsets)?;
        let counts = ints(&mut decoder, Tag::StripByteCounts)?;
        if bits.iter().any(|&b| b != 16) || bits.is_empty() {
            return Err(bad(format!(
                "{} bits per sample",
                bits.first().copied().unwrap_or(0)
            )));
        }
        let sample = match formats.first().copied().unwrap_or(1) {
            2 => BandSample::I16,
            3 => BandSample::F16,
            f => return Err(bad(format!("sample format {f}"))),
        };
        if formats.iter().any(|&f| f != formats[0]) {
            return Err(bad("bands of different sample formats".into()));
        }
        if compression.first().copied().unwrap_or(1) != 1 {
            return Err(bad("compressed data".into()));
        }
        if n > 1 && planar.first().copied() != Some(2) {
            return Err(bad("pixel-interleaved bands".into()));
        }
        let band_bytes = 2 * rows as u64 * cols as u64;
        if rows_per_strip.first().copied().unwrap_or(rows as u64) < rows as u64
            || offsets.len() != n
            || counts.len() != n
            || counts.iter().any(|&c| c != band_bytes)
        {
            return Err(bad(format!(
                "{} strips for {n} bands (one strip of {band_bytes} bytes per band expected)",
                offsets.len()
            )));
        }
        let file_len = file
            .metadata()
            .map_err(|source| DemError::Io {
                path: name.clone(),
                source,
            })?
            .len();
        if let Some(end) = offsets
            .iter()
            .map(|&o| o.saturating_add(band_bytes))
            .max()
            .filter(|&end| end > file_len)
        {
            return Err(DemError::Truncated {
                path: name,
                detail: format!("a band ends at byte {end} of a {file_len}-byte file"),
            });
        }

        // Georeferencing, as for a DEM.
        let (grid, projection) = read_georeferencing(&mut decoder, &name, rows, cols)?;
        let items = find_ascii(&mut decoder, Tag::Unknown(TAG_GDAL_METADATA))
            .map_err(tiff_err)?
            .map(|xml| parse_gdal_metadata(&xml))
            .unwrap_or_default();
        let mut descriptions = vec![String::new(); n];
        let mut metadata = Vec::new();
        for item in items {
            match (item.sample.as_deref(), item.role.as_deref()) {
                (Some(s), Some("description")) => {
                    if let Some(d) = s
                        .parse::<usize>()
                        .ok()
                        .and_then(|i| descriptions.get_mut(i))
                    {
                        *d = item.value;
                    }
                }
                (None, None) => metadata.push((item.name, item.value)),
                _ => {}
            }
        }
        Ok(MultiBandTiffReader {
            file,
            path: path.to_path_buf(),
            grid,
            projection,
            sample,
            descriptions,
            metadata,
            band_offsets: offsets,
        })
    }

    /// Number of bands.
    pub fn n_bands(&self) -> usize {
        self.band_offsets.len()
    }

    /// The value of dataset metadata item `name`.
    pub fn metadata_item(&self, name: &str) -> Option<&str> {
        self.metadata
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// Reads rows `rows` of band `band` as raw 16-bit words (row-major) into `out`.
    pub fn read_rows(
        &mut self,
        band: usize,
        rows: std::ops::Range<usize>,
        out: &mut Vec<u16>,
    ) -> Result<()> {
        let cols = self.grid.cols;
        if band >= self.n_bands() || rows.end > self.grid.rows || rows.start > rows.end {
            return Err(DemError::InvalidParameter(format!(
                "rows {rows:?} of band {band} in a {}-band file of {} rows",
                self.n_bands(),
                self.grid.rows
            )));
        }
        let n = rows.len() * cols;
        let start = self.band_offsets[band] + 2 * (rows.start * cols) as u64;
        let mut bytes = vec![0_u8; 2 * n];
        let io = |source| DemError::Io {
            path: self.path.display().to_string(),
            source,
        };
        self.file.seek(SeekFrom::Start(start)).map_err(io)?;
        self.file
            .read_exact(&mut bytes)
            .map_err(|source| DemError::Io {
                path: self.path.display().to_string(),
                source,
            })?;
        out.clear();
        out.extend(
            bytes
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]])),
        );
        Ok(())
    }
}

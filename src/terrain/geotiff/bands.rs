//! Streaming multi-band GeoTIFFs (BigTIFF, one uncompressed strip per band, bands stored one
//! after the other: `PlanarConfiguration = 2`), for products with hundreds of bands that do not
//! fit in memory at once (a whole-grid horizon map: one band per azimuth). Bands are written in
//! any order as they are computed; the file is built under a temporary name next to the output
//! and renamed into place by [`MultiBandTiff::finish`], so an interrupted run leaves nothing.
//! GDAL reads them as one dataset with per-band descriptions (`GDAL_METADATA`).

use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use super::*;

/// The sample type of every band.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BandSample {
    /// Signed 16-bit integers.
    I16,
    /// IEEE half floats (GDAL: Float16, read as Float32).
    F16,
}

impl BandSample {
    fn sample_format(self) -> u16 {
        match self {
            BandSample::I16 => 2,
            BandSample::F16 => 3,
        }
    }
}

/// A multi-band GeoTIFF being written; see the module docs.
pub struct MultiBandTiff {
    tmp: tempfile::NamedTempFile,
    path: PathBuf,
    n_bands: usize,
    band_bytes: u64,
    data_start: u64,
    written: Vec<bool>,
}

const TYPE_ASCII: u16 = 2;
const TYPE_SHORT: u16 = 3;
const TYPE_LONG: u16 = 4;
const TYPE_DOUBLE: u16 = 12;
const TYPE_LONG8: u16 = 16;

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> DemError + '_ {
    move |source| {
        DemError::Output(OutputError::Io {
            path: path.display().to_string(),
            source,
        })
    }
}

impl MultiBandTiff {
    /// Starts `path` with `descriptions.len()` bands of 16-bit `sample`s on `grid`, with GDAL
    /// band descriptions, a nodata value (as GDAL text) and dataset metadata items.
    pub fn create(
        path: &Path,
        grid: &GridGeometry,
        projection: &Projection,
        sample: BandSample,
        descriptions: &[String],
        nodata: &str,
        metadata: &[(&str, &str)],
    ) -> Result<Self> {
        let n = descriptions.len();
        if n == 0 || n > 65_535 || grid.rows == 0 || grid.cols == 0 {
            return Err(DemError::InvalidParameter(format!(
                "{n} bands of {} x {} cells",
                grid.rows, grid.cols
            )));
        }
        let mut tmp = crate::output::temp_file_beside(path).map_err(io_err(path))?;
        let band_bytes = 2 * (grid.rows * grid.cols) as u64;
        let (geo_dir, geo_doubles, geo_ascii) = write::geo_keys_for(projection);
        let xml = gdal_metadata_xml_with_bands(metadata, descriptions);

        // Entries (tag, type, count, little-endian value bytes), sorted by tag. Strip offsets are
        // filled once the layout is known.
        let shorts = |v: &[u16]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let doubles = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let ascii = |s: &str| {
            let mut b = s.as_bytes().to_vec();
            b.push(0);
            b
        };
        let n16 = n as u16;
        let mut entries: Vec<(u16, u16, u64, Vec<u8>)> = vec![
            (256, TYPE_LONG, 1, (grid.cols as u32).to_le_bytes().to_vec()),
            (257, TYPE_LONG, 1, (grid.rows as u32).to_le_bytes().to_vec()),
            (258, TYPE_SHORT, n as u64, shorts(&vec![16; n])),
            (259, TYPE_SHORT, 1, shorts(&[1])),
            (262, TYPE_SHORT, 1, shorts(&[1])),
            (273, TYPE_LONG8, n as u64, vec![0; 8 * n]),
            (277, TYPE_SHORT, 1, shorts(&[n16])),
            (278, TYPE_LONG, 1, (grid.rows as u32).to_le_bytes().to_vec()),
            (
                279,
                TYPE_LONG8,
                n as u64,
                (0..n).flat_map(|_| band_bytes.to_le_bytes()).collect(),
            ),
            (284, TYPE_SHORT, 1, shorts(&[2])),
        ];
        if n > 1 {
            entries.push((338, TYPE_SHORT, (n - 1) as u64, shorts(&vec![0; n - 1])));
        }
        entries.push((
            339,
            TYPE_SHORT,
            n as u64,
            shorts(&vec![sample.sample_format(); n]),
        ));
        entries.push((
            33550,
            TYPE_DOUBLE,
            3,
            doubles(&[grid.px_x_m, grid.px_y_m, 0.0]),
        ));
        entries.push((
            33922,
            TYPE_DOUBLE,
            6,
            doubles(&[0.0, 0.0, 0.0, grid.x_left_m, grid.y_top_m, 0.0]),
        ));
        entries.push((34735, TYPE_SHORT, geo_dir.len() as u64, shorts(&geo_dir)));
        entries.push((
            34736,
            TYPE_DOUBLE,
            geo_doubles.len() as u64,
            doubles(&geo_doubles),
        ));
        let ga = ascii(&geo_ascii);
        entries.push((34737, TYPE_ASCII, ga.len() as u64, ga));
        let x = ascii(&xml);
        entries.push((TAG_GDAL_METADATA, TYPE_ASCII, x.len() as u64, x));
        let nd = ascii(nodata);
        entries.push((TAG_GDAL_NODATA, TYPE_ASCII, nd.len() as u64, nd));

        // Layout: header (16), IFD (8 + 20 per entry + 8), out-of-line values, data.
        let ifd_len = 8 + 20 * entries.len() as u64 + 8;
        let mut extra_at = 16 + ifd_len;
        let mut offsets = Vec::with_capacity(entries.len());
        for e in &entries {
            if e.3.len() > 8 {
                offsets.push(Some(extra_at));
                extra_at += e.3.len() as u64;
                extra_at += extra_at % 2;
            } else {
                offsets.push(None);
            }
        }
        let data_start = extra_at.div_ceil(16) * 16;
        let strip_offsets: Vec<u8> = (0..n as u64)
            .flat_map(|i| (data_start + i * band_bytes).to_le_bytes())
            .collect();
        if let Some(e) = entries.iter_mut().find(|e| e.0 == 273) {
            e.3 = strip_offsets;
        }
        let mut head: Vec<u8> = Vec::with_capacity(data_start as usize);
        head.extend_from_slice(b"II");
        head.extend_from_slice(&43u16.to_le_bytes());
        head.extend_from_slice(&8u16.to_le_bytes());
        head.extend_from_slice(&0u16.to_le_bytes());
        head.extend_from_slice(&16u64.to_le_bytes());
        head.extend_from_slice(&(entries.len() as u64).to_le_bytes());
        for (e, off) in entries.iter().zip(&offsets) {
            head.extend_from_slice(&e.0.to_le_bytes());
            head.extend_from_slice(&e.1.to_le_bytes());
            head.extend_from_slice(&e.2.to_le_bytes());
            let mut v = [0u8; 8];
            match off {
                Some(o) => v.copy_from_slice(&o.to_le_bytes()),
                None => v[..e.3.len()].copy_from_slice(&e.3),
            }
            head.extend_from_slice(&v);
        }
        head.extend_from_slice(&0u64.to_le_bytes());
        for (e, off) in entries.iter().zip(&offsets) {
            if let Some(o) = off {
                head.resize(*o as usize, 0);
                head.extend_from_slice(&e.3);
            }
        }
        head.resize(data_start as usize, 0);
        let f = tmp.as_file_mut();
        f.write_all(&head).map_err(io_err(path))?;
        f.set_len(data_start + n as u64 * band_bytes)
            .map_err(io_err(path))?;
        Ok(MultiBandTiff {
            tmp,
            path: path.to_path_buf(),
            n_bands: n,
            band_bytes,
            data_start,
            written: vec![false; n],
        })
    }

    /// Writes band `index` (row-major values as little-endian 16-bit words).
    pub fn write_band(&mut self, index: usize, words: &[u16]) -> Result<()> {
        if index >= self.n_bands || 2 * words.len() as u64 != self.band_bytes {
            return Err(DemError::InvalidParameter(format!(
                "band {index} of {} values for a {}-band file of {} values per band",
                words.len(),
                self.n_bands,
                self.band_bytes / 2
            )));
        }
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let path = self.path.clone();
        let f = self.tmp.as_file_mut();
        f.seek(SeekFrom::Start(
            self.data_start + index as u64 * self.band_bytes,
        ))
        .map_err(io_err(&path))?;
        f.write_all(&bytes).map_err(io_err(&path))?;
        self.written[index] = true;
        Ok(())
    }

    /// Renames the finished file into place; every band must have been written.
    pub fn finish(self) -> Result<()> {
        if let Some(missing) = self.written.iter().position(|w| !w) {
            return Err(DemError::InvalidParameter(format!(
                "band {missing} of {} was never written",
                self.n_bands
            )));
        }
        let path = self.path;
        self.tmp.as_file().sync_all().map_err(io_err(&path))?;
        crate::output::persist_temp(self.tmp, &path).map_err(io_err(&path))?;
        Ok(())
    }
}

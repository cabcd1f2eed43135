//! GeoTIFF input and output for single-band DEMs and maps, with the pure-Rust `tiff` crate.
//!
//! [`read_geotiff`] reads one band of float or integer samples (strips or tiles, uncompressed,
//! LZW, Deflate or ZSTD, with or without a predictor), scales integers by the `SCALE`/`OFFSET`
//! items of GDAL_METADATA, turns GDAL_NODATA into `NaN`, and takes the grid from ModelPixelScale +
//! ModelTiepoint or ModelTransformation and the GeoKeyDirectory: polar stereographic or
//! equirectangular on a lunar sphere, or a PROJ string in a citation key. A pixel-is-point raster
//! is shifted by half a pixel into the pixel-is-area convention of [`GridGeometry`], as GDAL
//! does; false easting/northing are folded into the grid origin, so the [`Projection`] never
//! carries them. The image is decoded chunk by chunk into the output `Vec<f32>` (peak: the DEM
//! plus one chunk).
//!
//! [`write_geotiff`] (f32, u16 or u8) and [`write_dem`] write Cloud-Optimized GeoTIFFs in GDAL's
//! layout (`cog.rs`) with a user-defined GeoKeyDirectory, GDAL_NODATA and a GDAL_METADATA block
//! ([`BandInfo`]), atomically ([`crate::output::write_atomic`]). Sample types, GeoKeys, tags and
//! measured sizes: `docs/terrain.md`, "Reading" and "Writing".

use std::collections::BTreeMap;
use std::io::{Read, Seek};
use std::path::Path;

use tiff::decoder::{ChunkType, Decoder, DecodingResult};
use tiff::tags::Tag;
use tiff::{TiffError, TiffFormatError};

use super::error::{DemError, Result};
use super::grid::{Dem, GridGeometry, Projection};
use crate::output::{OutputError, write_atomic};

/// TIFF tag of GDAL's XML metadata block.
const TAG_GDAL_METADATA: u16 = 42112;
/// TIFF tag of GDAL's nodata value (ASCII).
const TAG_GDAL_NODATA: u16 = 42113;

// GeoKey ids (GeoTIFF 1.0 specification, section 6.2).
const KEY_MODEL_TYPE: u16 = 1024;
const KEY_RASTER_TYPE: u16 = 1025;
const KEY_GT_CITATION: u16 = 1026;
const KEY_GEOGRAPHIC_TYPE: u16 = 2048;
const KEY_GEOG_CITATION: u16 = 2049;
const KEY_GEOG_DATUM: u16 = 2050;
const KEY_GEOG_ANGULAR_UNITS: u16 = 2054;
const KEY_GEOG_ELLIPSOID: u16 = 2056;
const KEY_GEOG_SEMI_MAJOR: u16 = 2057;
const KEY_GEOG_SEMI_MINOR: u16 = 2058;
const KEY_GEOG_INV_FLATTENING: u16 = 2059;
const KEY_GEOG_PRIME_MERIDIAN_LONG: u16 = 2061;
const KEY_PROJECTED_CS_TYPE: u16 = 3072;
const KEY_PCS_CITATION: u16 = 3073;
const KEY_PROJECTION: u16 = 3074;
const KEY_PROJ_COORD_TRANS: u16 = 3075;
const KEY_PROJ_LINEAR_UNITS: u16 = 3076;
const KEY_PROJ_STD_PARALLEL1: u16 = 3078;
const KEY_PROJ_NAT_ORIGIN_LONG: u16 = 3080;
const KEY_PROJ_NAT_ORIGIN_LAT: u16 = 3081;
const KEY_PROJ_FALSE_EASTING: u16 = 3082;
const KEY_PROJ_FALSE_NORTHING: u16 = 3083;
const KEY_PROJ_CENTER_LONG: u16 = 3088;
const KEY_PROJ_CENTER_LAT: u16 = 3089;
const KEY_PROJ_SCALE_AT_NAT_ORIGIN: u16 = 3092;
const KEY_PROJ_STRAIGHT_VERT_POLE_LONG: u16 = 3095;

/// GeoTIFF "user-defined" code.
const USER_DEFINED: u16 = 32767;
/// `CT_PolarStereographic`.
const CT_POLAR_STEREOGRAPHIC: u16 = 15;
/// `CT_Equirectangular`.
const CT_EQUIRECTANGULAR: u16 = 17;
/// TIFF Compression value of ZSTD (GDAL, libtiff).
const COMPRESSION_ZSTD: u16 = 50000;
/// ProjCoordTransGeoKey value of the orthographic projection.
const CT_ORTHOGRAPHIC: u16 = 21;
/// EPSG unit code of the metre.
const EPSG_METRE: u16 = 9001;
/// EPSG unit code of the degree.
const EPSG_DEGREE: u16 = 9102;
/// Range of sphere radii accepted as "the Moon", metres (LOLA uses 1,737,400 m; some products
/// use 1,737,150 m).
const LUNAR_RADIUS_RANGE_M: std::ops::RangeInclusive<f64> = 1_700_000.0..=1_780_000.0;

/// One GeoKey value.
#[derive(Debug, Clone, PartialEq)]
enum GeoKeyValue {
    Short(u16),
    Doubles(Vec<f64>),
    Ascii(String),
}

/// Reads a single-band GeoTIFF DEM (see the module docs for what is supported). Heights are
/// returned as stored (after scale/offset), nodata as `NaN`.
pub fn read_geotiff(path: &Path) -> Result<Dem> {
    Ok(read_geotiff_with_metadata(path)?.0)
}

/// Like [`read_geotiff`], and also returns the `name`/value items of the GDAL_METADATA tag
/// (empty when there is none).
pub fn read_geotiff_with_metadata(path: &Path) -> Result<(Dem, Vec<(String, String)>)> {
    let name = path.display().to_string();
    let file = crate::output::guard::open_regular(path).map_err(|source| DemError::Io {
        path: name.clone(),
        source,
    })?;
    read_geotiff_from(std::io::BufReader::new(file), &name)
}

/// Reads a single-band GeoTIFF from any seekable reader; `name` labels the DEM and the errors.
pub fn read_geotiff_from<R: Read + Seek>(
    mut reader: R,
    name: &str,
) -> Result<(Dem, Vec<(String, String)>)> {
    let tiff_err = |e: TiffError| map_tiff_error(name, e);
    let io_err = |source| DemError::Io {
        path: name.into(),
        source,
    };
    let file_len = reader.seek(std::io::SeekFrom::End(0)).map_err(io_err)?;
    reader.rewind().map_err(io_err)?;
    let mut decoder = Decoder::new(reader).map_err(tiff_err)?;

    // --- sample layout -------------------------------------------------------------------------
    let (cols_u32, rows_u32) = decoder.dimensions().map_err(tiff_err)?;
    let bands: u16 = decoder
        .find_tag_unsigned(Tag::SamplesPerPixel)
        .map_err(tiff_err)?
        .unwrap_or(1);
    if bands != 1 {
        return Err(DemError::MultiBand {
            path: name.into(),
            bands,
        });
    }
    let bits: u16 = decoder
        .find_tag_unsigned(Tag::BitsPerSample)
        .map_err(tiff_err)?
        .unwrap_or(1);
    let format: u16 = decoder
        .find_tag_unsigned(Tag::SampleFormat)
        .map_err(tiff_err)?
        .unwrap_or(1);
    let kind = match (format, bits) {
        (3, 32) => SampleKind::F32,
        (3, 64) => SampleKind::F64,
        (2, 16) => SampleKind::I16,
        (2, 32) => SampleKind::I32,
        (1, 16) => SampleKind::U16,
        (1, 8) => SampleKind::U8,
        _ => {
            let what = match format {
                1 => "unsigned integer",
                2 => "signed integer",
                3 => "float",
                5 => "complex integer",
                6 => "complex float",
                _ => "undefined",
            };
            return Err(DemError::UnsupportedSampleFormat {
                path: name.into(),
                detail: format!("{bits}-bit {what}"),
            });
        }
    };

    // --- georeferencing ------------------------------------------------------------------------
    let geo_err = |detail: String| DemError::Georeferencing {
        path: name.into(),
        detail,
    };
    let (grid, projection) =
        read_georeferencing(&mut decoder, name, rows_u32 as usize, cols_u32 as usize)?;
    Dem::check_georeferencing(&grid, &projection).map_err(geo_err)?;
    check_declared_size(&mut decoder, &grid, kind, file_len).map_err(|detail| {
        DemError::Rejected {
            path: name.into(),
            detail,
        }
    })?;

    // --- nodata and scale/offset ---------------------------------------------------------------
    let nodata = find_ascii(&mut decoder, Tag::Unknown(TAG_GDAL_NODATA))
        .map_err(tiff_err)?
        .and_then(|s| parse_nodata(&s));
    let metadata = find_ascii(&mut decoder, Tag::Unknown(TAG_GDAL_METADATA))
        .map_err(tiff_err)?
        .map(|xml| parse_gdal_metadata(&xml))
        .unwrap_or_default();
    let band_item = |role: &str| -> Option<f64> {
        metadata
            .iter()
            .find(|item| {
                item.name.eq_ignore_ascii_case(role) && item.sample.as_deref() != Some("1")
            })
            .and_then(|item| item.value.trim().parse().ok())
    };
    let scale = band_item("SCALE").unwrap_or(1.0);
    let offset = band_item("OFFSET").unwrap_or(0.0);
    if !(scale.is_finite() && scale != 0.0 && scale.abs() <= 1e6 && offset.is_finite()) {
        return Err(geo_err(format!(
            "GDAL SCALE {scale} / OFFSET {offset} (the scale must be finite, non-zero and at most 1e6 in size, the offset finite)"
        )));
    }

    // --- pixels, chunk by chunk into the output buffer ----------------------------------------
    let (rows, cols) = (grid.rows, grid.cols);
    let mut heights_m = vec![f32::NAN; rows * cols];
    let chunk_type = decoder.get_chunk_type();
    let (chunk_w, chunk_h) = decoder.chunk_dimensions();
    let (chunk_w, chunk_h) = (chunk_w as usize, chunk_h as usize);
    let n_chunks = match chunk_type {
        ChunkType::Strip => decoder.strip_count(),
        ChunkType::Tile => decoder.tile_count(),
    }
    .map_err(tiff_err)?;
    let chunks_across = match chunk_type {
        ChunkType::Strip => 1,
        ChunkType::Tile => cols.div_ceil(chunk_w.max(1)),
    };
    // ZSTD chunks are decoded here (pure-Rust `ruzstd`; the `tiff` crate's ZSTD needs C libzstd).
    let compression: u16 = decoder
        .find_tag_unsigned(Tag::Compression)
        .map_err(tiff_err)?
        .unwrap_or(1);
    let zstd = (compression == COMPRESSION_ZSTD)
        .then(|| -> std::result::Result<_, TiffError> {
            let (offsets_tag, counts_tag) = match chunk_type {
                ChunkType::Strip => (Tag::StripOffsets, Tag::StripByteCounts),
                ChunkType::Tile => (Tag::TileOffsets, Tag::TileByteCounts),
            };
            let predictor: u16 = decoder.find_tag_unsigned(Tag::Predictor)?.unwrap_or(1);
            Ok((
                decoder.get_tag_u64_vec(offsets_tag)?,
                decoder.get_tag_u64_vec(counts_tag)?,
                predictor,
            ))
        })
        .transpose()
        .map_err(tiff_err)?;
    let scaled = |x: f64| int_sample(x, nodata, scale, offset);
    for chunk in 0..n_chunks {
        let (w, h) = decoder.chunk_data_dimensions(chunk);
        let (w, h) = (w as usize, h as usize);
        let idx = chunk as usize;
        let (col0, row0) = match chunk_type {
            ChunkType::Strip => (0, idx * chunk_h),
            ChunkType::Tile => (
                (idx % chunks_across) * chunk_w,
                (idx / chunks_across) * chunk_h,
            ),
        };
        let data = match &zstd {
            None => decoder.read_chunk(chunk).map_err(tiff_err)?,
            Some((offsets, counts, predictor)) => {
                // A tile is stored whole (padded); a strip holds its own rows.
                let stored = match chunk_type {
                    ChunkType::Strip => (w, h),
                    ChunkType::Tile => (chunk_w, chunk_h),
                };
                let at = (offsets.get(idx).copied(), counts.get(idx).copied());
                let (Some(offset), Some(count)) = at else {
                    return Err(geo_err(format!("no offset or size for chunk {idx}")));
                };
                let big_endian = decoder.byte_order() == tiff::tags::ByteOrder::BigEndian;
                zstd_chunk::read(
                    decoder.inner(),
                    (offset, count),
                    stored,
                    (w, h),
                    kind,
                    *predictor,
                    big_endian,
                )
                .map_err(|detail| DemError::Decode {
                    path: name.into(),
                    detail: format!("ZSTD chunk {idx}: {detail}"),
                })?
            }
        };
        let place = Placement {
            cols,
            rows,
            col0,
            row0,
            w,
            h,
        };
        match (kind, data) {
            (SampleKind::F32, DecodingResult::F32(v)) => {
                let nd = nodata.map(|n| n as f32);
                place.copy(&mut heights_m, &v, |x| {
                    if Some(x) == nd {
                        f32::NAN
                    } else if scale == 1.0 && offset == 0.0 {
                        x
                    } else {
                        (f64::from(x) * scale + offset) as f32
                    }
                });
            }
            // NaN nodata never equals itself: NaN samples are holes anyway.
            (SampleKind::F64, DecodingResult::F64(v)) => {
                place.copy_widened(&mut heights_m, &v, scaled)
            }
            (SampleKind::I32, DecodingResult::I32(v)) => {
                place.copy_widened(&mut heights_m, &v, scaled)
            }
            (SampleKind::I16, DecodingResult::I16(v)) => {
                place.copy_widened(&mut heights_m, &v, scaled)
            }
            (SampleKind::U16, DecodingResult::U16(v)) => {
                place.copy_widened(&mut heights_m, &v, scaled)
            }
            (SampleKind::U8, DecodingResult::U8(v)) => {
                place.copy_widened(&mut heights_m, &v, scaled)
            }
            (_, other) => {
                return Err(DemError::Decode {
                    path: name.into(),
                    detail: format!(
                        "decoder returned {} samples for a {kind:?} raster",
                        variant_name(&other)
                    ),
                });
            }
        }
    }
    if heights_m.iter().all(|h| h.is_nan()) {
        return Err(DemError::AllNodata { path: name.into() });
    }
    if let Some(h) = heights_m.iter().find(|h| h.is_infinite()) {
        return Err(DemError::Rejected {
            path: name.into(),
            detail: format!("holds an infinite value ({h})"),
        });
    }
    let items = metadata
        .into_iter()
        .filter(|item| item.sample.is_none() && item.role.is_none())
        .map(|item| (item.name, item.value))
        .collect();
    Ok((
        Dem {
            grid,
            projection,
            heights_m,
            name: name.into(),
        },
        items,
    ))
}

/// Largest ratio of decoded to stored pixel bytes accepted for compressed data (LZW reaches
/// ≈ 2,700:1 on constant data, Deflate ≈ 1,030:1).
const MAX_COMPRESSION_RATIO: u128 = 4096;

/// Checks what the header declares before the pixel buffer is allocated: the decoded size within
/// the memory budget, the chunks inside the file, and enough stored bytes for the pixels they
/// claim to hold (a 4 KiB file cannot hold 10¹⁰ pixels).
fn check_declared_size<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    grid: &GridGeometry,
    kind: SampleKind,
    file_len: u64,
) -> std::result::Result<(), String> {
    let cells = grid.rows as u128 * grid.cols as u128;
    crate::output::guard::check_budget(
        &format!("the {} x {} pixel grid", grid.cols, grid.rows),
        cells * 4,
    )?;
    let counts_tag = match decoder.get_chunk_type() {
        ChunkType::Strip => Tag::StripByteCounts,
        ChunkType::Tile => Tag::TileByteCounts,
    };
    let counts = decoder
        .get_tag_u64_vec(counts_tag)
        .map_err(|e| format!("no chunk byte counts: {e}"))?;
    let stored: u128 = counts.iter().map(|&c| u128::from(c)).sum();
    if stored > u128::from(file_len) {
        return Err(format!(
            "the header declares {stored} bytes of pixel data but the file has {file_len} bytes (truncated?)"
        ));
    }
    let decoded = cells * kind.bytes() as u128;
    let compression: u16 = decoder
        .find_tag_unsigned(Tag::Compression)
        .ok()
        .flatten()
        .unwrap_or(1);
    let ratio = if compression == 1 {
        1
    } else {
        MAX_COMPRESSION_RATIO
    };
    if decoded > stored * ratio {
        return Err(format!(
            "the header declares {} x {} pixels ({decoded} bytes) but the file stores only {stored} bytes of pixel data",
            grid.cols, grid.rows
        ));
    }
    Ok(())
}

/// The sample types penumbra reads.
#[derive(Debug, Clone, Copy)]
enum SampleKind {
    F64,
    F32,
    I32,
    I16,
    U16,
    U8,
}

impl SampleKind {
    /// Bytes per sample.
    fn bytes(self) -> usize {
        match self {
            SampleKind::F64 => 8,
            SampleKind::F32 | SampleKind::I32 => 4,
            SampleKind::I16 | SampleKind::U16 => 2,
            SampleKind::U8 => 1,
        }
    }
}

fn variant_name(d: &DecodingResult) -> &'static str {
    match d {
        DecodingResult::U8(_) => "u8",
        DecodingResult::U16(_) => "u16",
        DecodingResult::U32(_) => "u32",
        DecodingResult::U64(_) => "u64",
        DecodingResult::F16(_) => "f16",
        DecodingResult::F32(_) => "f32",
        DecodingResult::F64(_) => "f64",
        DecodingResult::I8(_) => "i8",
        DecodingResult::I16(_) => "i16",
        DecodingResult::I32(_) => "i32",
        DecodingResult::I64(_) => "i64",
    }
}

#[inline]
fn int_sample(raw: f64, nodata: Option<f64>, scale: f64, offset: f64) -> f32 {
    if Some(raw) == nodata {
        f32::NAN
    } else {
        (raw * scale + offset) as f32
    }
}

/// Where a decoded chunk (`w` x `h` samples, row-major) lands in the image.
struct Placement {
    cols: usize,
    rows: usize,
    col0: usize,
    row0: usize,
    w: usize,
    h: usize,
}

impl Placement {
    /// [`Self::copy`] of samples that `f64` holds exactly, converted by `conv`.
    fn copy_widened<T: Copy + Into<f64>>(
        &self,
        out: &mut [f32],
        src: &[T],
        conv: impl Fn(f64) -> f32,
    ) {
        self.copy(out, src, |x| conv(x.into()));
    }

    fn copy<T: Copy>(&self, out: &mut [f32], src: &[T], conv: impl Fn(T) -> f32) {
        let w = self.w.min(self.cols.saturating_sub(self.col0));
        let h = self.h.min(self.rows.saturating_sub(self.row0));
        for r in 0..h {
            let Some(src_row) = src.get(r * self.w..r * self.w + w) else {
                return;
            };
            let start = (self.row0 + r) * self.cols + self.col0;
            for (o, &s) in out[start..start + w].iter_mut().zip(src_row) {
                *o = conv(s);
            }
        }
    }
}

fn map_tiff_error(name: &str, e: TiffError) -> DemError {
    match e {
        TiffError::FormatError(
            f @ (TiffFormatError::TiffSignatureNotFound | TiffFormatError::TiffSignatureInvalid),
        ) => DemError::NotTiff {
            path: name.into(),
            detail: f.to_string(),
        },
        TiffError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            DemError::Truncated {
                path: name.into(),
                detail: io.to_string(),
            }
        }
        TiffError::IoError(io) => DemError::Io {
            path: name.into(),
            source: io,
        },
        TiffError::UnsupportedError(u) if u.to_string().to_lowercase().contains("sample") => {
            DemError::UnsupportedSampleFormat {
                path: name.into(),
                detail: u.to_string(),
            }
        }
        TiffError::UnsupportedError(
            u @ tiff::TiffUnsupportedError::UnsupportedCompressionMethod(_),
        ) => DemError::Decode {
            path: name.into(),
            detail: format!(
                "{u} (penumbra reads uncompressed, LZW, Deflate and ZSTD; convert with \
                     `gdal_translate -co COMPRESS=DEFLATE -co PREDICTOR=3 IN OUT`)"
            ),
        },
        other => DemError::Decode {
            path: name.into(),
            detail: other.to_string(),
        },
    }
}

/// The georeferencing of the first image of `decoder` (`rows` x `cols` pixels): its pixel-is-area
/// grid (false easting/northing folded into the origin) and projection, from the model tie point,
/// pixel scale or transformation tags and the GeoKey directory.
fn read_georeferencing<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    name: &str,
    rows: usize,
    cols: usize,
) -> Result<(GridGeometry, Projection)> {
    let tiff_err = |e: TiffError| map_tiff_error(name, e);
    let geo_err = |detail: String| DemError::Georeferencing {
        path: name.into(),
        detail,
    };
    let pixel_scale = find_f64s(decoder, Tag::ModelPixelScaleTag).map_err(tiff_err)?;
    let tiepoint = find_f64s(decoder, Tag::ModelTiepointTag).map_err(tiff_err)?;
    let transformation = find_f64s(decoder, Tag::ModelTransformationTag).map_err(tiff_err)?;
    let Some(key_dir) = decoder
        .find_tag(Tag::GeoKeyDirectoryTag)
        .map_err(tiff_err)?
    else {
        return Err(geo_err(
            "no GeoKeyDirectory tag (34735): not a GeoTIFF".into(),
        ));
    };
    let key_dir = key_dir.into_u16_vec().map_err(tiff_err)?;
    let doubles = find_f64s(decoder, Tag::GeoDoubleParamsTag)
        .map_err(tiff_err)?
        .unwrap_or_default();
    let ascii = find_ascii(decoder, Tag::GeoAsciiParamsTag)
        .map_err(tiff_err)?
        .unwrap_or_default();
    let keys = parse_geo_keys(&key_dir, &doubles, &ascii).map_err(geo_err)?;
    let crs = projection_from_geo_keys(&keys).map_err(|detail| DemError::UnknownCrs {
        path: name.into(),
        detail,
    })?;
    let pixel_is_point = matches!(keys.get(&KEY_RASTER_TYPE), Some(GeoKeyValue::Short(2)));
    let grid = grid_from_tags(
        rows,
        cols,
        pixel_scale.as_deref(),
        tiepoint.as_deref(),
        transformation.as_deref(),
        pixel_is_point,
        (crs.false_easting_m, crs.false_northing_m),
    )
    .map_err(geo_err)?;
    Ok((grid, crs.projection))
}

fn find_f64s<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    tag: Tag,
) -> std::result::Result<Option<Vec<f64>>, TiffError> {
    decoder.find_tag(tag)?.map(|v| v.into_f64_vec()).transpose()
}

fn find_ascii<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    tag: Tag,
) -> std::result::Result<Option<String>, TiffError> {
    decoder.find_tag(tag)?.map(|v| v.into_string()).transpose()
}

/// Parses the GeoKeyDirectory (GeoTIFF 1.0 section 2.4): a header `(version, revision, minor,
/// count)` then `count` entries `(key, location, count, value_or_offset)`.
fn parse_geo_keys(
    dir: &[u16],
    doubles: &[f64],
    ascii: &str,
) -> std::result::Result<BTreeMap<u16, GeoKeyValue>, String> {
    if dir.len() < 4 {
        return Err("GeoKeyDirectory shorter than its header".into());
    }
    let n = usize::from(dir[3]);
    if dir.len() < 4 + 4 * n {
        return Err(format!(
            "GeoKeyDirectory announces {n} keys but holds {} values",
            dir.len()
        ));
    }
    let mut keys = BTreeMap::new();
    for e in dir[4..4 + 4 * n].chunks_exact(4) {
        let (key, loc, count, off) = (e[0], e[1], usize::from(e[2]), usize::from(e[3]));
        let value = match loc {
            0 => GeoKeyValue::Short(e[3]),
            34736 => GeoKeyValue::Doubles(
                doubles
                    .get(off..off + count)
                    .ok_or_else(|| format!("GeoKey {key}: double parameters out of range"))?
                    .to_vec(),
            ),
            34737 => {
                let s = ascii
                    .get(off..(off + count).min(ascii.len()))
                    .ok_or_else(|| format!("GeoKey {key}: ASCII parameters out of range"))?;
                GeoKeyValue::Ascii(s.trim_end_matches(['|', '\0']).to_string())
            }
            34735 => GeoKeyValue::Short(*dir.get(off).unwrap_or(&0)),
            _ => continue,
        };
        keys.insert(key, value);
    }
    Ok(keys)
}

/// A recognised CRS: the projection and the false easting/northing (folded into the grid).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Crs {
    projection: Projection,
    false_easting_m: f64,
    false_northing_m: f64,
}

fn key_short(keys: &BTreeMap<u16, GeoKeyValue>, key: u16) -> Option<u16> {
    match keys.get(&key) {
        Some(GeoKeyValue::Short(v)) => Some(*v),
        _ => None,
    }
}

fn key_f64(keys: &BTreeMap<u16, GeoKeyValue>, key: u16) -> Option<f64> {
    match keys.get(&key) {
        Some(GeoKeyValue::Doubles(v)) => v.first().copied(),
        _ => None,
    }
}

/// Recognises polar stereographic or equirectangular on a lunar sphere from the GeoKeys (see the
/// module docs); the error string says why a CRS was rejected.
fn projection_from_geo_keys(keys: &BTreeMap<u16, GeoKeyValue>) -> std::result::Result<Crs, String> {
    let model_type = key_short(keys, KEY_MODEL_TYPE);
    if model_type == Some(2) {
        return Err(
            "geographic (latitude/longitude) raster; reproject to polar stereographic or equirectangular metres"
                .into(),
        );
    }
    let Some(ct) = key_short(keys, KEY_PROJ_COORD_TRANS) else {
        // Fallback: a PROJ string in one of the citations.
        for key in [KEY_PCS_CITATION, KEY_GT_CITATION, KEY_GEOG_CITATION] {
            if let Some(GeoKeyValue::Ascii(s)) = keys.get(&key)
                && s.contains("+proj=")
            {
                return crs_from_proj_string(s);
            }
        }
        return Err(match key_short(keys, KEY_PROJECTED_CS_TYPE) {
            Some(code) if code != USER_DEFINED => {
                format!("EPSG:{code} is not a lunar polar stereographic or equirectangular CRS")
            }
            _ => "no ProjCoordTransGeoKey and no PROJ string".into(),
        });
    };
    if let Some(units) = key_short(keys, KEY_PROJ_LINEAR_UNITS)
        && units != EPSG_METRE
    {
        return Err(format!("linear unit EPSG:{units} is not the metre"));
    }
    let radius_m = sphere_radius_m(keys)?;
    let fe = key_f64(keys, KEY_PROJ_FALSE_EASTING).unwrap_or(0.0);
    let fn_ = key_f64(keys, KEY_PROJ_FALSE_NORTHING).unwrap_or(0.0);
    let projection = match ct {
        CT_POLAR_STEREOGRAPHIC => {
            let lat0 = key_f64(keys, KEY_PROJ_NAT_ORIGIN_LAT)
                .or_else(|| key_f64(keys, KEY_PROJ_CENTER_LAT))
                .unwrap_or(90.0);
            if (lat0.abs() - 90.0).abs() > 1e-9 {
                return Err(format!(
                    "stereographic with latitude of origin {lat0} deg is not polar"
                ));
            }
            let lon0_deg = key_f64(keys, KEY_PROJ_STRAIGHT_VERT_POLE_LONG)
                .or_else(|| key_f64(keys, KEY_PROJ_NAT_ORIGIN_LONG))
                .or_else(|| key_f64(keys, KEY_PROJ_CENTER_LONG))
                .unwrap_or(0.0);
            // Variant B gives a standard parallel instead of a scale factor; on the sphere
            // k0 = (1 + sin|lat_ts|) / 2 (Snyder 1987, eq. 21-7 with the sphere).
            let k0 = key_f64(keys, KEY_PROJ_SCALE_AT_NAT_ORIGIN).unwrap_or_else(|| {
                key_f64(keys, KEY_PROJ_STD_PARALLEL1)
                    .map(|ts| (1.0 + ts.abs().to_radians().sin()) / 2.0)
                    .unwrap_or(1.0)
            });
            Projection::PolarStereographic {
                south: lat0 < 0.0,
                lon0_deg,
                k0,
                radius_m,
            }
        }
        CT_EQUIRECTANGULAR => {
            let lon0_deg = key_f64(keys, KEY_PROJ_CENTER_LONG)
                .or_else(|| key_f64(keys, KEY_PROJ_NAT_ORIGIN_LONG))
                .unwrap_or(0.0);
            let lat_ts_deg = key_f64(keys, KEY_PROJ_STD_PARALLEL1).unwrap_or(0.0);
            // y = R (lat - lat0) + FN, so a non-zero lat0 is one more false northing.
            let lat0 = key_f64(keys, KEY_PROJ_CENTER_LAT).unwrap_or(0.0);
            return Ok(Crs {
                projection: Projection::Equirectangular {
                    lon0_deg,
                    lat_ts_deg,
                    radius_m,
                },
                false_easting_m: fe,
                false_northing_m: fn_ - radius_m * lat0.to_radians(),
            });
        }
        other => {
            return Err(format!(
                "coordinate transformation code {other} (only 15 polar stereographic and 17 equirectangular)"
            ));
        }
    };
    Ok(Crs {
        projection,
        false_easting_m: fe,
        false_northing_m: fn_,
    })
}

/// The sphere radius from the ellipsoid GeoKeys; errors for a non-lunar or non-spherical body.
fn sphere_radius_m(keys: &BTreeMap<u16, GeoKeyValue>) -> std::result::Result<f64, String> {
    if let Some(code) = key_short(keys, KEY_GEOG_ELLIPSOID)
        && code != USER_DEFINED
    {
        return Err(format!("ellipsoid EPSG:{code} is not the lunar sphere"));
    }
    if let Some(code) = key_short(keys, KEY_GEOGRAPHIC_TYPE)
        && code != USER_DEFINED
        && key_f64(keys, KEY_GEOG_SEMI_MAJOR).is_none()
    {
        return Err(format!("geographic CRS EPSG:{code} is not lunar"));
    }
    let a = key_f64(keys, KEY_GEOG_SEMI_MAJOR)
        .ok_or("no ellipsoid semi-major axis (GeogSemiMajorAxisGeoKey)")?;
    let b = key_f64(keys, KEY_GEOG_SEMI_MINOR).unwrap_or_else(|| {
        match key_f64(keys, KEY_GEOG_INV_FLATTENING) {
            Some(inv_f) if inv_f != 0.0 => a * (1.0 - 1.0 / inv_f),
            _ => a,
        }
    });
    if !LUNAR_RADIUS_RANGE_M.contains(&a) {
        return Err(format!("semi-major axis {a} m is not the Moon's"));
    }
    if (a - b).abs() > 1e-3 {
        return Err(format!("ellipsoid a = {a} m, b = {b} m is not a sphere"));
    }
    Ok(a)
}

/// Parses a PROJ string such as `+proj=stere +lat_0=-90 +lon_0=0 +k=1 +R=1737400`.
fn crs_from_proj_string(s: &str) -> std::result::Result<Crs, String> {
    let mut params = BTreeMap::new();
    for tok in s.split_whitespace() {
        let tok = tok.trim_start_matches('+');
        if let Some((k, v)) = tok.split_once('=') {
            params.insert(k.to_string(), v.trim_matches(['|', '"']).to_string());
        }
    }
    let num = |k: &str| -> std::result::Result<Option<f64>, String> {
        params
            .get(k)
            .map(|v| {
                v.parse::<f64>()
                    .map_err(|_| format!("PROJ parameter {k}={v}"))
            })
            .transpose()
    };
    let radius_m = num("R")?
        .or(num("a")?)
        .ok_or("PROJ string without +R or +a")?;
    if let Some(b) = num("b")?
        && (b - radius_m).abs() > 1e-3
    {
        return Err(format!(
            "PROJ ellipsoid a = {radius_m} m, b = {b} m is not a sphere"
        ));
    }
    if !LUNAR_RADIUS_RANGE_M.contains(&radius_m) {
        return Err(format!("PROJ radius {radius_m} m is not the Moon's"));
    }
    let lon0_deg = num("lon_0")?.unwrap_or(0.0);
    let fe = num("x_0")?.unwrap_or(0.0);
    let fn_ = num("y_0")?.unwrap_or(0.0);
    match params.get("proj").map(String::as_str) {
        Some("stere") | Some("ups") => {
            let lat0 = num("lat_0")?.unwrap_or(0.0);
            if (lat0.abs() - 90.0).abs() > 1e-9 {
                return Err(format!("+proj=stere with lat_0={lat0} is not polar"));
            }
            let k0 = match (num("k")?.or(num("k_0")?), num("lat_ts")?) {
                (Some(k), _) => k,
                (None, Some(ts)) => (1.0 + ts.abs().to_radians().sin()) / 2.0,
                (None, None) => 1.0,
            };
            Ok(Crs {
                projection: Projection::PolarStereographic {
                    south: lat0 < 0.0,
                    lon0_deg,
                    k0,
                    radius_m,
                },
                false_easting_m: fe,
                false_northing_m: fn_,
            })
        }
        Some("eqc") => {
            let lat0 = num("lat_0")?.unwrap_or(0.0);
            Ok(Crs {
                projection: Projection::Equirectangular {
                    lon0_deg,
                    lat_ts_deg: num("lat_ts")?.unwrap_or(0.0),
                    radius_m,
                },
                false_easting_m: fe,
                false_northing_m: fn_ - radius_m * lat0.to_radians(),
            })
        }
        other => Err(format!("PROJ projection {other:?}")),
    }
}

/// Builds the pixel-is-area grid from the raster tags; `false_en_m` is removed from the map
/// coordinates so that they are the projection's own.
fn grid_from_tags(
    rows: usize,
    cols: usize,
    pixel_scale: Option<&[f64]>,
    tiepoint: Option<&[f64]>,
    transformation: Option<&[f64]>,
    pixel_is_point: bool,
    false_en_m: (f64, f64),
) -> std::result::Result<GridGeometry, String> {
    let (x_corner, y_corner, px_x_m, px_y_m) = match (pixel_scale, tiepoint, transformation) {
        (Some(scale), Some(tie), _) if scale.len() >= 2 && tie.len() >= 6 => {
            if tie.len() > 6 {
                return Err("several tie points (warped rasters are not supported)".into());
            }
            // Tie point (i, j, k, x, y, z): raster (i, j) sits at map (x, y).
            (
                tie[3] - tie[0] * scale[0],
                tie[4] + tie[1] * scale[1],
                scale[0],
                scale[1],
            )
        }
        (_, _, Some(m)) if m.len() >= 16 => {
            if m[1] != 0.0 || m[4] != 0.0 {
                return Err("rotated ModelTransformation is not supported".into());
            }
            (m[3], m[7], m[0], -m[5])
        }
        _ => {
            return Err(
                "neither ModelPixelScale + ModelTiepoint nor ModelTransformation is present".into(),
            );
        }
    };
    if !(px_x_m > 0.0 && px_y_m > 0.0 && px_x_m.is_finite() && px_y_m.is_finite()) {
        return Err(format!(
            "pixel size {px_x_m} x {px_y_m} m (must be positive, north-up)"
        ));
    }
    // Pixel-is-point: the tie point is the centre of pixel (0, 0); move it to its outer corner.
    let (half_x, half_y) = if pixel_is_point {
        (px_x_m / 2.0, px_y_m / 2.0)
    } else {
        (0.0, 0.0)
    };
    Ok(GridGeometry {
        rows,
        cols,
        x_left_m: x_corner - half_x - false_en_m.0,
        y_top_m: y_corner + half_y - false_en_m.1,
        px_x_m,
        px_y_m,
    })
}

/// Parses GDAL's nodata string (`"-32768"`, `"nan"`, `"-3.4028234663852886e+38"`).
fn parse_nodata(s: &str) -> Option<f64> {
    let t = s.trim().trim_end_matches('\0');
    if t.eq_ignore_ascii_case("nan") {
        return Some(f64::NAN);
    }
    t.parse().ok()
}

mod bands;
mod bands_read;
mod cog;
mod gdal_metadata;
mod write;
mod zstd_chunk;

pub use bands::{BandSample, MultiBandTiff};
pub use bands_read::MultiBandTiffReader;

pub use cog::COG_TILE_PX;
/// GDAL's metadata XML (`GDAL_METADATA`, tag 42112) of dataset items and one band's description
/// and unit.
pub use gdal_metadata::gdal_metadata_xml_with_band;
use gdal_metadata::*;
pub use write::{
    BandInfo, WriteSample, iau_2015_crs, orthographic_model_tags, write_dem, write_geotiff,
};

#[cfg(test)]
mod tests;

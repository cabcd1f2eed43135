//! Cloud-Optimized GeoTIFF encoding of one band, as GDAL's COG driver lays it out.
//!
//! - **Tiles** of [`COG_TILE_PX`]² pixels, **Deflate** (zlib, pure-Rust `miniz_oxide` through
//!   `flate2`) with a **predictor**: horizontal differencing (2) for integers, the floating-point
//!   predictor (3, byte planes then differencing) for `f32`. Partial edge tiles are padded with
//!   the nodata value (or 0).
//! - **Overviews** halving the size until the image fits in one tile: the mean of the valid
//!   pixels of each 2 × 2 block for `f32` (nodata where none is valid), the first valid pixel
//!   (row-major) for integer classes (masks keep their classes).
//! - **IFDs before the data**: the header, GDAL's structural-metadata "ghost" area
//!   (`LAYOUT=IFDS_BEFORE_DATA`, `BLOCK_ORDER=ROW_MAJOR`, `BLOCK_LEADER=SIZE_AS_UINT4`,
//!   `BLOCK_TRAILER=LAST_4_BYTES_REPEATED`), the full-resolution IFD, the overview IFDs, then the
//!   tile data from the smallest overview to the full resolution, each tile preceded by its size
//!   (u32) and followed by a copy of its last 4 bytes. `validate_cloud_optimized_geotiff.py
//!   --full-check=yes` accepts the files (`tests/it/terrain.rs`).
//! - Classic TIFF up to 4 GiB, BigTIFF above.
//!
//! Georeferencing and GDAL metadata go into the full-resolution IFD; GDAL_NODATA into every IFD.

use rayon::prelude::*;

/// Tile edge, pixels (GDAL's COG driver uses 512 by default; 256 keeps the 400² demo maps with
/// one overview and costs a few % in size).
pub const COG_TILE_PX: usize = 256;

/// A sample type written to a COG.
pub(super) trait CogSample: Copy + Send + Sync + PartialEq {
    /// BitsPerSample.
    const BITS: u16;
    /// SampleFormat: 1 unsigned integer, 3 IEEE float.
    const FORMAT: u16;
    /// Predictor: 2 horizontal differencing, 3 floating point.
    const PREDICTOR: u16;
    /// Whether `self` is nodata (`NaN` always is, for floats).
    fn is_nodata(self, nodata: Option<Self>) -> bool;
    /// The overview pixel of a 2 × 2 block (`None` outside the image).
    fn reduce(block: [Option<Self>; 4], nodata: Option<Self>) -> Self;
    /// The zero of the type (padding without a nodata value).
    fn zero() -> Self;
    /// Appends one row of samples with the predictor applied, little-endian.
    fn predict_row(row: &[Self], out: &mut Vec<u8>);
}

fn first_valid<T: CogSample>(block: [Option<T>; 4], nodata: Option<T>) -> T {
    block
        .into_iter()
        .flatten()
        .find(|v| !v.is_nodata(nodata))
        .or(nodata)
        .unwrap_or_else(T::zero)
}

/// The unsigned integer classes: nodata by equality, the first valid pixel of a block, horizontal
/// differencing.
macro_rules! unsigned_cog_sample {
    ($($t:ty),*) => {$(
        impl CogSample for $t {
            const BITS: u16 = <$t>::BITS as u16;
            const FORMAT: u16 = 1;
            const PREDICTOR: u16 = 2;
            fn is_nodata(self, nodata: Option<Self>) -> bool {
                nodata == Some(self)
            }
            fn reduce(block: [Option<Self>; 4], nodata: Option<Self>) -> Self {
                first_valid(block, nodata)
            }
            fn zero() -> Self {
                0
            }
            fn predict_row(row: &[Self], out: &mut Vec<u8>) {
                let mut prev: $t = 0;
                for &v in row {
                    out.extend_from_slice(&v.wrapping_sub(prev).to_le_bytes());
                    prev = v;
                }
            }
        }
    )*};
}

unsigned_cog_sample!(u8, u16);

impl CogSample for f32 {
    const BITS: u16 = 32;
    const FORMAT: u16 = 3;
    const PREDICTOR: u16 = 3;
    fn is_nodata(self, nodata: Option<Self>) -> bool {
        self.is_nan() || nodata == Some(self)
    }
    fn reduce(block: [Option<Self>; 4], nodata: Option<Self>) -> Self {
        let (mut sum, mut n) = (0.0f64, 0u32);
        for v in block.into_iter().flatten() {
            if !v.is_nodata(nodata) {
                sum += f64::from(v);
                n += 1;
            }
        }
        if n == 0 {
            nodata.unwrap_or(f32::NAN)
        } else {
            (sum / f64::from(n)) as f32
        }
    }
    fn zero() -> Self {
        0.0
    }
    /// TIFF Technical Note 3: the row's bytes as planes, most significant byte first, then
    /// byte-wise horizontal differencing over the whole row.
    fn predict_row(row: &[Self], out: &mut Vec<u8>) {
        let w = row.len();
        let start = out.len();
        out.resize(start + 4 * w, 0);
        let planes = &mut out[start..];
        for (x, v) in row.iter().enumerate() {
            let b = v.to_be_bytes();
            for (k, byte) in b.into_iter().enumerate() {
                planes[k * w + x] = byte;
            }
        }
        for i in (1..planes.len()).rev() {
            planes[i] = planes[i].wrapping_sub(planes[i - 1]);
        }
    }
}

/// One image of the pyramid.
struct Level<T> {
    width: usize,
    height: usize,
    values: Vec<T>,
}

fn reduce_level<T: CogSample>(
    width: usize,
    height: usize,
    values: &[T],
    nodata: Option<T>,
) -> Level<T> {
    let (w2, h2) = (width.div_ceil(2), height.div_ceil(2));
    let at = |r: usize, c: usize| (r < height && c < width).then(|| values[r * width + c]);
    let values = (0..h2)
        .into_par_iter()
        .flat_map_iter(|r| {
            (0..w2).map(move |c| {
                let (r0, c0) = (2 * r, 2 * c);
                T::reduce(
                    [
                        at(r0, c0),
                        at(r0, c0 + 1),
                        at(r0 + 1, c0),
                        at(r0 + 1, c0 + 1),
                    ],
                    nodata,
                )
            })
        })
        .collect();
    Level {
        width: w2,
        height: h2,
        values,
    }
}

/// The compressed tiles of one image, row-major.
fn encode_tiles<T: CogSample>(
    width: usize,
    height: usize,
    values: &[T],
    nodata: Option<T>,
) -> Vec<Vec<u8>> {
    use std::io::Write as _;
    let (tx, ty) = (width.div_ceil(COG_TILE_PX), height.div_ceil(COG_TILE_PX));
    let pad = nodata.unwrap_or_else(T::zero);
    (0..tx * ty)
        .into_par_iter()
        .map(|t| {
            let (r0, c0) = ((t / tx) * COG_TILE_PX, (t % tx) * COG_TILE_PX);
            let mut raw = Vec::with_capacity(COG_TILE_PX * COG_TILE_PX * usize::from(T::BITS / 8));
            let mut row = vec![pad; COG_TILE_PX];
            for r in r0..r0 + COG_TILE_PX {
                row.fill(pad);
                if r < height {
                    let n = COG_TILE_PX.min(width - c0);
                    row[..n].copy_from_slice(&values[r * width + c0..r * width + c0 + n]);
                }
                T::predict_row(&row, &mut raw);
            }
            let mut z = flate2::write::ZlibEncoder::new(
                Vec::with_capacity(raw.len() / 2),
                flate2::Compression::new(6),
            );
            z.write_all(&raw).expect("writing to memory");
            z.finish().expect("writing to memory")
        })
        .collect()
}

/// A TIFF field value.
enum Val {
    Short(Vec<u16>),
    Long(Vec<u32>),
    Long8(Vec<u64>),
    Double(Vec<f64>),
    Ascii(String),
}

impl Val {
    fn type_code(&self) -> u16 {
        match self {
            Val::Ascii(_) => 2,
            Val::Short(_) => 3,
            Val::Long(_) => 4,
            Val::Double(_) => 12,
            Val::Long8(_) => 16,
        }
    }
    fn count(&self) -> u64 {
        match self {
            Val::Short(v) => v.len() as u64,
            Val::Long(v) => v.len() as u64,
            Val::Long8(v) => v.len() as u64,
            Val::Double(v) => v.len() as u64,
            Val::Ascii(s) => s.len() as u64 + 1,
        }
    }
    fn bytes(&self) -> Vec<u8> {
        match self {
            Val::Short(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Val::Long(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Val::Long8(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Val::Double(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Val::Ascii(s) => s.bytes().chain([0]).collect(),
        }
    }
}

/// Bytes an IFD and its out-of-line values take (each value block at an even offset).
fn ifd_len(entries: &[(u16, Val)], big: bool) -> u64 {
    let (head, entry, next, inline) = if big { (8, 20, 8, 8) } else { (2, 12, 4, 4) };
    let outside: u64 = entries
        .iter()
        .map(|(_, v)| v.bytes().len() as u64)
        .filter(|&n| n > inline)
        .map(|n| n + n % 2)
        .sum();
    head + entry * entries.len() as u64 + next + outside
}

/// Appends an IFD at `out.len()` (which must be its planned offset) and its values.
fn write_ifd(out: &mut Vec<u8>, entries: &[(u16, Val)], big: bool, next_ifd: u64) {
    let inline = if big { 8 } else { 4 };
    let start = out.len() as u64;
    let table_len = if big {
        8 + 20 * entries.len() as u64 + 8
    } else {
        2 + 12 * entries.len() as u64 + 4
    };
    let mut outside_at = start + table_len;
    let mut outside = Vec::new();
    if big {
        out.extend_from_slice(&(entries.len() as u64).to_le_bytes());
    } else {
        out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    }
    for (tag, v) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&v.type_code().to_le_bytes());
        if big {
            out.extend_from_slice(&v.count().to_le_bytes());
        } else {
            out.extend_from_slice(&(v.count() as u32).to_le_bytes());
        }
        let mut b = v.bytes();
        if b.len() <= inline {
            b.resize(inline, 0);
            out.extend_from_slice(&b);
        } else {
            if big {
                out.extend_from_slice(&outside_at.to_le_bytes());
            } else {
                out.extend_from_slice(&(outside_at as u32).to_le_bytes());
            }
            if b.len() % 2 == 1 {
                b.push(0);
            }
            outside_at += b.len() as u64;
            outside.extend_from_slice(&b);
        }
    }
    if big {
        out.extend_from_slice(&next_ifd.to_le_bytes());
    } else {
        out.extend_from_slice(&(next_ifd as u32).to_le_bytes());
    }
    out.extend_from_slice(&outside);
}

/// GDAL's structural metadata, written after the header (its "ghost area").
const GHOST: &str = "LAYOUT=IFDS_BEFORE_DATA\nBLOCK_ORDER=ROW_MAJOR\nBLOCK_LEADER=SIZE_AS_UINT4\n\
BLOCK_TRAILER=LAST_4_BYTES_REPEATED\nKNOWN_INCOMPATIBLE_EDITION=NO\n ";

/// Tags of the full-resolution IFD only (georeferencing, GDAL metadata), ascending.
pub(super) type ExtraTags = Vec<(u16, ExtraVal)>;

/// The value of an extra tag.
#[derive(Clone)]
pub(super) enum ExtraVal {
    /// SHORT values.
    Short(Vec<u16>),
    /// DOUBLE values.
    Double(Vec<f64>),
    /// ASCII text.
    Ascii(String),
}

/// Encodes `values` (`width` × `height`, row-major) as a COG: tiles, Deflate + predictor,
/// overviews, IFDs first. `extra` tags go into the full-resolution IFD; `nodata_text` (GDAL_NODATA)
/// into every IFD.
pub(super) fn encode_cog<T: CogSample>(
    width: usize,
    height: usize,
    values: &[T],
    nodata: Option<T>,
    nodata_text: Option<&str>,
    extra: ExtraTags,
) -> Vec<u8> {
    // The pyramid: full resolution, then halves until one tile holds the image.
    let mut overviews: Vec<Level<T>> = Vec::new();
    let (mut w, mut h) = (width, height);
    while w > COG_TILE_PX || h > COG_TILE_PX {
        let next = match overviews.last() {
            None => reduce_level(width, height, values, nodata),
            Some(l) => reduce_level(l.width, l.height, &l.values, nodata),
        };
        (w, h) = (next.width, next.height);
        overviews.push(next);
    }
    let mut images: Vec<(usize, usize, Vec<Vec<u8>>)> =
        vec![(width, height, encode_tiles(width, height, values, nodata))];
    for l in &overviews {
        images.push((
            l.width,
            l.height,
            encode_tiles(l.width, l.height, &l.values, nodata),
        ));
    }
    let data_bytes: u64 = images
        .iter()
        .flat_map(|(_, _, tiles)| tiles.iter().map(|t| t.len() as u64 + 8))
        .sum();
    let big = data_bytes > u64::from(u32::MAX) - (64 << 20);

    let ifd_entries = |level: usize, offsets: Vec<u64>| {
        let (w, h, tiles) = &images[level];
        let mut e: Vec<(u16, Val)> = vec![
            (254, Val::Long(vec![u32::from(level > 0)])),
            (256, Val::Long(vec![*w as u32])),
            (257, Val::Long(vec![*h as u32])),
            (258, Val::Short(vec![T::BITS])),
            (259, Val::Short(vec![8])),
            (262, Val::Short(vec![1])),
            (277, Val::Short(vec![1])),
            (284, Val::Short(vec![1])),
            (317, Val::Short(vec![T::PREDICTOR])),
            (322, Val::Long(vec![COG_TILE_PX as u32])),
            (323, Val::Long(vec![COG_TILE_PX as u32])),
            (
                324,
                if big {
                    Val::Long8(offsets)
                } else {
                    Val::Long(offsets.iter().map(|&o| o as u32).collect())
                },
            ),
            (
                325,
                Val::Long(tiles.iter().map(|t| t.len() as u32).collect()),
            ),
            (339, Val::Short(vec![T::FORMAT])),
        ];
        if level == 0 {
            e.extend(extra.iter().cloned().map(|(tag, v)| {
                (
                    tag,
                    match v {
                        ExtraVal::Short(s) => Val::Short(s),
                        ExtraVal::Double(d) => Val::Double(d),
                        ExtraVal::Ascii(a) => Val::Ascii(a),
                    },
                )
            }));
        }
        if let Some(nd) = nodata_text {
            e.push((42113, Val::Ascii(nd.to_string())));
        }
        e.sort_by_key(|(tag, _)| *tag);
        e
    };

    // Plan: header, ghost, IFDs (sizes do not depend on the offsets' values), then the data.
    let header_len: u64 = if big { 16 } else { 8 };
    let ghost = format!(
        "GDAL_STRUCTURAL_METADATA_SIZE={:06} bytes\n{GHOST}",
        GHOST.len()
    );
    let mut at = header_len + ghost.len() as u64;
    at += at % 2;
    let first_ifd = at;
    let mut ifd_at = Vec::new();
    for (level, (_, _, tiles)) in images.iter().enumerate() {
        ifd_at.push(at);
        at += ifd_len(&ifd_entries(level, vec![0; tiles.len()]), big);
        at += at % 2;
    }
    // Tile data: smallest overview first, each tile as [size u32][bytes][last 4 bytes].
    let mut offsets: Vec<Vec<u64>> = vec![Vec::new(); images.len()];
    for level in (0..images.len()).rev() {
        for t in &images[level].2 {
            offsets[level].push(at + 4);
            at += t.len() as u64 + 8;
        }
    }
    let data_start = offsets
        .last()
        .and_then(|o| o.first())
        .map_or(at, |&o| o - 4);

    let mut out = Vec::with_capacity(at as usize);
    if big {
        out.extend_from_slice(b"II+\0");
        out.extend_from_slice(&8u16.to_le_bytes());
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(&first_ifd.to_le_bytes());
    } else {
        out.extend_from_slice(b"II*\0");
        out.extend_from_slice(&(first_ifd as u32).to_le_bytes());
    }
    out.extend_from_slice(ghost.as_bytes());
    for (level, offs) in offsets.into_iter().enumerate() {
        out.resize(ifd_at[level] as usize, 0);
        let next = ifd_at.get(level + 1).copied().unwrap_or(0);
        write_ifd(&mut out, &ifd_entries(level, offs), big, next);
    }
    out.resize(data_start as usize, 0);
    for level in (0..images.len()).rev() {
        for t in &images[level].2 {
            out.extend_from_slice(&(t.len() as u32).to_le_bytes());
            out.extend_from_slice(t);
            out.extend_from_slice(&t[t.len() - 4..]);
        }
    }
    debug_assert_eq!(out.len() as u64, at);
    out
}

//! ZSTD-compressed TIFF chunks (Compression 50000, as GDAL writes them), decoded with the pure-Rust
//! `ruzstd` (the `tiff` crate's own ZSTD support links the C libzstd): the chunk's bytes are read,
//! decompressed, the predictor undone (2: horizontal differencing; 3: floating point, TIFF
//! Technical Note 3), and the valid part returned as the `tiff` crate's `read_chunk` would.

use std::io::{Read, Seek, SeekFrom};

use tiff::decoder::DecodingResult;

use super::SampleKind;

/// Reads chunk `(offset, count)` holding `stored` (width, height) samples and returns its
/// `valid` (width, height) top-left part, row-major.
pub(super) fn read<R: Read + Seek>(
    reader: &mut R,
    (offset, count): (u64, u64),
    stored: (usize, usize),
    valid: (usize, usize),
    kind: SampleKind,
    predictor: u16,
    big_endian: bool,
) -> Result<DecodingResult, String> {
    let bps = kind.bytes();
    let row_bytes = stored.0 * bps;
    let want = row_bytes * stored.1;
    reader
        .seek(SeekFrom::Start(offset))
        .map_err(|e| e.to_string())?;
    let mut packed = Vec::new();
    reader
        .take(count)
        .read_to_end(&mut packed)
        .map_err(|e| e.to_string())?;
    if packed.len() as u64 != count {
        return Err(format!(
            "{} of {count} bytes in the file (truncated?)",
            packed.len()
        ));
    }
    let mut raw = Vec::with_capacity(want);
    ruzstd::decoding::StreamingDecoder::new(packed.as_slice())
        .map_err(|e| e.to_string())?
        .take(want as u64 + 1)
        .read_to_end(&mut raw)
        .map_err(|e| e.to_string())?;
    if raw.len() != want {
        return Err(format!("{} bytes decompressed, {want} expected", raw.len()));
    }
    // To native-order samples, predictor undone, one stored row at a time.
    let mut samples = Vec::with_capacity(stored.0 * stored.1);
    for row in raw.chunks_exact_mut(row_bytes) {
        match predictor {
            1 => {}
            2 if !matches!(kind, SampleKind::F32 | SampleKind::F64) => {}
            3 if matches!(kind, SampleKind::F32 | SampleKind::F64) => {
                for i in 1..row.len() {
                    row[i] = row[i].wrapping_add(row[i - 1]);
                }
                // Byte planes, most significant first, back to big-endian samples.
                let planes = row.to_vec();
                for x in 0..stored.0 {
                    for k in 0..bps {
                        row[x * bps + k] = planes[k * stored.0 + x];
                    }
                }
            }
            p => return Err(format!("predictor {p} with {kind:?} samples")),
        }
        let be = big_endian || predictor == 3;
        let mut prev: i64 = 0;
        for s in row.chunks_exact(bps) {
            let mut b = [0u8; 8];
            b[..bps].copy_from_slice(s);
            if be {
                b[..bps].reverse();
            }
            let bits = u64::from_le_bytes(b);
            let v = match kind {
                SampleKind::F64 => f64::from_bits(bits),
                SampleKind::F32 => f64::from(f32::from_bits(bits as u32)),
                _ => {
                    // Integers: sign-extend, then undo the differencing.
                    let shift = 64 - 8 * bps as u32;
                    let mut x = if matches!(kind, SampleKind::I16 | SampleKind::I32) {
                        ((bits << shift) as i64) >> shift
                    } else {
                        bits as i64
                    };
                    if predictor == 2 {
                        x = wrap(prev + x, kind);
                        prev = x;
                    }
                    x as f64
                }
            };
            samples.push(v);
        }
    }
    let (w, h) = valid;
    let crop = (0..h).flat_map(|r| samples[r * stored.0..r * stored.0 + w].iter().copied());
    Ok(match kind {
        SampleKind::F64 => DecodingResult::F64(crop.collect()),
        SampleKind::F32 => DecodingResult::F32(crop.map(|v| v as f32).collect()),
        SampleKind::I32 => DecodingResult::I32(crop.map(|v| v as i32).collect()),
        SampleKind::I16 => DecodingResult::I16(crop.map(|v| v as i16).collect()),
        SampleKind::U16 => DecodingResult::U16(crop.map(|v| v as u16).collect()),
        SampleKind::U8 => DecodingResult::U8(crop.map(|v| v as u8).collect()),
    })
}

/// `x` wrapped into the sample type's range (the predictor's sums are modular).
fn wrap(x: i64, kind: SampleKind) -> i64 {
    match kind {
        SampleKind::U8 => i64::from(x as u8),
        SampleKind::U16 => i64::from(x as u16),
        SampleKind::I16 => i64::from(x as i16),
        SampleKind::I32 => i64::from(x as i32),
        _ => x,
    }
}

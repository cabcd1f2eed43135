//! PDS3 DEMs (`.IMG` with a detached `.LBL` or an attached label), as LOLA distributes its
//! gridded products (`LDEM_*`): read natively, heights above the 1737.4 km sphere.
//!
//! - **Label**: ODL `KEY = VALUE` lines, `OBJECT = IMAGE` / `OBJECT = IMAGE_MAP_PROJECTION`
//!   blocks, `/* comments */`, units in `<…>`, quoted strings; `^IMAGE` as `"file"`,
//!   `("file", record)`, `record` or `bytes <BYTES>` (1-based, records of `RECORD_BYTES`).
//! - **Pixels**: one band of `LSB_`/`MSB_`/`PC_`/`MAC_`/`SUN_` integers (8, 16, 32 bits, signed or
//!   `UNSIGNED_`) or `PC_REAL`/`IEEE_REAL` floats (32, 64 bits), `LINE_PREFIX_BYTES` and
//!   `LINE_SUFFIX_BYTES` skipped; `MISSING_CONSTANT` (or `NULL`) becomes a hole.
//! - **Values**: `raw × SCALING_FACTOR + OFFSET`, in metres (`UNIT = KILOMETER` scaled by 1000).
//!   LOLA labels give `OFFSET = 1737400` (the value is then a radius): values within
//!   1,700–1,780 km are radii and become heights by subtracting 1,737,400 m.
//! - **Georeferencing** (`IMAGE_MAP_PROJECTION`): `POLAR STEREOGRAPHIC` (true scale at the pole,
//!   `CENTER_LATITUDE = ±90`) or `EQUIRECTANGULAR`/`SIMPLE CYLINDRICAL`, sphere
//!   `A_AXIS_RADIUS` (= `B_`, = `C_`), `MAP_SCALE` in metres (or km) per pixel, no rotation. The
//!   map x of sample `s` (1-based, pixel centre) is `(s − SAMPLE_PROJECTION_OFFSET − 1) ·
//!   MAP_SCALE` and y of line `l` is `(LINE_PROJECTION_OFFSET − l + 1) · MAP_SCALE`, as GDAL's
//!   PDS driver reads it (checked against it in `tests/it/terrain.rs`).

use std::collections::HashMap;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::error::{DemError, Result};
use super::grid::{Dem, GridGeometry, Projection};

/// Largest label read, bytes.
const MAX_LABEL_BYTES: u64 = 1 << 20;

/// Whether `path` looks like a PDS3 product: a `.lbl`/`.img` name, or a file starting with a
/// PDS3 label.
pub fn is_pds3(path: &Path) -> bool {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    ext == "lbl"
        || starts_with_label(path).unwrap_or(false)
        || (ext == "img" && sibling_label(path).is_some())
}

/// Whether the file begins with a PDS3 label (`PDS_VERSION_ID`, leading blanks allowed).
fn starts_with_label(path: &Path) -> std::io::Result<bool> {
    let mut head = [0u8; 64];
    let n = crate::output::guard::open_regular(path)?.read(&mut head)?;
    Ok(String::from_utf8_lossy(&head[..n])
        .trim_start()
        .starts_with("PDS_VERSION_ID"))
}

/// The detached label next to an image (`x.IMG` → `x.LBL` or `x.lbl`).
fn sibling_label(img: &Path) -> Option<PathBuf> {
    ["LBL", "lbl"]
        .iter()
        .map(|e| img.with_extension(e))
        .find(|p| p.is_file())
}

/// One ODL value (units kept apart).
#[derive(Debug, Clone)]
struct Value {
    text: String,
    unit: Option<String>,
}

impl Value {
    fn number(&self) -> Option<f64> {
        self.text.trim().parse().ok()
    }
}

/// The label: top-level keys and the keys of each object, by object name.
#[derive(Debug, Default)]
struct Label {
    top: HashMap<String, Value>,
    objects: HashMap<String, HashMap<String, Value>>,
}

/// Parses an ODL label (up to its `END` line).
fn parse_label(text: &str) -> std::result::Result<Label, String> {
    // Strip comments, then join continuation lines of quoted strings and parenthesised lists.
    let mut clean = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find("/*") {
        clean.push_str(&rest[..start]);
        rest = match rest[start..].find("*/") {
            Some(end) => &rest[start + end + 2..],
            None => "",
        };
    }
    clean.push_str(rest);
    let mut label = Label::default();
    let mut stack: Vec<String> = Vec::new();
    let mut lines = clean.lines();
    while let Some(line) = lines.next() {
        let line = line.trim();
        if line == "END" {
            break;
        }
        let Some((key, value)) = line.split_once('=') else {
            continue;
        };
        let key = key.trim().to_ascii_uppercase();
        let mut value = value.trim().to_string();
        // A quoted string or a list may continue over lines.
        while (value.matches('"').count() % 2 == 1)
            || (value.starts_with('(') && !value.contains(')'))
        {
            match lines.next() {
                Some(more) => {
                    value.push(' ');
                    value.push_str(more.trim());
                }
                None => return Err(format!("unterminated value of {key}")),
            }
        }
        match key.as_str() {
            "OBJECT" => {
                stack.push(value.trim_matches('"').to_ascii_uppercase());
                continue;
            }
            "END_OBJECT" => {
                stack.pop();
                continue;
            }
            _ => {}
        }
        let (text, unit) = match (value.rfind('<'), value.rfind('>')) {
            (Some(a), Some(b)) if a < b && !value.starts_with('"') => (
                value[..a].trim().to_string(),
                Some(value[a + 1..b].trim().to_ascii_uppercase()),
            ),
            _ => (value.clone(), None),
        };
        let v = Value {
            text: text.trim_matches('"').trim().to_string(),
            unit,
        };
        match stack.first() {
            None => {
                label.top.insert(key, v);
            }
            Some(obj) => {
                label
                    .objects
                    .entry(obj.clone())
                    .or_default()
                    .entry(key)
                    .or_insert(v);
            }
        }
    }
    Ok(label)
}

/// Sample types of a PDS3 (or PDS4) image.
#[derive(Debug, Clone, Copy)]
pub(super) enum Sample {
    Int {
        bytes: usize,
        signed: bool,
        big: bool,
    },
    Real {
        bytes: usize,
        big: bool,
    },
}

impl Sample {
    pub(super) fn parse(kind: &str, bits: u32) -> std::result::Result<Self, String> {
        let kind = kind.to_ascii_uppercase();
        let bytes = match bits {
            8 | 16 | 32 | 64 => bits as usize / 8,
            _ => return Err(format!("SAMPLE_BITS = {bits}")),
        };
        let big = kind.starts_with("MSB")
            || kind.starts_with("MAC")
            || kind.starts_with("SUN")
            || kind.starts_with("IEEE");
        let real = kind.contains("REAL");
        if real {
            if bytes != 4 && bytes != 8 {
                return Err(format!("{kind} with {bits} bits"));
            }
            if !(kind.starts_with("PC")
                || kind.starts_with("IEEE")
                || kind.starts_with("MAC")
                || kind.starts_with("SUN"))
            {
                return Err(format!("SAMPLE_TYPE = {kind} (VAX reals are not read)"));
            }
            Ok(Sample::Real { bytes, big })
        } else if kind.contains("INTEGER") {
            if bytes == 8 {
                return Err(format!("{kind} with 64 bits"));
            }
            Ok(Sample::Int {
                bytes,
                signed: !kind.contains("UNSIGNED") && bytes > 1,
                big: big && bytes > 1,
            })
        } else {
            Err(format!("SAMPLE_TYPE = {kind}"))
        }
    }

    fn bytes(self) -> usize {
        match self {
            Sample::Int { bytes, .. } | Sample::Real { bytes, .. } => bytes,
        }
    }

    fn value(self, b: &[u8]) -> f64 {
        let mut buf = [0u8; 8];
        let n = self.bytes();
        buf[..n].copy_from_slice(b);
        let big = match self {
            Sample::Int { big, .. } | Sample::Real { big, .. } => big,
        };
        if big {
            buf[..n].reverse();
        }
        let bits = u64::from_le_bytes(buf);
        match self {
            Sample::Real { bytes: 4, .. } => f64::from(f32::from_bits(bits as u32)),
            Sample::Real { .. } => f64::from_bits(bits),
            Sample::Int { bytes, signed, .. } => {
                let shift = 64 - 8 * bytes as u32;
                if signed {
                    (((bits << shift) as i64) >> shift) as f64
                } else {
                    bits as f64
                }
            }
        }
    }
}

/// Reads a PDS3 DEM: `path` is the label (`.LBL`) or the image (`.IMG`, with an attached label
/// or a `.LBL` beside it).
pub fn read_pds3(path: &Path) -> Result<Dem> {
    let name = path.display().to_string();
    let bad = |detail: String| DemError::Decode {
        path: name.clone(),
        detail: format!("PDS3: {detail}"),
    };
    // The label: the file itself (attached or detached label) or the .LBL beside an .IMG.
    let has_label = starts_with_label(path).map_err(|source| DemError::Io {
        path: name.clone(),
        source,
    })?;
    let label_path = if has_label {
        path.to_path_buf()
    } else {
        sibling_label(path)
            .ok_or_else(|| bad("no PDS3 label in the file and no .LBL beside it".into()))?
    };
    let mut label_bytes = Vec::new();
    crate::output::guard::open_regular(&label_path)
        .map_err(|source| DemError::Io {
            path: label_path.display().to_string(),
            source,
        })?
        .take(MAX_LABEL_BYTES)
        .read_to_end(&mut label_bytes)
        .map_err(|source| DemError::Io {
            path: label_path.display().to_string(),
            source,
        })?;
    let text = String::from_utf8_lossy(&label_bytes);
    let label = parse_label(&text).map_err(&bad)?;
    let top = |k: &str| label.top.get(k);
    let image = label
        .objects
        .get("IMAGE")
        .ok_or_else(|| bad("no OBJECT = IMAGE".into()))?;
    let proj = label.objects.get("IMAGE_MAP_PROJECTION").ok_or_else(|| {
        bad("no OBJECT = IMAGE_MAP_PROJECTION (the DEM must be map-projected)".into())
    })?;
    let num = |obj: &HashMap<String, Value>, k: &str| -> std::result::Result<f64, DemError> {
        obj.get(k)
            .and_then(Value::number)
            .ok_or_else(|| bad(format!("{k} missing or not a number")))
    };
    let opt = |obj: &HashMap<String, Value>,
               k: &str,
               default: f64|
     -> std::result::Result<f64, DemError> {
        match obj.get(k) {
            None => Ok(default),
            Some(v) => v
                .number()
                .ok_or_else(|| bad(format!("{k} = {} is not a number", v.text))),
        }
    };

    // --- the pixels' place in the files -------------------------------------------------------
    let lines = num(image, "LINES")?;
    let samples = num(image, "LINE_SAMPLES")?;
    let bands = opt(image, "BANDS", 1.0)?;
    if bands != 1.0 {
        return Err(DemError::MultiBand {
            path: name,
            bands: bands as u16,
        });
    }
    if !(lines >= 1.0
        && samples >= 1.0
        && lines <= 1e6
        && samples <= 1e6
        && lines.fract() == 0.0
        && samples.fract() == 0.0)
    {
        return Err(bad(format!("{samples} x {lines} samples")));
    }
    let (rows, cols) = (lines as usize, samples as usize);
    let sample = Sample::parse(
        &image
            .get("SAMPLE_TYPE")
            .map(|v| v.text.clone())
            .unwrap_or_default(),
        num(image, "SAMPLE_BITS")? as u32,
    )
    .map_err(&bad)?;
    let prefix = opt(image, "LINE_PREFIX_BYTES", 0.0)? as u64;
    let suffix = opt(image, "LINE_SUFFIX_BYTES", 0.0)? as u64;
    let record_bytes = opt(&label.top, "RECORD_BYTES", 0.0)?;
    let pointer = top("^IMAGE").ok_or_else(|| bad("no ^IMAGE pointer".into()))?;
    let base = label_path.parent().unwrap_or(Path::new("."));
    let (data_path, offset_bytes) = {
        let t = pointer
            .text
            .trim()
            .trim_start_matches('(')
            .trim_end_matches(')');
        let parts: Vec<&str> = t.split(',').map(|p| p.trim().trim_matches('"')).collect();
        let position = |p: &str, unit: Option<&str>| -> std::result::Result<u64, DemError> {
            let n: f64 = p
                .parse()
                .map_err(|_| bad(format!("^IMAGE position '{p}'")))?;
            if n < 1.0 {
                return Err(bad(format!("^IMAGE position {n}")));
            }
            Ok(if unit == Some("BYTES") {
                n as u64 - 1
            } else {
                if record_bytes <= 0.0 {
                    return Err(bad("^IMAGE in records but no RECORD_BYTES".into()));
                }
                (n as u64 - 1) * record_bytes as u64
            })
        };
        match parts.as_slice() {
            [file] if file.parse::<f64>().is_err() => (base.join(file), 0),
            [pos] => (label_path.clone(), position(pos, pointer.unit.as_deref())?),
            [file, pos] => (base.join(file), position(pos, pointer.unit.as_deref())?),
            _ => return Err(bad(format!("^IMAGE = {}", pointer.text))),
        }
    };
    // A label may name the image in another case than the file system has it.
    let data_path = if data_path.is_file() {
        data_path
    } else {
        let lower = data_path.with_file_name(
            data_path
                .file_name()
                .map(|f| f.to_string_lossy().to_ascii_lowercase())
                .unwrap_or_default(),
        );
        let upper = data_path.with_file_name(
            data_path
                .file_name()
                .map(|f| f.to_string_lossy().to_ascii_uppercase())
                .unwrap_or_default(),
        );
        [lower, upper]
            .into_iter()
            .find(|p| p.is_file())
            .ok_or_else(|| bad(format!("the image file {} is absent", data_path.display())))?
    };
    // --- values -------------------------------------------------------------------------------
    let scale = opt(image, "SCALING_FACTOR", 1.0)?;
    let offset = opt(image, "OFFSET", 0.0)?;
    let unit = image
        .get("UNIT")
        .map(|v| v.text.to_ascii_uppercase())
        .unwrap_or_else(|| "METER".into());
    let to_m = match unit.as_str() {
        "METER" | "METERS" | "M" => 1.0,
        "KILOMETER" | "KILOMETERS" | "KM" => 1000.0,
        u => return Err(bad(format!("UNIT = {u} (heights in METER or KILOMETER)"))),
    };
    let missing: Vec<f64> = image
        .get("MISSING_CONSTANT")
        .or_else(|| image.get("NULL"))
        .and_then(Value::number)
        .into_iter()
        .collect();
    let heights_m = read_heights(
        &Layout {
            data_path,
            offset_bytes,
            rows,
            cols,
            sample,
            prefix,
            suffix,
        },
        Scaling {
            scale,
            offset,
            to_m,
            missing,
        },
        &bad,
    )?;

    // --- georeferencing -----------------------------------------------------------------------
    let kind = proj
        .get("MAP_PROJECTION_TYPE")
        .map(|v| v.text.to_ascii_uppercase())
        .unwrap_or_default();
    let km = |k: &str| -> std::result::Result<f64, DemError> {
        let v = proj.get(k).ok_or_else(|| bad(format!("{k} missing")))?;
        let n = v.number().ok_or_else(|| bad(format!("{k} = {}", v.text)))?;
        Ok(match v.unit.as_deref() {
            Some("M") | Some("METER") | Some("METERS") => n,
            _ => n * 1000.0,
        })
    };
    let radius_m = km("A_AXIS_RADIUS")?;
    for other in ["B_AXIS_RADIUS", "C_AXIS_RADIUS"] {
        if proj.contains_key(other) && (km(other)? - radius_m).abs() > 1e-6 * radius_m {
            return Err(bad(format!(
                "{other} differs from A_AXIS_RADIUS (only spheres are read)"
            )));
        }
    }
    if !(1_700_000.0..=1_780_000.0).contains(&radius_m) {
        return Err(bad(format!(
            "A_AXIS_RADIUS = {radius_m} m is not the Moon's"
        )));
    }
    let rotation = opt(proj, "MAP_PROJECTION_ROTATION", 0.0)?;
    if rotation != 0.0 {
        return Err(bad(format!(
            "MAP_PROJECTION_ROTATION = {rotation} (rotated grids are not read)"
        )));
    }
    let scale_m = {
        let v = proj
            .get("MAP_SCALE")
            .ok_or_else(|| bad("MAP_SCALE missing".into()))?;
        let n = v
            .number()
            .ok_or_else(|| bad(format!("MAP_SCALE = {}", v.text)))?;
        match v.unit.as_deref() {
            Some(u) if u.starts_with("KM") || u.starts_with("KILOMETER") => n * 1000.0,
            _ => n,
        }
    };
    if !(scale_m > 0.0 && scale_m.is_finite()) {
        return Err(bad(format!("MAP_SCALE = {scale_m} m")));
    }
    let lon0 = num(proj, "CENTER_LONGITUDE")?;
    let lat0 = num(proj, "CENTER_LATITUDE")?;
    let projection = match kind.as_str() {
        "POLAR STEREOGRAPHIC" => {
            if (lat0.abs() - 90.0).abs() > 1e-9 {
                return Err(bad(format!(
                    "POLAR STEREOGRAPHIC with CENTER_LATITUDE = {lat0}"
                )));
            }
            Projection::PolarStereographic {
                south: lat0 < 0.0,
                lon0_deg: lon0,
                k0: 1.0,
                radius_m,
            }
        }
        // (GDAL's PDS driver: latitude of true scale = CENTER_LATITUDE, origin at the equator)
        "EQUIRECTANGULAR" | "SIMPLE CYLINDRICAL" | "SIMPLE_CYLINDRICAL" => {
            Projection::Equirectangular {
                lon0_deg: lon0,
                lat_ts_deg: lat0,
                radius_m,
            }
        }
        k => {
            return Err(bad(format!(
                "MAP_PROJECTION_TYPE = {k} (POLAR STEREOGRAPHIC or EQUIRECTANGULAR)"
            )));
        }
    };
    let spo = num(proj, "SAMPLE_PROJECTION_OFFSET")?;
    let lpo = num(proj, "LINE_PROJECTION_OFFSET")?;
    let grid = GridGeometry {
        rows,
        cols,
        x_left_m: -(spo + 0.5) * scale_m,
        y_top_m: (lpo + 0.5) * scale_m,
        px_x_m: scale_m,
        px_y_m: scale_m,
    };
    Ok(Dem {
        grid,
        projection,
        heights_m,
        name: name.clone(),
    })
}

/// Where an image's samples are: `rows` lines of `prefix` bytes, `cols` samples, `suffix` bytes,
/// from byte `offset_bytes` of `data_path`.
pub(super) struct Layout {
    pub data_path: PathBuf,
    pub offset_bytes: u64,
    pub rows: usize,
    pub cols: usize,
    pub sample: Sample,
    pub prefix: u64,
    pub suffix: u64,
}

/// How raw samples become heights: `(raw · scale + offset) · to_m`, `missing` values are holes.
pub(super) struct Scaling {
    pub scale: f64,
    pub offset: f64,
    pub to_m: f64,
    pub missing: Vec<f64>,
}

/// Reads the samples of `layout` as heights above the 1737.4 km sphere, metres (`NaN` holes):
/// the file must hold what the label declares (checked before allocating, with the memory
/// budget); values that are radii (an offset within 1700–1780 km, as LOLA's 1737400 m) become
/// heights.
pub(super) fn read_heights(
    layout: &Layout,
    scaling: Scaling,
    bad: &dyn Fn(String) -> DemError,
) -> Result<Vec<f32>> {
    let &Layout {
        ref data_path,
        offset_bytes,
        rows,
        cols,
        sample,
        prefix,
        suffix,
    } = layout;
    let Scaling {
        scale,
        offset,
        to_m,
        missing,
    } = scaling;
    let io_err = |source| DemError::Io {
        path: data_path.display().to_string(),
        source,
    };
    let row_bytes = prefix + cols as u64 * sample.bytes() as u64 + suffix;
    let need = offset_bytes + row_bytes * rows as u64;
    let file_len = std::fs::metadata(data_path).map_err(io_err)?.len();
    if need > file_len {
        return Err(DemError::Truncated {
            path: data_path.display().to_string(),
            detail: format!(
                "the label declares {cols} x {rows} samples at byte {offset_bytes} ({need} bytes) but the file has {file_len}"
            ),
        });
    }
    crate::output::guard::check_budget(
        &format!("the {cols} x {rows} pixel grid"),
        rows as u128 * cols as u128 * 4,
    )
    .map_err(bad)?;
    if !(scale.is_finite() && scale != 0.0 && offset.is_finite()) {
        return Err(bad(format!("scaling factor {scale} / offset {offset}")));
    }
    // Values that are radii (LOLA: OFFSET = 1737400 m) become heights above the 1737.4 km sphere.
    let offset_m = offset * to_m;
    let radius_shift = if (1_700_000.0..=1_780_000.0).contains(&offset_m) {
        crate::MOON_RADIUS_M
    } else {
        0.0
    };
    let mut heights_m = vec![f32::NAN; rows * cols];
    let mut f = crate::output::guard::open_regular(data_path).map_err(io_err)?;
    f.seek(SeekFrom::Start(offset_bytes)).map_err(io_err)?;
    let mut reader = std::io::BufReader::new(f);
    let mut row = vec![0u8; row_bytes as usize];
    for r in 0..rows {
        reader.read_exact(&mut row).map_err(io_err)?;
        let data = &row[prefix as usize..prefix as usize + cols * sample.bytes()];
        for (c, b) in data.chunks_exact(sample.bytes()).enumerate() {
            let raw = sample.value(b);
            if raw.is_nan() || missing.contains(&raw) {
                continue;
            }
            heights_m[r * cols + c] = ((raw * scale + offset) * to_m - radius_shift) as f32;
        }
    }
    Ok(heights_m)
}

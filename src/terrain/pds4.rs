//! PDS4 DEMs: an XML label (`Product_Observational`) with one 2-D image (or a 3-D image of one
//! band) in a file beside it, and the Cartography discipline's map projection (polar
//! stereographic or equirectangular on a sphere), read as GDAL's PDS4 driver reads them.
//!
//! The label gives the file (`File/file_name`), the array (`Array_2D_Image` / `Array_3D_Image`:
//! `offset`, `axis_index_order` = Last Index Fastest, `Axis_Array` Line and Sample (and a Band of
//! one element)), the samples (`Element_Array`: `data_type`, `scaling_factor`, `value_offset`,
//! `unit`), holes (`Special_Constants`: `missing_constant`, `invalid_constant`) and the grid
//! (`cart:Polar_Stereographic` or `cart:Equirectangular`, `cart:pixel_resolution_x/_y`,
//! `cart:upperleft_corner_x/_y`, `cart:a_axis_radius`). Values that are radii (a
//! `value_offset` of 1700–1780 km) become heights above the 1737.4 km sphere, as for PDS3.

use std::io::Read;
use std::path::Path;

use super::error::{DemError, Result};
use super::grid::{Dem, GridGeometry, Projection};
use super::pds3::{Layout, Sample, Scaling, read_heights};

/// Largest label read, bytes.
const MAX_LABEL_BYTES: u64 = 4 << 20;

/// Whether `path` is a PDS4 label: an `.xml` file whose head names a PDS4 product.
pub fn is_pds4(path: &Path) -> bool {
    let is_xml = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("xml") || e.eq_ignore_ascii_case("lblx"));
    if !is_xml {
        return false;
    }
    let mut head = vec![0u8; 4096];
    let n = crate::output::guard::open_regular(path)
        .and_then(|mut f| f.read(&mut head))
        .unwrap_or(0);
    let head = String::from_utf8_lossy(&head[..n]);
    head.contains("Product_Observational") || head.contains("pds.nasa.gov/pds4")
}

/// The PDS4 sample types penumbra reads, as the PDS3 names of the same layouts.
fn sample_of(data_type: &str) -> Option<Sample> {
    let (kind, bits) = match data_type {
        "SignedByte" => ("LSB_INTEGER", 8),
        "UnsignedByte" => ("LSB_UNSIGNED_INTEGER", 8),
        "SignedLSB2" => ("LSB_INTEGER", 16),
        "SignedMSB2" => ("MSB_INTEGER", 16),
        "UnsignedLSB2" => ("LSB_UNSIGNED_INTEGER", 16),
        "UnsignedMSB2" => ("MSB_UNSIGNED_INTEGER", 16),
        "SignedLSB4" => ("LSB_INTEGER", 32),
        "SignedMSB4" => ("MSB_INTEGER", 32),
        "UnsignedLSB4" => ("LSB_UNSIGNED_INTEGER", 32),
        "UnsignedMSB4" => ("MSB_UNSIGNED_INTEGER", 32),
        "IEEE754LSBSingle" => ("PC_REAL", 32),
        "IEEE754MSBSingle" => ("IEEE_REAL", 32),
        "IEEE754LSBDouble" => ("PC_REAL", 64),
        "IEEE754MSBDouble" => ("IEEE_REAL", 64),
        _ => return None,
    };
    Sample::parse(kind, bits).ok()
}

/// The first element named `tag` (local name, whatever its namespace prefix) within `scope`.
fn first<'a, 'i>(scope: roxmltree::Node<'a, 'i>, tag: &str) -> Option<roxmltree::Node<'a, 'i>> {
    scope
        .descendants()
        .find(|n| n.is_element() && n.tag_name().name() == tag)
}

/// The trimmed text of [`first`].
fn text_of<'a>(scope: roxmltree::Node<'a, '_>, tag: &str) -> Option<&'a str> {
    first(scope, tag).and_then(|n| n.text()).map(str::trim)
}

/// Reads a PDS4 DEM from its XML label.
pub fn read_pds4(path: &Path) -> Result<Dem> {
    let name = path.display().to_string();
    let bad = |detail: String| DemError::Decode {
        path: name.clone(),
        detail: format!("PDS4: {detail}"),
    };
    let io = |source| DemError::Io {
        path: name.clone(),
        source,
    };
    let mut bytes = Vec::new();
    crate::output::guard::open_regular(path)
        .map_err(io)?
        .take(MAX_LABEL_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_LABEL_BYTES {
        return Err(bad(format!("label larger than {MAX_LABEL_BYTES} bytes")));
    }
    let text = String::from_utf8(bytes).map_err(|_| bad("the label is not UTF-8".into()))?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| bad(format!("XML: {e}")))?;
    let root = doc.root_element();
    let area = first(root, "File_Area_Observational")
        .ok_or_else(|| bad("no File_Area_Observational".into()))?;
    let file_name = text_of(area, "file_name").ok_or_else(|| bad("no File/file_name".into()))?;
    if file_name.contains('/') || file_name.contains('\\') || file_name.starts_with('.') {
        return Err(bad(format!(
            "file_name '{file_name}' is not a file beside the label"
        )));
    }
    let array = area
        .children()
        .find(|n| n.is_element() && n.tag_name().name().starts_with("Array_"))
        .ok_or_else(|| bad("no Array_2D_Image / Array_3D_Image".into()))?;
    // A number with its unit attribute, converted to metres (or bytes) where given.
    let number = |scope: roxmltree::Node<'_, '_>, tag: &str| -> Result<Option<(f64, String)>> {
        match first(scope, tag) {
            None => Ok(None),
            Some(n) => {
                let t = n.text().unwrap_or("").trim();
                let v: f64 = t
                    .parse()
                    .map_err(|_| bad(format!("{tag} = '{t}' is not a number")))?;
                if !v.is_finite() {
                    return Err(bad(format!("{tag} = {v}")));
                }
                Ok(Some((
                    v,
                    n.attribute("unit").unwrap_or("").to_ascii_lowercase(),
                )))
            }
        }
    };
    let metres = |scope: roxmltree::Node<'_, '_>, tag: &str| -> Result<f64> {
        let (v, unit) = number(scope, tag)?.ok_or_else(|| bad(format!("no {tag}")))?;
        Ok(match unit.as_str() {
            "km" | "km/pixel" => v * 1000.0,
            "" | "m" | "m/pixel" => v,
            u => return Err(bad(format!("{tag} in '{u}' (m or km)"))),
        })
    };

    // --- the samples' place in the file ----------------------------------------------------------
    let order = text_of(array, "axis_index_order").unwrap_or("Last Index Fastest");
    if order != "Last Index Fastest" {
        return Err(bad(format!("axis_index_order = {order}")));
    }
    let mut axes: Vec<(u32, String, f64)> = Vec::new();
    for a in array
        .children()
        .filter(|n| n.is_element() && n.tag_name().name() == "Axis_Array")
    {
        let axis = text_of(a, "axis_name").unwrap_or("").to_string();
        let elements = number(a, "elements")?.map(|v| v.0).unwrap_or(0.0);
        let seq = number(a, "sequence_number")?.map(|v| v.0).unwrap_or(0.0);
        axes.push((seq as u32, axis, elements));
    }
    axes.sort_by_key(|a| a.0);
    let count = |v: f64, what: &str| -> Result<usize> {
        if (1.0..=1e6).contains(&v) && v.fract() == 0.0 {
            Ok(v as usize)
        } else {
            Err(bad(format!("{what}: {v} elements")))
        }
    };
    let (rows, cols) = match axes.as_slice() {
        [(_, l, r), (_, s, c)] if l == "Line" && s == "Sample" => {
            (count(*r, "Line")?, count(*c, "Sample")?)
        }
        [(_, b, n), (_, l, r), (_, s, c)] if b == "Band" && l == "Line" && s == "Sample" => {
            if *n != 1.0 {
                return Err(DemError::MultiBand {
                    path: name,
                    bands: *n as u16,
                });
            }
            (count(*r, "Line")?, count(*c, "Sample")?)
        }
        _ => {
            let names: Vec<&str> = axes.iter().map(|a| a.1.as_str()).collect();
            return Err(bad(format!(
                "axes {names:?} (Line, Sample, or Band of one, Line, Sample)"
            )));
        }
    };
    let element = first(array, "Element_Array").ok_or_else(|| bad("no Element_Array".into()))?;
    let data_type = text_of(element, "data_type").unwrap_or("");
    let sample = sample_of(data_type).ok_or_else(|| bad(format!("data_type = {data_type}")))?;
    let offset_bytes = number(array, "offset")?.map(|v| v.0).unwrap_or(0.0);
    if !(0.0..=1e15).contains(&offset_bytes) {
        return Err(bad(format!("offset = {offset_bytes}")));
    }
    let to_m = match text_of(element, "unit")
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        None | Some("m") | Some("meter") | Some("meters") | Some("metre") => 1.0,
        Some("km") | Some("kilometer") | Some("kilometers") => 1000.0,
        Some(u) => return Err(bad(format!("unit = {u} (heights in m or km)"))),
    };
    let missing: Vec<f64> = ["missing_constant", "invalid_constant"]
        .iter()
        .filter_map(|t| first(array, t).and_then(|n| n.text()))
        .filter_map(|t| t.trim().parse().ok())
        .collect();
    let base = path.parent().unwrap_or(Path::new("."));
    let heights_m = read_heights(
        &Layout {
            data_path: base.join(file_name),
            offset_bytes: offset_bytes as u64,
            rows,
            cols,
            sample,
            prefix: 0,
            suffix: 0,
        },
        Scaling {
            scale: number(element, "scaling_factor")?.map_or(1.0, |v| v.0),
            offset: number(element, "value_offset")?.map_or(0.0, |v| v.0),
            to_m,
            missing,
        },
        &bad,
    )?;

    // --- georeferencing --------------------------------------------------------------------------
    let carto = first(root, "Cartography")
        .ok_or_else(|| bad("no cart:Cartography (the DEM must be map-projected)".into()))?;
    let radius_m = metres(carto, "a_axis_radius")?;
    for other in ["b_axis_radius", "c_axis_radius"] {
        if first(carto, other).is_some()
            && (metres(carto, other)? - radius_m).abs() > 1e-6 * radius_m
        {
            return Err(bad(format!(
                "{other} differs from a_axis_radius (only spheres are read)"
            )));
        }
    }
    if !(1_700_000.0..=1_780_000.0).contains(&radius_m) {
        return Err(bad(format!(
            "a_axis_radius = {radius_m} m is not the Moon's"
        )));
    }
    let degrees = |scope: roxmltree::Node<'_, '_>, tag: &str| -> Result<f64> {
        Ok(number(scope, tag)?
            .ok_or_else(|| bad(format!("no {tag}")))?
            .0)
    };
    let projection = if let Some(ps) = first(carto, "Polar_Stereographic") {
        let lat0 = degrees(ps, "latitude_of_projection_origin")?;
        if (lat0.abs() - 90.0).abs() > 1e-9 {
            return Err(bad(format!(
                "Polar_Stereographic with latitude_of_projection_origin = {lat0}"
            )));
        }
        let k0 = number(ps, "scale_factor_at_projection_origin")?.map_or(1.0, |v| v.0);
        if !(k0 > 0.5 && k0 <= 2.0) {
            return Err(bad(format!("scale_factor_at_projection_origin = {k0}")));
        }
        Projection::PolarStereographic {
            south: lat0 < 0.0,
            lon0_deg: degrees(ps, "longitude_of_central_meridian")?,
            k0,
            radius_m,
        }
    } else if let Some(eq) = first(carto, "Equirectangular") {
        Projection::Equirectangular {
            lon0_deg: degrees(eq, "longitude_of_central_meridian")?,
            lat_ts_deg: degrees(eq, "standard_parallel_1")?,
            radius_m,
        }
    } else {
        let kind = text_of(carto, "map_projection_name").unwrap_or("none");
        return Err(bad(format!(
            "map projection '{kind}' (Polar Stereographic or Equirectangular)"
        )));
    };
    let px_x_m = metres(carto, "pixel_resolution_x")?;
    let px_y_m = metres(carto, "pixel_resolution_y")?;
    for (tag, v) in [
        ("pixel_resolution_x", px_x_m),
        ("pixel_resolution_y", px_y_m),
    ] {
        if !(v > 0.0 && v < 1e6) {
            return Err(bad(format!("{tag} = {v} m")));
        }
    }
    let grid = GridGeometry {
        rows,
        cols,
        x_left_m: metres(carto, "upperleft_corner_x")?,
        y_top_m: metres(carto, "upperleft_corner_y")?,
        px_x_m,
        px_y_m,
    };
    Ok(Dem {
        grid,
        projection,
        heights_m,
        name,
    })
}

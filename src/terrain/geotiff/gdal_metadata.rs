//! GDAL's metadata XML (`GDAL_METADATA` tag): a minimal parser and writer.

/// One `<Item>` of a GDAL_METADATA block.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct MetadataItem {
    pub(super) name: String,
    pub(super) sample: Option<String>,
    pub(super) role: Option<String>,
    pub(super) value: String,
}

/// Minimal parser of GDAL's metadata XML: `<GDALMetadata><Item name=".." [sample=".."]
/// [role=".."]>value</Item>...</GDALMetadata>`.
pub(super) fn parse_gdal_metadata(xml: &str) -> Vec<MetadataItem> {
    let attr = |head: &str, key: &str| -> Option<String> {
        let pat = format!("{key}=\"");
        let start = head.find(&pat)? + pat.len();
        let end = head[start..].find('"')? + start;
        Some(xml_unescape(&head[start..end]))
    };
    let mut items = Vec::new();
    let mut rest = xml;
    while let Some(start) = rest.find("<Item") {
        rest = &rest[start + 5..];
        let Some(head_end) = rest.find('>') else {
            break;
        };
        let head = &rest[..head_end];
        let Some(close) = rest.find("</Item>") else {
            break;
        };
        let value = if head.ends_with('/') || close < head_end {
            String::new()
        } else {
            xml_unescape(&rest[head_end + 1..close])
        };
        if let Some(name) = attr(head, "name") {
            items.push(MetadataItem {
                name,
                sample: attr(head, "sample"),
                role: attr(head, "role"),
                value,
            });
        }
        rest = &rest[close + 7..];
    }
    items
}

fn xml_unescape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(amp) = rest.find('&') {
        out.push_str(&rest[..amp]);
        rest = &rest[amp..];
        let Some(semi) = rest.find(';') else {
            break;
        };
        let entity = &rest[1..semi];
        let ch = match entity {
            "amp" => Some('&'),
            "lt" => Some('<'),
            "gt" => Some('>'),
            "quot" => Some('"'),
            "apos" => Some('\''),
            e if e.starts_with("#x") => u32::from_str_radix(&e[2..], 16)
                .ok()
                .and_then(char::from_u32),
            e if e.starts_with('#') => e[1..].parse().ok().and_then(char::from_u32),
            _ => None,
        };
        match ch {
            Some(c) => {
                out.push(c);
                rest = &rest[semi + 1..];
            }
            None => {
                out.push('&');
                rest = &rest[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

/// Escapes text for XML and keeps it ASCII (TIFF ASCII tags): non-ASCII becomes `&#N;`.
fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            c if c.is_ascii() && (c == '\n' || c == '\t' || !c.is_ascii_control()) => out.push(c),
            c => out.push_str(&format!("&#{};", u32::from(c))),
        }
    }
    out
}

/// The GDAL_METADATA XML of `items` (dataset-level items).
fn gdal_metadata_xml(items: &[(&str, &str)]) -> String {
    gdal_metadata_xml_with_bands(items, &[])
}

/// The GDAL_METADATA XML of dataset-level `items` and one description per band.
pub(super) fn gdal_metadata_xml_with_bands(items: &[(&str, &str)], bands: &[String]) -> String {
    let mut xml = String::from("<GDALMetadata>\n");
    for (k, v) in items {
        xml.push_str(&format!(
            "  <Item name=\"{}\">{}</Item>\n",
            xml_escape(k),
            xml_escape(v)
        ));
    }
    for (i, d) in bands.iter().enumerate() {
        xml.push_str(&format!(
            "  <Item name=\"DESCRIPTION\" sample=\"{i}\" role=\"description\">{}</Item>\n",
            xml_escape(d)
        ));
    }
    xml.push_str("</GDALMetadata>");
    xml
}

/// The GDAL_METADATA XML of dataset-level `items` and one band's description and unit (roles
/// `description` and `unittype`, as GDAL writes them).
pub fn gdal_metadata_xml_with_band(items: &[(&str, &str)], band: super::BandInfo<'_>) -> String {
    let mut xml = gdal_metadata_xml(items);
    xml.truncate(xml.len() - "</GDALMetadata>".len());
    if !band.description.is_empty() {
        xml.push_str(&format!(
            "  <Item name=\"DESCRIPTION\" sample=\"0\" role=\"description\">{}</Item>\n",
            xml_escape(band.description)
        ));
    }
    if !band.unit.is_empty() {
        xml.push_str(&format!(
            "  <Item name=\"UNITTYPE\" sample=\"0\" role=\"unittype\">{}</Item>\n",
            xml_escape(band.unit)
        ));
    }
    xml.push_str("</GDALMetadata>");
    xml
}

//! A series' site results for GIS tools: `sites.geojson` (QGIS and any GeoJSON reader: Points in
//! lunar longitude/latitude, degrees, with each site's key statistics, its neighbourhood's
//! spread and best spot) and `sites.kml` (Google Earth in Moon mode).

use std::path::Path;

use crate::illum::stats::SiteStats;

/// The GeoJSON file of a series' sites.
pub const SITES_GEOJSON: &str = "sites.geojson";
/// The KML file of a series' sites.
pub const SITES_KML: &str = "sites.kml";

/// Each site as a GeoJSON Feature's properties.
fn properties(s: &SiteStats) -> serde_json::Value {
    let mut p = serde_json::json!({
        "name": s.site,
        "sun_visible_pct": s.sun_visible_pct,
        "sun_mean_visible_fraction": s.sun_mean_visible_fraction,
        "longest_dark_h": s.longest_dark_h,
        "earth_visible_pct": s.earth_visible_pct,
        "sun_and_earth_pct": s.sun_and_earth_pct,
    });
    if let Some(l) = &s.location {
        p["height_above_ground_m"] = l.height_above_ground_m.into();
        p["ground_height_m"] = l.ground_height_m.into();
    }
    if let Some(h) = &s.neighbourhood {
        p["neighbourhood_radius_m"] = h.radius_m.into();
        p["neighbourhood_sun_visible_min_pct"] = h.sun_visible_pct.min.into();
        p["neighbourhood_sun_visible_max_pct"] = h.sun_visible_pct.max.into();
        p["best_lat_deg"] = h.best.lat_deg.into();
        p["best_lon_deg"] = h.best.lon_deg.into();
        p["best_distance_m"] = h.best.distance_m.into();
        p["best_sun_visible_pct"] = h.best.sun_visible_pct.into();
        p["caution"] = h.cautions.join(" ").into();
    }
    p
}

/// Writes [`SITES_GEOJSON`] and [`SITES_KML`] into `out_dir`; returns their names.
pub fn write_sites(out_dir: &Path, sites: &[SiteStats]) -> anyhow::Result<Vec<String>> {
    let features: Vec<serde_json::Value> = sites
        .iter()
        .filter_map(|s| {
            let l = s.location?;
            Some(serde_json::json!({
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [l.lon_deg, l.lat_deg]},
                "properties": properties(s),
            }))
        })
        .collect();
    let mut doc = serde_json::json!({
        "type": "FeatureCollection",
        "name": "penumbra sites",
        // Lunar longitude/latitude on the 1737.4 km sphere (IAU 2015 Moon, planetocentric).
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:IAU_2015::30100"}},
        "features": features,
    });
    crate::output::round_json_numbers(&mut doc);
    let mut bytes = serde_json::to_vec_pretty(&doc)?;
    bytes.push(b'\n');
    crate::output::write_bytes_atomic(&out_dir.join(SITES_GEOJSON), &bytes)?;

    let escape = |t: &str| {
        t.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
    };
    crate::output::write_atomic(&out_dir.join(SITES_KML), |w| -> anyhow::Result<()> {
        writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
        writeln!(
            w,
            r#"<kml xmlns="http://www.opengis.net/kml/2.2"><Document><name>penumbra sites (Moon)</name>"#
        )?;
        for s in sites {
            let Some(l) = s.location else { continue };
            let mut text = format!(
                "Sun visible {:.1} %, Earth visible {:.1} %, longest darkness {:.0} h",
                s.sun_visible_pct, s.earth_visible_pct, s.longest_dark_h
            );
            if let Some(h) = &s.neighbourhood {
                text.push_str(&format!(
                    "; within {:.0} m: Sun {:.1}–{:.1} %, best {:.1} % {:.0} m away",
                    h.radius_m,
                    h.sun_visible_pct.min,
                    h.sun_visible_pct.max,
                    h.best.sun_visible_pct,
                    h.best.distance_m
                ));
            }
            writeln!(
                w,
                "<Placemark><name>{}</name><description>{}</description><Point><coordinates>{:.6},{:.6},0</coordinates></Point></Placemark>",
                escape(&s.site),
                escape(&text),
                (l.lon_deg + 180.0).rem_euclid(360.0) - 180.0,
                l.lat_deg
            )?;
        }
        writeln!(w, "</Document></kml>")?;
        Ok(())
    })?;
    Ok(vec![SITES_GEOJSON.into(), SITES_KML.into()])
}

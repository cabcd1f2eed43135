//! A site's neighbourhood: the same statistics at every pixel centre of the finest layer within
//! a radius of the site, their spread, the best spot among them, and the cautions a planner needs
//! when the value at the typed point is sensitive to where exactly it is (`docs/sites.md`).
//!
//! Published sites are the local crests of 5–20 m DEMs; on a 60–240 m grid the pixel under the
//! typed point can sit on the crest's flank, and its Sun-visible time differ by tens of
//! percentage points from a pixel 300 m away. The physics is the same at every pixel; what this
//! adds is the context: how much the number moves within the radius, and where it is best.
//!
//! Each neighbour is a site like the others (its own horizon from every layer, the strip
//! integral of each disc, the same epochs), so a neighbour's value is what `series` gives at
//! that pixel centre. Ephemeris and horizons are computed for each pixel exactly; only the CSV
//! and plots are not written.

use std::path::Path;

use anyhow::Context as _;

use crate::horizon::Horizon;
use crate::illum::stats::{NEAR_HORIZON_PX, Neighbourhood, SiteStats, SpotStats, Spread};
use crate::model::Site;
use crate::terrain::TerrainStack;

/// The default radius, in pixels of the finest layer under the site.
pub const DEFAULT_RADIUS_PX: f64 = 3.0;

/// Runs of more sites than this get no neighbourhood unless they ask for one (a radius).
pub const DEFAULT_MAX_SITES: usize = 10;

/// The largest radius, metres.
pub const MAX_RADIUS_M: f64 = 20_000.0;

/// The most pixels a neighbourhood may hold (each costs one horizon and one pass over the
/// epochs).
pub const MAX_PIXELS: usize = 2_000;

/// A spread larger than this (percentage points of Sun- or Earth-visible time) within the
/// neighbourhood raises a caution.
pub const SENSITIVE_PP: f64 = 10.0;

/// The Sun's largest apparent radius seen from the Moon, degrees (at perihelion, 0.2725°).
const SUN_RADIUS_MAX_DEG: f64 = 0.28;

/// A caution is raised when more than this % of the azimuths where the Sun goes behind the
/// horizon have it set by ground within [`NEAR_HORIZON_PX`] pixels.
pub const NEAR_HORIZON_SHARE_PCT: f64 = 50.0;

/// The file each site's neighbourhood is written to, in the site's folder.
pub const NEIGHBOURHOOD_CSV: &str = "neighbourhood.csv";

/// Checks a requested radius: finite, 0 (off) … [`MAX_RADIUS_M`].
pub fn check_radius_m(radius_m: f64) -> anyhow::Result<()> {
    anyhow::ensure!(
        radius_m.is_finite() && (0.0..=MAX_RADIUS_M).contains(&radius_m),
        "neighbourhood radius {radius_m} m must lie in 0 .. {MAX_RADIUS_M} (0 = no neighbourhood)"
    );
    Ok(())
}

/// The pixels of one site's neighbourhood.
#[derive(Debug, Clone)]
pub struct SiteNeighbourhood {
    /// Radius, metres.
    pub radius_m: f64,
    /// The layer's name.
    pub layer: String,
    /// The layer's pixel size, metres.
    pub px_m: f64,
    /// Each pixel centre as a site (the site's height above ground), its distance and bearing
    /// from the site.
    pub pixels: Vec<(Site, f64, f64)>,
}

/// The neighbourhood of `site`: the pixel centres of the finest layer with data under it within
/// `radius_m` (`None`: [`DEFAULT_RADIUS_PX`] pixels of that layer), with data. `None` for a
/// radius of 0.
pub fn neighbour_pixels(
    stack: &TerrainStack,
    site: &Site,
    radius_m: Option<f64>,
) -> anyhow::Result<Option<SiteNeighbourhood>> {
    let Some((_, layer_idx)) = stack.height_at_lat_lon_m(site.lat_deg(), site.lon_deg()) else {
        anyhow::bail!(
            "site '{}' ({}, {}) lies outside every DEM layer",
            site.name(),
            site.lat_deg(),
            site.lon_deg()
        );
    };
    let dem = &stack.layers[layer_idx];
    let px_m = dem.px_m();
    let radius_m = radius_m.unwrap_or(DEFAULT_RADIUS_PX * px_m);
    check_radius_m(radius_m)?;
    if radius_m == 0.0 {
        return Ok(None);
    }
    let g = dem.grid;
    let (x0, y0) = dem
        .projection
        .xy_from_lat_lon(site.lat_deg(), site.lon_deg());
    let (r0, c0) = g.row_col_from_xy(x0, y0);
    // Map distances differ from ground distances by the projection's scale (≈ 1 near the
    // pole); take a margin and keep the pixels by their ground distance.
    let reach_px = (1.2 * radius_m / g.px_x_m.min(g.px_y_m)).ceil() + 1.0;
    let rows = (r0 - reach_px).floor().max(0.0) as usize
        ..=((r0 + reach_px).ceil().max(0.0) as usize).min(g.rows.saturating_sub(1));
    let cols = (c0 - reach_px).floor().max(0.0) as usize
        ..=((c0 + reach_px).ceil().max(0.0) as usize).min(g.cols.saturating_sub(1));
    let here = crate::frames::site_in_moon_me_km(site.lat_deg(), site.lon_deg(), 0.0).normalize();
    let enu = crate::frames::enu_from_moon_me(site.lat_deg(), site.lon_deg());
    let mut pixels = Vec::new();
    for row in rows {
        for col in cols.clone() {
            if dem
                .cell_height_m(row as isize, col as isize)
                .is_none_or(f32::is_nan)
            {
                continue;
            }
            let (x, y) = g.xy_from_row_col(row as f64, col as f64);
            let (lat, lon) = dem.projection.lat_lon_from_xy(x, y);
            let there = crate::frames::site_in_moon_me_km(lat, lon, 0.0).normalize();
            let distance_m = here.angle(&there) * crate::MOON_RADIUS_M;
            if distance_m > radius_m {
                continue;
            }
            let (bearing_deg, _) = crate::frames::az_el_deg_from_enu(&(enu * (there - here)));
            let name = format!(
                "{}-r{row}c{col}",
                site.name().chars().take(60).collect::<String>()
            );
            let s = Site::new(
                &name,
                lat,
                lon.rem_euclid(360.0),
                site.height_above_ground(),
            )
            .or_else(|_| {
                Site::new(
                    &format!("r{row}c{col}"),
                    lat,
                    lon.rem_euclid(360.0),
                    site.height_above_ground(),
                )
            })?;
            pixels.push((s, distance_m, bearing_deg));
            anyhow::ensure!(
                pixels.len() <= MAX_PIXELS,
                "the neighbourhood of site '{}' ({radius_m} m on the {px_m} m layer '{}') holds more than {MAX_PIXELS} pixels: ask for a smaller radius",
                site.name(),
                dem.name
            );
        }
    }
    Ok(Some(SiteNeighbourhood {
        radius_m,
        layer: dem.name.clone(),
        px_m,
        pixels,
    }))
}

/// A spot's key statistics from its full statistics.
pub fn spot(
    (lat_deg, lon_deg): (f64, f64),
    (distance_m, bearing_deg): (f64, f64),
    ground_height_m: f64,
    s: &SiteStats,
) -> SpotStats {
    SpotStats {
        lat_deg,
        lon_deg,
        distance_m,
        bearing_deg,
        ground_height_m,
        sun_visible_pct: s.sun_visible_pct,
        sun_mean_visible_fraction: s.sun_mean_visible_fraction,
        longest_dark_h: s.longest_dark_h,
        earth_visible_pct: s.earth_visible_pct,
    }
}

/// Where the Sun goes behind the site's horizon: the nearest ground that sets the horizon at an
/// azimuth whose horizon is above the Sun's lowest disc edge, metres, and the % of those
/// azimuths whose horizon is set within `near_m`.
pub fn sun_horizon_nearness(horizon: &Horizon, sun_el_deg: &[f64], near_m: f64) -> (f64, f64) {
    let lowest_deg = sun_el_deg.iter().copied().fold(f64::INFINITY, f64::min) - SUN_RADIUS_MAX_DEG;
    let (mut nearest_m, mut relevant, mut near) = (f64::INFINITY, 0usize, 0usize);
    for (&el, &d) in horizon.elevation_deg.iter().zip(&horizon.distance_m) {
        if el > lowest_deg && d.is_finite() {
            relevant += 1;
            nearest_m = nearest_m.min(d);
            if d <= near_m {
                near += 1;
            }
        }
    }
    let pct = if relevant == 0 {
        0.0
    } else {
        100.0 * near as f64 / relevant as f64
    };
    (nearest_m, pct)
}

/// The neighbourhood's summary: spreads (the site included), the best spot (most Sun, then the
/// nearest), and the cautions.
pub fn summarise(
    site: &Site,
    here: &SpotStats,
    hood: &SiteNeighbourhood,
    spots: &[SpotStats],
    (nearest_sun_horizon_m, near_sun_horizon_pct): (f64, f64),
) -> Neighbourhood {
    let spread = |f: fn(&SpotStats) -> f64| {
        let v: Vec<f64> = spots.iter().map(f).collect();
        Spread::of(f(here), &v)
    };
    let sun = spread(|s| s.sun_visible_pct);
    let earth = spread(|s| s.earth_visible_pct);
    let best = *std::iter::once(here)
        .chain(spots)
        .max_by(|a, b| {
            a.sun_visible_pct
                .total_cmp(&b.sun_visible_pct)
                .then(b.distance_m.total_cmp(&a.distance_m))
        })
        .expect("the site itself");
    // One line per site: the spread (when large), the near horizon (when it sets most of the
    // Sun's horizon), and where it is better.
    let near_m = NEAR_HORIZON_PX * hood.px_m;
    let sensitive = sun.range() > SENSITIVE_PP || earth.range() > SENSITIVE_PP;
    let near = near_sun_horizon_pct > NEAR_HORIZON_SHARE_PCT;
    let mut why = Vec::new();
    if sensitive {
        why.push(format!(
            "{:.1}–{:.1} % within {:.0} m ({} px of {:.0} m; Earth {:.1}–{:.1} %)",
            sun.min,
            sun.max,
            hood.radius_m,
            spots.len(),
            hood.px_m,
            earth.min,
            earth.max
        ));
    }
    if near {
        why.push(format!(
            "the horizon where the Sun sets is ground within {near_m:.0} m ({NEAR_HORIZON_PX} px) on {near_sun_horizon_pct:.0} % of its azimuths"
        ));
    }
    let mut cautions = Vec::new();
    if !why.is_empty() {
        let (better, so) = if best.distance_m > 0.0 {
            (
                format!(
                    "; best {:.1} % at ({:.5}°, {:.5}°), {:.0} m away",
                    best.sun_visible_pct, best.lat_deg, best.lon_deg, best.distance_m
                ),
                "the value depends on where exactly the site stands",
            )
        } else {
            (
                String::new(),
                "the site is the best spot within the radius, and the value falls off it",
            )
        };
        cautions.push(format!(
            "site '{}': Sun visible {:.1} % here, {}{better}: {so}",
            site.name(),
            sun.here,
            why.join("; ")
        ));
    }
    Neighbourhood {
        radius_m: hood.radius_m,
        layer: hood.layer.clone(),
        px_m: hood.px_m,
        pixels: spots.len(),
        sun_visible_pct: sun,
        sun_mean_visible_fraction: spread(|s| s.sun_mean_visible_fraction),
        longest_dark_h: spread(|s| s.longest_dark_h),
        earth_visible_pct: earth,
        best,
        nearest_sun_horizon_m,
        near_sun_horizon_pct,
        cautions,
    }
}

/// Writes [`NEIGHBOURHOOD_CSV`]: the site first (`point` = `site`), then each pixel by distance.
pub fn write_csv(path: &Path, here: &SpotStats, spots: &[SpotStats]) -> anyhow::Result<()> {
    let mut sorted: Vec<&SpotStats> = spots.iter().collect();
    sorted.sort_by(|a, b| a.distance_m.total_cmp(&b.distance_m));
    crate::output::write_atomic(path, |w| -> anyhow::Result<()> {
        writeln!(
            w,
            "point,lat_deg,lon_deg,distance_m,bearing_deg,ground_height_m,sun_visible_pct,sun_mean_visible_fraction,longest_dark_h,earth_visible_pct"
        )?;
        for (kind, s) in std::iter::once(("site", here)).chain(sorted.into_iter().map(|s| ("pixel", s))) {
            writeln!(
                w,
                "{kind},{:.6},{:.6},{:.1},{:.1},{:.2},{:.2},{:.4},{:.2},{:.2}",
                s.lat_deg,
                s.lon_deg,
                s.distance_m,
                s.bearing_deg,
                s.ground_height_m,
                s.sun_visible_pct,
                s.sun_mean_visible_fraction,
                s.longest_dark_h,
                s.earth_visible_pct
            )?;
        }
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

//! A summary of a DEM for `penumbra dem info`: size, pixel size, CRS, bounds in map and
//! geographic coordinates, height statistics and nodata count.

use serde::Serialize;

use super::grid::{Dem, Projection};

/// Summary of a DEM (see the module docs). Serialised as the JSON of `dem info --format json`.
#[derive(Debug, Clone, Serialize)]
pub struct DemInfo {
    /// The DEM's name (file path).
    pub name: String,
    /// Number of columns.
    pub cols: usize,
    /// Number of rows.
    pub rows: usize,
    /// Pixel width, metres.
    pub px_x_m: f64,
    /// Pixel height, metres.
    pub px_y_m: f64,
    /// Projection kind: `polar stereographic (south)`, `polar stereographic (north)` or
    /// `equirectangular`.
    pub projection: String,
    /// PROJ string of the CRS.
    pub proj: String,
    /// Map bounds of the outer pixel edges, metres: `[x_min, y_min, x_max, y_max]`.
    pub bounds_xy_m: [f64; 4],
    /// Smallest latitude on or inside the outer edges, degrees.
    pub lat_min_deg: f64,
    /// Largest latitude on or inside the outer edges, degrees.
    pub lat_max_deg: f64,
    /// Smallest east longitude on the outer edges, degrees in `(-180, 180]` (`-180` when the
    /// grid contains the pole).
    pub lon_min_deg: f64,
    /// Largest east longitude on the outer edges, degrees (`180` when the grid contains the
    /// pole).
    pub lon_max_deg: f64,
    /// Lowest valid height, metres.
    pub height_min_m: f64,
    /// Highest valid height, metres.
    pub height_max_m: f64,
    /// Mean valid height, metres.
    pub height_mean_m: f64,
    /// Number of nodata pixels.
    pub nodata_count: usize,
}

impl DemInfo {
    /// Computes the summary. Latitude/longitude extremes are taken along the outer edges (1000
    /// samples per edge, plus the corners); a grid that contains a pole reaches ±90° there.
    pub fn of(dem: &Dem) -> Self {
        let g = &dem.grid;
        let (x0, y0, x1, y1) = g.bounds_m();
        let p = &dem.projection;
        let mut lat_min = f64::INFINITY;
        let mut lat_max = f64::NEG_INFINITY;
        let mut lon_min = f64::INFINITY;
        let mut lon_max = f64::NEG_INFINITY;
        const SAMPLES: usize = 1000;
        for i in 0..=SAMPLES {
            let t = i as f64 / SAMPLES as f64;
            let (xs, ys) = (x0 + t * (x1 - x0), y0 + t * (y1 - y0));
            for (x, y) in [(xs, y0), (xs, y1), (x0, ys), (x1, ys)] {
                let (lat, lon) = p.lat_lon_from_xy(x, y);
                lat_min = lat_min.min(lat);
                lat_max = lat_max.max(lat);
                lon_min = lon_min.min(lon);
                lon_max = lon_max.max(lon);
            }
        }
        let (kind, pole_xy) = match *p {
            Projection::PolarStereographic { south: true, .. } => {
                ("polar stereographic (south)", Some((0.0, 0.0, -90.0)))
            }
            Projection::PolarStereographic { south: false, .. } => {
                ("polar stereographic (north)", Some((0.0, 0.0, 90.0)))
            }
            Projection::Equirectangular { .. } => ("equirectangular", None),
        };
        if let Some((px, py, pole_lat)) = pole_xy
            && g.contains_xy(px, py)
        {
            lat_min = lat_min.min(pole_lat);
            lat_max = lat_max.max(pole_lat);
            lon_min = -180.0;
            lon_max = 180.0;
        }
        let (mut lo, mut hi, mut sum, mut valid) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0usize);
        for &h in &dem.heights_m {
            if !h.is_nan() {
                let h = f64::from(h);
                lo = lo.min(h);
                hi = hi.max(h);
                sum += h;
                valid += 1;
            }
        }
        DemInfo {
            name: dem.name.clone(),
            cols: g.cols,
            rows: g.rows,
            px_x_m: g.px_x_m,
            px_y_m: g.px_y_m,
            projection: kind.into(),
            proj: p.proj_string(),
            bounds_xy_m: [x0, y0, x1, y1],
            lat_min_deg: lat_min,
            lat_max_deg: lat_max,
            lon_min_deg: lon_min,
            lon_max_deg: lon_max,
            height_min_m: lo,
            height_max_m: hi,
            height_mean_m: if valid > 0 {
                sum / valid as f64
            } else {
                f64::NAN
            },
            nodata_count: dem.heights_m.len() - valid,
        }
    }

    /// Plain-text report, one `key: value` per line.
    pub fn to_text(&self) -> String {
        let [x0, y0, x1, y1] = self.bounds_xy_m;
        format!(
            "file: {}\n\
             size: {} x {} px (cols x rows)\n\
             pixel size: {} x {} m\n\
             projection: {}\n\
             crs: {}\n\
             bounds x: {} .. {} m\n\
             bounds y: {} .. {} m\n\
             latitude: {:.6} .. {:.6} deg\n\
             longitude: {:.6} .. {:.6} deg\n\
             heights: {:.3} .. {:.3} m (mean {:.3} m)\n\
             nodata: {} of {} px\n",
            self.name,
            self.cols,
            self.rows,
            self.px_x_m,
            self.px_y_m,
            self.projection,
            self.proj,
            x0,
            x1,
            y0,
            y1,
            self.lat_min_deg,
            self.lat_max_deg,
            self.lon_min_deg,
            self.lon_max_deg,
            self.height_min_m,
            self.height_max_m,
            self.height_mean_m,
            self.nodata_count,
            self.rows * self.cols,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::synth;

    #[test]
    fn polar_grid_containing_the_pole_spans_all_longitudes() {
        let mut dem = synth::flat(10, 10, 1000.0, 3.0);
        dem.heights_m[0] = f32::NAN;
        dem.heights_m[1] = -2.0;
        let info = DemInfo::of(&dem);
        assert_eq!(info.lat_min_deg, -90.0);
        assert_eq!((info.lon_min_deg, info.lon_max_deg), (-180.0, 180.0));
        // Corner (5 km, 5 km): colatitude 2 atan(rho / 2R).
        let rho = 5000.0_f64 * 2f64.sqrt();
        let lat_corner = -90.0 + 2.0 * (rho / (2.0 * crate::MOON_RADIUS_M)).atan().to_degrees();
        assert!((info.lat_max_deg - lat_corner).abs() < 1e-9);
        assert_eq!(info.nodata_count, 1);
        assert_eq!((info.height_min_m, info.height_max_m), (-2.0, 3.0));
        assert!(info.to_text().contains("nodata: 1 of 100 px"));
    }
}

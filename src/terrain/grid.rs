//! Georeferenced raster grids: projections, the pixel ↔ map transform and nodata-aware bilinear
//! sampling.
//!
//! Conventions (stated once, also in `docs/ARCHITECTURE.md`):
//! - Grid indices are `row` (down) and `col` (right); row 0 is the top (largest `y_m`).
//! - The transform is GDAL's pixel-is-area geotransform: the **outer corner** of cell (0, 0) is at
//!   `(x_left_m, y_top_m)`; the **centre** of cell (row, col) is at
//!   `x_m = x_left_m + (col + 0.5) * px_x_m`, `y_m = y_top_m - (row + 0.5) * px_y_m`.
//!   A pixel-is-point file is converted to this convention when it is read.
//! - Heights are metres above the 1737.4 km reference sphere; nodata cells hold `NaN` (holes: no
//!   terrain there, rays pass).

use crate::MOON_RADIUS_M;

/// A map projection on the Moon's reference sphere.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Projection {
    /// Polar stereographic, spherical form (PDS/LOLA polar products, PROJ `+proj=stere`).
    ///
    /// South aspect: `rho = 2 R k0 tan(pi/4 + lat/2)`, `x = rho sin(lon - lon0)`,
    /// `y = rho cos(lon - lon0)`. North aspect: `rho = 2 R k0 tan(pi/4 - lat/2)`,
    /// `x = rho sin(lon - lon0)`, `y = -rho cos(lon - lon0)`.
    PolarStereographic {
        /// `true` for the south-polar aspect (latitude of origin −90°), `false` for the north.
        south: bool,
        /// Central meridian, degrees east.
        lon0_deg: f64,
        /// Scale factor at the pole (1 for LOLA products, whose true-scale latitude is the pole).
        k0: f64,
        /// Sphere radius, metres.
        radius_m: f64,
    },
    /// Equirectangular (simple cylindrical) on the sphere: `x = R (lon - lon0) cos(lat_ts)`,
    /// `y = R lat` (angles in radians).
    Equirectangular {
        /// Central meridian, degrees east.
        lon0_deg: f64,
        /// Latitude of true scale, degrees.
        lat_ts_deg: f64,
        /// Sphere radius, metres.
        radius_m: f64,
    },
}

impl Projection {
    /// The LOLA south-polar stereographic projection (`+proj=stere +lat_0=-90 +lon_0=0 +k=1
    /// +R=1737400`).
    pub const LOLA_SOUTH_POLAR: Projection = Projection::PolarStereographic {
        south: true,
        lon0_deg: 0.0,
        k0: 1.0,
        radius_m: MOON_RADIUS_M,
    };

    /// Projected coordinates (m) of a planetocentric latitude / east longitude (deg).
    pub fn xy_from_lat_lon(&self, lat_deg: f64, lon_deg: f64) -> (f64, f64) {
        match *self {
            Projection::PolarStereographic {
                south,
                lon0_deg,
                k0,
                radius_m,
            } => {
                let lat = lat_deg.to_radians();
                let (sl, cl) = (lon_deg - lon0_deg).to_radians().sin_cos();
                let quarter = std::f64::consts::FRAC_PI_4;
                if south {
                    let rho = 2.0 * radius_m * k0 * (quarter + lat / 2.0).tan();
                    (rho * sl, rho * cl)
                } else {
                    let rho = 2.0 * radius_m * k0 * (quarter - lat / 2.0).tan();
                    (rho * sl, -rho * cl)
                }
            }
            Projection::Equirectangular {
                lon0_deg,
                lat_ts_deg,
                radius_m,
            } => {
                let dlon = wrap_deg_180(lon_deg - lon0_deg).to_radians();
                (
                    radius_m * dlon * lat_ts_deg.to_radians().cos(),
                    radius_m * lat_deg.to_radians(),
                )
            }
        }
    }

    /// Planetocentric latitude and east longitude (deg, longitude in `(-180, 180]`) of projected
    /// coordinates (m). Inverse of [`Projection::xy_from_lat_lon`].
    pub fn lat_lon_from_xy(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        match *self {
            Projection::PolarStereographic {
                south,
                lon0_deg,
                k0,
                radius_m,
            } => {
                let rho = x_m.hypot(y_m);
                let c = 2.0 * (rho / (2.0 * radius_m * k0)).atan();
                let quarter = std::f64::consts::FRAC_PI_2;
                if south {
                    let lat = c - quarter;
                    let lon = x_m.atan2(y_m);
                    (lat.to_degrees(), wrap_deg_180(lon.to_degrees() + lon0_deg))
                } else {
                    let lat = quarter - c;
                    let lon = x_m.atan2(-y_m);
                    (lat.to_degrees(), wrap_deg_180(lon.to_degrees() + lon0_deg))
                }
            }
            Projection::Equirectangular {
                lon0_deg,
                lat_ts_deg,
                radius_m,
            } => {
                let lat = (y_m / radius_m).to_degrees();
                let lon = (x_m / (radius_m * lat_ts_deg.to_radians().cos())).to_degrees();
                (lat, wrap_deg_180(lon + lon0_deg))
            }
        }
    }

    /// The sphere radius of the projection, metres.
    pub fn radius_m(&self) -> f64 {
        match *self {
            Projection::PolarStereographic { radius_m, .. }
            | Projection::Equirectangular { radius_m, .. } => radius_m,
        }
    }

    /// A PROJ-style description, e.g. `+proj=stere +lat_0=-90 +lon_0=0 +k=1 +R=1737400`.
    pub fn proj_string(&self) -> String {
        match *self {
            Projection::PolarStereographic {
                south,
                lon0_deg,
                k0,
                radius_m,
            } => format!(
                "+proj=stere +lat_0={} +lon_0={lon0_deg} +k={k0} +R={radius_m} +units=m",
                if south { -90 } else { 90 }
            ),
            Projection::Equirectangular {
                lon0_deg,
                lat_ts_deg,
                radius_m,
            } => format!("+proj=eqc +lat_ts={lat_ts_deg} +lon_0={lon0_deg} +R={radius_m} +units=m"),
        }
    }
}

/// Wraps an angle in degrees into `(-180, 180]`.
fn wrap_deg_180(deg: f64) -> f64 {
    let mut d = deg % 360.0;
    if d <= -180.0 {
        d += 360.0;
    } else if d > 180.0 {
        d -= 360.0;
    }
    d
}

/// The pixel ↔ map transform of a north-up grid (pixel-is-area; see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GridGeometry {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Map x of the left edge of column 0, metres.
    pub x_left_m: f64,
    /// Map y of the top edge of row 0, metres.
    pub y_top_m: f64,
    /// Cell width along x, metres (> 0).
    pub px_x_m: f64,
    /// Cell height along y, metres (> 0; rows grow towards −y).
    pub px_y_m: f64,
}

impl GridGeometry {
    /// Map coordinates (m) of the centre of cell (row, col); fractional indices interpolate.
    pub fn xy_from_row_col(&self, row: f64, col: f64) -> (f64, f64) {
        (
            self.x_left_m + (col + 0.5) * self.px_x_m,
            self.y_top_m - (row + 0.5) * self.px_y_m,
        )
    }

    /// Fractional (row, col) of a map point, so that integer values are cell centres.
    pub fn row_col_from_xy(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        (
            (self.y_top_m - y_m) / self.px_y_m - 0.5,
            (x_m - self.x_left_m) / self.px_x_m - 0.5,
        )
    }

    /// Map bounds `(x_min, y_min, x_max, y_max)` of the outer cell edges, metres.
    pub fn bounds_m(&self) -> (f64, f64, f64, f64) {
        (
            self.x_left_m,
            self.y_top_m - self.rows as f64 * self.px_y_m,
            self.x_left_m + self.cols as f64 * self.px_x_m,
            self.y_top_m,
        )
    }

    /// Points on the outer cell edges (map metres): `per_side + 1` evenly spaced on each of the
    /// four sides, corners included. For bounding the grid's extent in another frame, where the
    /// image of a side is curved.
    pub fn edge_points_m(&self, per_side: usize) -> impl Iterator<Item = (f64, f64)> {
        let (x0, y0, x1, y1) = self.bounds_m();
        let n = per_side.max(1);
        (0..=n).flat_map(move |k| {
            let f = k as f64 / n as f64;
            [
                (x0 + f * (x1 - x0), y0),
                (x0 + f * (x1 - x0), y1),
                (x0, y0 + f * (y1 - y0)),
                (x1, y0 + f * (y1 - y0)),
            ]
        })
    }

    /// Whether a map point lies inside the outer cell edges.
    pub fn contains_xy(&self, x_m: f64, y_m: f64) -> bool {
        let (x0, y0, x1, y1) = self.bounds_m();
        x_m >= x0 && x_m <= x1 && y_m >= y0 && y_m <= y1
    }
}

/// A single-band elevation model: heights (m above the 1737.4 km sphere, `NaN` = nodata) on a
/// georeferenced grid, row-major.
#[derive(Debug, Clone)]
pub struct Dem {
    /// Where the grid sits on the map.
    pub grid: GridGeometry,
    /// The map projection of `grid`.
    pub projection: Projection,
    /// Heights, metres above the reference sphere, row-major (`rows * cols`), `NaN` for nodata.
    pub heights_m: Vec<f32>,
    /// A label for messages (usually the file path).
    pub name: String,
}

/// Physical bounds a DEM must meet (checked by [`Dem::check`] on every DEM read).
pub mod bounds {
    /// Smallest pixel size accepted, metres.
    pub const MIN_PIXEL_M: f64 = 0.01;
    /// Largest pixel size accepted, metres (a whole-Moon grid at 0.5° is ≈ 15 km).
    pub const MAX_PIXEL_M: f64 = 100_000.0;
    /// Largest map coordinate of a grid edge, metres (two lunar radii: beyond the equator of a
    /// polar stereographic map, or half the circumference of an equirectangular one).
    pub const MAX_MAP_COORD_M: f64 = 2.0 * 1_737_400.0 * 2.0;
    /// Largest |height| accepted, metres above the reference sphere (the Moon's relief spans
    /// −9.1 km .. +10.8 km about 1737.4 km).
    pub const MAX_ABS_HEIGHT_M: f64 = 50_000.0;
}

impl Dem {
    /// Checks the DEM against physical bounds ([`bounds`]): at least 2 × 2 cells, finite
    /// georeferencing with pixel sizes from 1 cm to 100 km, a grid within two lunar diameters of
    /// the projection's origin, a projection with a finite central meridian, a positive scale
    /// factor and a lunar radius, and finite heights within ±50 km of the sphere. Heights near
    /// 1.737e6 m are radii from the Moon's centre (a PDS label's OFFSET applied), not heights.
    pub fn check(&self) -> Result<(), String> {
        Self::check_georeferencing(&self.grid, &self.projection)?;
        Self::check_heights(&self.heights_m)
    }

    /// The georeferencing part of [`Dem::check`] (before any pixel is read).
    pub fn check_georeferencing(g: &GridGeometry, projection: &Projection) -> Result<(), String> {
        use bounds::*;
        if g.rows < 2 || g.cols < 2 {
            return Err(format!(
                "{} x {} pixels: a DEM needs at least 2 x 2 pixels",
                g.cols, g.rows
            ));
        }
        for (what, px) in [("x", g.px_x_m), ("y", g.px_y_m)] {
            if !(MIN_PIXEL_M..=MAX_PIXEL_M).contains(&px) {
                return Err(format!(
                    "pixel size along {what} is {px} m (must lie in {MIN_PIXEL_M} .. {MAX_PIXEL_M} m)"
                ));
            }
        }
        let x_right = g.x_left_m + g.cols as f64 * g.px_x_m;
        let y_bottom = g.y_top_m - g.rows as f64 * g.px_y_m;
        for (what, v) in [
            ("left edge x", g.x_left_m),
            ("right edge x", x_right),
            ("top edge y", g.y_top_m),
            ("bottom edge y", y_bottom),
        ] {
            if !(v.is_finite() && v.abs() <= MAX_MAP_COORD_M) {
                return Err(format!(
                    "the grid's {what} is {v} m (must be finite and within ±{MAX_MAP_COORD_M} m of the projection's origin)"
                ));
            }
        }
        let (lon0, radius, extra) = match *projection {
            Projection::PolarStereographic {
                lon0_deg,
                k0,
                radius_m,
                ..
            } => (lon0_deg, radius_m, ("scale factor", k0, 1e-3..=10.0)),
            Projection::Equirectangular {
                lon0_deg,
                lat_ts_deg,
                radius_m,
            } => (
                lon0_deg,
                radius_m,
                ("latitude of true scale", lat_ts_deg, -89.0..=89.0),
            ),
        };
        if !(lon0.is_finite() && lon0.abs() <= 360.0) {
            return Err(format!(
                "central meridian {lon0} deg (must lie in -360 .. 360)"
            ));
        }
        if !(1_700_000.0..=1_780_000.0).contains(&radius) {
            return Err(format!(
                "sphere radius {radius} m is not the Moon's (1.70e6 .. 1.78e6 m)"
            ));
        }
        let (what, v, range) = extra;
        if !range.contains(&v) {
            return Err(format!(
                "{what} {v} (must lie in {} .. {})",
                range.start(),
                range.end()
            ));
        }
        Ok(())
    }

    /// The heights part of [`Dem::check`].
    fn check_heights(heights_m: &[f32]) -> Result<(), String> {
        use bounds::*;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for &h in heights_m {
            if h.is_infinite() {
                return Err(format!("holds an infinite height ({h})"));
            }
            if !h.is_nan() {
                lo = lo.min(h);
                hi = hi.max(h);
            }
        }
        if lo.is_finite() && lo > 1_000_000.0 {
            return Err(format!(
                "heights {lo:.0} .. {hi:.0} m are radii from the Moon's centre, not heights above the \
                 1737.4 km sphere (a PDS label's OFFSET was applied): subtract 1737400 m, e.g. \
                 gdal_translate -a_offset 0 on the label, or gdal_calc.py --calc=\"A-1737400\""
            ));
        }
        if f64::from(lo) < -MAX_ABS_HEIGHT_M || f64::from(hi) > MAX_ABS_HEIGHT_M {
            return Err(format!(
                "heights {lo} .. {hi} m exceed ±{MAX_ABS_HEIGHT_M} m above the 1737.4 km sphere \
                 (the Moon's relief spans -9.1 .. +10.8 km): wrong units, scale or offset?"
            ));
        }
        Ok(())
    }

    /// Height of cell (row, col), or `None` outside the grid or in a hole.
    pub fn cell_height_m(&self, row: isize, col: isize) -> Option<f32> {
        if row < 0 || col < 0 {
            return None;
        }
        let (row, col) = (row as usize, col as usize);
        if row >= self.grid.rows || col >= self.grid.cols {
            return None;
        }
        let h = self.heights_m[row * self.grid.cols + col];
        (!h.is_nan()).then_some(h)
    }

    /// Nodata-aware bilinear height (m) at a map point.
    ///
    /// The surface is the bilinear interpolant between cell centres. Where some of the four
    /// surrounding centres are holes, the valid ones are re-weighted; where the nearest centre is a
    /// hole, or the point is more than half a cell outside the outer centres, there is no surface
    /// (`None`). Within the outer half-cell border the edge values are extended (clamped).
    pub fn height_at_xy_m(&self, x_m: f64, y_m: f64) -> Option<f64> {
        let (r, c) = self.grid.row_col_from_xy(x_m, y_m);
        self.height_at_row_col(r, c)
    }

    /// Nodata-aware bilinear height (m) at a fractional (row, col); see
    /// [`Dem::height_at_xy_m`].
    pub fn height_at_row_col(&self, row: f64, col: f64) -> Option<f64> {
        let (rows, cols) = (self.grid.rows as f64, self.grid.cols as f64);
        if !(row >= -0.5 && col >= -0.5 && row <= rows - 0.5 && col <= cols - 0.5) {
            return None;
        }
        let r = row.clamp(0.0, rows - 1.0);
        let c = col.clamp(0.0, cols - 1.0);
        // r, c >= 0: truncation is the floor (and no call into libm's `floor`).
        let r0 = (r as isize).min(self.grid.rows as isize - 2).max(0);
        let c0 = (c as isize).min(self.grid.cols as isize - 2).max(0);
        let (fr, fc) = (r - r0 as f64, c - c0 as f64);
        let weights = [
            (1.0 - fr) * (1.0 - fc),
            (1.0 - fr) * fc,
            fr * (1.0 - fc),
            fr * fc,
        ];
        // The common case, all four cells with (finite) data, then the nearest centre too: the
        // same sum as below without a branch (a zero weight times a finite height adds a zero).
        if let (Ok(r0u), Ok(c0u)) = (usize::try_from(r0), usize::try_from(c0))
            && r0u + 1 < self.grid.rows
            && c0u + 1 < self.grid.cols
        {
            let i = r0u * self.grid.cols + c0u;
            let h = &self.heights_m;
            let cells = [
                h[i],
                h[i + 1],
                h[i + self.grid.cols],
                h[i + self.grid.cols + 1],
            ];
            if cells.iter().all(|v| v.is_finite()) {
                let mut sum = 0.0;
                let mut wsum = 0.0;
                for (w, v) in weights.into_iter().zip(cells) {
                    sum += w * f64::from(v);
                    wsum += w;
                }
                return Some(sum / wsum);
            }
        }
        // Nearest centre must be valid.
        let nearest = self.cell_height_m(
            row.round().clamp(0.0, rows - 1.0) as isize,
            col.round().clamp(0.0, cols - 1.0) as isize,
        );
        nearest?;
        let mut sum = 0.0;
        let mut wsum = 0.0;
        for (k, w) in weights.into_iter().enumerate() {
            if w <= 0.0 {
                continue;
            }
            if let Some(h) = self.cell_height_m(r0 + (k / 2) as isize, c0 + (k % 2) as isize) {
                sum += w * f64::from(h);
                wsum += w;
            }
        }
        (wsum > 0.0).then(|| sum / wsum)
    }

    /// Height (m) at a latitude / east longitude (deg), bilinear; `None` off the grid or in a hole.
    pub fn height_at_lat_lon_m(&self, lat_deg: f64, lon_deg: f64) -> Option<f64> {
        let (x, y) = self.projection.xy_from_lat_lon(lat_deg, lon_deg);
        self.height_at_xy_m(x, y)
    }

    /// Smallest cell size, metres.
    pub fn px_m(&self) -> f64 {
        self.grid.px_x_m.min(self.grid.px_y_m)
    }
}

/// DEM layers, finest first: at any point the finest layer that has a surface there is used.
#[derive(Debug, Clone, Default)]
pub struct TerrainStack {
    /// The layers, sorted by increasing cell size.
    pub layers: Vec<Dem>,
}

impl TerrainStack {
    /// Builds a stack, sorting the layers finest first.
    pub fn new(mut layers: Vec<Dem>) -> Self {
        layers.sort_by(|a, b| a.px_m().total_cmp(&b.px_m()));
        TerrainStack { layers }
    }

    /// Height (m) at a latitude / east longitude from the finest layer with a surface there, and
    /// that layer's index.
    pub fn height_at_lat_lon_m(&self, lat_deg: f64, lon_deg: f64) -> Option<(f64, usize)> {
        self.layers
            .iter()
            .enumerate()
            .find_map(|(i, dem)| dem.height_at_lat_lon_m(lat_deg, lon_deg).map(|h| (h, i)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polar_stereographic_matches_provenance_formula() {
        // PROVENANCE.md: x = 2R tan(colat/2) sin(lon), y = 2R tan(colat/2) cos(lon), colat from
        // the south pole.
        let p = Projection::LOLA_SOUTH_POLAR;
        let (lat, lon): (f64, f64) = (-89.45, 222.7);
        let colat = (90.0 + lat).to_radians();
        let rho = 2.0 * MOON_RADIUS_M * (colat / 2.0).tan();
        let (x, y) = p.xy_from_lat_lon(lat, lon);
        assert!((x - rho * lon.to_radians().sin()).abs() < 1e-6);
        assert!((y - rho * lon.to_radians().cos()).abs() < 1e-6);
    }

    #[test]
    fn projections_round_trip_to_a_millimetre() {
        let projections = [
            Projection::LOLA_SOUTH_POLAR,
            Projection::PolarStereographic {
                south: false,
                lon0_deg: 0.0,
                k0: 1.0,
                radius_m: MOON_RADIUS_M,
            },
            Projection::Equirectangular {
                lon0_deg: 0.0,
                lat_ts_deg: 0.0,
                radius_m: MOON_RADIUS_M,
            },
        ];
        for p in projections {
            for &(lat, lon) in &[
                (-89.45, -137.3),
                (-85.99, 2.93),
                (-88.0, 179.9),
                (89.5, 45.0),
            ] {
                let lat = match p {
                    Projection::PolarStereographic { south: false, .. } => -lat,
                    _ => lat,
                };
                let (x, y) = p.xy_from_lat_lon(lat, lon);
                let (lat2, lon2) = p.lat_lon_from_xy(x, y);
                let (x2, y2) = p.xy_from_lat_lon(lat2, lon2);
                assert!((x - x2).hypot(y - y2) < 1e-3, "{p:?} {lat} {lon}");
            }
        }
    }

    fn ramp_dem() -> Dem {
        let grid = GridGeometry {
            rows: 4,
            cols: 5,
            x_left_m: -250.0,
            y_top_m: 200.0,
            px_x_m: 100.0,
            px_y_m: 100.0,
        };
        // h = 10 * col + 1000 * row, exactly representable and bilinear.
        let heights_m = (0..20)
            .map(|i| (10 * (i % 5) + 1000 * (i / 5)) as f32)
            .collect();
        Dem {
            grid,
            projection: Projection::LOLA_SOUTH_POLAR,
            heights_m,
            name: "ramp".into(),
        }
    }

    #[test]
    fn bilinear_reproduces_a_plane_and_respects_holes() {
        let mut dem = ramp_dem();
        let (x, y) = dem.grid.xy_from_row_col(1.25, 2.5);
        let h = dem.height_at_xy_m(x, y).unwrap();
        assert!((h - (10.0 * 2.5 + 1000.0 * 1.25)).abs() < 1e-9);
        assert!(dem.height_at_xy_m(-1000.0, 0.0).is_none());
        dem.heights_m[5 + 2] = f32::NAN;
        assert!(
            dem.height_at_row_col(1.1, 2.1).is_none(),
            "nearest is a hole"
        );
        assert!(
            dem.height_at_row_col(1.6, 2.6).is_some(),
            "re-weighted around the hole"
        );
    }

    /// The bilinear read (its fast path where all four cells have data, the re-weighting near
    /// holes and the edges) against the definition written out here: the mean of the cells with
    /// data weighted by their bilinear weights, `None` off the grid or where the nearest centre
    /// is a hole; at 20,000 pseudo-random points over a field with holes and beyond its edges.
    #[test]
    fn bilinear_reads_match_the_weighted_mean_of_the_cells_with_data() {
        let mut dem = ramp_dem();
        let (rows, cols) = (dem.grid.rows, dem.grid.cols);
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for h in dem.heights_m.iter_mut() {
            *h = (next() * 4000.0 - 2000.0) as f32;
        }
        dem.heights_m[cols + 2] = f32::NAN;
        dem.heights_m[2 * cols + 3] = f32::NAN;
        let cell = |r: i64, c: i64| {
            (r >= 0 && c >= 0 && (r as usize) < rows && (c as usize) < cols)
                .then(|| f64::from(dem.heights_m[r as usize * cols + c as usize]))
                .filter(|h| !h.is_nan())
        };
        let (mut fast, mut holes, mut off) = (0, 0, 0);
        for _ in 0..20_000 {
            let row = next() * (rows as f64 + 1.0) - 1.0;
            let col = next() * (cols as f64 + 1.0) - 1.0;
            let got = dem.height_at_row_col(row, col);
            let inside =
                row >= -0.5 && col >= -0.5 && row <= rows as f64 - 0.5 && col <= cols as f64 - 0.5;
            if !inside {
                assert!(got.is_none(), "({row}, {col}) is off the grid");
                off += 1;
                continue;
            }
            let (r, c) = (
                row.clamp(0.0, rows as f64 - 1.0),
                col.clamp(0.0, cols as f64 - 1.0),
            );
            let (r0, c0) = (
                (r.floor() as i64).min(rows as i64 - 2),
                (c.floor() as i64).min(cols as i64 - 2),
            );
            let (fr, fc) = (r - r0 as f64, c - c0 as f64);
            let mut sum = 0.0;
            let mut wsum = 0.0;
            let mut all = true;
            for (dr, wr) in [(0, 1.0 - fr), (1, fr)] {
                for (dc, wc) in [(0, 1.0 - fc), (1, fc)] {
                    match cell(r0 + dr, c0 + dc) {
                        Some(h) => {
                            sum += wr * wc * h;
                            wsum += wr * wc;
                        }
                        None => all &= wr * wc == 0.0,
                    }
                }
            }
            let nearest = cell(r.round() as i64, c.round() as i64);
            let want = (nearest.is_some() && wsum > 0.0).then(|| sum / wsum);
            match (got, want) {
                (Some(g), Some(w)) => assert!((g - w).abs() < 1e-9, "({row}, {col}): {g} vs {w}"),
                (None, None) => {}
                other => panic!("({row}, {col}): {other:?}"),
            }
            if want.is_none() {
                holes += 1;
            } else if all {
                fast += 1;
            }
        }
        assert!(
            fast > 3_000 && holes > 50 && off > 1_000,
            "{fast} {holes} {off}"
        );
    }
}

//! The model-space height field that every shadow engine works on.
//!
//! **Model space** is the local Cartesian frame tangent to the 1737.4 km sphere at a centre point
//! `C` (planetocentric `centre_lat_deg`, `centre_lon_deg`), origin on the sphere at `C`:
//!
//! ```text
//!   z (up = radial direction at C)
//!   ^     y (north at C)
//!   |    /         terrain point P: body-fixed p = (R + h) * u(lat, lon)
//!   |   /          model coordinates m = enu_from_moon_me(C) * (p - R * u(C))
//!   C--------> x (east at C)
//! ```
//!
//! `m` is a rigid transform of body-fixed positions, so the curvature is in `z` (about
//! `-(x² + y²) / 2R` on a bare sphere) and a light at infinity is one direction over the whole
//! grid: height-field shadow algorithms are exact on a curved Moon. The grid follows the
//! pixel-is-area convention of [`crate::terrain::GridGeometry`] in model `x`/`y`: the centre of
//! cell (row, col) is `x_m = x_left_m + (col + 0.5) * px_m`, `y_m = y_top_m - (row + 0.5) * px_m`,
//! row 0 the top (north of `C`). More: `docs/terrain.md`, "Model space".

use nalgebra::{Matrix3, Vector3};

use crate::MOON_RADIUS_M;
use crate::frames::enu_from_moon_me;

/// A terrain height field in model space (see the module docs). Heights are `f32` metres along
/// the model `z` axis; `NaN` marks holes (no terrain; rays pass).
#[derive(Debug, Clone)]
pub struct HeightField {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Cell size along model x and y, metres.
    pub px_m: f64,
    /// Model x of the left edge of column 0, metres.
    pub x_left_m: f64,
    /// Model y of the top edge of row 0, metres.
    pub y_top_m: f64,
    /// Model z of the terrain surface at each cell centre, metres, row-major; `NaN` for holes.
    pub z_m: Vec<f32>,
    /// Planetocentric latitude of the model-space origin `C`, degrees.
    pub centre_lat_deg: f64,
    /// East longitude of the model-space origin `C`, degrees.
    pub centre_lon_deg: f64,
    /// Rotation (rad, counter-clockwise seen from above) of the model x/y axes from east/north at
    /// `C`: a map's model grid is turned so that its rows and columns run along the DEM's
    /// (see [`crate::model::MapGrid`]); 0 gives the plain ENU frame.
    pub rotation_rad: f64,
    /// The cells whose results are wanted (`None`: all). A map's grid covers every DEM layer so
    /// that all of them cast shadows, but only the cells under the output raster are evaluated;
    /// the CPU engines leave the others at their nodata value (the terrain there still blocks).
    pub window: Option<CellWindow>,
}

/// A half-open rectangle of cells `rows.0 .. rows.1` x `cols.0 .. cols.1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CellWindow {
    /// First and one-past-last row.
    pub rows: (usize, usize),
    /// First and one-past-last column.
    pub cols: (usize, usize),
}

impl CellWindow {
    /// Whether cell (row, col) is inside.
    #[inline]
    pub fn contains(&self, row: usize, col: usize) -> bool {
        (self.rows.0..self.rows.1).contains(&row) && (self.cols.0..self.cols.1).contains(&col)
    }
}

impl HeightField {
    /// A height field with every cell at `z = 0` on a grid centred on the model origin. Mainly for
    /// tests and analytic fixtures (a flat plane, not a sphere).
    pub fn flat(rows: usize, cols: usize, px_m: f64) -> Self {
        HeightField {
            rows,
            cols,
            px_m,
            x_left_m: -(cols as f64) * px_m / 2.0,
            y_top_m: rows as f64 * px_m / 2.0,
            z_m: vec![0.0; rows * cols],
            centre_lat_deg: -90.0,
            centre_lon_deg: 0.0,
            rotation_rad: 0.0,
            window: None,
        }
    }

    /// Whether the results of cell (row, col) are wanted (inside [`HeightField::window`]).
    #[inline]
    pub fn evaluates(&self, row: usize, col: usize) -> bool {
        self.window.is_none_or(|w| w.contains(row, col))
    }

    /// Height at cell (row, col), metres; `None` outside the grid or in a hole.
    #[inline]
    pub fn z_at(&self, row: isize, col: isize) -> Option<f32> {
        if row < 0 || col < 0 || row as usize >= self.rows || col as usize >= self.cols {
            return None;
        }
        let z = self.z_m[row as usize * self.cols + col as usize];
        (!z.is_nan()).then_some(z)
    }

    /// Model x/y (m) of the centre of cell (row, col).
    #[inline]
    pub fn xy_from_row_col(&self, row: f64, col: f64) -> (f64, f64) {
        (
            self.x_left_m + (col + 0.5) * self.px_m,
            self.y_top_m - (row + 0.5) * self.px_m,
        )
    }

    /// Fractional (row, col) of a model x/y (m); integer values are cell centres.
    #[inline]
    pub fn row_col_from_xy(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        (
            (self.y_top_m - y_m) / self.px_m - 0.5,
            (x_m - self.x_left_m) / self.px_m - 0.5,
        )
    }

    /// Rotation from `MOON_ME` to model space (the ENU frame at the centre `C`, turned by
    /// [`HeightField::rotation_rad`]). Apply it to a body-fixed light direction to get the
    /// model-space light direction.
    pub fn model_from_moon_me(&self) -> Matrix3<f64> {
        model_from_enu(self.rotation_rad)
            * enu_from_moon_me(self.centre_lat_deg, self.centre_lon_deg)
    }

    /// Rotation from the ENU frame at `C` to model space.
    pub fn model_from_enu(&self) -> Matrix3<f64> {
        model_from_enu(self.rotation_rad)
    }

    /// Unit radial ("up") direction of the Moon at a model-space point, in model space. An
    /// observer `h` metres above the ground at `p` stands at `p + h * up`.
    pub fn up_at(&self, x_m: f64, y_m: f64, z_m: f64) -> Vector3<f64> {
        Vector3::new(x_m, y_m, z_m + MOON_RADIUS_M).normalize()
    }
}

/// The rotation about the up axis by `rotation_rad` (counter-clockwise seen from above) that
/// takes ENU coordinates at the model centre to model coordinates.
pub fn model_from_enu(rotation_rad: f64) -> Matrix3<f64> {
    let (s, c) = rotation_rad.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

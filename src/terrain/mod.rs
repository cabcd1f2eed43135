//! Terrain: DEM rasters, georeferencing, DEM layers and the curvature-exact model space.

pub mod grid;
pub mod heightfield;

pub use grid::{Dem, GridGeometry, Projection, TerrainStack};
pub use heightfield::HeightField;

//! Terrain: DEM rasters, georeferencing, DEM layers and the curvature-exact model space.
//!
//! - [`grid`]: projections, the pixel ↔ map transform, nodata-aware bilinear sampling, layers.
//! - [`geotiff`]: GeoTIFF input and output.
//! - [`model_space`]: resampling a [`TerrainStack`] onto a model-space [`HeightField`].
//! - [`synth`]: the seeded synthetic south-polar DEM and analytic test DEMs.
//!
//! See `docs/terrain.md` for formats, conventions and measured accuracy.

pub mod error;
pub mod geotiff;
pub mod grid;
pub mod heightfield;
pub mod info;
pub mod model_space;
pub mod pds3;
pub mod pds4;
pub mod synth;
pub(crate) mod unit_projector;

use std::path::Path;

pub use error::DemError;
pub use geotiff::{
    BandInfo, WriteSample, gdal_metadata_xml_with_band, orthographic_model_tags, read_geotiff,
    write_dem, write_geotiff,
};
pub use grid::{Dem, GridGeometry, Projection, TerrainStack};
pub use heightfield::{CellWindow, HeightField};
pub use info::DemInfo;
pub use model_space::{ModelFrame, ModelGridSpec, ResampleStats, resample_to_model_space};

/// Loads a DEM file and checks it against physical bounds ([`Dem::check`]: georeferencing,
/// heights above the 1737.4 km sphere): a GeoTIFF ([`read_geotiff`]), a PDS3 product (`.LBL`,
/// or an `.IMG` with an attached label or a `.LBL` beside it: [`pds3::read_pds3`]) or a PDS4 one
/// (its `.xml` label: [`pds4::read_pds4`]).
pub fn load_dem(path: &Path) -> error::Result<Dem> {
    let dem = if pds3::is_pds3(path) {
        pds3::read_pds3(path)?
    } else if pds4::is_pds4(path) {
        pds4::read_pds4(path)?
    } else {
        read_geotiff(path)?
    };
    dem.check().map_err(|detail| DemError::Rejected {
        path: path.display().to_string(),
        detail,
    })?;
    Ok(dem)
}

impl TerrainStack {
    /// Loads DEM layers from files and sorts them finest first.
    pub fn load<P: AsRef<Path>>(paths: &[P]) -> error::Result<Self> {
        let layers = paths
            .iter()
            .map(|p| load_dem(p.as_ref()))
            .collect::<error::Result<Vec<_>>>()?;
        Ok(TerrainStack::new(layers))
    }

    /// Like [`TerrainStack::height_at_lat_lon_m`], with [`DemError::OutsideLayers`] where no
    /// layer has a surface.
    pub fn height_at_lat_lon_m_checked(
        &self,
        lat_deg: f64,
        lon_deg: f64,
    ) -> error::Result<(f64, usize)> {
        self.height_at_lat_lon_m(lat_deg, lon_deg)
            .ok_or(DemError::OutsideLayers { lat_deg, lon_deg })
    }
}

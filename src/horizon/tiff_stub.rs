//! A minimal float32 GeoTIFF reader for the shared LOLA grids, used by the `horizon` command,
//! its tests and benches until the terrain reader lands.
//!
//! TODO(lead): replace with terrain::load_dem. It reads only what the shared grids need: one
//! band of 32-bit floats, ModelPixelScale (33550) and ModelTiepoint (33922), pixel-is-area; the
//! projection is *assumed* to be LOLA south polar stereographic (`+proj=stere +lat_0=-90
//! +lon_0=0 +k=1 +R=1737400`, as documented in the grids' PROVENANCE.md); the GeoKeyDirectory is
//! not checked.

use std::path::Path;

use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;

use crate::terrain::{Dem, GridGeometry, Projection, TerrainStack};

/// Reads one float32 GeoTIFF (see the module docs for what is assumed).
pub fn read_dem_f32(path: &Path) -> anyhow::Result<Dem> {
    use anyhow::Context as _;
    let ctx = || format!("reading DEM {}", path.display());
    let file = std::fs::File::open(path).with_context(ctx)?;
    let mut dec = Decoder::new(std::io::BufReader::new(file))
        .with_context(ctx)?
        .with_limits(Limits::unlimited());
    let (cols, rows) = dec.dimensions().with_context(ctx)?;
    let scale = dec
        .get_tag_f64_vec(Tag::ModelPixelScaleTag)
        .with_context(|| format!("{}: no ModelPixelScale tag", ctx()))?;
    let tie = dec
        .get_tag_f64_vec(Tag::ModelTiepointTag)
        .with_context(|| format!("{}: no ModelTiepoint tag", ctx()))?;
    anyhow::ensure!(
        scale.len() >= 2 && tie.len() >= 6 && scale[0] > 0.0 && scale[1] > 0.0,
        "{}: malformed georeferencing tags",
        ctx()
    );
    let heights_m = match dec.read_image().with_context(ctx)? {
        DecodingResult::F32(v) => v,
        _ => anyhow::bail!("{}: only float32 rasters are supported here", ctx()),
    };
    let grid = GridGeometry {
        rows: rows as usize,
        cols: cols as usize,
        x_left_m: tie[3] - tie[0] * scale[0],
        y_top_m: tie[4] + tie[1] * scale[1],
        px_x_m: scale[0],
        px_y_m: scale[1],
    };
    anyhow::ensure!(
        heights_m.len() == grid.rows * grid.cols,
        "{}: {} samples for {}x{} pixels",
        ctx(),
        heights_m.len(),
        grid.cols,
        grid.rows
    );
    Ok(Dem {
        grid,
        projection: Projection::LOLA_SOUTH_POLAR,
        heights_m,
        name: path.display().to_string(),
    })
}

/// Reads several GeoTIFFs into a stack (finest first).
pub fn load_stack(paths: &[impl AsRef<Path>]) -> anyhow::Result<TerrainStack> {
    let layers = paths
        .iter()
        .map(|p| read_dem_f32(p.as_ref()))
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(TerrainStack::new(layers))
}

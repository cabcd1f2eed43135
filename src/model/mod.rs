//! What the products share below the engines: the model grid on the DEM's own grid
//! ([`MapGrid`]) and the light directions of each epoch in its frame ([`EpochLights`]).

mod grid;
mod lights;

pub(crate) use grid::BelowSphereTally;
pub use grid::{
    MAX_MODEL_CELLS, MapGrid, RasterInfo, VISIBLE_MIN_FRACTION, write_f32_on, write_u8_on,
};
pub use lights::{EpochLights, epoch_lights};

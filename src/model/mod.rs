//! What the products share below the engine switch: the values a user types, parsed once
//! ([`ObserverHeight`], [`Site`], [`Epochs`]), the model grid on the DEM's own grid
//! ([`MapGrid`]), the light directions of each epoch in its frame ([`EpochLights`]), and the CPU
//! map engines on that grid with their statistics over a range of epochs ([`MapEngine`],
//! [`RangeStats`]) and the rasters those statistics are written as ([`write_range`]).

mod engine;
mod grid;
mod input;
mod lights;
mod near_field;
mod rasters;
mod sites;

pub use engine::{
    HorizonExtras, MapEngine, MapEngineKind, ObserverPlacement, PowerMaps, RangeStats,
    per_epoch_statistics, per_epoch_statistics_with,
};
pub(crate) use grid::BelowSphereTally;
pub use grid::{MAX_MODEL_CELLS, MapGrid, MapSample, RasterInfo, VISIBLE_MIN_FRACTION, write_on};
pub use input::{
    EpochRange, Epochs, InputError, MAX_SITE_NAME_CHARS, ObserverHeight, Site, check_distinct_sites,
};
pub use lights::{EpochLights, epoch_lights};
pub use near_field::NEAR_FIELD_CELLS;
pub use rasters::{
    PSR_DESCRIPTION, RangeRaster, geotiff_unit, range_metadata, range_rasters, span_text,
    write_range,
};
pub use sites::{parse_site_flag, read_sites_file};

//! `penumbra map`, a scenario's `[map]` and the Python module's maps: illumination maps on the DEM's
//! own grid, for one light ([`one_light()`]) or as statistics over an epoch range ([`statistics`]),
//! computed through [`crate::compute`] and written by [`write_range`] (and [`shard`] for one
//! block of rows of a job split across machines).
//!
//! The command line, a scenario and Python build the same [`MapSettings`]; [`run`] is the
//! command line's whole job (inputs, compute, files, `run.json`).

mod one_light;
mod range;
pub mod shard;

use std::path::PathBuf;

use super::{KernelSource, TerrainSource};
use crate::ephem::AbCorr;
use crate::model::{EpochRange, MapEngineKind};

pub use crate::compute::one_light::{
    Light, OneLightMaps, OneLightOutputs, one_light, one_light_metadata,
};
pub use crate::compute::{AUTO_HORIZONS_MIN_EPOCHS, MapSettings, auto_engine};
pub use crate::model::{
    PSR_DESCRIPTION, RangeRaster, geotiff_unit, range_metadata, range_rasters, span_text,
    write_range,
};
pub use one_light::{
    EARTH_FRACTION_DESCRIPTION, SUN_FRACTION_DESCRIPTION, SUN_MASK_DESCRIPTION, made_with_items,
};
pub use range::statistics;

/// The files of a one-light map (at least one).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OneLightFiles {
    /// The Sun's visible fraction (float32 GeoTIFF).
    pub fraction: Option<PathBuf>,
    /// The hard mask of the Sun's disc centre (uint8 GeoTIFF).
    pub mask: Option<PathBuf>,
    /// The Earth's visible fraction (float32 GeoTIFF; needs an epoch).
    pub earth_fraction: Option<PathBuf>,
}

impl OneLightFiles {
    /// Which maps these files need.
    pub fn outputs(&self) -> OneLightOutputs {
        OneLightOutputs {
            sun_fraction: self.fraction.is_some(),
            sun_mask: self.mask.is_some(),
            earth_fraction: self.earth_fraction.is_some(),
        }
    }
}

/// Where the statistics of an epoch range go.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeFiles {
    /// The folder of the statistics maps.
    pub out_dir: PathBuf,
    /// Carry on an unfinished run in `out_dir` (the horizons engine keeps finished blocks of
    /// rows).
    pub resume: bool,
    /// Compute this shard of the job only and write a partial for `penumbra merge`.
    pub shard: Option<shard::Shard>,
}

/// What a map is asked for: one light and its files, or an epoch range and its folder.
#[derive(Debug, Clone, PartialEq)]
pub enum MapTask {
    /// One light.
    OneLight {
        /// The light.
        light: Light,
        /// The files.
        files: OneLightFiles,
    },
    /// Statistics over an epoch range.
    Range {
        /// The epochs.
        epochs: EpochRange,
        /// The files.
        files: RangeFiles,
    },
}

impl MapTask {
    /// A one-light task, if it writes something and asks for the Earth only with an epoch.
    pub fn one_light(light: Light, files: OneLightFiles) -> anyhow::Result<Self> {
        if files == OneLightFiles::default() {
            anyhow::bail!(
                "nothing to write: give --out-fraction, --out-mask or --out-earth-fraction"
            );
        }
        if files.earth_fraction.is_some() && !matches!(light, Light::Epoch(_)) {
            anyhow::bail!(
                "--out-earth-fraction needs an epoch (--utc): an explicit Sun direction gives no Earth"
            );
        }
        Ok(MapTask::OneLight {
            light: light.checked()?,
            files,
        })
    }
}

/// What `penumbra map` computes and writes.
#[derive(Debug, Clone)]
pub struct MapRequest {
    /// The terrain (every layer).
    pub terrain: TerrainSource,
    /// The kernels.
    pub kernels: KernelSource,
    /// Aberration correction.
    pub abcorr: AbCorr,
    /// How the map is computed.
    pub settings: MapSettings,
    /// What it is asked for.
    pub task: MapTask,
}

/// Runs `penumbra map`.
pub fn run(req: &MapRequest) -> anyhow::Result<()> {
    match &req.task {
        MapTask::OneLight { light, files } => one_light::one_light_job(req, *light, files),
        MapTask::Range { epochs, files } => range::range_job(req, epochs, files),
    }
}

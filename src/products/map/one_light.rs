//! One light's maps: the Sun's visible fraction and the hard mask of its centre, and the Earth's
//! visible fraction at an epoch, per DEM pixel ([`crate::compute::one_light::one_light()`]; the command line's `--utc` /
//! `--sun-*` maps, Python's `map_light`).

use std::path::Path;

use hifitime::Epoch;

use super::{Light, MapRequest, MapSettings, OneLightFiles, OneLightMaps};
use crate::model::MapEngineKind;
use crate::products::{DemFiles, Inputs};

/// The command line's one-light job: the checks, the inputs, the maps, the files.
pub(super) fn one_light_job(
    req: &MapRequest,
    light: Light,
    files: &OneLightFiles,
) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    check_one_light(&req.settings, files)?;
    let epochs: Vec<Epoch> = match light {
        Light::Epoch(e) => vec![e],
        _ => Vec::new(),
    };
    let (terrain, kernels) = (&req.terrain, &req.kernels);
    let inputs = Inputs::load(terrain, kernels, &epochs, DemFiles::Record)?;
    let mut maps = crate::compute::one_light::one_light(
        &req.settings,
        &inputs.stack,
        (light, inputs.kernels.as_ref(), req.abcorr),
        files.outputs(),
    )?;
    maps.metadata
        .extend(made_with_items(&inputs.provenance, !epochs.is_empty()));
    write(&maps, files)?;
    crate::note!(
        "penumbra: map written ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The metadata items a one-light map adds to those of `one_light` (engine, observer height,
/// light): its layers (file and sha256, or the synthetic DEM's description) and, for a light
/// from the ephemeris, the kernels. The command line and Python's `map_light` write the same.
pub fn made_with_items(
    prov: &crate::output::Provenance,
    light_from_ephemeris: bool,
) -> Vec<(String, String)> {
    crate::output::MadeWith::new(prov, f64::NAN, "", "", "")
        .items()
        .into_iter()
        .filter(|(k, _)| k == "dem_layers" || (light_from_ephemeris && k == "kernels"))
        .collect()
}

/// The checks of a one-light map that need no input read: the engine makes one light, the
/// output files can be written side by side.
fn check_one_light(settings: &MapSettings, files: &OneLightFiles) -> anyhow::Result<()> {
    if settings.engine == Some(MapEngineKind::Horizons) {
        anyhow::bail!(
            "--engine horizons makes statistics over an epoch range (--start/--stop/--step); \
             for one light use combined, dp or fourier"
        );
    }
    let outputs: Vec<(&str, &Path)> = [
        ("--out-fraction", &files.fraction),
        ("--out-mask", &files.mask),
        ("--out-earth-fraction", &files.earth_fraction),
    ]
    .into_iter()
    .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
    .collect();
    for (flag, path) in &outputs {
        crate::output::guard::check_output_target(flag, path, outputs.len() == 1)
            .map_err(anyhow::Error::msg)?;
    }
    crate::output::guard::check_distinct_outputs(&outputs).map_err(anyhow::Error::msg)
}

/// Writes the files of `maps` that `files` asks for.
fn write(maps: &OneLightMaps, files: &OneLightFiles) -> anyhow::Result<()> {
    let info = |description| crate::model::RasterInfo {
        description,
        unit: "",
        items: maps.metadata.clone(),
    };
    if let (Some(path), Some(f)) = (&files.fraction, &maps.sun_fraction) {
        maps.grid.write(path, f, &info(SUN_FRACTION_DESCRIPTION))?;
    }
    if let (Some(path), Some(m)) = (&files.mask, &maps.sun_mask) {
        maps.grid.write(path, m, &info(SUN_MASK_DESCRIPTION))?;
    }
    if let (Some(path), Some(f)) = (&files.earth_fraction, &maps.earth_fraction) {
        maps.grid
            .write(path, f, &info(EARTH_FRACTION_DESCRIPTION))?;
    }
    Ok(())
}

/// The GeoTIFF `content` of a one-light Sun fraction map.
pub const SUN_FRACTION_DESCRIPTION: &str = "visible fraction of the Sun's disc";
/// The GeoTIFF `content` of a one-light hard mask.
pub const SUN_MASK_DESCRIPTION: &str = "Sun disc centre: 1 lit, 0 shadow, 255 no data";
/// The GeoTIFF `content` of a one-epoch Earth fraction map.
pub const EARTH_FRACTION_DESCRIPTION: &str = "visible fraction of the Earth's disc";

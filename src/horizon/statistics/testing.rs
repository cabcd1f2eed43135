//! Test support, not part of the API: a rough synthetic terrain, its horizons and a year of the
//! bodies, shared by the engine's unit tests and the integration tests of its kernels.

use std::path::Path;

use super::{EpochBodies, InMemoryHorizons};
use crate::horizon::{HorizonSweep, SweepParams};
use crate::terrain::TerrainStack;
use crate::terrain::synth::{SynthParams, south_polar_dem};

/// A rough synthetic DEM (the demo's generator: `size_px`² px of 150 m round the pole, crater
/// floors that never see the Sun, slopes that never see the Earth), its line sweep (2 m
/// observer, 180 azimuths, max step 8) and the bodies every `step_h` hours of 2027 from the
/// kernels in `kernel_dir`. Panics on failure (it is test set-up).
pub fn rough_terrain_2027(
    size_px: usize,
    seed: u64,
    step_h: f64,
    kernel_dir: &Path,
) -> (TerrainStack, InMemoryHorizons, Vec<EpochBodies>) {
    let dem = south_polar_dem(&SynthParams {
        size_px,
        px_m: 150.0,
        seed,
    })
    .expect("the synthetic DEM");
    let stack = TerrainStack::new(vec![dem]);
    let sweep = HorizonSweep::new(
        &stack,
        SweepParams {
            observer_height_m: 2.0,
            azimuths: 180,
            max_step: 8,
        },
    )
    .expect("the sweep's parameters");
    let horizons = InMemoryHorizons::sweep(&sweep, |_| true).expect("the sweep");
    let kernels = crate::ephem::Kernels::load(kernel_dir).expect("the SPICE kernels");
    let epochs = crate::ephem::time::epoch_range(
        crate::ephem::time::parse_utc("2027-01-01").expect("a date"),
        crate::ephem::time::parse_utc("2027-12-31").expect("a date"),
        hifitime::Duration::from_hours(step_h),
    )
    .expect("the epochs");
    let bodies = EpochBodies::over_dem(&stack.layers[0], &kernels, &epochs, Default::default())
        .expect("the ephemeris");
    (stack, horizons, bodies)
}

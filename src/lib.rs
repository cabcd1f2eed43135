//! # penumbra
//!
//! A simulator of sunlight and earthlight at the lunar poles. penumbra answers the question a
//! landing-site planner asks: *how much of the Sun, and of the Earth, does a lander standing here
//! see, hour by hour, for years?*
//!
//! The pipeline (see `docs/ARCHITECTURE.md`):
//!
//! 1. [`ephem`]: SPICE kernels (read with `anise`, times with `hifitime`) give the topocentric
//!    directions of the Sun and the Earth in the Moon's `MOON_ME` frame at UTC epochs.
//! 2. [`terrain`]: DEMs (GeoTIFF, polar stereographic or equirectangular) resampled into a
//!    curvature-exact local model space.
//! 3. [`horizon`], [`illum`], [`shadow`]: horizons, visible fractions of the Sun's and the Earth's
//!    discs, shadow maps; [`compute`] runs them on the CPU or the GPU ([`gpu`], [`twins`]).
//! 4. [`products`] and [`scenario`]: one home per product (typed requests in, files out) and
//!    declarative runs. The command line lives in the binary (`src/cli/`); the library knows no
//!    clap. Conventions (azimuth from north clockwise, heights above the 1737.4 km sphere,
//!    planetocentric latitude, east longitude) are stated once in `docs/ARCHITECTURE.md`.

pub mod comms;
pub mod compute;
pub mod ephem;
pub mod frames;
pub mod gpu;
pub mod horizon;
pub mod illum;
pub mod model;
pub mod output;
pub mod products;
pub mod render;
pub mod scenario;
pub mod shadow;
pub mod terrain;
pub mod twins;

/// Observer height above the ground used wherever none is given (maps, series sites, horizons,
/// site cameras, scenarios), metres: a lander's solar panel or camera mast.
pub const DEFAULT_OBSERVER_HEIGHT_M: f64 = 2.0;
/// Mean radius of the Moon's reference sphere, metres (LOLA and PDS convention).
pub const MOON_RADIUS_M: f64 = 1_737_400.0;
/// Mean radius of the Moon's reference sphere, kilometres.
pub const MOON_RADIUS_KM: f64 = 1_737.4;
/// Radius of the Sun's photosphere, kilometres (IAU 2015 nominal 695,700 km; SPICE `pck00010`
/// uses 696,000 km, which is the value penumbra uses so that its radii match SPICE's).
pub const SUN_RADIUS_KM: f64 = 696_000.0;
/// Equatorial radius of the Earth, kilometres (`pck00010`/WGS-84-like value 6378.1366 km).
pub const EARTH_RADIUS_KM: f64 = 6_378.136_6;
/// Total solar irradiance at 1 au, W/m² (Kopp & Lean 2011, 1360.8 ± 0.5 W/m²).
pub const SOLAR_CONSTANT_W_M2: f64 = 1_360.8;
/// The astronomical unit, kilometres (IAU 2012 exact).
pub const AU_KM: f64 = 149_597_870.7;
/// The speed of light in vacuum, km/s (exact; equals SPICE's `clight()`).
pub const SPEED_OF_LIGHT_KM_S: f64 = 299_792.458;

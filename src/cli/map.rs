//! `penumbra map`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use penumbra::products::map::MapRequest;

use super::{BackendArg, EpochArgs, KernelArgs, TerrainArgs};

/// Where a map's rays start (`map --observers`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObserversArg {
    /// At each DEM pixel's own surface point.
    Pixels,
    /// At the model grid's cells, resampled back onto the DEM grid.
    Cells,
}

impl From<ObserversArg> for penumbra::map::ObserverPlacement {
    fn from(o: ObserversArg) -> Self {
        match o {
            ObserversArg::Pixels => penumbra::map::ObserverPlacement::Pixels,
            ObserversArg::Cells => penumbra::map::ObserverPlacement::Cells,
        }
    }
}

/// Shadow engine on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EngineArg {
    /// Brute-force ray march (the reference; slow).
    Brute,
    /// SMap hard shadows ("Real-time terrain shadowing by directional light"); soft fractions
    /// via SMap + DP.
    Smap,
    /// DP maximum-mipmap soft shadows everywhere (Jung, Schrempp and Son: dynamic programming
    /// and maximum mipmaps).
    Dp,
    /// SMap at the disc limbs + DP in the penumbra only (the design's combination).
    Combined,
    /// Fourier-compressed horizon maps (Fritsch et al.): per-cell horizons at 64 azimuths, 16 complex
    /// DFT coefficients in f16, built once; each light is then a cheap evaluation.
    Fourier,
    /// Epoch ranges only: exact whole-grid horizons (line sweep, every layer; or --horizons
    /// FILE), then every epoch at every pixel with the pixel's own Sun and Earth directions.
    Horizons,
    /// One light: `combined`. Epoch ranges: `horizons` from 1,000 epochs on (or with
    /// --horizons FILE), `combined` below (measured break-even, docs/PERFORMANCE.md); on the GPU
    /// its DP sweep.
    Auto,
}

impl EngineArg {
    /// The engine, or `None` for `auto` (the product chooses).
    fn kind(self) -> Option<penumbra::map::MapEngineKind> {
        use penumbra::map::MapEngineKind;
        use penumbra::shadow::Engine;
        Some(match self {
            EngineArg::Brute => MapEngineKind::Direct(Engine::Brute),
            EngineArg::Smap => MapEngineKind::Direct(Engine::Smap),
            EngineArg::Dp => MapEngineKind::Direct(Engine::Dp),
            EngineArg::Combined => MapEngineKind::Direct(Engine::Combined),
            EngineArg::Fourier => MapEngineKind::Fourier,
            EngineArg::Horizons => MapEngineKind::Horizons,
            EngineArg::Auto => return None,
        })
    }
}

/// Arguments of `penumbra map`.
#[derive(Debug, Clone, Args)]
pub struct MapArgs {
    /// Terrain: DEM layers or the synthetic DEM.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// Observer height above the ground, metres.
    #[arg(long, default_value_t = penumbra::DEFAULT_OBSERVER_HEIGHT_M, allow_hyphen_values = true)]
    pub observer_height_m: f64,
    /// Shadow engine.
    #[arg(long, value_enum, default_value_t = EngineArg::Auto)]
    pub engine: EngineArg,
    /// Epoch(s), UTC: --utc for one light, --start/--stop/--step for statistics over a range.
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// The Sun's direction as a MOON_ME vector x,y,z (any length > 0) instead of an epoch.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, conflicts_with_all = ["utc", "start", "sun_az_deg"])]
    pub sun_dir_body: Option<String>,
    /// The Sun's azimuth at the map centre, degrees clockwise from north (with --sun-el-deg).
    #[arg(long, allow_hyphen_values = true, requires = "sun_el_deg", conflicts_with_all = ["utc", "start"])]
    pub sun_az_deg: Option<f64>,
    /// The Sun's elevation at the map centre, degrees.
    #[arg(long, allow_hyphen_values = true, requires = "sun_az_deg")]
    pub sun_el_deg: Option<f64>,
    /// Angular radius of the Sun's disc for an explicit direction, degrees (epochs use the real
    /// radius).
    #[arg(long, default_value_t = 0.2666)]
    pub sun_radius_deg: f64,
    /// One light: write the Sun's visible fraction (float32 GeoTIFF, NaN = nodata).
    #[arg(long, value_name = "FILE")]
    pub out_fraction: Option<PathBuf>,
    /// One light: write the hard mask of the disc centre (uint8 GeoTIFF: 1 lit, 0 shadow, 255 nodata).
    #[arg(long, value_name = "FILE")]
    pub out_mask: Option<PathBuf>,
    /// One epoch: write the Earth's visible fraction (float32 GeoTIFF).
    #[arg(long, value_name = "FILE", requires = "utc")]
    pub out_earth_fraction: Option<PathBuf>,
    /// Epoch range: output folder for the statistics GeoTIFFs and PNG previews.
    #[arg(long, value_name = "DIR", requires = "start")]
    pub out_dir: Option<PathBuf>,
    /// Epoch range: carry on an unfinished (killed) map in `--out-dir` with the same arguments:
    /// the horizons engine keeps finished blocks of rows, and the maps are the same bytes as an
    /// uninterrupted run's.
    #[arg(long, requires = "out_dir")]
    pub resume: bool,
    /// Epoch range: compute shard I of N only (0 <= I < N; a block of rows of the finest layer,
    /// horizons engine) and write a partial (shard.json + shard.pnbstat) into --out-dir;
    /// `penumbra merge` combines the N partials into this command's maps (docs/SCALING.md).
    #[arg(long, value_name = "I/N", value_parser = penumbra::products::shard::Shard::parse, requires = "out_dir")]
    pub shard: Option<penumbra::products::shard::Shard>,
    /// Compute backend: `gpu` (DP max-mipmap soft shadows of the discs for sweeps and one-light
    /// maps whatever `--engine` says, except `fourier` one-light maps: horizon map built and
    /// evaluated on the GPU), `cpu` (the engine of `--engine`) or `auto` (the GPU when a hardware
    /// adapter exists, else the CPU with one warning line).
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    /// GPU maps and sweeps: compute in 2-D tiles of this many cells per side (≥ 2) instead of
    /// choosing automatically (tiles of 2048 only when the grid or its mipmap exceed one storage
    /// binding or 4 GiB; docs/gpu.md, "Large grids").
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(2..))]
    pub gpu_tile_cells: Option<u32>,
    /// Where the rays start: `pixels` (default) = at each DEM pixel's own surface point (the
    /// same point as a `series` site at the pixel centre), `cells` = at the cells of the
    /// resampled model grid, resampled back onto the DEM grid. On the GPU the Fourier engine and
    /// grids that need 2-D tiles always use `cells` (with a warning for the tiles).
    #[arg(long, value_enum)]
    pub observers: Option<ObserversArg>,
    /// `--engine horizons`: read the whole-grid horizons from this GeoTIFF (written by
    /// `penumbra horizon-map sweep` for the same finest layer and observer height) instead of
    /// sweeping them in memory.
    #[arg(long, value_name = "FILE")]
    pub horizons: Option<PathBuf>,
    /// `--engine horizons` without --horizons: requested azimuths of the line sweep (uniform in
    /// grid azimuth; each served by the nearest exact grid direction).
    #[arg(long, default_value_t = penumbra::horizon::sweep::DEFAULT_SWEEP_AZIMUTHS as u32, value_parser = clap::value_parser!(u32).range(4..=100_000))]
    pub azimuths: u32,
    /// `--engine horizons` without --horizons: largest step component (cells) of a sweep
    /// direction, 1 … 64; the work grows with it, the azimuth gaps near the grid axes shrink.
    #[arg(long, default_value_t = penumbra::horizon::sweep::DEFAULT_MAX_STEP, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub max_step: u32,
    /// `--engine horizons`: limb darkening of the Sun's disc in the mean visible fraction and
    /// the irradiance (the per-epoch engines use a uniform disc).
    #[arg(long, value_enum, default_value_t = super::series::LimbLawArg::Eddington)]
    pub limb_darkening: super::series::LimbLawArg,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
}

/// Parses `x,y,z` into a non-zero finite vector.
fn parse_vector3(text: &str) -> anyhow::Result<nalgebra::Vector3<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--sun-dir-body '{text}': expected three numbers X,Y,Z"))?;
    if v.len() != 3 {
        anyhow::bail!("--sun-dir-body '{text}': expected three numbers X,Y,Z");
    }
    let v = nalgebra::Vector3::new(v[0], v[1], v[2]);
    if !v.iter().all(|c| c.is_finite()) || v.norm() == 0.0 {
        anyhow::bail!("--sun-dir-body '{text}': the direction must be finite and non-zero");
    }
    Ok(v)
}

/// Runs `penumbra map`.
pub fn run(args: &MapArgs) -> anyhow::Result<()> {
    penumbra::products::map::run(&MapRequest {
        terrain: args.terrain.source(),
        observer_height_m: args.observer_height_m,
        engine: args.engine.kind(),
        epochs: args.epochs.spec()?,
        sun_dir_in_moon_me: args
            .sun_dir_body
            .as_deref()
            .map(parse_vector3)
            .transpose()?,
        sun_az_el_deg: args
            .sun_az_deg
            .map(|az| (az, args.sun_el_deg.unwrap_or(0.0))),
        sun_radius_deg: args.sun_radius_deg,
        out_fraction: args.out_fraction.clone(),
        out_mask: args.out_mask.clone(),
        out_earth_fraction: args.out_earth_fraction.clone(),
        out_dir: args.out_dir.clone(),
        resume: args.resume,
        shard: args.shard,
        backend: args.backend.into(),
        gpu_tile_cells: args.gpu_tile_cells,
        observers: args.observers.map(Into::into),
        horizons: match &args.horizons {
            Some(path) => penumbra::compute::sweep::HorizonsFrom::File(path.clone()),
            None => penumbra::compute::sweep::HorizonsFrom::Sweep {
                azimuths: args.azimuths as usize,
                max_step: args.max_step,
            },
        },
        limb: args.limb_darkening.into(),
        abcorr: super::abcorr(&args.abcorr)?,
        kernels: args.kernels.source(),
    })
}

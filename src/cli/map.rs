//! `penumbra map`.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::{Args, ValueEnum};
use penumbra::model::{MapEngineKind, ObserverHeight, ObserverPlacement};
use penumbra::products::map::{
    Light, MapRequest, MapSettings, MapTask, OneLightFiles, RangeFiles, shard::Shard,
};

use super::{BackendArg, EpochArgs, KernelArgs, TerrainArgs};

/// Where a map's rays start (`map --observers`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObserversArg {
    /// At each DEM pixel's own surface point.
    Pixels,
    /// At the model grid's cells, resampled back onto the DEM grid.
    Cells,
}

impl From<ObserversArg> for ObserverPlacement {
    fn from(o: ObserversArg) -> Self {
        match o {
            ObserversArg::Pixels => ObserverPlacement::Pixels,
            ObserversArg::Cells => ObserverPlacement::Cells,
        }
    }
}

/// Map engine on the command line (the names of [`MapEngineKind::parse_choice`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EngineArg {
    /// SMap hard shadows at the disc limbs + DP maximum-mipmap soft shadows in the penumbra only
    /// (the design's combination; CPU).
    Combined,
    /// DP maximum-mipmap soft shadows everywhere (Jung, Schrempp and Son: dynamic programming
    /// and maximum mipmaps; CPU or GPU).
    Dp,
    /// Fourier-compressed horizon maps (Fritsch et al.): per-cell horizons at 64 azimuths, 16
    /// complex DFT coefficients in f16, built once; each light is then a cheap evaluation.
    Fourier,
    /// Epoch ranges only: exact whole-grid horizons (line sweep, every layer; or --horizons
    /// FILE), then every epoch at every pixel with the pixel's own Sun and Earth directions.
    Horizons,
    /// One light: `dp` on a GPU, else `combined`. Epoch ranges: `horizons` from 1,000 epochs on
    /// (or with --horizons FILE), else `dp` on a GPU, `combined` on the CPU.
    Auto,
}

impl EngineArg {
    /// The engine, or `None` for `auto` (the product chooses).
    fn kind(self) -> Option<MapEngineKind> {
        let name = self
            .to_possible_value()
            .map(|v| v.get_name().to_string())
            .unwrap_or_default();
        MapEngineKind::parse_choice(&name).unwrap_or(None)
    }
}

/// Arguments of `penumbra map`.
#[derive(Debug, Clone, Args)]
pub struct MapArgs {
    /// Terrain: DEM layers or the synthetic DEM.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// Observer height above the ground, metres (0 … 100000).
    #[arg(long, value_name = "M", default_value_t = ObserverHeight::DEFAULT, allow_hyphen_values = true)]
    pub observer_height_m: ObserverHeight,
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
    #[arg(long, value_name = "I/N", value_parser = Shard::parse, requires = "out_dir")]
    pub shard: Option<Shard>,
    /// Where the engine runs: `cpu`, `gpu` (dp, fourier one-light maps and the horizons engine
    /// have GPU kernels; combined and fourier ranges run on the CPU with one line saying so) or
    /// `auto` (the GPU when a hardware adapter exists, else the CPU with one warning line).
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
    /// Ground stations of the direct-to-Earth maps (dte_pct, longest_dte_blackout_h; epoch
    /// ranges, the horizons engine): none (default), dsn (DSS-14, DSS-43, DSS-63) or a CSV file
    /// with a header naming name, lat_deg, lon_deg, height_m (geodetic, WGS84) and optionally
    /// mask_deg.
    #[arg(long, value_name = "none|dsn|FILE", default_value = "none")]
    pub stations: String,
    /// Elevation mask of the DSN stations and of file rows without their own, degrees (0 … <90).
    #[arg(long, value_name = "DEG", default_value_t = penumbra::comms::DEFAULT_MASK_DEG, allow_hyphen_values = true)]
    pub station_mask_deg: f64,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Solar panel and load (epoch ranges, the horizons engine): mean_power_w.tif and
    /// required_battery_wh.tif.
    #[command(flatten)]
    pub power: super::power::PowerArgs,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
}

/// Parses `x,y,z` into three numbers.
fn parse_vector3(text: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--sun-dir-body '{text}': expected three numbers X,Y,Z"))?;
    <[f64; 3]>::try_from(v)
        .map_err(|_| anyhow::anyhow!("--sun-dir-body '{text}': expected three numbers X,Y,Z"))
}

impl MapArgs {
    /// What the flags ask for: one light (`--utc`, `--sun-dir-body`, `--sun-az-deg`) and its
    /// files, or an epoch range and its folder.
    fn task(&self) -> anyhow::Result<MapTask> {
        let epochs = self.epochs.spec()?;
        if let Some(penumbra::model::Epochs::Range(range)) = epochs {
            let out_dir = self.out_dir.clone().ok_or_else(|| {
                anyhow::anyhow!("an epoch range needs --out-dir DIR for the statistics maps")
            })?;
            return Ok(MapTask::Range {
                epochs: range,
                files: RangeFiles {
                    out_dir,
                    resume: self.resume,
                    shard: self.shard,
                },
            });
        }
        if self.shard.is_some() {
            anyhow::bail!(
                "--shard makes one part of a map over an epoch range: give --start/--stop/--step \
                 and --out-dir"
            );
        }
        let radius_deg = self.sun_radius_deg;
        let light = match (epochs, &self.sun_dir_body, self.sun_az_deg) {
            (Some(penumbra::model::Epochs::One(e)), _, _) => Light::Epoch(e),
            (_, Some(text), _) => Light::DirectionInMoonMe {
                dir: parse_vector3(text)?,
                radius_deg,
            }
            .checked()
            .context("--sun-dir-body, --sun-radius-deg")?,
            (_, None, Some(az_deg)) => Light::AzElAtCentre {
                az_deg,
                el_deg: self.sun_el_deg.unwrap_or(0.0),
                radius_deg,
            }
            .checked()
            .context("--sun-az-deg, --sun-el-deg, --sun-radius-deg")?,
            _ => anyhow::bail!(
                "give the light: --utc T, --sun-dir-body X,Y,Z or --sun-az-deg/--sun-el-deg"
            ),
        };
        MapTask::one_light(
            light,
            OneLightFiles {
                fraction: self.out_fraction.clone(),
                mask: self.out_mask.clone(),
                earth_fraction: self.out_earth_fraction.clone(),
            },
        )
    }

    /// How the map is computed.
    fn settings(&self) -> anyhow::Result<MapSettings> {
        if self.power.battery_wh.is_some() || self.power.battery_start_pct.is_some() {
            anyhow::bail!(
                "--battery-wh, --battery-start-pct: a map gives the smallest battery that survives \
                 (required_battery_wh.tif), not the charge of a given one (use a series)"
            );
        }
        Ok(MapSettings {
            observer_height: self.observer_height_m,
            engine: self.engine.kind(),
            backend: self.backend.into(),
            gpu_tile_cells: self.gpu_tile_cells,
            observers: self.observers.map(Into::into),
            horizons: match &self.horizons {
                Some(path) => penumbra::compute::range::HorizonsFrom::File(path.clone()),
                None => penumbra::compute::range::HorizonsFrom::Sweep {
                    azimuths: self.azimuths as usize,
                    max_step: self.max_step,
                },
            },
            limb: self.limb_darkening.into(),
            stations: penumbra::comms::Stations::parse(&self.stations),
            station_mask_deg: self.station_mask_deg,
            power: self.power.config()?,
        })
    }
}

/// Runs `penumbra map`.
pub fn run(args: &MapArgs) -> anyhow::Result<()> {
    let request = MapRequest {
        terrain: args.terrain.source(),
        kernels: args.kernels.source(),
        abcorr: super::abcorr(&args.abcorr)?,
        settings: args.settings()?,
        task: args.task()?,
    };
    penumbra::products::map::run(&request)
}

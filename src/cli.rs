//! Command-line interface (clap derive). Every argument documents its unit.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// penumbra: sunlight and earthlight at the lunar poles.
#[derive(Debug, Parser)]
#[command(name = "penumbra", version, about, long_about = None)]
pub struct Cli {
    /// The subcommand to run.
    #[command(subcommand)]
    pub command: Command,
}

/// penumbra's subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Sun and Earth azimuth, elevation, range and angular radius seen from a site.
    Ephem(EphemArgs),
    /// List the SPICE kernels that are loaded: files, bodies, frames and time coverage.
    Kernels(KernelArgs),
    /// Run a scenario file (scenarios/*.toml).
    Run(RunArgs),
    /// Terrain horizon (elevation vs azimuth) seen by an observer above a site.
    Horizon(HorizonArgs),
    /// Illumination maps: one light (Sun fraction, hard mask, Earth fraction) or statistics over
    /// an epoch range (average illumination, longest darkness, PSR, Earth visibility).
    Map(MapArgs),
    /// Per-site illumination time series: Sun and Earth visible fractions, irradiance,
    /// statistics and plots.
    Series(SeriesArgs),
    /// Inspect or generate DEMs (GeoTIFF).
    Dem {
        /// The DEM action.
        #[command(subcommand)]
        command: DemCommand,
    },
    /// List the GPU adapters wgpu finds (honours WGPU_BACKEND): name, backend, device type,
    /// driver and the compute limits that bound penumbra's kernels.
    GpuInfo(GpuInfoArgs),
    /// Render the terrain seen from a camera at one epoch (CPU reference renderer): Lambert
    /// sunlight + earthshine with soft shadows, 8-bit sRGB PNG.
    Render(RenderArgs),
    /// Fourier-compressed horizon maps (paper 001): build one from a DEM, or describe one.
    HorizonMap {
        /// The horizon-map action.
        #[command(subcommand)]
        command: HorizonMapCommand,
    },
}

/// Output formats for tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Comma-separated values with a header row.
    Csv,
    /// A JSON document.
    Json,
}

/// Where the SPICE kernels come from.
#[derive(Debug, Clone, Args)]
pub struct KernelArgs {
    /// Folder of SPICE kernels (.bsp, .bpc, .tf, .tls). Default: $PENUMBRA_KERNELS, ./kernels,
    /// then the kernels/ folder of the source tree.
    #[arg(long, value_name = "DIR")]
    pub kernels: Option<PathBuf>,
}

/// DEM layers or the synthetic DEM.
#[derive(Debug, Clone, Args)]
pub struct TerrainArgs {
    /// DEM GeoTIFF layer; repeat for several layers (the finest with data is used at each point;
    /// maps are on the finest layer's grid).
    #[arg(
        long = "dem",
        value_name = "FILE",
        required_unless_present = "synthetic"
    )]
    pub dem: Vec<PathBuf>,
    /// Use penumbra's synthetic south-polar DEM (400 x 400 px at 100 m, seed 1) instead of --dem.
    #[arg(long, conflicts_with = "dem")]
    pub synthetic: bool,
}

/// An epoch or a range of epochs (UTC).
#[derive(Debug, Clone, Args)]
pub struct EpochArgs {
    /// A single epoch, UTC (e.g. 2024-01-03T00:00:00).
    #[arg(long, value_name = "UTC", conflicts_with_all = ["start", "stop", "step"])]
    pub utc: Option<String>,
    /// First epoch of a range, UTC.
    #[arg(long, value_name = "UTC", requires_all = ["stop", "step"])]
    pub start: Option<String>,
    /// Last epoch of a range, UTC (inclusive when it falls on the step grid).
    #[arg(long, value_name = "UTC", requires_all = ["start", "step"])]
    pub stop: Option<String>,
    /// Step of the range: a number and a unit s, m, h or d (e.g. 10m, 1h, 6h, 1d).
    #[arg(long, value_name = "STEP", requires_all = ["start", "stop"])]
    pub step: Option<String>,
}

/// Arguments of `penumbra ephem`.
#[derive(Debug, Clone, Args)]
pub struct EphemArgs {
    /// Site planetocentric latitude, degrees (-90..90).
    #[arg(long, allow_hyphen_values = true)]
    pub lat_deg: f64,
    /// Site east longitude, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub lon_deg: f64,
    /// Site height above the 1737.4 km reference sphere, metres.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub height_m: f64,
    /// Epoch(s).
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// Aberration correction: lt+s (light time + stellar aberration) or none (geometric).
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Csv)]
    pub format: Format,
    /// Output file (default: standard output). Written atomically.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// Arguments of `penumbra run`.
#[derive(Debug, Clone, Args)]
pub struct RunArgs {
    /// The scenario file (TOML).
    pub scenario: PathBuf,
    /// Override the scenario's output folder.
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    /// Kernels (overrides the scenario's `kernels`).
    #[command(flatten)]
    pub kernels: KernelArgs,
}

/// `penumbra dem ...` actions.
#[derive(Debug, Subcommand)]
pub enum DemCommand {
    /// Print a DEM's size, pixel size, CRS, bounds (x/y in m, lat/lon in deg), height range and
    /// nodata count.
    Info {
        /// The DEM file (GeoTIFF).
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value_t = InfoFormat::Text)]
        format: InfoFormat,
        /// Also print the bilinear height (m) at a point `LAT,LON` (planetocentric latitude and
        /// east longitude, deg); repeatable. A point outside the DEM is an error.
        #[arg(long = "at", value_name = "LAT,LON", allow_hyphen_values = true)]
        at: Vec<String>,
    },
    /// Write the deterministic synthetic south-polar DEM (craters, a ridge, a massif, fractal
    /// roughness) as a float32 GeoTIFF.
    Synth {
        /// Grid size, pixels (square).
        #[arg(long, default_value_t = 400)]
        size: usize,
        /// Pixel size, metres.
        #[arg(long = "px-m", default_value_t = 100.0)]
        px_m: f64,
        /// Seed of the pseudo-random generator.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output GeoTIFF path.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Output format of `dem info`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InfoFormat {
    /// `key: value` lines.
    Text,
    /// One JSON object.
    Json,
}

/// Arguments of `penumbra horizon`.
#[derive(Debug, Clone, Args)]
pub struct HorizonArgs {
    /// DEM GeoTIFF layer; repeat for several layers (the finest with data is used at each point).
    #[arg(long = "dem", value_name = "FILE", required = true)]
    pub dem: Vec<PathBuf>,
    /// Site planetocentric latitude, degrees.
    #[arg(long, allow_negative_numbers = true)]
    pub lat_deg: f64,
    /// Site east longitude, degrees.
    #[arg(long, allow_negative_numbers = true)]
    pub lon_deg: f64,
    /// Observer height above the terrain surface (radial), metres.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub observer_height_m: f64,
    /// Azimuth step, degrees (must divide 360).
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    pub az_step_deg: f64,
    /// Scan method: `exact` (every cell crossed) or `fast` (conservative skipping, <= 0.002 deg).
    #[arg(long, value_enum, default_value_t = HorizonMethodArg::Fast)]
    pub method: HorizonMethodArg,
    /// Output format.
    #[arg(long, value_enum, default_value_t = HorizonFormat::Csv)]
    pub format: HorizonFormat,
    /// Output file (written atomically); stdout when absent.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Compute backend: `gpu` runs the GPU horizon scan (sampled like `--method exact`;
    /// `--method` is then ignored), `auto` the GPU when a hardware adapter exists else the CPU.
    #[arg(long, value_enum, default_value_t = crate::gpu::Backend::Cpu)]
    pub backend: crate::gpu::Backend,
}

/// Horizon scan method on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HorizonMethodArg {
    /// Conservative block-maximum skipping.
    Fast,
    /// The reference scan.
    Exact,
}

/// Output format of `penumbra horizon`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HorizonFormat {
    /// `az_deg,horizon_el_deg,distance_m` rows.
    Csv,
    /// One JSON object with the site and the arrays.
    Json,
}

/// Arguments of `penumbra series`.
#[derive(Debug, Clone, Args)]
pub struct SeriesArgs {
    /// Terrain: DEM layers or the synthetic DEM.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// A site as NAME,LAT_DEG,LON_DEG or NAME,LAT_DEG,LON_DEG,HEIGHT_ABOVE_GROUND_M
    /// (planetocentric latitude, east longitude, degrees; height in metres); repeatable.
    #[arg(long, value_name = "SITE", allow_hyphen_values = true)]
    pub site: Vec<String>,
    /// Latitude of a single site named "site", degrees (alternative to --site).
    #[arg(
        long,
        allow_hyphen_values = true,
        requires = "lon_deg",
        conflicts_with = "site"
    )]
    pub lat_deg: Option<f64>,
    /// East longitude of a single site named "site", degrees.
    #[arg(long, allow_hyphen_values = true, requires = "lat_deg")]
    pub lon_deg: Option<f64>,
    /// Observer height above the ground, metres (for sites that do not give their own).
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub observer_height_m: f64,
    /// Epoch(s).
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Disc integration: exact (strip integral, default), segment (paper 001 circular segment)
    /// or middle-value.
    #[arg(long, value_enum, default_value_t = DiscMethodArg::Exact)]
    pub disc_method: DiscMethodArg,
    /// Solar limb darkening used to flux-weight the Sun's visible fraction.
    #[arg(long, value_enum, default_value_t = crate::series::LimbLaw::Eddington)]
    pub limb_darkening: crate::series::LimbLaw,
    /// Horizon azimuth step, degrees (must divide 360).
    #[arg(long, default_value_t = 0.25)]
    pub az_step_deg: f64,
    /// Horizon scan method.
    #[arg(long, value_enum, default_value_t = HorizonMethodArg::Fast)]
    pub horizon_method: HorizonMethodArg,
    /// Do not draw PNG plots.
    #[arg(long)]
    pub no_plots: bool,
    /// Do not write the per-epoch series.csv files (statistics only).
    #[arg(long)]
    pub no_csv: bool,
    /// Compute backend: with `--engine horizon`, of the horizons (`gpu`: GPU horizon scan,
    /// sampled like the exact method; `--horizon-method` is then ignored); with
    /// `--engine smap-dp`, of the per-site DP searches (profiles and every epoch's Sun and Earth).
    /// `auto`: GPU when a hardware adapter exists; `cpu`.
    #[arg(long, value_enum, default_value_t = crate::gpu::Backend::Cpu)]
    pub backend: crate::gpu::Backend,
    /// Engine of the visible fractions: horizon (per-site horizons from every DEM layer) or
    /// smap-dp (the map pipeline's model grid + DP search at each site; finest layer only;
    /// CPU or GPU, `--backend`).
    #[arg(long, value_enum, default_value_t = crate::series::SeriesEngine::Horizon)]
    pub engine: crate::series::SeriesEngine,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
    /// Output folder (created if needed): one sub-folder per site, plus stats.json and run.json.
    #[arg(long, value_name = "DIR")]
    pub out_dir: PathBuf,
}

/// Disc integration method on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DiscMethodArg {
    /// Exact strip integral.
    Exact,
    /// Circular segment under the line through the disc's edge azimuths (paper 001).
    Segment,
    /// Horizontal chord at the centre azimuth's horizon (Max 1988).
    MiddleValue,
}

impl From<DiscMethodArg> for crate::illum::DiscMethod {
    fn from(m: DiscMethodArg) -> Self {
        match m {
            DiscMethodArg::Exact => crate::illum::DiscMethod::Exact,
            DiscMethodArg::Segment => crate::illum::DiscMethod::Segment,
            DiscMethodArg::MiddleValue => crate::illum::DiscMethod::MiddleValue,
        }
    }
}

impl From<HorizonMethodArg> for crate::horizon::HorizonMethod {
    fn from(m: HorizonMethodArg) -> Self {
        match m {
            HorizonMethodArg::Fast => crate::horizon::HorizonMethod::Fast,
            HorizonMethodArg::Exact => crate::horizon::HorizonMethod::Exact,
        }
    }
}

/// Where a map's rays start (`map --observers`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObserversArg {
    /// At each DEM pixel's own surface point.
    Pixels,
    /// At the model grid's cells, resampled back onto the DEM grid.
    Cells,
}

impl From<ObserversArg> for crate::map::ObserverPlacement {
    fn from(o: ObserversArg) -> Self {
        match o {
            ObserversArg::Pixels => crate::map::ObserverPlacement::Pixels,
            ObserversArg::Cells => crate::map::ObserverPlacement::Cells,
        }
    }
}

/// Shadow engine on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EngineArg {
    /// Brute-force ray march (the reference; slow).
    Brute,
    /// SMap hard shadows (paper 004); soft fractions via SMap + DP.
    Smap,
    /// DP maximum-mipmap soft shadows everywhere (papers 000/003).
    Dp,
    /// SMap at the disc limbs + DP in the penumbra only (the design's combination).
    Combined,
    /// Fourier-compressed horizon maps (paper 001): per-cell horizons at 64 azimuths, 16 complex
    /// DFT coefficients in f16, built once; each light is then a cheap evaluation.
    Fourier,
    /// The best available: `combined`.
    Auto,
}

impl From<EngineArg> for crate::map::MapEngineKind {
    fn from(e: EngineArg) -> Self {
        use crate::map::MapEngineKind;
        use crate::shadow::Engine;
        match e {
            EngineArg::Brute => MapEngineKind::Direct(Engine::Brute),
            EngineArg::Smap => MapEngineKind::Direct(Engine::Smap),
            EngineArg::Dp => MapEngineKind::Direct(Engine::Dp),
            EngineArg::Combined | EngineArg::Auto => MapEngineKind::Direct(Engine::Combined),
            EngineArg::Fourier => MapEngineKind::Fourier,
        }
    }
}

/// Surface BRDF of `penumbra render`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BrdfArg {
    /// Hapke (2012) with the lunar parameters of Sato et al. (2014), 643 nm.
    Hapke,
    /// Lambert with `--albedo`.
    Lambert,
}

/// Camera kind of `penumbra render`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CameraArg {
    /// At a site: --lat-deg/--lon-deg, --height-m above the ground, looking along
    /// --look-az-deg/--look-el-deg.
    Site,
    /// In orbit: --lat-deg/--lon-deg, --altitude-km above the 1737.4 km sphere, looking at the
    /// surface point --target-lat-deg/--target-lon-deg (image up towards local north).
    Orbit,
}

/// Arguments of `penumbra render`.
#[derive(Debug, Clone, Args)]
pub struct RenderArgs {
    /// The terrain.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// Camera kind: site (on the ground) or orbit (above the sphere, looking at a target).
    #[arg(long, value_enum, default_value_t = CameraArg::Site)]
    pub camera: CameraArg,
    /// Camera latitude (planetocentric), degrees: the site, or the point below the orbital camera.
    #[arg(long, allow_hyphen_values = true)]
    pub lat_deg: f64,
    /// Camera east longitude, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub lon_deg: f64,
    /// Site camera: height above the ground (DEM), metres.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub height_m: f64,
    /// Site camera: view azimuth, degrees from north clockwise (local frame of the site).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub look_az_deg: f64,
    /// Site camera: view elevation above the local horizontal, degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub look_el_deg: f64,
    /// Orbit camera: altitude above the 1737.4 km reference sphere, kilometres.
    #[arg(long, allow_hyphen_values = true)]
    pub altitude_km: Option<f64>,
    /// Orbit camera: latitude of the surface point looked at, degrees (default: --lat-deg).
    #[arg(long, allow_hyphen_values = true)]
    pub target_lat_deg: Option<f64>,
    /// Orbit camera: east longitude of the surface point looked at, degrees (default: --lon-deg).
    #[arg(long, allow_hyphen_values = true)]
    pub target_lon_deg: Option<f64>,
    /// Horizontal field of view, degrees, in (0, 180).
    #[arg(long, default_value_t = 60.0, allow_hyphen_values = true)]
    pub fov_deg: f64,
    /// Epoch(s), UTC: --utc for one frame, --start/--stop/--step for numbered frames
    /// `<stem>_0000.png`, `<stem>_0001.png`, ...
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// Image width, pixels.
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Surface BRDF.
    #[arg(long, value_enum, default_value_t = BrdfArg::Hapke)]
    pub brdf: BrdfArg,
    /// Lambert albedo (only with --brdf lambert), in [0, 1]; default 0.12.
    #[arg(long)]
    pub albedo: Option<f64>,
    /// Exposure, 1/(W m^-2 sr^-1), applied before the Reinhard curve; default: automatic
    /// (the 99th percentile of the terrain radiance maps to 2).
    #[arg(long)]
    pub exposure: Option<f64>,
    /// Output PNG file (8-bit sRGB).
    #[arg(long, value_name = "FILE.png")]
    pub out: PathBuf,
    /// Also write the terrain radiance, W m^-2 sr^-1, as a 32-bit float TIFF (sky pixels 0;
    /// numbered like --out for a range).
    #[arg(long, value_name = "FILE.tif")]
    pub out_radiance: Option<PathBuf>,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Compute backend of the ray casting and shading: `gpu` (wgpu), `cpu` (rayon) or `auto`
    /// (the GPU when a hardware adapter exists, else the CPU with one warning line). On the GPU
    /// the shadow fractions come from the GPU DP kernel, on the CPU from the CPU engine.
    #[arg(long, value_enum, default_value_t = crate::gpu::Backend::Auto)]
    pub backend: crate::gpu::Backend,
    /// SPICE kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
}

/// Arguments of `penumbra map`.
#[derive(Debug, Clone, Args)]
pub struct MapArgs {
    /// Terrain: DEM layers or the synthetic DEM.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// Observer height above the ground, metres.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
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
    /// Compute backend: `gpu` (DP max-mipmap soft shadows of the discs for sweeps and one-light
    /// maps whatever `--engine` says, except `fourier` one-light maps: horizon map built and
    /// evaluated on the GPU), `cpu` (the engine of `--engine`) or `auto` (the GPU when a hardware
    /// adapter exists, else the CPU with one warning line).
    #[arg(long, value_enum, default_value_t = crate::gpu::Backend::Auto)]
    pub backend: crate::gpu::Backend,
    /// GPU maps and sweeps: compute in 2-D tiles of this many cells per side (≥ 2) instead of
    /// choosing automatically (tiles of 2048 only when the grid or its mipmap exceed one storage
    /// binding or 4 GiB; docs/gpu.md, "Large grids").
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(2..))]
    pub gpu_tile_cells: Option<u32>,
    /// Where the rays start: `pixels` = at each DEM pixel's own surface point (the CPU default;
    /// the same point as a `series` site at the pixel centre), `cells` = at the cells of the
    /// resampled model grid (the GPU's method, resampled back onto the DEM grid). Default: the
    /// backend's own (`pixels` on the CPU, `cells` on the GPU, which has no other).
    #[arg(long, value_enum)]
    pub observers: Option<ObserversArg>,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
}

/// Arguments of `penumbra gpu-info`.
#[derive(Debug, Clone, Args)]
pub struct GpuInfoArgs {
    /// Also resolve this backend choice (as `--backend` of the compute commands does) and print
    /// the result: `auto` falls back to the CPU with one warning, `gpu` fails without an adapter.
    #[arg(long, value_enum, value_name = "BACKEND")]
    pub backend: Option<crate::gpu::Backend>,
}

/// Actions of `penumbra horizon-map`.
#[derive(Debug, Clone, Subcommand)]
pub enum HorizonMapCommand {
    /// Build a Fourier-compressed horizon map (16 f16 complex coefficients per cell) and write
    /// it as a multi-page TIFF.
    Build(HorizonMapBuildArgs),
    /// Describe a horizon-map TIFF: geometry, parameters, mean coefficient amplitudes.
    Info {
        /// The horizon-map TIFF.
        file: PathBuf,
    },
}

/// Arguments of `penumbra horizon-map build`.
#[derive(Debug, Clone, Args)]
pub struct HorizonMapBuildArgs {
    /// The terrain.
    #[command(flatten)]
    pub terrain: TerrainArgs,
    /// Observer height above the ground (radial), metres.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub observer_height_m: f64,
    /// Number of sampled azimuths before the DFT (at least 32).
    #[arg(long, default_value_t = crate::shadow::fourier::DEFAULT_AZIMUTHS)]
    pub azimuths: usize,
    /// Longest horizon ray, cells (default: the grid's rows + columns, i.e. the whole grid).
    #[arg(long)]
    pub max_distance_cells: Option<usize>,
    /// Output TIFF.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Compute backend of the build: `gpu` (shaders/fourier_build.wgsl, f32; the map agrees with
    /// the CPU build within the bounds of docs/gpu.md), `cpu` (the rayon engine, f64) or `auto`
    /// (the GPU when a hardware adapter exists, else the CPU with one warning line).
    #[arg(long, value_enum, default_value_t = crate::gpu::Backend::Auto)]
    pub backend: crate::gpu::Backend,
}

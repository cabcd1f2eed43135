//! `penumbra render`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use penumbra::products::render::{BrdfChoice, CameraKind, CameraSpec, RenderOptions};

use super::{BackendArg, EpochArgs, KernelArgs, TerrainArgs};

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
    /// At a site: --lat-deg/--lon-deg, --observer-height-m above the ground, looking along
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
    /// Where: latitude and longitude.
    #[command(flatten)]
    pub at: super::LatLonArgs,
    /// Site camera: height above the ground (DEM), metres (as `--observer-height-m` of `horizon`
    /// and `map`; `--height-m` is an old alias).
    #[arg(
        long = "observer-height-m",
        alias = "height-m",
        value_name = "M",
        default_value_t = penumbra::model::ObserverHeight::DEFAULT,
        allow_hyphen_values = true
    )]
    pub height_m: penumbra::model::ObserverHeight,
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
    #[arg(long, default_value_t = penumbra::products::render::DEFAULT_FOV_DEG, allow_hyphen_values = true)]
    pub fov_deg: f64,
    /// Epoch(s), UTC: --utc for one frame, --start/--stop/--step for numbered frames
    /// `<stem>_0000.png`, `<stem>_0001.png`, ...
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// Image width, pixels (`--width` is an old alias).
    #[arg(long = "width-px", alias = "width", default_value_t = penumbra::products::render::DEFAULT_WIDTH_PX)]
    pub width: u32,
    /// Image height, pixels (`--height` is an old alias).
    #[arg(long = "height-px", alias = "height", default_value_t = penumbra::products::render::DEFAULT_HEIGHT_PX)]
    pub height: u32,
    /// Surface BRDF.
    #[arg(long, value_enum, default_value_t = BrdfArg::Hapke)]
    pub brdf: BrdfArg,
    /// Lambert albedo (only with --brdf lambert), in [0, 1]; default 0.12.
    #[arg(long)]
    pub albedo: Option<f64>,
    /// Exposure: `sequence` (default: one exposure for all frames of the run, so brightness is
    /// comparable between frames: the brightest frame's 99th-percentile lit terrain radiance maps
    /// near white, never brighter than level ground under a 1 deg Sun, so earthshine-only scenes
    /// stay dark), `auto` (each frame its own), or a number in 1/(W m^-2 sr^-1).
    #[arg(long, default_value = "sequence", value_name = "sequence|auto|NUMBER")]
    pub exposure: penumbra::render::Exposure,
    /// Output PNG file (8-bit sRGB).
    #[arg(long, value_name = "FILE.png")]
    pub out: PathBuf,
    /// Also write the terrain radiance, W m^-2 sr^-1, as a 32-bit float TIFF (sky pixels NaN,
    /// declared as nodata; the frame's epoch and camera as metadata; numbered like --out for a
    /// range).
    #[arg(long, value_name = "FILE.tif")]
    pub out_radiance: Option<PathBuf>,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Compute backend of the ray casting and shading: `gpu` (wgpu), `cpu` (rayon) or `auto`
    /// (the GPU when a hardware adapter exists, else the CPU with one warning line). On the GPU
    /// the shadow fractions come from the GPU DP kernel, on the CPU from the CPU engine.
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    /// Keep the frames bare: no epoch, Sun/Earth elevation and azimuth, camera or azimuth ticks
    /// drawn into them (they stay in the PNG's text chunks).
    #[arg(long)]
    pub no_annotation: bool,
    /// SPICE kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
}

/// Runs `penumbra render`.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let options = RenderOptions {
        terrain: args.terrain.source(),
        width: args.width,
        height: args.height,
        brdf: match args.brdf {
            BrdfArg::Hapke => BrdfChoice::Hapke,
            BrdfArg::Lambert => BrdfChoice::Lambert,
        },
        albedo: args.albedo,
        exposure: args.exposure,
        out: args.out.clone(),
        out_radiance: args.out_radiance.clone(),
        abcorr: super::abcorr(&args.abcorr)?,
        backend: args.backend.into(),
        kernels: args.kernels.source(),
        annotate: !args.no_annotation,
    };
    let camera = CameraSpec {
        kind: match args.camera {
            CameraArg::Site => CameraKind::Site,
            CameraArg::Orbit => CameraKind::Orbit,
        },
        lat_deg: args.at.lat_deg,
        lon_deg: args.at.lon_deg,
        height_m: args.height_m.m(),
        look_az_deg: args.look_az_deg,
        look_el_deg: args.look_el_deg,
        altitude_km: args.altitude_km,
        target_lat_deg: args.target_lat_deg,
        target_lon_deg: args.target_lon_deg,
        fov_deg: args.fov_deg,
    };
    penumbra::products::render::run(&options, &camera, &args.epochs.required()?)
}

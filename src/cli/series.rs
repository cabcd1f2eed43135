//! `penumbra series`.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use penumbra::illum::LimbLaw;
use penumbra::model::{ObserverHeight, Site};
use penumbra::products::series::{SeriesConfig, SeriesEngine, SeriesRequest};

use super::horizon::HorizonMethodArg;
use super::{BackendArg, EpochArgs, KernelArgs, TerrainArgs};

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
    /// Sites from a file: CSV with a header naming name, lat_deg, lon_deg and optionally
    /// height_m (above the ground, metres), or GeoJSON Points [lon_deg, lat_deg] with
    /// properties.name and optionally properties.height_m. Adds to --site.
    #[arg(long, value_name = "FILE")]
    pub sites: Option<PathBuf>,
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
    /// Observer height above the ground, metres (0 … 100000; for sites that do not give their
    /// own).
    #[arg(long, value_name = "M", default_value_t = ObserverHeight::DEFAULT, allow_hyphen_values = true)]
    pub observer_height_m: ObserverHeight,
    /// Epoch(s).
    #[command(flatten)]
    pub epochs: EpochArgs,
    /// Aberration correction: lt+s or none.
    #[arg(long, default_value = "lt+s")]
    pub abcorr: String,
    /// Disc integration: exact (strip integral, default), segment (the circular segment of
    /// Fritsch et al.) or middle-value.
    #[arg(long, value_enum, default_value_t = DiscMethodArg::Exact)]
    pub disc_method: DiscMethodArg,
    /// Solar limb darkening used to flux-weight the Sun's visible fraction.
    #[arg(long, value_enum, default_value_t = LimbLawArg::Eddington)]
    pub limb_darkening: LimbLawArg,
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
    /// `auto` (default, as in every command): the CPU scans for `--engine horizon`, the GPU for
    /// `--engine smap-dp` when a hardware adapter exists (else the CPU, with one warning line).
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    /// Engine of the visible fractions: horizon (per-site horizons from every DEM layer) or
    /// smap-dp (the map pipeline's model grid of every layer + DP search at each site; CPU or
    /// GPU, `--backend`).
    #[arg(long, value_enum, default_value_t = SeriesEngineArg::Horizon)]
    pub engine: SeriesEngineArg,
    /// Ground stations of the link to Earth: dsn (DSS-14, DSS-43, DSS-63), none, or a CSV file
    /// with a header naming name, lat_deg, lon_deg, height_m (geodetic, WGS84) and optionally
    /// mask_deg. Adds the dte, station_el_deg and station columns to series.csv, DTE statistics
    /// to stats.json and dte_windows.csv / dte_windows.ics per site.
    #[arg(long, value_name = "dsn|none|FILE", default_value = "dsn")]
    pub stations: String,
    /// Elevation mask of the DSN stations and of file rows without their own, degrees (0 … <90).
    #[arg(long, value_name = "DEG", default_value_t = penumbra::comms::DEFAULT_MASK_DEG, allow_hyphen_values = true)]
    pub station_mask_deg: f64,
    /// A relay orbiter as a link target: NAME=NAIF_ID of a body in a --relay-spk file
    /// (repeatable). Adds relay_visible, relay_el_deg and relay to series.csv and relay
    /// statistics to stats.json; a relay is visible above the site's terrain horizon.
    #[arg(long = "relay", value_name = "NAME=NAIF_ID", value_parser = parse_relay, allow_hyphen_values = true)]
    pub relays: Vec<penumbra::comms::Relay>,
    /// An SPK file holding the relays (repeatable).
    #[arg(long = "relay-spk", value_name = "FILE")]
    pub relay_spks: Vec<PathBuf>,
    /// Slant-range limit of a relay link, km (none by default).
    #[arg(long, value_name = "KM", allow_hyphen_values = true)]
    pub relay_max_range_km: Option<f64>,
    /// Solar panel, load and battery.
    #[command(flatten)]
    pub power: super::power::PowerArgs,
    /// Radius of each site's neighbourhood, metres (0 … 20000; 0: none; default 3 pixels of the
    /// finest layer under the site for runs of up to 10 sites, none beyond): the key statistics at every pixel centre within it, their
    /// spread, the best spot (stats.json, <site>/neighbourhood.csv) and a caution when the
    /// value at the typed point is that sensitive (docs/sites.md).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub neighbourhood_m: Option<f64>,
    /// Kernels.
    #[command(flatten)]
    pub kernels: KernelArgs,
    /// Output folder (created if needed): one sub-folder per site, plus stats.json and run.json.
    #[arg(long, value_name = "DIR")]
    pub out_dir: PathBuf,
}

fn parse_relay(text: &str) -> Result<penumbra::comms::Relay, String> {
    penumbra::comms::Relay::parse(text).map_err(|e| e.to_string())
}

/// Disc integration method on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DiscMethodArg {
    /// Exact strip integral.
    Exact,
    /// Circular segment under the line through the disc's edge azimuths (Fritsch et al.).
    Segment,
    /// Horizontal chord at the centre azimuth's horizon (Max 1988).
    MiddleValue,
}

impl From<DiscMethodArg> for penumbra::illum::DiscMethod {
    fn from(m: DiscMethodArg) -> Self {
        match m {
            DiscMethodArg::Exact => penumbra::illum::DiscMethod::Exact,
            DiscMethodArg::Segment => penumbra::illum::DiscMethod::Segment,
            DiscMethodArg::MiddleValue => penumbra::illum::DiscMethod::MiddleValue,
        }
    }
}

/// Solar limb darkening on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LimbLawArg {
    /// Uniform disc: the visible fraction is an area fraction.
    None,
    /// Eddington law `(2 + 3μ)/5`, for total (bolometric) irradiance: the default, since the
    /// irradiance columns are total irradiance.
    Eddington,
    /// Allen's 550 nm quadratic law (visible band).
    Allen550nm,
}

impl From<LimbLawArg> for LimbLaw {
    fn from(l: LimbLawArg) -> Self {
        match l {
            LimbLawArg::None => LimbLaw::None,
            LimbLawArg::Eddington => LimbLaw::Eddington,
            LimbLawArg::Allen550nm => LimbLaw::Allen550nm,
        }
    }
}

/// Series engine on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SeriesEngineArg {
    /// One horizon per site from every DEM layer, then the strip integral of each disc against
    /// it.
    Horizon,
    /// The map pipeline: the model-space grid of the finest layer and the DP max-mipmap search at
    /// each site's point, per epoch and light.
    SmapDp,
}

impl From<SeriesEngineArg> for SeriesEngine {
    fn from(e: SeriesEngineArg) -> Self {
        match e {
            SeriesEngineArg::Horizon => SeriesEngine::Horizon,
            SeriesEngineArg::SmapDp => SeriesEngine::SmapDp,
        }
    }
}

/// Runs `penumbra series`.
pub fn run(args: &SeriesArgs) -> anyhow::Result<()> {
    penumbra::products::series::run(&request(args)?)
}

/// The series request of `args` (shared with `penumbra windows`).
pub fn request(args: &SeriesArgs) -> anyhow::Result<SeriesRequest> {
    let mut sites: Vec<Site> = args
        .site
        .iter()
        .map(|s| penumbra::model::parse_site_flag(s, args.observer_height_m))
        .collect::<anyhow::Result<_>>()?;
    if let Some(path) = &args.sites {
        sites.extend(penumbra::model::read_sites_file(
            path,
            args.observer_height_m,
        )?);
    }
    if let (Some(lat_deg), Some(lon_deg)) = (args.lat_deg, args.lon_deg) {
        sites.push(Site::new("site", lat_deg, lon_deg, args.observer_height_m)?);
    }
    let config = SeriesConfig {
        abcorr: super::abcorr(&args.abcorr)?,
        disc_method: args.disc_method.into(),
        limb_darkening: args.limb_darkening.into(),
        az_step_deg: args.az_step_deg,
        horizon_method: args.horizon_method.into(),
        plots: !args.no_plots,
        write_csv: !args.no_csv,
        backend: args.backend.into(),
        engine: args.engine.into(),
        stations: penumbra::comms::Stations::parse(&args.stations),
        station_mask_deg: args.station_mask_deg,
        relays: args.relays.clone(),
        relay_spks: args.relay_spks.clone(),
        relay_max_range_km: args.relay_max_range_km,
        power: args.power.config()?,
        neighbourhood_m: args.neighbourhood_m,
    };
    Ok(SeriesRequest {
        terrain: args.terrain.source(),
        sites,
        epochs: args.epochs.required()?,
        config,
        kernels: args.kernels.source(),
        out_dir: args.out_dir.clone(),
    })
}

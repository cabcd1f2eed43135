//! The command line (clap derive): one file per subcommand, each thin (parse the flags into the
//! library's typed request, run the product). Every argument documents its unit.
//!
//! This is the only place that knows clap: the library ([`penumbra::products`]) takes typed
//! requests, and scenario files build the same requests from TOML.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use penumbra::model::Epochs;
use penumbra::products::{KernelSource, TerrainSource};

mod dem;
mod ephem;
mod gpu_info;
mod horizon;
mod horizon_map;
mod map;
mod mast;
mod power;
mod render;
mod run;
mod series;
mod windows;

/// Arguments of `penumbra merge`.
#[derive(Debug, Clone, Args)]
pub struct MergeArgs {
    /// Output folder of the merged maps and their run.json.
    #[arg(long, value_name = "DIR")]
    pub out_dir: PathBuf,
    /// The shards' output folders (each holding shard.json and shard.pnbstat), all N of one job
    /// in any order.
    #[arg(value_name = "SHARD_DIR", required = true)]
    pub shards: Vec<PathBuf>,
}

/// penumbra: sunlight and earthlight at the lunar poles.
#[derive(Debug, Parser)]
#[command(name = "penumbra", version, about, long_about = None)]
pub struct Cli {
    /// Say nothing on stderr but warnings and errors (no progress bars, no summary lines).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
    /// Also print details (kernel and terrain files used, checkpoints kept).
    #[arg(short, long, global = true)]
    pub verbose: bool,
    /// The subcommand to run.
    #[command(subcommand)]
    pub command: Command,
}

/// penumbra's subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Sun and Earth azimuth, elevation, range and angular radius seen from a site.
    Ephem(ephem::EphemArgs),
    /// List the SPICE kernels that are loaded: files, bodies, frames and time coverage.
    Kernels(KernelArgs),
    /// Run a scenario file (scenarios/*.toml).
    Run(run::RunArgs),
    /// Terrain horizon (elevation vs azimuth) seen by an observer above a site.
    Horizon(horizon::HorizonArgs),
    /// Illumination maps: one light (Sun fraction, hard mask, Earth fraction) or statistics over
    /// an epoch range (average illumination, longest darkness, PSR, Earth visibility).
    Map(map::MapArgs),
    /// Combine the partials of `penumbra map --shard I/N` into the maps of the whole job (the
    /// same bytes as one `penumbra map` run).
    Merge(MergeArgs),
    /// Per-site illumination time series: Sun and Earth visible fractions, irradiance,
    /// statistics and plots.
    Series(series::SeriesArgs),
    /// Landing windows: every start epoch whose stay satisfies a mission profile (lit %, longest
    /// dark, DTE %, longest blackout) at each site, merged and ranked (windows.csv, .json, .ics),
    /// beside the series' own files.
    Windows(windows::WindowsArgs),
    /// Mast-height trade at sites: % lit, DTE % and the required battery at each of a list of
    /// heights (mast.csv, mast.png, one series folder per height).
    Mast(mast::MastArgs),
    /// Smallest mast height per pixel (of a list) at which the Sun is visible a given % of the
    /// time (min_height_m.tif): one horizons-engine map per height.
    MastMap(mast::MastMapArgs),
    /// Inspect or generate DEMs (GeoTIFF).
    Dem {
        /// The DEM action.
        #[command(subcommand)]
        command: dem::DemCommand,
    },
    /// List the GPU adapters wgpu finds (honours WGPU_BACKEND): name, backend, device type,
    /// driver and the compute limits that bound penumbra's kernels.
    GpuInfo(gpu_info::GpuInfoArgs),
    /// Render the terrain seen from a camera at an epoch or a sequence of epochs: sunlight and
    /// earthshine with soft shadows (Hapke BRDF by default; the GPU when one exists), 8-bit
    /// sRGB PNG and optionally a radiance GeoTIFF.
    Render(render::RenderArgs),
    /// Horizon maps: exact whole-grid horizons by the line sweep (`sweep`), or Fourier-compressed
    /// ones (Fritsch et al.; `build`, `info`).
    HorizonMap {
        /// The horizon-map action.
        #[command(subcommand)]
        command: horizon_map::HorizonMapCommand,
    },
    /// Print a shell completion script, e.g. `penumbra completions bash >
    /// ~/.local/share/bash-completion/completions/penumbra`.
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the man page (roff) on stdout, or write one page per command into a folder
    /// (`penumbra.1`, `penumbra-map.1`, …).
    Man {
        /// Write the pages into this folder instead.
        #[arg(long, value_name = "DIR")]
        out_dir: Option<PathBuf>,
    },
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    penumbra::output::set_verbosity(match (cli.quiet, cli.verbose) {
        (true, _) => 0,
        (false, false) => 1,
        (false, true) => 2,
    });
    match cli.command {
        Command::Ephem(args) => ephem::run(&args),
        Command::Kernels(args) => {
            print!("{}", penumbra::products::kernels::report(&args.source())?);
            Ok(())
        }
        Command::Run(args) => run::run(&args),
        Command::Dem { command } => dem::run(command),
        Command::Series(args) => series::run(&args),
        Command::Windows(args) => windows::run(&args),
        Command::Mast(args) => mast::run(&args),
        Command::MastMap(args) => mast::run_map(&args),
        Command::Map(args) => map::run(&args),
        Command::Merge(args) => penumbra::products::map::shard::merge(&args.out_dir, &args.shards),
        Command::Horizon(args) => horizon::run(&args),
        Command::GpuInfo(args) => gpu_info::run(&args),
        Command::Render(args) => render::run(&args),
        Command::HorizonMap { command } => horizon_map::run(command),
        Command::Completions { shell } => {
            use clap::CommandFactory as _;
            let mut out = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "penumbra", &mut out);
            std::io::Write::write_all(&mut std::io::stdout().lock(), &out)?;
            Ok(())
        }
        Command::Man { out_dir } => man(out_dir.as_deref()),
    }
}

/// `penumbra man`: the page on stdout, or every command's page into `out_dir`.
fn man(out_dir: Option<&std::path::Path>) -> anyhow::Result<()> {
    use clap::CommandFactory as _;
    let cmd = Cli::command();
    let Some(dir) = out_dir else {
        let mut out = Vec::new();
        clap_mangen::Man::new(cmd).render(&mut out)?;
        std::io::Write::write_all(&mut std::io::stdout().lock(), &out)?;
        return Ok(());
    };
    std::fs::create_dir_all(dir)?;
    let mut pages = vec![("penumbra".to_string(), cmd.clone())];
    for sub in cmd.get_subcommands() {
        // The page is named as man(1) expects (`penumbra-series`, its NAME section too); its
        // usage line is the command as typed (`penumbra series`).
        let name = format!("penumbra-{}", sub.get_name());
        // (clap takes a command's name as `&'static str`: a few bytes per page, once per run.)
        let static_name: &'static str = Box::leak(name.clone().into_boxed_str());
        let page = sub
            .clone()
            .name(static_name)
            .bin_name(format!("penumbra {}", sub.get_name()));
        pages.push((name, page));
    }
    for (name, page) in pages {
        let path = dir.join(format!("{name}.1"));
        penumbra::output::write_atomic(&path, |w| -> anyhow::Result<()> {
            clap_mangen::Man::new(page).title(name.clone()).render(w)?;
            Ok(())
        })?;
    }
    penumbra::note!("penumbra: man pages written to {}", dir.display());
    Ok(())
}

/// Where the SPICE kernels come from.
#[derive(Debug, Clone, Args)]
pub struct KernelArgs {
    /// Folder of SPICE kernels (.bsp, .bpc, .tf, .tls), or a SPICE meta-kernel (.tm) listing
    /// them. Default: $PENUMBRA_KERNELS, else the kernel set built into penumbra (DE440 Sun/Earth/
    /// Moon 2000-2050, MOON_ME DE421; `penumbra kernels` lists it).
    #[arg(long, value_name = "DIR|TM")]
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
        required_unless_present_any = ["synthetic", "synthetic_far_field"]
    )]
    pub dem: Vec<PathBuf>,
    /// Use penumbra's synthetic south-polar DEM (400 x 400 px at 100 m, seed 1) instead of --dem
    /// (no far field: rays that leave it toward the sphere are counted and warned about).
    #[arg(long, conflicts_with = "dem")]
    pub synthetic: bool,
    /// The synthetic DEM with its far field (400 x 400 px at 1 km, generated the same way and
    /// blended into the DEM's edge): two layers, no ray leaving the terrain. The per-epoch map
    /// engines then build a 4000 x 4000 model grid; the horizons engine and series stay cheap.
    #[arg(long, conflicts_with = "dem")]
    pub synthetic_far_field: bool,
}

/// A place on the Moon: planetocentric latitude and east longitude.
#[derive(Debug, Clone, Copy, Args)]
pub struct LatLonArgs {
    /// Planetocentric latitude, degrees (-90 … 90): the site (for `render`, the site camera's,
    /// or the point below the orbital camera).
    #[arg(long, allow_hyphen_values = true)]
    pub lat_deg: f64,
    /// East longitude, degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub lon_deg: f64,
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

impl KernelArgs {
    /// The kernel source of `--kernels`.
    pub fn source(&self) -> KernelSource {
        KernelSource {
            dir: self.kernels.clone(),
        }
    }
}

impl TerrainArgs {
    /// The terrain of `--dem FILE…` or `--synthetic`.
    pub fn source(&self) -> TerrainSource {
        if self.synthetic_far_field {
            TerrainSource::SyntheticWithFarField(penumbra::terrain::synth::SynthParams::default())
        } else if self.synthetic {
            TerrainSource::Synthetic(penumbra::terrain::synth::SynthParams::default())
        } else {
            TerrainSource::Dems(self.dem.clone())
        }
    }
}

impl EpochArgs {
    /// The epochs of `--utc` or `--start/--stop/--step`, `None` when neither is given.
    pub fn spec(&self) -> anyhow::Result<Option<Epochs>> {
        Ok(Epochs::parse(
            self.utc.as_deref(),
            self.start.as_deref(),
            self.stop.as_deref(),
            self.step.as_deref(),
        )?)
    }

    /// Like [`EpochArgs::spec`], but one of the two forms is required.
    pub fn required(&self) -> anyhow::Result<Epochs> {
        self.spec()?.ok_or_else(|| {
            anyhow::anyhow!("give either --utc T or all of --start T --stop T --step S")
        })
    }
}

/// Compute backend on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    /// The CPU (rayon) reference engines.
    Cpu,
    /// The wgpu backend; an error when no adapter exists.
    Gpu,
    /// The GPU when a hardware adapter exists, else the CPU with one warning line on stderr
    /// (a software adapter such as lavapipe counts as none).
    Auto,
}

impl From<BackendArg> for penumbra::gpu::Backend {
    fn from(b: BackendArg) -> Self {
        match b {
            BackendArg::Cpu => penumbra::gpu::Backend::Cpu,
            BackendArg::Gpu => penumbra::gpu::Backend::Gpu,
            BackendArg::Auto => penumbra::gpu::Backend::Auto,
        }
    }
}

/// Parses `--abcorr`.
fn abcorr(text: &str) -> anyhow::Result<penumbra::ephem::AbCorr> {
    Ok(penumbra::ephem::AbCorr::parse(text)?)
}

//! Runs a parsed command line: the glue between [`crate::cli`] and the library.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use hifitime::Epoch;

use crate::cli::{Cli, Command, EphemArgs, EpochArgs, Format, KernelArgs};
use crate::ephem::{self, AbCorr, Kernels, Site, SunEarth, time::format_utc};

/// Runs one invocation of the tool.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Ephem(args) => run_ephem(&args),
        Command::Kernels(args) => run_kernels(&args),
        Command::Run(args) => crate::scenario::run_file(&args),
        Command::GpuInfo(args) => run_gpu_info(&args),
    }
}

/// Formats an error chain on one line (`outer: inner: root cause`), as `main` prints it.
pub fn one_line(err: &anyhow::Error) -> String {
    format!("{err:#}").replace('\n', " ")
}

/// The kernel folder chosen by `--kernels` or the defaults.
pub fn kernel_dir(args: &KernelArgs) -> PathBuf {
    args.kernels
        .clone()
        .unwrap_or_else(ephem::kernels::default_kernel_dir)
}

/// Loads the kernels chosen by `--kernels` or the defaults.
pub fn load_kernels(args: &KernelArgs) -> anyhow::Result<Kernels> {
    let dir = kernel_dir(args);
    Kernels::load(&dir).context("loading SPICE kernels")
}

/// The epochs asked for by `--utc` or `--start/--stop/--step`.
pub fn epochs_from_args(args: &EpochArgs) -> anyhow::Result<Vec<Epoch>> {
    match (&args.utc, &args.start, &args.stop, &args.step) {
        (Some(t), None, None, None) => Ok(vec![ephem::time::parse_utc(t)?]),
        (None, Some(a), Some(b), Some(s)) => Ok(ephem::time::epoch_range(
            ephem::time::parse_utc(a)?,
            ephem::time::parse_utc(b)?,
            ephem::time::parse_step(s)?,
        )?),
        _ => anyhow::bail!("give either --utc T or all of --start T --stop T --step S"),
    }
}

/// Writes to `--out` atomically, or to stdout.
pub fn write_output(
    out: Option<&Path>,
    fill: impl FnOnce(&mut dyn Write) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    match out {
        Some(path) => crate::output::write_atomic(path, fill)
            .with_context(|| format!("writing {}", path.display())),
        None => {
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            fill(&mut lock)?;
            lock.flush().ok();
            Ok(())
        }
    }
}

/// The exact CSV header of `penumbra ephem`.
pub const EPHEM_CSV_HEADER: &str = "utc,sun_az_deg,sun_el_deg,sun_range_km,sun_radius_deg,earth_az_deg,earth_el_deg,earth_range_km,earth_radius_deg";

/// Writes one `ephem` CSV row.
pub fn write_ephem_row(w: &mut dyn Write, epoch: Epoch, v: &SunEarth) -> std::io::Result<()> {
    writeln!(
        w,
        "{},{:.9},{:.9},{:.6},{:.9},{:.9},{:.9},{:.6},{:.9}",
        format_utc(epoch),
        v.sun.az_deg,
        v.sun.el_deg,
        v.sun.range_km,
        v.sun.radius_deg,
        v.earth.az_deg,
        v.earth.el_deg,
        v.earth.range_km,
        v.earth.radius_deg
    )
}

fn run_ephem(args: &EphemArgs) -> anyhow::Result<()> {
    let abcorr = AbCorr::parse(&args.abcorr)?;
    let site = Site::new(args.lat_deg, args.lon_deg, args.height_m)?;
    let epochs = epochs_from_args(&args.epochs)?;
    let kernels = load_kernels(&args.kernels)?;
    let series = ephem::sun_earth_series(&kernels, &[site], &epochs, abcorr)?;
    let rows = &series[0];
    write_output(args.out.as_deref(), |w| {
        match args.format {
            Format::Csv => {
                writeln!(w, "{EPHEM_CSV_HEADER}")?;
                for (e, v) in epochs.iter().zip(rows) {
                    write_ephem_row(w, *e, v)?;
                }
            }
            Format::Json => {
                let doc = serde_json::json!({
                    "site": {"lat_deg": args.lat_deg, "lon_deg": args.lon_deg, "height_m": args.height_m},
                    "abcorr": abcorr.spice_name(),
                    "frame": "MOON_ME",
                    "epochs": epochs.iter().zip(rows).map(|(e, v)| serde_json::json!({
                        "utc": format_utc(*e),
                        "sun": v.sun,
                        "earth": v.earth,
                    })).collect::<Vec<_>>(),
                });
                serde_json::to_writer_pretty(&mut *w, &doc)?;
                writeln!(w)?;
            }
        }
        Ok(())
    })
}

fn run_kernels(args: &KernelArgs) -> anyhow::Result<()> {
    let kernels = load_kernels(args)?;
    let mut out = String::new();
    use std::fmt::Write as _;
    writeln!(out, "kernel folder: {}", kernels.dir.display())?;
    for f in &kernels.files {
        writeln!(
            out,
            "  {:<4} {:>10} B  sha256 {}  {}",
            f.kind,
            f.size_bytes,
            &f.sha256[..16],
            f.path.display()
        )?;
    }
    writeln!(out, "bodies (SPK, NAIF id: span TDB):")?;
    let mut domains: Vec<_> = kernels
        .almanac
        .spk_domains()
        .map(|d| d.into_iter().collect())
        .unwrap_or_default();
    domains.sort_by_key(|(id, _)| *id);
    for (id, (s, e)) in domains {
        writeln!(out, "  {:>4} {}: {} .. {}", id, body_name(id), s, e)?;
    }
    writeln!(
        out,
        "frames: J2000 (1), MOON_PA_DE421 (31006, binary PCK), MOON_ME = MOON_ME_DE421 (31007, from the frame kernel)"
    )?;
    if let Ok((s, e)) = kernels.almanac.bpc_domain(ephem::kernels::MOON_PA_DE421_ID) {
        writeln!(out, "  MOON_PA_DE421 orientation data: {s} .. {e}")?;
    }
    writeln!(
        out,
        "usable epochs (all bodies and MOON_ME, light-time margin included): {} .. {} UTC",
        format_utc(kernels.coverage.0),
        format_utc(kernels.coverage.1)
    )?;
    writeln!(
        out,
        "time scales: UTC input, leap seconds from hifitime's table (= naif0012), TDB for the kernels"
    )?;
    print!("{out}");
    Ok(())
}

fn body_name(id: i32) -> &'static str {
    match id {
        0 => "solar-system barycentre",
        3 => "Earth-Moon barycentre",
        10 => "Sun",
        301 => "Moon",
        399 => "Earth",
        1 => "Mercury barycentre",
        2 => "Venus barycentre",
        4 => "Mars barycentre",
        5 => "Jupiter barycentre",
        6 => "Saturn barycentre",
        7 => "Uranus barycentre",
        8 => "Neptune barycentre",
        9 => "Pluto barycentre",
        _ => "",
    }
}

fn run_gpu_info(args: &crate::cli::GpuInfoArgs) -> anyhow::Result<()> {
    print_adapters()?;
    if let Some(requested) = args.backend {
        let resolved = crate::gpu::resolve_backend(requested)
            .with_context(|| format!("resolving --backend {}", requested.as_str()))?;
        println!("backend {}: {}", requested.as_str(), resolved.describe());
    }
    Ok(())
}

#[cfg(feature = "gpu")]
fn print_adapters() -> anyhow::Result<()> {
    let adapters = crate::gpu::adapter_report();
    let mut out = String::new();
    use std::fmt::Write as _;
    if adapters.is_empty() {
        writeln!(
            out,
            "no GPU adapter found (WGPU_BACKEND={}); --backend auto will use the CPU",
            std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "unset".into())
        )?;
    }
    for (i, a) in adapters.iter().enumerate() {
        writeln!(out, "adapter {i}: {}", a.name)?;
        writeln!(
            out,
            "  backend: {}, device type: {}, driver: {}",
            a.backend, a.device_type, a.driver
        )?;
        writeln!(
            out,
            "  max_storage_buffer_binding_size: {} B",
            a.max_storage_buffer_binding_size
        )?;
        writeln!(out, "  max_buffer_size: {} B", a.max_buffer_size)?;
        writeln!(
            out,
            "  max_compute_workgroup_size_x: {}",
            a.max_compute_workgroup_size_x
        )?;
        writeln!(
            out,
            "  max_compute_invocations_per_workgroup: {}",
            a.max_compute_invocations_per_workgroup
        )?;
        writeln!(
            out,
            "  max_compute_workgroups_per_dimension: {}",
            a.max_compute_workgroups_per_dimension
        )?;
    }
    print!("{out}");
    Ok(())
}

#[cfg(not(feature = "gpu"))]
fn print_adapters() -> anyhow::Result<()> {
    println!("this penumbra was built without the `gpu` cargo feature: no GPU adapters");
    Ok(())
}

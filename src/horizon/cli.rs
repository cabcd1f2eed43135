//! The `penumbra horizon` command's logic and the CSV/JSON writers of a [`Horizon`].

use std::io::Write;

use anyhow::Context as _;

use super::{Horizon, HorizonEngine, HorizonMethod, HorizonParams};
use crate::cli::{HorizonArgs, HorizonFormat, HorizonMethodArg};
use crate::terrain::TerrainStack;

/// Runs `penumbra horizon` on an already loaded stack: computes the profile and writes it to
/// `--out` (atomically) or to stdout.
pub fn cli_run(args: &HorizonArgs, stack: &TerrainStack) -> anyhow::Result<()> {
    let params = HorizonParams {
        observer_height_m: args.observer_height_m,
        az_step_deg: args.az_step_deg,
        method: match args.method {
            HorizonMethodArg::Fast => HorizonMethod::Fast,
            HorizonMethodArg::Exact => HorizonMethod::Exact,
        },
        ..HorizonParams::default()
    };
    let horizon = match crate::gpu::resolve_backend(args.backend)
        .with_context(|| format!("resolving --backend {}", args.backend.as_str()))?
    {
        crate::gpu::ResolvedBackend::Cpu => {
            HorizonEngine::new(stack).horizon(args.lat_deg, args.lon_deg, &params)?
        }
        crate::gpu::ResolvedBackend::Gpu(ctx) => gpu_horizon(&ctx, stack, args, &params)?,
    };
    let fill = |w: &mut dyn Write| -> anyhow::Result<()> {
        match args.format {
            HorizonFormat::Csv => write_csv(&horizon, w)?,
            HorizonFormat::Json => write_json(&horizon, w)?,
        }
        Ok(())
    };
    match &args.out {
        Some(path) => crate::output::write_atomic(path, fill),
        None => {
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            fill(&mut lock)?;
            lock.flush()?;
            Ok(())
        }
    }
}

/// One site on the GPU (validated as on the CPU).
#[cfg(feature = "gpu")]
fn gpu_horizon(
    ctx: &crate::gpu::GpuContext,
    stack: &TerrainStack,
    args: &HorizonArgs,
    params: &HorizonParams,
) -> anyhow::Result<Horizon> {
    let site = (args.lat_deg, args.lon_deg, params.observer_height_m);
    let mut hz = crate::gpu::horizon::horizons_gpu(ctx, stack, None, &[site], params.az_step_deg)?;
    hz.pop().context("the GPU horizon scan returned no site")
}

#[cfg(not(feature = "gpu"))]
fn gpu_horizon(
    ctx: &crate::gpu::GpuContext,
    _stack: &TerrainStack,
    _args: &HorizonArgs,
    _params: &HorizonParams,
) -> anyhow::Result<Horizon> {
    match *ctx {}
}

/// Writes `az_deg,horizon_el_deg,distance_m`, one row per azimuth (`NaN` distance where there is
/// no terrain).
pub fn write_csv(horizon: &Horizon, w: &mut dyn Write) -> std::io::Result<()> {
    writeln!(w, "az_deg,horizon_el_deg,distance_m")?;
    for ((az, el), d) in horizon
        .az_deg
        .iter()
        .zip(&horizon.elevation_deg)
        .zip(&horizon.distance_m)
    {
        writeln!(w, "{az:.4},{el:.6},{d:.1}")?;
    }
    Ok(())
}

/// Writes the profile and its site description as one JSON object (`null` for `NaN` distances).
pub fn write_json(horizon: &Horizon, w: &mut dyn Write) -> std::io::Result<()> {
    serde_json::to_writer_pretty(&mut *w, horizon)?;
    writeln!(w)
}

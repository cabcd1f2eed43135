//! `penumbra gpu-info`.

use clap::Args;

use super::BackendArg;

/// Arguments of `penumbra gpu-info`.
#[derive(Debug, Clone, Args)]
pub struct GpuInfoArgs {
    /// Also resolve this backend choice (as `--backend` of the compute commands does) and print
    /// the result: `auto` falls back to the CPU with one warning, `gpu` fails without an adapter.
    #[arg(long, value_enum, value_name = "BACKEND")]
    pub backend: Option<BackendArg>,
}

/// Runs `penumbra gpu-info`: the adapters, then what `--backend` resolves to.
pub fn run(args: &GpuInfoArgs) -> anyhow::Result<()> {
    print!("{}", penumbra::products::gpu_info::adapters()?);
    if let Some(requested) = args.backend {
        print!(
            "{}",
            penumbra::products::gpu_info::resolved(requested.into())?
        );
    }
    Ok(())
}

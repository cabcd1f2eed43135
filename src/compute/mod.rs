//! The one CPU|GPU switch: the backend is resolved here, once per process ([`resolve`]), and each
//! question a product asks is answered on it, one file per question (statistics over an epoch
//! range, one-light maps, site horizons and the smap-dp series engine, a frame's fractions and
//! samples). Every `cfg(feature = "gpu")` arm of the products lives here (vello
//! `WgpuEngine { use_cpu }`). `--backend` decides where a computation runs, never what it
//! computes: an engine without a GPU kernel runs on the CPU, with one line that says so.

use anyhow::Context as _;

pub use crate::gpu::{Backend, ResolvedBackend};

#[cfg(feature = "gpu")]
pub mod gpu_maps;
pub mod horizons;
pub mod one_light;
pub mod range;
pub mod render;
pub mod site_dp;

/// What the GPU can do for a computation, which decides what `--backend` resolves to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnGpu {
    /// A GPU kernel runs it: `gpu` and `auto` on a hardware adapter take the GPU.
    Preferred,
    /// A GPU kernel runs it when asked (`--backend gpu`); `auto` keeps the CPU, which answers it
    /// as fast (one site's horizon, the horizons engine's statistics), without probing adapters.
    WhenAsked,
    /// No GPU kernel computes `what`: it runs on the CPU, and `--backend gpu` prints one line
    /// that says so.
    Never {
        /// The computation, as the line names it (e.g. "the combined engine").
        what: &'static str,
    },
}

/// Resolves a `--backend` choice for a computation the GPU can do `on_gpu`: `cpu` is the CPU;
/// `gpu` a GPU context (an error without an adapter) unless no kernel exists; `auto` the GPU on a
/// hardware adapter, else the CPU with one warning line. The GPU context is created once and
/// shared by every later call of the process.
pub fn resolve(requested: Backend, on_gpu: OnGpu) -> anyhow::Result<ResolvedBackend> {
    match (requested, on_gpu) {
        (Backend::Cpu, _) | (Backend::Auto, OnGpu::WhenAsked | OnGpu::Never { .. }) => {
            Ok(ResolvedBackend::Cpu)
        }
        (Backend::Gpu, OnGpu::Never { what }) => {
            eprintln!("penumbra: note: {what} has no GPU kernel: it runs on the CPU");
            Ok(ResolvedBackend::Cpu)
        }
        (Backend::Gpu | Backend::Auto, _) => crate::gpu::resolve_backend(requested)
            .with_context(|| format!("resolving --backend {}", requested.as_str())),
    }
}

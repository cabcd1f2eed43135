//! The one CPU|GPU switch: each question a product asks (a map sweep, one-light maps, the
//! fractions and samples of a frame, horizons) answered on the backend resolved once per
//! process, in one file per question. Every `cfg(feature = "gpu")` arm of the products lives
//! here (vello `WgpuEngine { use_cpu }`); the products never match on the backend.

use anyhow::Context as _;

pub use crate::gpu::{Backend, ResolvedBackend};

#[cfg(feature = "gpu")]
pub mod gpu_maps;
pub mod horizons;
pub mod one_light;
pub mod render;
pub mod sweep;

/// Resolves a `--backend` choice (`auto` falls back to the CPU with one warning line; the GPU
/// context is shared by every later call of the process).
pub fn resolve(requested: Backend) -> anyhow::Result<ResolvedBackend> {
    crate::gpu::resolve_backend(requested)
        .with_context(|| format!("resolving --backend {}", requested.as_str()))
}

//! The wgpu compute backend: GPU versions of the shadow kernels, checked against their CPU twins
//! in [`crate::twins`].
//!
//! This is the only module that imports `wgpu`, and only behind the `gpu` cargo feature (on by
//! default; `--no-default-features` builds a CPU-only binary). [`Backend`], [`GpuError`] and
//! the backend resolution ([`backend`]) are always compiled so that the command line can offer
//! `--backend cpu|gpu|auto` in every build, and so is the shader table ([`shaders`]) so that
//! every build validates the shaders.
//!
//! Layout (vello/rerun): [`GpuContext`] builds the instance, adapter, device and queue once and
//! each kernel family's pipelines on first use, and holds the helpers the kernels share; one
//! module per shader family (`dp`, `tiles`, `fourier`, …) holds its runners and its
//! `mod gpu_data` mirror structs. The WGSL lives in `shaders/` at the crate root; [`shaders`] says
//! which shared parts each kernel is composed of and embeds the result at compile time.

/// Declares `$name`, a [`context::SingleKernel`] of the shader `$shader` with `$reads` read-only
/// and `$read_writes` read-write storage buffers after its uniform; `$what` names its pipeline
/// build in errors.
#[cfg(feature = "gpu")]
macro_rules! single_kernel {
    ($(#[$doc:meta])* $name:ident = $shader:ident, $reads:literal, $read_writes:literal, $what:literal) => {
        $(#[$doc])*
        pub(crate) struct $name;

        impl super::context::SingleKernel for $name {
            const SHADER: super::shaders::Shader = super::shaders::$shader;
            const READS: u32 = $reads;
            const READ_WRITES: u32 = $read_writes;
            const WHAT: &'static str = $what;
        }
    };
}

pub mod backend;
mod error;
pub mod shaders;

pub use backend::{Backend, ResolvedBackend};
pub use error::GpuError;

#[cfg(feature = "gpu")]
mod context;
#[cfg(feature = "gpu")]
pub mod dp;
#[cfg(feature = "gpu")]
pub mod fourier;
#[cfg(feature = "gpu")]
pub mod horizon;
#[cfg(feature = "gpu")]
pub mod horizon_stats;
#[cfg(feature = "gpu")]
pub mod line_sweep;
#[cfg(feature = "gpu")]
pub mod render;
#[cfg(feature = "gpu")]
pub mod tiles;

#[cfg(feature = "gpu")]
pub use context::{AdapterSummary, DEFAULT_BAND_BYTES, GpuContext, GpuGrid, adapter_report};

/// Stand-in for the GPU context in builds without the `gpu` feature: it has no values, so
/// [`ResolvedBackend::Gpu`] can never be constructed there.
#[cfg(not(feature = "gpu"))]
#[derive(Debug)]
pub enum GpuContext {}

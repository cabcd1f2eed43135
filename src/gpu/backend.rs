//! The `--backend cpu|gpu|auto` switch and its resolution (vello `use_cpu`).

use super::{GpuContext, GpuError};

/// Which compute backend a command should use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Backend {
    /// The CPU (rayon) reference engines.
    Cpu,
    /// The wgpu backend; an error when no adapter exists.
    Gpu,
    /// The GPU when an adapter exists, else the CPU with one warning line on stderr.
    #[default]
    Auto,
}

impl Backend {
    /// The command-line spelling: `cpu`, `gpu` or `auto`.
    pub fn as_str(self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Gpu => "gpu",
            Backend::Auto => "auto",
        }
    }
}

/// The outcome of [`resolve_backend`].
#[derive(Debug)]
pub enum ResolvedBackend {
    /// Run on the CPU.
    Cpu,
    /// Run on the GPU with this context (device and pipelines built once; reuse it).
    Gpu(Box<GpuContext>),
}

impl ResolvedBackend {
    /// "cpu" or "gpu (adapter name)", for logs and output provenance.
    pub fn describe(&self) -> String {
        match self {
            ResolvedBackend::Cpu => "cpu".to_string(),
            #[cfg(feature = "gpu")]
            ResolvedBackend::Gpu(ctx) => format!("gpu ({})", ctx.adapter_name()),
            #[cfg(not(feature = "gpu"))]
            ResolvedBackend::Gpu(ctx) => match **ctx {},
        }
    }
}

/// Resolves `requested`: `cpu` → CPU; `gpu` → a [`GpuContext`] or the error (no adapter, no
/// device, or a build without the `gpu` feature); `auto` → the GPU when a context can be built,
/// else the CPU after printing exactly one warning line on stderr.
pub fn resolve_backend(requested: Backend) -> Result<ResolvedBackend, GpuError> {
    match requested {
        Backend::Cpu => Ok(ResolvedBackend::Cpu),
        Backend::Gpu => new_context().map(|ctx| ResolvedBackend::Gpu(Box::new(ctx))),
        Backend::Auto => match new_context() {
            Ok(ctx) => Ok(ResolvedBackend::Gpu(Box::new(ctx))),
            Err(err) => {
                eprintln!(
                    "penumbra: warning: --backend auto: {}; using the CPU backend",
                    one_line(&err)
                );
                Ok(ResolvedBackend::Cpu)
            }
        },
    }
}

fn one_line(err: &GpuError) -> String {
    let mut s = err.to_string();
    let mut source = std::error::Error::source(err);
    while let Some(e) = source {
        s.push_str(": ");
        s.push_str(&e.to_string());
        source = e.source();
    }
    s.replace('\n', " ")
}

#[cfg(feature = "gpu")]
fn new_context() -> Result<GpuContext, GpuError> {
    GpuContext::new()
}

#[cfg(not(feature = "gpu"))]
fn new_context() -> Result<GpuContext, GpuError> {
    Err(GpuError::NotCompiled)
}

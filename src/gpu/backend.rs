//! The `cpu|gpu|auto` backend choice and its resolution (vello `use_cpu`), called only by
//! `compute::resolve`.

use super::{GpuContext, GpuError};

/// Which compute backend a command should use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Backend {
    /// The CPU (rayon) reference engines.
    Cpu,
    /// The wgpu backend; an error when no adapter exists.
    Gpu,
    /// The GPU when a hardware adapter exists, else the CPU with one warning line on stderr
    /// (a software adapter such as lavapipe counts as none).
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

impl std::str::FromStr for Backend {
    type Err = String;
    /// Parses `cpu`, `gpu` or `auto`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "cpu" => Ok(Backend::Cpu),
            "gpu" => Ok(Backend::Gpu),
            "auto" => Ok(Backend::Auto),
            _ => Err(format!("backend '{s}': expected cpu, gpu or auto")),
        }
    }
}

/// A [`Backend`] resolved (`compute::resolve`, the one place a backend is resolved).
#[derive(Debug)]
pub enum ResolvedBackend {
    /// Run on the CPU.
    Cpu,
    /// Run on the GPU with this context: one per process, shared by every command and stage
    /// that resolves to the GPU (device once, each kernel family's pipelines on first use).
    Gpu(std::sync::Arc<GpuContext>),
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
/// device, or a build without the `gpu` feature); `auto` → the GPU when a context can be built
/// on a hardware adapter, else the CPU after printing exactly one warning line on stderr (no
/// adapter, or only a software one such as lavapipe).
pub fn resolve_backend(requested: Backend) -> Result<ResolvedBackend, GpuError> {
    match requested {
        Backend::Cpu => Ok(ResolvedBackend::Cpu),
        Backend::Gpu => shared_context().map(ResolvedBackend::Gpu),
        // One process (e.g. `penumbra run` with a map and several renders) probes and warns
        // once: after `auto` fell back to the CPU, later `auto` requests take the CPU silently.
        Backend::Auto if AUTO_FELL_BACK.load(std::sync::atomic::Ordering::Relaxed) => {
            Ok(ResolvedBackend::Cpu)
        }
        Backend::Auto => match shared_context() {
            #[cfg(feature = "gpu")]
            Ok(ctx) if ctx.is_software() => {
                // A software adapter (lavapipe) runs the same kernels on the same CPU cores, more
                // slowly than the rayon engines: `auto` means "the fast path", so it is skipped.
                // What `auto` is for, not a problem: a line of information, not a warning.
                crate::note!(
                    "penumbra: --backend auto: only a software adapter ({}) was found; \
                     using the CPU backend (--backend gpu forces it)",
                    ctx.adapter_name()
                );
                AUTO_FELL_BACK.store(true, std::sync::atomic::Ordering::Relaxed);
                Ok(ResolvedBackend::Cpu)
            }
            Ok(ctx) => Ok(ResolvedBackend::Gpu(ctx)),
            Err(err) => {
                crate::note!(
                    "penumbra: --backend auto: {}; using the CPU backend",
                    one_line(&err)
                );
                AUTO_FELL_BACK.store(true, std::sync::atomic::Ordering::Relaxed);
                Ok(ResolvedBackend::Cpu)
            }
        },
    }
}

/// Set once `auto` has fallen back to the CPU in this process.
static AUTO_FELL_BACK: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

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

/// The process's GPU context, created on the first successful call (a failure is not cached:
/// the next call tries again).
#[cfg(feature = "gpu")]
fn shared_context() -> Result<std::sync::Arc<GpuContext>, GpuError> {
    static SHARED: std::sync::Mutex<Option<std::sync::Arc<GpuContext>>> =
        std::sync::Mutex::new(None);
    let mut shared = SHARED
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(ctx) = shared.as_ref() {
        return Ok(ctx.clone());
    }
    let ctx = std::sync::Arc::new(GpuContext::new()?);
    *shared = Some(ctx.clone());
    Ok(ctx)
}

#[cfg(not(feature = "gpu"))]
fn shared_context() -> Result<std::sync::Arc<GpuContext>, GpuError> {
    Err(GpuError::NotCompiled)
}

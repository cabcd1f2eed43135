//! Errors of the GPU backend.

/// Everything that can go wrong on the GPU path. Never a panic: a missing adapter is an error
/// for `--backend gpu` and a one-line warning plus CPU fallback for `--backend auto`.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter (GPU or software Vulkan such as lavapipe) was found.
    #[error(
        "no GPU adapter found ({reason}); install a Vulkan driver (without a GPU: the \
         mesa-vulkan-drivers package gives lavapipe) or use --backend cpu"
    )]
    NoAdapter {
        /// What wgpu said.
        reason: String,
    },
    /// The adapter exists but refused to create a device.
    #[error("requesting a device from adapter {adapter}")]
    RequestDevice {
        /// Adapter name.
        adapter: String,
        /// wgpu's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A validation or out-of-memory error was raised while running a kernel.
    #[error("GPU error while {action}: {message}")]
    Device {
        /// What was being done.
        action: &'static str,
        /// wgpu's message.
        message: String,
    },
    /// Mapping a result buffer for reading failed.
    #[error("reading {what} back from the GPU: {message}")]
    Readback {
        /// Which buffer.
        what: &'static str,
        /// wgpu's message.
        message: String,
    },
    /// The input does not fit the kernel (grid too small or too wide, empty light table, ...).
    #[error("invalid input for the GPU kernel {kernel}: {message}")]
    InvalidInput {
        /// The kernel (shader entry point).
        kernel: &'static str,
        /// What is wrong.
        message: String,
    },
    /// `--backend gpu` in a binary built without the `gpu` cargo feature.
    #[error(
        "this penumbra was built without the `gpu` cargo feature; use --backend cpu or rebuild \
         with default features"
    )]
    NotCompiled,
}

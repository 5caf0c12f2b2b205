//! The errors of the GPU relight. Each names what failed and, where it applies, that the
//! CPU relight is the way out; none is a panic (wgpu's default uncaptured-error handler,
//! which panics, is replaced in [`crate::GpuRelighter::new`]).

use relume_engine::RelumeError;

/// What can go wrong choosing, building or running the GPU relight.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter at all (no driver, an empty Vulkan ICD list, no GPU).
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// An adapter exists but refused to give a device.
    #[error("the GPU adapter {adapter} gave no device: {message}")]
    RequestDevice { adapter: String, message: String },
    /// Uploading the layers (or allocating the image) ran out of GPU memory.
    #[error("out of GPU memory uploading {bytes} bytes of layers to {adapter}: {message}")]
    OutOfMemory {
        adapter: String,
        bytes: u64,
        message: String,
    },
    /// The stack does not fit the adapter's limits (one layer larger than a binding).
    #[error("the stack does not fit the GPU {adapter}: {message}")]
    TooLarge { adapter: String, message: String },
    /// The device was lost (driver reset, GPU removed, timeout).
    #[error("the GPU device was lost: {0}")]
    DeviceLost(String),
    /// A wgpu validation or internal error, or a failed read-back: a bug or a driver fault.
    #[error("GPU error during {during}: {message}")]
    Backend { during: String, message: String },
    /// The stack or the coefficients were refused (same checks as the CPU relight).
    #[error(transparent)]
    Engine(#[from] RelumeError),
}

impl GpuError {
    /// As the engine's error, for callers (the command line) that report only that type:
    /// engine errors pass through, the rest become "invalid relight device: …".
    pub fn into_relume(self) -> RelumeError {
        match self {
            GpuError::Engine(e) => e,
            other => RelumeError::invalid("relight device", other.to_string()),
        }
    }
}

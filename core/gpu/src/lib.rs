//! Relume's relight on the GPU through wgpu, and the choice between it and the engine's
//! CPU relight.
//!
//! The sum is the engine's (`relume_engine::relight`): image = Σ weight · layer with
//! weights from the materials' basis coefficients. On a GPU the whole stack lives in
//! device memory and one edit is one small buffer write, one dispatch and one read-back
//! of the RGBA f32 image. The CPU sum stays the reference the GPU must match (tests:
//! 1e-3 relative L2 on every assets stack, full and incremental).
//!
//! Module map (one concept per file):
//! - [`device`]: `auto | gpu | cpu`, the adapter choice and its reason.
//! - [`layout`]: where each layer lives on the GPU (chunks within the binding limit),
//!   f16 pairs / f32 packing.
//! - [`tiles`]: which 256-pixel tiles of each layer are non-zero (the rest is skipped).
//! - `kernel` (+ `kernel.wgsl`): device, pipeline, upload, one submission per edit.
//! - [`relight`]: [`GpuRelighter`], the engine's relight bookkeeping
//!   (`relume_engine::relight::RelightBookkeeping`) over the kernel's sum.
//! - [`relighter`]: [`Relighter`], GPU or CPU behind the same methods, with fallback.
//! - [`error`]: the error type, [`GpuError`].

pub mod device;
pub mod error;
mod kernel;
pub mod layout;
pub mod relight;
pub mod relighter;
pub mod tiles;

pub use device::{choose_device, DeviceChoice, DeviceKind, DevicePreference};
pub use error::GpuError;
pub use kernel::GpuOptions;
pub use relight::{GpuRelighter, GpuTimings};
pub use relighter::{Relighter, StackSource};
/// The engine's shape of a stack and its checks, shared with the CPU relight.
pub use relume_engine::relight::StackShape;

/// The wgpu this crate is built on (for callers that hold an adapter from [`choose_device`]).
pub use wgpu;

//! Relume's relight on the GPU through wgpu, and the choice between it and the engine's
//! CPU relight.
//!
//! The sum is the engine's (`relume_engine::relight`): image = Σ weight · layer with
//! weights from the materials' basis coefficients. On a GPU the tiled stack
//! (`relume_engine::stack::tiled`) lives in device memory as it is on the host — per 16×16
//! tile only the layers present there — uploaded once; one edit is one write of the
//! per-layer weights, one dispatch (a workgroup per tile) and one read-back of the RGBA f32
//! image. The CPU tiled sum stays the reference the GPU must match, in the same per-pixel
//! order of operations (tests: 1e-6 relative L2, full and incremental).
//!
//! Module map (one concept per file):
//! - [`device`]: `auto | gpu | cpu`, the adapter choice and its reason.
//! - [`layout`]: which storage buffer ("chunk") holds each tile's values (within the
//!   binding limit), f16 pairs / f32 packing.
//! - [`tiles`]: the tile and entry tables the kernel reads, and the entry kind byte.
//! - `upload`: streaming the stack into its buffers in bounded pieces.
//! - `kernel` (+ `kernel.wgsl`): device, buffers, one submission per edit.
//! - `pipeline`: the compute pipeline and one dispatch per bind group of value chunks.
//! - `health`: device loss and uncaptured errors, as values.
//! - [`gpu_memory`]: [`GpuMemory`], the bytes on the GPU by purpose.
//! - [`relight`]: [`GpuRelighter`], the engine's relight bookkeeping
//!   (`relume_engine::relight::RelightBookkeeping`) over the kernel's sum.
//! - [`relighter`]: [`Relighter`], GPU or CPU behind the same methods, with fallback.
//! - [`error`]: the error type, [`GpuError`].

pub mod device;
pub mod error;
pub mod gpu_memory;
mod health;
mod kernel;
pub mod lattice;
pub mod layout;
mod pipeline;
pub mod relight;
pub mod relighter;
pub mod tiles;
mod upload;

pub use device::{choose_device, DeviceChoice, DeviceKind, DevicePreference};
pub use error::GpuError;
pub use gpu_memory::GpuMemory;
pub use kernel::GpuOptions;
pub use relight::{GpuRelighter, GpuTimings};
pub use relighter::{Relighter, StackSource};
/// The engine's shape of a stack and its checks, shared with the CPU relight.
pub use relume_engine::relight::StackShape;

/// The wgpu this crate is built on (for callers that hold an adapter from [`choose_device`]).
pub use wgpu;

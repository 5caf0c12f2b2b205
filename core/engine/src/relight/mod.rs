//! The relight: the weighted sum of the layers of a transfer stack for the current
//! materials. The CPU relight here is the reference the GPU relight (`relume-gpu`) must
//! match.
//!
//! For coefficients `c[region][basis]` (RGB, from the BRDF basis; this module does not
//! compute them), every layer gets the weight [`layer_weight`] — the product of the
//! coefficients along its path signature, 1 for a fixed vertex and for the empty path
//! (world seen directly) — times its light group's factor ([`group_factors`]), and the
//! image is `Σ weight · scale · layer`, RGBA f32 with alpha 1.
//!
//! Module map (one concept per file):
//! - `weight`: [`layer_weight`] and [`group_factors`], the arithmetic on weights.
//! - [`part_scales`]: how much each part of an editable material reflects now against at
//!   bake time, what the tail-edit layers (edits beyond the first bounce) weigh by.
//! - `shape`: [`StackShape`], the checks on a stack and on an edit's coefficients, and
//!   which layers each editable region appears in.
//! - `layer_sum`: the [`LayerSum`] trait a device implements (full sum, incremental add).
//! - `bookkeeping`: [`RelightBookkeeping`], coefficients → weights, the layers an edit
//!   touches, the periodic full re-sum; shared by the CPU and the GPU relighters.
//! - [`tiled_sum`]: the CPU's sum over a [`crate::stack::tiled::TiledStack`] (per tile, only
//!   the layers present there); `tile_accumulators`: what one tile sums into (pixels and
//!   lattice nodes) and the expansion of the nodes; `kernels`: its SIMD inner loops over
//!   the entries; `tile_output`: its per-pixel loops after them (interpolation along x, the
//!   image add); `ahead`: its paced prefetch of the next tile's values.
//! - `cpu_sum`: that sum as the CPU's [`LayerSum`], with its image.
//! - `cpu`: [`CpuRelighter`], the bookkeeping over the CPU sum.
//! - `finite`: [`check_finite_image`], the last check on a relit image.
//! - [`bandwidth`]: how fast this machine reads memory, the floor under any relight.
//!
//! The sum is memory-bound; how the CPU sum reads each needed sample once is in
//! `cpu_sum.rs`, and measured figures are in `docs/measurements.md`.

mod ahead;
pub mod bandwidth;
mod bookkeeping;
mod cpu;
mod cpu_sum;
mod finite;
pub(crate) mod kernels;
mod layer_sum;
pub mod part_scales;
mod region_entries;
mod shape;
mod tile_accumulators;
mod tile_output;
pub mod tiled_sum;
mod weight;

pub use bookkeeping::{RelightBookkeeping, FULL_RESUM_EVERY};
pub use cpu::CpuRelighter;
pub use finite::check_finite_image;
pub use layer_sum::{LayerSum, RelightStats};
pub use shape::StackShape;
pub use weight::{group_factors, group_factors_of, layer_weight};

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tile_output_tests;

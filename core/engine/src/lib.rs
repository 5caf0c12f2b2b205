//! Relume's pure core: no Python, no Blender, no GPU.
//!
//! The method is Sun, Zhou & Shi 2008 ("Real-time global illumination rendering with
//! dynamic materials"): the BRDF of every editable region is written in a small basis
//! (diffuse + PCA of Blinn–Phong lobes), a path tracer splits the radiance reaching the eye by
//! path signature — the (region, basis) pairs met along the path — into the layers of a
//! *transfer stack*, and a relight is a weighted sum of those layers whose weights are
//! products of per-region basis coefficients.
//!
//! Module map (one concept per file), from the ground floor up:
//! - [`error`], [`byte_size`], [`layer_key`] (path signatures, the key of every layer), [`options`] (the
//!   bake's options that the stack records, and the limits that size the integrator),
//!   [`progress`] (progress and cancellation): the shared vocabulary, importing none of the
//!   folders below.
//! - [`scene`]: the scene model, its versioned JSON file, validation.
//! - [`brdf`]: Blinn–Phong, the PCA basis, the Principled mapping.
//! - [`bssrdf`]: translucency: the dipole profile, its PCA basis, Blender's subsurface inputs.
//! - [`linalg`]: the Gram matrices and eigen-solvers behind both PCA bases.
//! - [`geometry`]: BVH (obvhs), sampling helpers, camera rays, light sampling.
//! - [`bake`]: the bake, a folder per stage (`prepare`, `path`: the integrator, `schedule`,
//!   `finish`, and `farm` for a bake split over machines), its settings and report, the
//!   reference renderer.
//! - [`stack`]: the transfer stack in memory and as one OpenEXR file.
//! - [`relight`]: the CPU relight (the reference for the GPU one).
//! - [`refine`]: after an edit settles, what the relight misses past the second path vertex,
//!   traced in passes and added to the relit image.
//! - [`materials`]: material edits (JSON) applied at relight time.
//! - [`features`]: the surfaces each pixel sees (albedo, normal), for denoising the shown image.

// `!(x > 0.0)` is written on purpose throughout: it also rejects NaN, which
// `x <= 0.0` would let through.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bake;
pub mod brdf;
pub mod bssrdf;
pub mod byte_size;
pub mod error;
pub mod features;
pub mod geometry;
pub mod image_io;
pub mod layer_key;
pub mod linalg;
pub mod materials;
pub mod memory;
pub mod options;
pub mod output_path;
pub mod progress;
pub mod refine;
pub mod relight;
pub mod scene;
pub mod stack;

pub use error::{RelumeError, Result};

/// Scene-linear Rec.709 RGB, the colour space of Cycles and of every Relume image.
pub type Rgb = glam::Vec3;

/// Rec. 709 luminance of a scene-linear colour (what guides and sampling weights steer by).
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

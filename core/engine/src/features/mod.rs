//! What a denoiser of the *shown* image needs to know of each pixel besides its colour: the
//! surfaces the pixel sees (OpenImageDenoise's "auxiliary features", albedo and normal).
//!
//! Why here and not in the stack: the relit image is an exact linear function of the stack,
//! and the features are an exact function of the scene alone (primary rays, no light), so
//! they need no sampling noise and no new stack format. [`PixelFeatures::trace`] computes
//! them once per loaded stack from the scene it was baked from; what changes with an edit is
//! only the albedo of the editable regions, which [`PixelFeatures::albedo`] recomputes from
//! the current materials in one pass over the pixels.
//!
//! Per pixel the features keep what the albedo needs under any material: the share of the
//! pixel's area each editable region covers (with the mean of its albedo texture there),
//! and the albedo the fixed surfaces add, which no edit changes. Pixels whose rays meet no
//! surface (the world, seen directly) have albedo 0 and normal 0.

mod albedo;
mod pixel_features;
mod trace;

pub use albedo::albedo_of;
pub use pixel_features::{EditableShare, PixelFeatures};
pub use trace::FEATURE_SAMPLES_PER_AXIS;

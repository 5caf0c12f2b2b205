//! Stage 1, preparation: everything a bake does before it traces the image, once per bake.
//!
//! - [`context`]: the scene laid out for tracing (validation, the BRDF and subsurface bases,
//!   the slots, the lights, the BVH, the camera), the [`context::BakeContext`] that every
//!   later stage reads.
//! - [`setup`]: the set-up steps that trace rays, in the bake's order: the light entering
//!   each translucent region ([`subsurface_light`]; the region's data and its gather at an
//!   eye hit are [`subsurface`]), the bounce pre-pass ([`bounces`], which picks the count
//!   by the rule in [`bounce_budget`]) and the guide pass ([`guide_pass`]).
//! - [`estimate`]: the memory forecast from a small probe trace, run between the pre-pass
//!   and the guide pass so that a bake that cannot fit is refused in a second, before
//!   anything long runs.
//!
//! Apart from the other stages because none of it depends on which eye samples are traced
//! or how: a streaming bake, a progressive one and each partition of a farm prepare the
//! same way, and the reference render prepares a context without baking.

pub mod bounce_budget;
pub mod bounces;
pub mod context;
pub mod estimate;
pub mod guide_pass;
pub mod setup;
pub mod subsurface;
pub mod subsurface_light;

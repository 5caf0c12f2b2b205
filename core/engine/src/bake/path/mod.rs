//! Stage 2, the path: what one eye sample traces and where its light goes.
//!
//! - [`integrator`]: one eye sample, from the camera ray to the light per slot (direct)
//!   and per slot pair (one bounce), with the frozen tail beyond; it hands its light to a
//!   [`integrator::PathSink`], traces through a [`integrator::Tracer`] and asks a
//!   [`integrator::VertexBrdf`] for the values at each vertex.
//! - [`vertex_brdf`]: the three vertex BRDFs (the bake's basis values, the true
//!   Blinn–Phong, the projected reconstruction); [`surface_brdf`] and [`frozen`]: the
//!   bake-time material, where the material is not edited and for Russian roulette;
//!   [`tail_edits`]: which editable parts a path's later vertices reflected at, for the
//!   tail-edit layers that let those vertices follow albedo edits.
//! - [`mixture`], [`guide`] and [`guide_tree`]: how indirect directions are drawn (cosine
//!   and lobes, or the guide pass's per-tile trees); [`mis`]: how light samples and
//!   BSDF-sampled rays are weighed against each other.
//! - [`bounce_kinds`]: Cycles' per-kind light path limits (diffuse, glossy), as the
//!   probability that a path is still within them at each vertex.
//!
//! Apart from the other stages because it is per sample and knows nothing of tiles,
//! passes, files or stacks: the schedulers, the preparation's probe, pre-pass and guide
//! pass, and the reference render all trace through it, and random numbers are drawn in
//! the same order whoever calls it.

pub mod bounce_kinds;
pub mod frozen;
pub mod guide;
pub mod guide_tree;
pub mod integrator;
pub mod mis;
pub mod mixture;
pub mod surface_brdf;
pub mod tail_edits;
pub mod vertex_brdf;

//! Stage 4, after the relight: refining an edit's tail in the background.
//!
//! The stack is exact at the first two path vertices for any materials; later vertices (the
//! tail) follow a region's diffuse and glossy energy through the tail-edit layers, but keep
//! the bake-time lobes' shapes, leave out the product of two regions edited together and
//! stop following a region after a few vertices on it (docs/bounces.md). What those leave
//! out is measured here, after an edit settles, and added to the relit image progressively.
//!
//! Each refinement pass traces one more eye sample per pixel, **twice along the same
//! path** (the same random numbers: directions come from each region's mixture and Russian
//! roulette steers by the bake-time throughput, neither depends on the edit):
//! - once as the bake traces it, each layer's light weighed at once by that layer's weight
//!   for the current materials and lights ([`weighted_sink`]) — that path's share of the
//!   relit image, the tail-edit layers included;
//! - once with the first two vertices still in the basis but the tail evaluated with the
//!   edited materials ([`edited_tail`]), and the path going on past the bounces baked to
//!   the bake's cap ([`crate::stack::StackHeader::refine_bounces`]): a bounce budget judged
//!   the later bounces at the bake-time materials, and an edit can make them matter.
//!
//! Their difference is zero wherever the stack's model of the tail is exact (and the bake
//! traced every bounce its cap allowed), so it adds
//! little noise where the relight is already right, and its mean over passes converges to
//! what the relight is missing: the image with the edited tail, the first two vertices
//! relit as the stack relights them. Pass `k` traces the bake's own eye sample
//! `k` of every pixel, so after as many passes as the bake had samples per pixel the
//! refined image is the one the bake would have made along its own paths with the edited
//! tail. The next edit starts a new refinement.
//!
//! Approximate where the stack is: the difference is taken against the path's layer sums
//! before the bake's finishing steps (the linear denoiser, the lattice of bounce layers,
//! layers dropped as negligible), so it corrects the tail, not those. And as the bake does
//! with its bounce layers, the correction is smoothed by the linear denoiser
//! ([`crate::bake::finish::denoise`], weights from the passes' eye hits, the stack's
//! bounce-layer iterations): a sharp lobe met along a direction drawn for another material
//! makes a noisy difference, and the tail is indirect light. That filter is a bias where the
//! tail's light changes faster than the geometry, as it is in the bake; a stack baked
//! without it gets the raw mean, the exact one along the bake's paths.
//!
//! Files: [`refiner`] prepares the scene for one stack and starts a [`Refinement`] per edit;
//! [`passes`] traces them; [`correction`] turns the sums into the image added to the relit
//! one, shrunk where it is within its own noise ([`shrinkage`]).

pub mod correction;
pub mod edited_tail;
pub mod passes;
pub mod refinement;
pub mod refiner;
pub mod shrinkage;
pub mod weighted_sink;

pub use refinement::Refinement;
pub use refiner::TailRefiner;

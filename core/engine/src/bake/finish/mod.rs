//! Stage 4, finishing: from the traced light to the stack that is stored.
//!
//! - [`denoise`]: the linear edge-avoiding filter whose weights come from the eye features
//!   only, never from the layers, so that it commutes with every relight.
//! - [`reach`]: how far a pixel's indirect light stays alike, from the geometry — the
//!   denoiser's edge-stop where light changes on one surface.
//! - [`finalise`]: one tile at a time, the denoised layers become entries of the tiled stack
//!   (lattice entries where the settings ask for them), and the statistics that layer
//!   dropping needs are gathered on the way.
//! - [`drop`](mod@drop): which layers the stack keeps (none that no path reached, and within the
//!   drop budget none whose worst-case contribution is negligible).
//! - [`describe`]: the stack's header and the report of its layers.
//!
//! Apart from the schedules because all of them end here with the same code (driven tile row
//! by tile row by [`crate::bake::schedule::stream`]): given the same f32 sums, a one-pass
//! bake, a progressive one and a farm's merge make the same stack, bit for bit.

pub mod denoise;
pub mod describe;
pub mod drop;
pub mod finalise;
pub mod reach;

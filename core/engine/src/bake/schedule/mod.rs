//! Stage 3, the schedule: which eye samples of which pixels are traced when, on which
//! threads, and how their light is held until it is finished into a stack.
//!
//! - [`tiles`]: tiled, parallel, cancellable per-pixel work whose result does not depend on
//!   the thread count.
//! - [`trace`]: a range of eye samples of one tile, each pixel's samples summed in the
//!   canonical order of [`blocks`], each pixel's partial sums in a [`pixel_tree`] that
//!   touches only the layers its samples reached.
//! - The streaming schedule, for every bake: [`stream`] traces (or is handed) tile rows in
//!   bands ([`band`]), keeps each tile as its sparse averages (`traced_tile`) and hands a
//!   tile row to the finishing stage as soon as the rows its denoiser reads are traced, the
//!   denoiser computing only where a layer can be non-zero ([`denoise_sparse`]); with
//!   adaptive sampling a tile takes samples in rounds and stops early ([`adaptive`]).
//! - Sample ranges: a progressive bake's passes and a farm's partitions keep each tile's
//!   blocks of the canonical tree sparse ([`tile_sums`]: per tile the layers reached there),
//!   and a pass or a merge finishes them through the same streaming walk
//!   (`summed_finish`); `passes` drives a bake's passes on either.
//!
//! Apart from the other stages because this is where a bake's memory and its bits are
//! decided: the schedule sets what is held at once, and the one summation order in
//! [`blocks`] is what makes a progressive bake, a farm's merge and a streaming bake give the
//! same stack.

pub mod adaptive;
pub mod band;
pub mod blocks;
pub mod denoise_sparse;
pub mod doubling;
pub(crate) mod passes;
pub mod pixel_tree;
pub mod stream;
pub(crate) mod summed_finish;
pub mod tile_sums;
pub mod tiles;
pub mod trace;
pub(crate) mod traced_tile;

//! The transfer stack laid out for sparsity: per 16×16 screen tile, only the layers that
//! are non-zero there.
//!
//! A pixel only holds the layers whose eye vertex is its own region, so in most tiles most
//! layers are zero. The dense [`TransferStack`](super::TransferStack) keeps every layer as a
//! full frame — the zeros compress in its file but cost memory and relight bandwidth. A
//! [`TiledStack`] stores, per tile in raster order, a table of the layers present there
//! ([`TileLayer`], sorted by layer id) and one vector of their values ([`TileValues`]).
//! One vector per tile keeps memory in small pieces, so a bake can finalise tiles in
//! parallel without one big concatenation at the end.
//!
//! - [`layout`]: the types — [`TiledStack`], [`StackTile`], [`TileLayer`], [`TileValues`] —
//!   and the tile geometry.
//! - [`build`]: from and to the dense stack, and [`TiledStackBuilder`] for a bake that
//!   hands in f32 radiance tile by tile.
//! - [`validate`]: the structural checks shared by the writer and the reader.
//! - [`lattice`]: lattice entries — a layer over a tile as hat coefficients per segment of
//!   the tile, for the smooth bounce layers.
//! - [`lattice_sign`]: lattice fits that never take a layer or a tile image below zero
//!   where it is not.
//! - [`file`]: stack file format version [`STACK_FORMAT_VERSION_TILED`] (still OpenEXR).

pub mod build;
pub mod file;
pub mod lattice;
pub mod lattice_sign;
pub mod layout;
pub mod validate;

pub use build::{TileCoefficients, TileRadiance, TiledStackBuilder};
pub use lattice::TileLattice;
pub use layout::*;

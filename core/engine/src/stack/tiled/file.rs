//! The tiled stack as one OpenEXR file: stack format version
//! [`STACK_FORMAT_VERSION_TILED`].
//!
//! Layout (three parts, scanlines, ZIP16 by default — [`StackCompression`] —, written
//! atomically like the dense file; each chunk is made from the stack when the compressor,
//! which works on several chunks at once, asks for it, so writing holds the stack once):
//! - part `tiles`: one pixel per stack tile (`tiles_x × tiles_y`), channel `entries` (u32):
//!   how many layers the tile holds — a map of the stack's sparsity that any EXR viewer
//!   shows. It carries the Relume attributes, named as in the dense file
//!   ([`ATTR_HEADER`] with format version 2, [`ATTR_FORMAT_VERSION`] = 2,
//!   [`ATTR_SCENE_HASH`], [`ATTR_LAYERS`]: `[{name, channels, scale}, …]` per layer id).
//! - part `entries`: the entry tables of all tiles back to back in raster order, one pixel
//!   per entry, row-major in rows of up to [`ROW_WIDTH`] pixels (the last row padded with
//!   zeros); channels `layer`, `channels`, `scale` (the f32's bits) and `offset`, all u32.
//! - part `values`: the values of all tiles back to back, in rows of up to [`ROW_WIDTH`],
//!   channel `value`, f16 or f32 per the stack's precision.
//!
//! Version 3 (a stack with lattice entries, [`super::lattice`]; a stack without any is still
//! written as version 2, which older readers read) adds:
//! - to part `tiles`, channel `lattice` (u32): the tile's lattice step in pixels, 0 when
//!   the tile has no segment map;
//! - to part `entries`, channel `segments` (u32): the entry's segment mask, 0 for a
//!   per-pixel entry (a lattice entry's values are its coefficients);
//! - a fourth part `segments`: the segment maps of the tiles with a lattice, back to back
//!   in raster order, one pixel per tile pixel (row-major inside the tile), channel
//!   `segment` (u32), in rows of up to [`ROW_WIDTH`]. The nodes each segment stores follow
//!   from its map and are not written.
//!
//! Reading validates before trusting: the part and channel layout, every claimed size
//! against the file's length and the memory budget before decoding, the entry count and
//! value count the tables imply against the parts, then everything [`validate`] checks.
//! Errors are the dense reader's: `StackForeign`, `StackVersion`, `StackTruncated`,
//! `StackFormat` with a message naming what is wrong.
//!
//! The writer is `write` ([`write_tiled`] and its variants), the reader `read`
//! ([`read_tiled`]), and `parts` the layout they share.
//!
//! [`STACK_FORMAT_VERSION_TILED`]: super::STACK_FORMAT_VERSION_TILED
//! [`ATTR_HEADER`]: crate::stack::exr_file::ATTR_HEADER
//! [`ATTR_FORMAT_VERSION`]: crate::stack::exr_file::ATTR_FORMAT_VERSION
//! [`ATTR_SCENE_HASH`]: crate::stack::exr_file::ATTR_SCENE_HASH
//! [`ATTR_LAYERS`]: crate::stack::exr_file::ATTR_LAYERS
//! [`validate`]: super::validate::validate

mod parts;
mod read;
mod write;

pub use parts::ROW_WIDTH;
pub use read::read_tiled;
pub use write::{
    write_tiled, write_tiled_cancellable, write_tiled_unchecked, write_tiled_with,
    StackCompression, WriteOptions,
};

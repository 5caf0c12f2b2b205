//! The layout the tiled stack file's writer and reader share: the parts and channels by
//! name, the layers attribute's entry and the rows a part's values are cut into.

use serde::{Deserialize, Serialize};

/// Longest row of the `entries` and `values` parts: wide enough that a big stack is a few
/// hundred thousand rows, narrow enough that padding the last row costs nothing.
pub const ROW_WIDTH: usize = 4096;

pub(super) const PART_TILES: &str = "tiles";
pub(super) const PART_ENTRIES: &str = "entries";
pub(super) const PART_VALUES: &str = "values";
pub(super) const PART_SEGMENTS: &str = "segments";
pub(super) const CHANNEL_COUNT: &str = "entries";
pub(super) const CHANNEL_STEP: &str = "lattice";
/// The entry channels, sorted by name as EXR stores them (version 2; version 3 adds
/// [`CHANNEL_MASK`], which sorts last).
pub(super) const ENTRY_CHANNELS: [&str; 4] = ["channels", "layer", "offset", "scale"];
pub(super) const CHANNEL_MASK: &str = "segments";
pub(super) const CHANNEL_VALUE: &str = "value";
pub(super) const CHANNEL_SEGMENT: &str = "segment";
/// The version of the layout without lattice entries.
pub(super) const VERSION_WITHOUT_LATTICE: u32 = 2;

/// One entry of the layers attribute.
#[derive(Serialize, Deserialize)]
pub(super) struct LayerEntry {
    pub(super) name: String,
    pub(super) channels: u8,
    pub(super) scale: f32,
}

/// Width and height of a part holding `n` values in rows of up to [`ROW_WIDTH`] (at least
/// one pixel: an EXR part is never empty).
pub(super) fn rows_for(n: usize) -> (usize, usize) {
    let width = n.clamp(1, ROW_WIDTH);
    (width, n.div_ceil(width).max(1))
}

//! The tiled stack's types: the stack, its tiles, their entries and values, and the tile
//! geometry they share with the bake.

use super::lattice::TileLattice;
use crate::layer_key::LayerKey;
use crate::stack::{Precision, StackHeader};

/// Tile edge in pixels: the bake's tile (`bake::schedule::tiles::TILE`, equal by a test), so a bake can hand
/// over each of its tiles as it finishes.
pub const STACK_TILE: u32 = 16;

/// Stack file format version of the tiled layout (the dense one is
/// [`crate::stack::STACK_FORMAT_VERSION`]); a [`TiledStack`]'s header carries this version.
///
/// Version 3 added lattice entries ([`super::lattice`]): a tile's segment map and, per
/// entry, the segments it covers. The writer still writes a stack without lattice entries
/// in the version-2 layout, and the reader reads both.
pub const STACK_FORMAT_VERSION_TILED: u32 = 3;

/// A whole transfer stack, tile by tile.
#[derive(Clone, Debug, PartialEq)]
pub struct TiledStack {
    /// The header; its `format_version` is [`STACK_FORMAT_VERSION_TILED`].
    pub header: StackHeader,
    /// Per layer id, what the layer is as a whole (entries refer to layers by position
    /// here). A layer present in no tile is still listed, so ids match the dense stack's
    /// layer order.
    pub layers: Vec<TiledLayerInfo>,
    /// Every tile in raster order: `tiles_x() × tiles_y()` of them.
    pub tiles: Vec<StackTile>,
}

/// What a layer is as a whole, independent of the tiles holding it.
#[derive(Clone, Debug, PartialEq)]
pub struct TiledLayerInfo {
    pub key: LayerKey,
    /// 1 (grey) or 3 (RGB): the channels of the full layer. A tile may store an RGB layer
    /// with 1 channel where its three channels are equal.
    pub channels: u8,
    /// The layer's scale in the dense stack: what [`TiledStack::to_dense`] quantises to.
    pub scale: f32,
}

/// The layers present in one tile and their values.
#[derive(Clone, Debug, PartialEq)]
pub struct StackTile {
    /// Sorted by layer id, no id twice; their values lie back to back in `values`.
    pub entries: Vec<TileLayer>,
    pub values: TileValues,
    /// The tile's segment map and lattice, which its lattice entries share; `None` when
    /// the tile has none.
    pub lattice: Option<TileLattice>,
}

impl StackTile {
    /// Values entry `e` holds in a tile of `pixels` pixels: per pixel its channels, or for
    /// a lattice entry its coefficients (0 when its mask does not fit the tile's lattice —
    /// [`super::validate::validate`] refuses such a stack).
    pub fn value_count(&self, e: &TileLayer, pixels: usize) -> usize {
        if e.segments == 0 {
            return pixels * e.channels as usize;
        }
        self.lattice
            .as_ref()
            .and_then(|l| l.coefficient_count(e.segments, e.channels))
            .unwrap_or(0)
    }
}

/// One layer in one tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileLayer {
    /// Position in [`TiledStack::layers`].
    pub layer: u32,
    /// 1 (grey: one value per pixel applies to R, G and B) or 3 (RGB interleaved).
    pub channels: u8,
    /// Stored value × scale = radiance.
    pub scale: f32,
    /// Index of the entry's first value in the tile's values: the tile's pixels row-major,
    /// channels interleaved — or, for a lattice entry, its coefficients.
    pub offset: u32,
    /// 0: a per-pixel entry. Otherwise a lattice entry ([`super::lattice`]): the mask of
    /// the tile's segments it covers (bit `s`: segment `s`); its values are, per covered
    /// segment in id order, per node the segment stores, its channels. Pixels of segments
    /// it does not cover are 0.
    pub segments: u32,
}

/// Values of one tile, in the stack's precision.
#[derive(Clone, Debug, PartialEq)]
pub enum TileValues {
    F16(Vec<half::f16>),
    F32(Vec<f32>),
}

impl TileValues {
    /// No value, in `precision`.
    pub fn empty(precision: Precision) -> TileValues {
        match precision {
            Precision::F16 => TileValues::F16(Vec::new()),
            Precision::F32 => TileValues::F32(Vec::new()),
        }
    }
    /// Number of stored values.
    pub fn len(&self) -> usize {
        match self {
            TileValues::F16(v) => v.len(),
            TileValues::F32(v) => v.len(),
        }
    }
    /// Whether there is no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Gives back the room beyond the values' length: a tile that stays in a stack for the
    /// rest of a bake should not keep what its growth over-allocated.
    pub fn shrink_to_fit(&mut self) {
        match self {
            TileValues::F16(v) => v.shrink_to_fit(),
            TileValues::F32(v) => v.shrink_to_fit(),
        }
    }
    /// The precision the values are stored in.
    pub fn precision(&self) -> Precision {
        match self {
            TileValues::F16(_) => Precision::F16,
            TileValues::F32(_) => Precision::F32,
        }
    }
    /// Bytes of value storage.
    pub fn bytes(&self) -> usize {
        self.len() * self.sample_bytes()
    }
    /// Bytes of one value.
    pub fn sample_bytes(&self) -> usize {
        match self {
            TileValues::F16(_) => 2,
            TileValues::F32(_) => 4,
        }
    }
    /// Address of the first value (for cache prefetches).
    pub fn address(&self) -> usize {
        match self {
            TileValues::F16(v) => v.as_ptr() as usize,
            TileValues::F32(v) => v.as_ptr() as usize,
        }
    }
    /// Value `i` as f32 (before the entry's scale).
    #[inline]
    pub fn get(&self, i: usize) -> f32 {
        match self {
            TileValues::F16(v) => v[i].to_f32(),
            TileValues::F32(v) => v[i],
        }
    }
}

/// The pixels one tile covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileRect {
    pub x0: u32,
    pub y0: u32,
    /// [`STACK_TILE`] except in the last column (`width − x0`).
    pub width: u32,
    /// [`STACK_TILE`] except in the last row.
    pub height: u32,
}

impl TileRect {
    /// Pixels in the tile.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// Tiles along an image side of `len` pixels.
pub fn tiles_along(len: u32) -> u32 {
    len.div_ceil(STACK_TILE)
}

/// Rectangle of tile `index` (raster order) in a `width × height` image.
pub fn tile_rect(width: u32, height: u32, index: usize) -> TileRect {
    let tx = tiles_along(width).max(1) as usize;
    let x0 = (index % tx) as u32 * STACK_TILE;
    let y0 = (index / tx) as u32 * STACK_TILE;
    TileRect {
        x0,
        y0,
        width: STACK_TILE.min(width.saturating_sub(x0)),
        height: STACK_TILE.min(height.saturating_sub(y0)),
    }
}

impl TiledStack {
    /// Tiles per row.
    pub fn tiles_x(&self) -> u32 {
        tiles_along(self.header.width)
    }
    /// Rows of tiles.
    pub fn tiles_y(&self) -> u32 {
        tiles_along(self.header.height)
    }
    /// Number of tiles the header's size needs.
    pub fn tile_count(&self) -> usize {
        self.tiles_x() as usize * self.tiles_y() as usize
    }
    /// Pixels covered by tile `index` (raster order).
    pub fn tile_rect(&self, index: usize) -> TileRect {
        tile_rect(self.header.width, self.header.height, index)
    }
    /// Total bytes of stored values (what a full relight reads, before its tables).
    pub fn sample_bytes(&self) -> usize {
        self.tiles.iter().map(|t| t.values.bytes()).sum()
    }
    /// Bytes the stack occupies in memory: its values, its tile tables and per-layer
    /// information (the header and allocator slack aside). What a relighter sharing it
    /// counts as the stack.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        let lattices: usize = self
            .tiles
            .iter()
            .filter_map(|t| t.lattice.as_ref())
            .map(TileLattice::memory_bytes)
            .sum();
        let tiles = self.tiles.len() * size_of::<StackTile>()
            + self.entry_count() * size_of::<TileLayer>()
            + self.sample_bytes()
            + lattices;
        let layers: usize = self
            .layers
            .iter()
            .map(|l| size_of::<TiledLayerInfo>() + std::mem::size_of_val(&l.key.path[..]))
            .sum();
        tiles + layers
    }
    /// Bytes of samples the dense layout ([`crate::stack::TransferStack`]) would hold for the same
    /// layers: every layer a full frame of its channels in the stack's precision.
    pub fn dense_sample_bytes(&self) -> usize {
        let value_bytes = match self.header.precision {
            Precision::F16 => 2,
            Precision::F32 => 4,
        };
        let pixels = self.header.width as usize * self.header.height as usize;
        self.layers
            .iter()
            .map(|l| pixels * l.channels as usize * value_bytes)
            .sum()
    }
    /// Number of layers present in at least one tile (of the `layers.len()` listed).
    pub fn stored_layer_count(&self) -> usize {
        let mut seen = vec![false; self.layers.len()];
        for e in self.tiles.iter().flat_map(|t| &t.entries) {
            if let Some(s) = seen.get_mut(e.layer as usize) {
                *s = true;
            }
        }
        seen.iter().filter(|&&s| s).count()
    }
    /// Number of (tile, layer) entries.
    pub fn entry_count(&self) -> usize {
        self.tiles.iter().map(|t| t.entries.len()).sum()
    }
    /// Bytes of stored values per layer id (what a relight that adds the layer reads).
    pub fn layer_bytes(&self) -> Vec<usize> {
        let mut bytes = vec![0usize; self.layers.len()];
        for (i, tile) in self.tiles.iter().enumerate() {
            let value_bytes = match tile.values {
                TileValues::F16(_) => 2,
                TileValues::F32(_) => 4,
            };
            let pixels = self.tile_rect(i).pixels();
            for e in &tile.entries {
                if let Some(b) = bytes.get_mut(e.layer as usize) {
                    *b += tile.value_count(e, pixels) * value_bytes;
                }
            }
        }
        bytes
    }
    /// Radiance of entry `entry` of tile `tile` at `pixel` (row-major inside the tile) and
    /// `channel` (0..3; a grey entry gives the same value for every channel). A lattice
    /// entry is evaluated at the pixel (its segment's ≤ 4 hats).
    ///
    /// # Panics
    /// If an index is out of range, or a lattice entry's tile has no lattice (a stack
    /// [`super::validate::validate`] refuses).
    pub fn value(&self, tile: usize, entry: usize, pixel: usize, channel: usize) -> f32 {
        let t = &self.tiles[tile];
        let e = t.entries[entry];
        assert!(channel < 3, "channel {channel} of an RGB value");
        let c = if e.channels == 1 { 0 } else { channel };
        let rect = self.tile_rect(tile);
        assert!(pixel < rect.pixels(), "pixel {pixel} outside tile {tile}");
        if e.segments == 0 {
            return t
                .values
                .get(e.offset as usize + pixel * e.channels as usize + c)
                * e.scale;
        }
        let lattice = t
            .lattice
            .as_ref()
            .expect("a lattice entry's tile has a lattice");
        let s = lattice.segments()[pixel] as usize;
        let Some(start) = lattice.segment_starts(e.segments, e.channels)[s] else {
            return 0.0;
        };
        let nodes = lattice.segment_nodes(s);
        let (x, y) = (pixel as u32 % rect.width, pixel as u32 / rect.width);
        let mut v = 0.0;
        for (node, w) in lattice.hats(x, y) {
            if w == 0.0 {
                continue;
            }
            let i = nodes.nodes.binary_search(&(node as u16)).unwrap_or(0);
            v += w * t
                .values
                .get(e.offset as usize + start + i * e.channels as usize + c);
        }
        v * e.scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_image_in_raster_order_with_smaller_edge_tiles() {
        let (w, h) = (37u32, 21u32);
        assert_eq!((tiles_along(w), tiles_along(h)), (3, 2));
        let rects: Vec<TileRect> = (0..6).map(|i| tile_rect(w, h, i)).collect();
        assert_eq!(
            rects[2],
            TileRect {
                x0: 32,
                y0: 0,
                width: 5,
                height: 16
            }
        );
        assert_eq!(
            rects[3],
            TileRect {
                x0: 0,
                y0: 16,
                width: 16,
                height: 5
            }
        );
        let covered: usize = rects.iter().map(|r| r.pixels()).sum();
        assert_eq!(covered, (w * h) as usize);
    }
}

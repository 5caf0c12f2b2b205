//! Where the tiled stack's values live on the GPU: which storage buffer ("chunk") holds
//! each tile, and how samples are packed into 32-bit words.
//!
//! **Packing.** Values go up as the stack stores them, in its precision: f16 two halves per
//! `u32` (low half first), f32 one word per sample. Nothing is converted or re-scaled, so
//! the GPU reads exactly the numbers the CPU reads and the two relights differ only in
//! rounding. Tiles are packed back to back in sample units, with no padding between them:
//! an f16 tile may start in the middle of a word. Only a chunk's end is padded, to a whole
//! word (wgpu buffers are sized in words).
//!
//! **Chunks.** A storage binding may not exceed the adapter's
//! `max_storage_buffer_binding_size`, so tiles are laid out greedily, whole and in raster
//! order, into chunks of at most that many bytes; a tile is never split. Raster order makes
//! the tiles of each chunk, and of each group of [`CHUNKS_PER_GROUP`] chunks sharing one
//! bind group, a contiguous range: one dispatch per group covers its range, and every tile
//! is summed by exactly one dispatch.

use relume_engine::stack::tiled::TiledStack;
use relume_engine::stack::Precision;

/// Chunk bindings in the shader (`chunk0` … `chunk3` in `kernel.wgsl`). With the image,
/// the weights and the tables that is 7 storage buffers per stage, within the WebGPU
/// default limit of 8.
pub const CHUNKS_PER_GROUP: usize = 4;

/// Sample encoding of the values on the GPU (the `format` parameter of the kernel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Two f16 per word, low half first.
    F16Pairs = 0,
    /// One f32 per word.
    F32 = 1,
}

impl Format {
    /// The encoding of a stack of `precision`.
    pub fn of(precision: Precision) -> Format {
        match precision {
            Precision::F16 => Format::F16Pairs,
            Precision::F32 => Format::F32,
        }
    }

    /// Bytes of one sample.
    pub fn sample_bytes(self) -> u64 {
        match self {
            Format::F16Pairs => 2,
            Format::F32 => 4,
        }
    }

    /// Bytes of a buffer of `samples` samples: whole words, at least one (a binding cannot
    /// be empty).
    pub fn buffer_bytes(self, samples: u64) -> u64 {
        (samples * self.sample_bytes()).div_ceil(4).max(1) * 4
    }
}

/// A run of consecutive tiles whose values share one storage buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chunk {
    pub first_tile: u32,
    pub tiles: u32,
    /// Samples of those tiles, back to back.
    pub samples: u64,
}

/// The layout of a whole stack's values.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    pub format: Format,
    /// In tile order; at least one (possibly empty) chunk.
    pub chunks: Vec<Chunk>,
}

impl Layout {
    /// Lays the tiles of `stack` out in chunks of at most `max_chunk_bytes`. Errors (as a
    /// message) when one tile alone holds more, naming the tile.
    pub fn new(stack: &TiledStack, max_chunk_bytes: u64) -> Result<Layout, String> {
        Self::from_tile_samples(
            Format::of(stack.header.precision),
            stack.tiles.iter().map(|t| t.values.len() as u64),
            max_chunk_bytes,
        )
        .map_err(|(t, bytes, cap)| {
            let rect = stack.tile_rect(t);
            format!(
                "the tile at pixel ({}, {}) holds {bytes} bytes of values, more than one \
                 storage binding may hold ({cap} bytes, the adapter's \
                 max_storage_buffer_binding_size)",
                rect.x0, rect.y0
            )
        })
    }

    /// [`new`](Self::new) from each tile's sample count, in raster order. The error is
    /// (tile, its bytes, the chunk's capacity in bytes).
    pub fn from_tile_samples(
        format: Format,
        tile_samples: impl Iterator<Item = u64>,
        max_chunk_bytes: u64,
    ) -> Result<Layout, (usize, u64, u64)> {
        // Offsets in the entry records are u32 sample indices.
        let cap = (max_chunk_bytes / 4 * 4 / format.sample_bytes()).min(1u64 << 32);
        let mut chunks = vec![Chunk {
            first_tile: 0,
            tiles: 0,
            samples: 0,
        }];
        for (t, n) in tile_samples.enumerate() {
            if n > cap {
                let b = format.sample_bytes();
                return Err((t, n * b, cap * b));
            }
            let last = chunks.last_mut().expect("one chunk at least");
            if last.samples + n > cap {
                chunks.push(Chunk {
                    first_tile: t as u32,
                    tiles: 1,
                    samples: n,
                });
            } else {
                last.tiles += 1;
                last.samples += n;
            }
        }
        Ok(Layout { format, chunks })
    }

    /// Bind groups: one per [`CHUNKS_PER_GROUP`] chunks.
    pub fn groups(&self) -> usize {
        self.chunks.len().div_ceil(CHUNKS_PER_GROUP)
    }

    /// First tile and number of tiles of group `g`'s dispatch.
    pub fn group_tiles(&self, g: usize) -> (u32, u32) {
        let chunks = &self.chunks[g * CHUNKS_PER_GROUP..]
            [..CHUNKS_PER_GROUP.min(self.chunks.len() - g * CHUNKS_PER_GROUP)];
        let first = chunks[0].first_tile;
        (first, chunks.iter().map(|c| c.tiles).sum())
    }

    /// Bytes of the value buffers on the GPU.
    pub fn value_bytes(&self) -> u64 {
        self.chunks
            .iter()
            .map(|c| self.format.buffer_bytes(c.samples))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(format: Format, samples: [u64; 6], max: u64) -> Result<Layout, (usize, u64, u64)> {
        Layout::from_tile_samples(format, samples.into_iter(), max)
    }

    #[test]
    fn tiles_fill_chunks_whole_and_in_raster_order() {
        // f16, 24-byte chunks = 12 samples: 5 + 0 + 7 fill chunk 0 exactly, 3 + 9 chunk 1,
        // 1 opens chunk 2.
        let l = layout(Format::F16Pairs, [5, 0, 7, 3, 9, 1], 24).unwrap();
        let got: Vec<(u32, u32, u64)> = l
            .chunks
            .iter()
            .map(|c| (c.first_tile, c.tiles, c.samples))
            .collect();
        assert_eq!(got, [(0, 3, 12), (3, 2, 12), (5, 1, 1)]);
        // Odd sample counts round up to a whole word per chunk only.
        assert_eq!(l.value_bytes(), 24 + 24 + 4);
        assert_eq!((l.groups(), l.group_tiles(0)), (1, (0, 6)));
        // f32, 9 samples a chunk: 5 + 0 | 7 | 3 | 9 | 1 — 5 chunks, 2 groups.
        let l = layout(Format::F32, [5, 0, 7, 3, 9, 1], 36).unwrap();
        assert_eq!(l.chunks.len(), 5, "{:?}", l.chunks);
        assert_eq!(l.groups(), 2);
        let (a, b) = (l.group_tiles(0), l.group_tiles(1));
        assert_eq!(a, (0, 5));
        assert_eq!(b, (5, 1), "groups cover consecutive tiles, every tile once");
    }

    #[test]
    fn a_tile_larger_than_a_chunk_is_refused() {
        let e = layout(Format::F32, [1, 1, 1, 1, 40, 1], 64).unwrap_err();
        assert_eq!(e, (4, 160, 64));
    }

    #[test]
    fn an_empty_stack_has_one_empty_chunk() {
        let l = layout(Format::F16Pairs, [0; 6], 1024).unwrap();
        assert_eq!(
            l.chunks,
            [Chunk {
                first_tile: 0,
                tiles: 6,
                samples: 0
            }]
        );
        assert_eq!((l.value_bytes(), l.groups()), (4, 1));
    }
}

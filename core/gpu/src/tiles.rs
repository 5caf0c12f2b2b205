//! The tables the kernel reads per tile, in one storage buffer of `u32` words:
//!
//! - **Tile starts** (words `0 ..= tiles`): tile `t`'s entries are records
//!   `starts[t] .. starts[t + 1]`, so the table costs one word per tile.
//! - **Entry records** (from word [`entries_at`], [`ENTRY_WORDS`] words each), the tiled
//!   stack's entries in tile order and, within a tile, its per-pixel entries then its
//!   lattice entries, each kind in its (ascending) layer order (`crate::lattice::gpu_order`:
//!   every accumulator receives its additions in the order the CPU's tiled sum adds them):
//!   `[layer, flags, scale (f32 bits), offset]`, where `offset` is the entry's first sample
//!   in its chunk and `flags` packs the channels (bits 0–7: 1 grey, 3 RGB), the entry kind
//!   (bits 8–15, [`EntryKind`]) and the chunk's slot in its bind group (bits 16–23).
//! - **Lattice pointers** (from word [`lattices_at`], one word a tile): the word where the
//!   tile's lattice block starts, 0 when the tile has no lattice. The kernel finds this
//!   table after the entry records, whose count is the last tile start.
//! - **Lattice blocks** (`crate::lattice`): per tile with a lattice, its segment map, the
//!   nodes each segment stores and its entries' segment masks.
//!
//! Sixteen bytes an entry, as the stack's own table in host memory, plus four a tile and
//! the lattice blocks. The kernel switches on the kind byte per entry (see `kernel.wgsl`).

/// Words of one entry record.
pub const ENTRY_WORDS: usize = 4;

/// Entries the kernel reads into workgroup memory at a time (`BATCH` in `kernel.wgsl`,
/// which the pipeline defines from this): a tile's entries are walked batch by batch.
pub const ENTRY_BATCH: usize = 128;

// The kernel's batch arrays (three words an entry, twice) also hold one float per invocation
// of a workgroup (256) when the lattice groups' sums are added, and together with the node
// accumulators (three floats a slot) and one flag word they must fit WebGPU's default 16 KiB
// of workgroup memory.
const _: () = assert!(3 * ENTRY_BATCH >= 256);
const _: () = assert!(4 * (3 * crate::lattice::MAX_NODE_SLOTS + 6 * ENTRY_BATCH + 1) <= 16384);

/// How an entry's values are stored (the kind byte of its flags).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntryKind {
    /// One value per pixel of the tile and channel, row-major, channels interleaved.
    Values = 0,
    /// Coefficients of hat functions on the tile's lattice, per covered segment
    /// (`crate::lattice`).
    Lattice = 1,
}

/// The flags word of an entry record.
pub fn entry_flags(channels: u8, kind: EntryKind, slot: u32) -> u32 {
    u32::from(channels) | (kind as u32) << 8 | (slot & 0xff) << 16
}

/// One entry record: layer id, flags ([`entry_flags`]), scale, first sample in the chunk.
pub fn entry_record(layer: u32, flags: u32, scale: f32, offset: u32) -> [u32; ENTRY_WORDS] {
    [layer, flags, scale.to_bits(), offset]
}

/// Word at which the entry records start, for a stack of `tiles` tiles.
pub fn entries_at(tiles: usize) -> u64 {
    tiles as u64 + 1
}

/// Word at which the lattice pointers start, after the entry records.
pub fn lattices_at(tiles: usize, entries: usize) -> u64 {
    entries_at(tiles) + (entries * ENTRY_WORDS) as u64
}

/// Words of the whole table, with `lattice_words` words of lattice blocks.
pub fn table_words(tiles: usize, entries: usize, lattice_words: u64) -> u64 {
    lattices_at(tiles, entries) + tiles as u64 + lattice_words
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_pack_channels_kind_and_slot_in_separate_bytes() {
        let f = entry_flags(3, EntryKind::Values, 2);
        assert_eq!((f & 0xff, (f >> 8) & 0xff, f >> 16), (3, 0, 2));
        let r = entry_record(7, f, 0.25, 1234);
        assert_eq!(r, [7, f, 0.25f32.to_bits(), 1234]);
        assert_eq!((entries_at(6), lattices_at(6, 10)), (7, 47));
        assert_eq!(table_words(6, 10, 20), 47 + 6 + 20);
        let f = entry_flags(1, EntryKind::Lattice, 3);
        assert_eq!((f & 0xff, (f >> 8) & 0xff, f >> 16), (1, 1, 3));
    }
}

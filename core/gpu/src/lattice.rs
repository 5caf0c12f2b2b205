//! Lattice entries on the GPU: the per-tile block of the tables that describes a tile's
//! segment map and lattice, and the limit the kernel's workgroup memory sets on them.
//!
//! The kernel sums a tile's lattice entries as the CPU's tiled sum does: each adds
//! `weight · scale · coefficient` into per-(segment, lattice node, channel) accumulators
//! held in workgroup memory, then every pixel adds its segment's ≤ 4 hat nodes into its RGB
//! accumulator. The accumulators cover `segments × lattice nodes × 3` floats, so a tile
//! with more than [`MAX_NODE_SLOTS`] (segment, node) pairs is refused before the upload.
//!
//! A tile's block, in `u32` words (offsets relative to the block's first word):
//!
//! - word 0: the lattice step (bits 0–7), the segment count (8–15), nodes per row (16–23)
//!   and rows of nodes (24–31);
//! - [`MAP_AT`] …: the segment map, four pixel ids a word (pixel `p` in byte `p % 4` of
//!   word `p / 4`), the tile's own width row-major;
//! - then, per segment, its stored-node count;
//! - then, per segment, a bit set of the lattice nodes it stores
//!   ([`mask_words`] words each, node `n` at bit `n % 32` of word `n / 32`);
//! - then, per entry of the tile in the GPU's order ([`gpu_order`]: its per-pixel entries,
//!   then its lattice entries), its segment mask (0 for an entry of per-pixel values);
//! - last, the number of the tile's per-pixel entries (where its lattice entries start).
//!
//! The stored-node counts and bit sets follow from the map (the engine's
//! [`TileLattice`] derives them the same way); uploading them spares the kernel a pass
//! over the map per entry.

use relume_engine::stack::tiled::lattice::TileLattice;
use relume_engine::stack::tiled::{StackTile, TileLayer, TiledStack};

/// Most (segment, lattice node) pairs one tile may hold: the kernel's workgroup array of
/// node accumulators has three floats for each (12 KiB, within WebGPU's default 16 KiB of
/// workgroup memory). Step 4 over 32 segments needs 800; step 2 fits 12 segments.
pub const MAX_NODE_SLOTS: usize = 1024;

/// Word of a block where the segment map starts.
pub const MAP_AT: usize = 1;

/// Words of a stored-node bit set for a lattice of `nodes` nodes.
pub fn mask_words(nodes: usize) -> usize {
    nodes.div_ceil(32)
}

/// The lattice the kernel needs for `tile`: its lattice when one of its entries is a
/// lattice entry (a lattice no entry uses needs no block).
fn used_lattice(tile: &StackTile) -> Option<&TileLattice> {
    let used = tile.entries.iter().any(|e| e.segments != 0);
    tile.lattice.as_ref().filter(|_| used)
}

/// Words of tile `tile`'s block (0 when none of its entries is a lattice entry).
pub fn block_words(tile: &StackTile) -> usize {
    let Some(l) = used_lattice(tile) else {
        return 0;
    };
    let (w, h) = l.size();
    let segments = l.segment_count();
    MAP_AT
        + (w * h) as usize / 4
        + usize::from((w * h) % 4 != 0)
        + segments * (1 + mask_words(l.node_count()))
        + tile.entries.len()
        + 1
}

/// `tile`'s entries in the order the GPU's tables list them: the per-pixel entries, then
/// the lattice entries, each in the tile's (layer) order. The two kinds add into different
/// accumulators (a pixel's, a lattice node's), so every accumulator still receives its
/// additions in layer order; the kernel walks each kind in a loop of its own.
pub fn gpu_order(tile: &StackTile) -> impl Iterator<Item = &TileLayer> {
    let values = tile.entries.iter().filter(|e| e.segments == 0);
    values.chain(tile.entries.iter().filter(|e| e.segments != 0))
}

/// Checks every used lattice against [`MAX_NODE_SLOTS`] and returns the words of all
/// the blocks. The error names the first tile over the limit.
pub fn check_and_count(stack: &TiledStack) -> Result<u64, String> {
    let mut words = 0u64;
    for (t, tile) in stack.tiles.iter().enumerate() {
        if let Some(l) = used_lattice(tile) {
            let slots = l.segment_count() * l.node_count();
            if slots > MAX_NODE_SLOTS {
                let rect = stack.tile_rect(t);
                return Err(format!(
                    "the tile at pixel ({}, {}) has {} segments × {} lattice nodes (step {}); \
                     the GPU relight holds at most {MAX_NODE_SLOTS} per tile in workgroup \
                     memory",
                    rect.x0,
                    rect.y0,
                    l.segment_count(),
                    l.node_count(),
                    l.step()
                ));
            }
        }
        words += block_words(tile) as u64;
    }
    Ok(words)
}

/// The words of `tile`'s block (empty when none of its entries is a lattice entry), as
/// the module doc lays them out.
pub fn block(tile: &StackTile) -> Vec<u32> {
    let Some(l) = used_lattice(tile) else {
        return Vec::new();
    };
    let mut out = Vec::with_capacity(block_words(tile));
    out.push(header_word(l));
    for ids in l.segments().chunks(4) {
        let word = ids
            .iter()
            .enumerate()
            .fold(0u32, |w, (i, &s)| w | u32::from(s) << (8 * i));
        out.push(word);
    }
    let nodes = l.node_count();
    let segments = l.segment_count();
    for s in 0..segments {
        out.push(l.segment_nodes(s).nodes.len() as u32);
    }
    for s in 0..segments {
        let mut bits = vec![0u32; mask_words(nodes)];
        for &n in &l.segment_nodes(s).nodes {
            bits[n as usize / 32] |= 1 << (n % 32);
        }
        out.extend(bits);
    }
    out.extend(gpu_order(tile).map(|e| e.segments));
    out.push(tile.entries.iter().filter(|e| e.segments == 0).count() as u32);
    out
}

fn header_word(l: &TileLattice) -> u32 {
    let (nx, ny) = l.nodes();
    // Each fits a byte: step ≤ 16, segments ≤ 32, nodes per side ≤ 16.
    l.step() | (l.segment_count() as u32) << 8 | nx << 16 | ny << 24
}

#[cfg(test)]
mod tests {
    use super::*;
    use relume_engine::stack::tiled::{TileLayer, TileValues};

    #[test]
    fn a_block_holds_the_map_the_node_sets_and_the_masks() {
        // 5 × 3 pixels, step 4: 2 × 2 nodes; segment 1 is the last column only, so it
        // stores the right-hand nodes alone.
        let map: Vec<u8> = (0..15).map(|p| u8::from(p % 5 == 4)).collect();
        let lattice = TileLattice::new(4, 5, 3, map.clone()).unwrap();
        let entry = |layer, segments| TileLayer {
            layer,
            channels: 1,
            scale: 1.0,
            offset: 0,
            segments,
        };
        let tile = StackTile {
            entries: vec![entry(0, 0b11), entry(1, 0), entry(2, 0b10)],
            values: TileValues::F32(Vec::new()),
            lattice: Some(lattice.clone()),
        };
        let b = block(&tile);
        assert_eq!(b.len(), block_words(&tile));
        assert_eq!(b[0], 4 | 2 << 8 | 2 << 16 | 2 << 24);
        let unpacked: Vec<u8> = (0..15)
            .map(|p| (b[MAP_AT + p / 4] >> (8 * (p % 4))) as u8)
            .collect();
        assert_eq!(unpacked, map);
        let counts_at = MAP_AT + 4;
        for s in 0..2 {
            let stored = &lattice.segment_nodes(s).nodes;
            assert_eq!(b[counts_at + s] as usize, stored.len());
            let bits = b[counts_at + 2 + s];
            let from_bits: Vec<u16> = (0..4).filter(|n| bits >> n & 1 == 1).collect();
            assert_eq!(&from_bits, stored, "segment {s}");
        }
        assert_eq!(&b[b.len() - 4..], [0, 0b11, 0b10, 1]);
    }
}

//! Where one editable region's layers sit in each tile: per tile, the indices of its table
//! entries whose layer contains the region. An edit of a region re-sums only those entries;
//! without this list the sum walks every tile's whole table to find them (a stack with many
//! editable regions holds thousands of layers, and a region's are scattered through each
//! table), which at large sizes cost about as much as a full relight. Built on a region's
//! first edit and kept, so a relighter's memory grows by two bytes per entry of each region
//! edited.

use rayon::prelude::*;

use crate::stack::tiled::TiledStack;
use crate::Result;

/// Per tile, the table indices (ascending) of the entries of one region's layers.
pub(crate) struct RegionEntries {
    /// Tile `t`'s indices are `indices[starts[t]..starts[t + 1]]`.
    starts: Vec<u32>,
    indices: Vec<u16>,
}

impl RegionEntries {
    /// The entries of `layers` (layer ids, any order) in every tile of `stack`. `None` when a
    /// tile holds more entries than a `u16` indexes, or the list would pass `u32` (a sum then
    /// walks the tables as without it). Errors when the lists cannot be allocated.
    pub(crate) fn build(stack: &TiledStack, layers: &[u32]) -> Result<Option<RegionEntries>> {
        let mut wanted: Vec<bool> =
            crate::memory::try_zeroed(stack.layers.len(), "region entry list")?;
        for &l in layers {
            if let Some(w) = wanted.get_mut(l as usize) {
                *w = true;
            }
        }
        let is_wanted = |layer: u32| wanted.get(layer as usize).copied().unwrap_or(false);
        if stack
            .tiles
            .iter()
            .any(|t| t.entries.len() > usize::from(u16::MAX) + 1)
        {
            return Ok(None);
        }
        // One pass over the tables, tiles in parallel (it is what a region's first edit
        // waits for), then the lists laid end to end.
        let per_tile: Vec<Vec<u16>> = stack
            .tiles
            .par_iter()
            .map(|tile| {
                let wanted_here = tile
                    .entries
                    .iter()
                    .enumerate()
                    .filter(|(_, e)| is_wanted(e.layer));
                wanted_here.map(|(k, _)| k as u16).collect()
            })
            .collect();
        let count: usize = per_tile.iter().map(Vec::len).sum();
        if u32::try_from(count).is_err() {
            return Ok(None);
        }
        let mut starts: Vec<u32> =
            crate::memory::try_with_capacity(stack.tiles.len() + 1, "region entry list")?;
        let mut indices: Vec<u16> = crate::memory::try_with_capacity(count, "region entry list")?;
        starts.push(0);
        for list in &per_tile {
            indices.extend_from_slice(list);
            starts.push(indices.len() as u32);
        }
        Ok(Some(RegionEntries { starts, indices }))
    }

    /// The table indices of tile `tile`'s entries of the region, ascending.
    #[inline(always)]
    pub(crate) fn of_tile(&self, tile: usize) -> &[u16] {
        &self.indices[self.starts[tile] as usize..self.starts[tile + 1] as usize]
    }

    /// Heap bytes held.
    pub(crate) fn heap_bytes(&self) -> usize {
        self.starts.capacity() * std::mem::size_of::<u32>()
            + self.indices.capacity() * std::mem::size_of::<u16>()
    }
}

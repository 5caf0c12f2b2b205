//! One tile's eye-sample sums, kept sparse: per aligned block of the canonical summation
//! tree ([`super::blocks`]) the pixels' feature sums and the layers some sample of the block
//! reached on the tile. A farm partition writes these per tile ([`crate::bake::farm::partial`]),
//! its merge reads and sums them, and a progressive bake keeps them in memory between its
//! passes; all three combine blocks here, in the tree's grouping, so they reach the same
//! bits as a one-pass bake without ever holding a full frame of any layer.

use std::ops::Range;
use std::sync::atomic::AtomicU64;

use super::blocks::siblings;
use super::tiles::Tile;
use super::trace::trace_tile_records;
use crate::bake::finish::denoise::{EyeFeatures, FEATURE_STRIDE};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::progress::Progress;
use crate::{RelumeError, Result};

/// One block of one tile: the pixels' feature sums and, per layer non-zero on the tile,
/// its per-pixel RGB sums (sorted by layer id).
#[derive(Clone, Debug, Default)]
pub struct TileSums {
    pub features: Vec<f32>,
    pub layers: Vec<(u32, Vec<f32>)>,
}

impl TileSums {
    /// Traces eye samples `samples` of `tile` and returns them as sparse sums, one per
    /// block of [`super::blocks::dyadic_blocks`] of `samples`: what a farm partition writes
    /// and a progressive bake keeps of a tile. Progress is checked, not advanced.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn traced(
        ctx: &BakeContext,
        brdf: &BasisBrdf,
        blocks: usize,
        tile: &Tile,
        samples: Range<u32>,
        progress: &Progress,
        rays: &AtomicU64,
    ) -> Result<Vec<TileSums>> {
        let records = trace_tile_records(ctx, brdf, blocks, false, tile, samples, progress, rays)?
            .ok_or(RelumeError::Cancelled)?;
        Ok(TileSums::from_records(
            &records,
            tile.pixels(),
            ctx.layer_count(),
            blocks,
        ))
    }

    /// A traced tile's records ([`super::trace::trace_tile_records`]: `blocks` × `tp`
    /// pixels, block-major, each record the layers' sums then the features) as sparse sums:
    /// per block the features and the layers non-zero somewhere on the tile.
    pub(crate) fn from_records(
        buf: &[f32],
        tp: usize,
        layer_count: usize,
        blocks: usize,
    ) -> Vec<TileSums> {
        let record = layer_count * 3 + FEATURE_STRIDE;
        (0..blocks)
            .map(|b| {
                let rec = &buf[b * tp * record..(b + 1) * tp * record];
                let mut features = Vec::with_capacity(tp * FEATURE_STRIDE);
                let mut non_zero = vec![false; layer_count];
                for p in 0..tp {
                    let r = &rec[p * record..(p + 1) * record];
                    features.extend_from_slice(&r[layer_count * 3..]);
                    for (seen, texel) in non_zero.iter_mut().zip(r.chunks_exact(3)) {
                        *seen |= texel.iter().any(|v| *v != 0.0);
                    }
                }
                let layers = (0..layer_count)
                    .filter(|l| non_zero[*l])
                    .map(|l| {
                        let mut sums = Vec::with_capacity(tp * 3);
                        for p in 0..tp {
                            let at = p * record + l * 3;
                            sums.extend_from_slice(&rec[at..at + 3]);
                        }
                        (l as u32, sums)
                    })
                    .collect();
                TileSums { features, layers }
            })
            .collect()
    }

    /// Bytes its features and sums hold.
    pub fn bytes(&self) -> usize {
        4 * (self.features.len() + self.layers.iter().map(|(_, s)| s.len()).sum::<usize>())
    }

    /// Adds `right` into `self`: per pixel left + right for a layer both hold, the one held
    /// otherwise (an absent layer is zeros, which are never added: exact, see
    /// [`super::blocks`]), and the features merged as the bake merges them.
    pub fn absorb(&mut self, right: TileSums) {
        for (a, b) in self
            .features
            .chunks_exact_mut(FEATURE_STRIDE)
            .zip(right.features.chunks_exact(FEATURE_STRIDE))
        {
            EyeFeatures::merge(a, b);
        }
        let mut out = Vec::with_capacity(self.layers.len().max(right.layers.len()));
        let mut mine = std::mem::take(&mut self.layers).into_iter().peekable();
        let mut theirs = right.layers.into_iter().peekable();
        loop {
            let next = match (mine.peek(), theirs.peek()) {
                (None, None) => break,
                (Some(_), None) => mine.next(),
                (None, Some(_)) => theirs.next(),
                (Some((a, _)), Some((b, _))) if a < b => mine.next(),
                (Some((a, _)), Some((b, _))) if b < a => theirs.next(),
                _ => {
                    let (id, mut x) = mine.next().expect("peeked");
                    let (_, y) = theirs.next().expect("peeked");
                    for (p, q) in x.iter_mut().zip(&y) {
                        *p += *q;
                    }
                    Some((id, x))
                }
            };
            out.extend(next);
        }
        self.layers = out;
    }
}

/// One tile's blocks of the samples given so far, in sample order, siblings summed as they
/// meet: what the tile holds between a progressive bake's passes, or while a merge reads
/// its parts.
#[derive(Clone, Debug, Default)]
pub struct TileBlocks {
    blocks: Vec<(Range<u32>, TileSums)>,
}

impl TileBlocks {
    /// Appends `sums` of the samples `range` (the next ones in order: an aligned dyadic
    /// range, or a folded `[0, spp)`) and sums siblings as they meet.
    pub fn push(&mut self, range: Range<u32>, sums: TileSums) {
        self.blocks.push((range, sums));
        while self.blocks.len() >= 2 {
            let k = self.blocks.len() - 1;
            if !siblings(&self.blocks[k - 1].0, &self.blocks[k].0) {
                break;
            }
            let (right_range, right) = self.blocks.pop().expect("two blocks");
            let left = self.blocks.last_mut().expect("two blocks");
            left.1.absorb(right);
            left.0.end = right_range.end;
        }
    }

    /// The samples covered: `[first start, last end)` (empty when there is no block).
    pub fn range(&self) -> Range<u32> {
        match (self.blocks.first(), self.blocks.last()) {
            (Some(a), Some(b)) => a.0.start..b.0.end,
            _ => 0..0,
        }
    }

    /// Bytes the blocks hold.
    pub fn bytes(&self) -> usize {
        self.blocks.iter().map(|(_, s)| s.bytes()).sum()
    }

    /// The right fold `b₀ + (b₁ + (…))` of the blocks: the tile's canonical sums of every
    /// sample given. Consumes the blocks (the last pass of a bake, or a merge).
    pub fn fold(mut self) -> TileSums {
        while self.blocks.len() >= 2 {
            let (_, right) = self.blocks.pop().expect("two blocks");
            self.blocks.last_mut().expect("one block").1.absorb(right);
        }
        self.blocks.pop().map(|(_, s)| s).unwrap_or_default()
    }

    /// [`Self::fold`] of a copy, keeping the blocks for more samples (between the passes of
    /// a progressive bake): only this tile's sums are copied at a time.
    pub fn folded_copy(&self) -> TileSums {
        self.clone().fold()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::schedule::blocks::dyadic_blocks;
    use crate::bake::schedule::pixel_tree::PixelTree;
    use crate::Rgb;

    /// Per-sample values whose sums round differently in every grouping.
    fn value(s: u32) -> f32 {
        let h = s.wrapping_mul(2_654_435_761) >> 8;
        (h % 9973) as f32 * 1.0e-3 * 10f32.powi((h % 7) as i32 - 3)
    }

    fn tree_sum(from: u32, to: u32, fold: bool) -> (Vec<Range<u32>>, Vec<f32>) {
        let mut t = PixelTree::new(1).unwrap();
        for s in from..to {
            t.push_leaf(s).add(0, Rgb::new(value(s), 0.0, 0.0));
            t.close_leaf();
        }
        if fold {
            t.fold();
        }
        (
            t.blocks().to_vec(),
            (0..t.blocks().len()).map(|k| t.record(k)[0]).collect(),
        )
    }

    #[test]
    fn any_split_folds_to_the_same_bits() {
        let spp = 37;
        let (_, whole) = tree_sum(0, spp, true);
        let sequential: f32 = (0..spp).map(value).sum();
        for parts in [1u32, 2, 3, 5, 7, 37] {
            let mut store = TileBlocks::default();
            for i in 0..parts {
                let (a, b) = (i * spp / parts, (i + 1) * spp / parts);
                let (ranges, values) = tree_sum(a, b, false);
                assert_eq!(ranges, dyadic_blocks(a, b));
                for (r, v) in ranges.into_iter().zip(values) {
                    let sums = TileSums {
                        features: EyeFeatures::EMPTY.to_vec(),
                        layers: vec![(0, vec![v, 0.0, 0.0])],
                    };
                    store.push(r, sums);
                }
            }
            assert_eq!(store.range(), 0..spp);
            let copy = store.folded_copy();
            let merged = store.fold().layers[0].1[0];
            assert_eq!(merged.to_bits(), whole[0].to_bits(), "{parts} parts");
            assert_eq!(copy.layers[0].1[0].to_bits(), merged.to_bits());
        }
        // The point of it all: another grouping gives other bits for these values.
        assert_ne!(sequential.to_bits(), whole[0].to_bits());
    }
}

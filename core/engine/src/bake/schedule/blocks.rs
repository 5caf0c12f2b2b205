//! The one order in which a bake adds its eye samples, so that a bake split into sample
//! ranges (a farm's partitions, a progressive bake's passes) adds up to the same bits as
//! one bake.
//!
//! f32 addition is not associative: `(a + b) + c` and `a + (b + c)` differ in the last bits,
//! and a pixel summed sample by sample on one machine would differ from the same samples
//! summed per partition and then across partitions. Three ways out were weighed:
//!
//! - *An exactly associative accumulator* (fixed point in i64/i128, or a "superaccumulator"
//!   wide enough for the whole f32 exponent range). Radiance is HDR and unbounded: a fixed
//!   point scale that is exact for a 1e-9 contribution of a dim bounce layer and does not
//!   overflow on a 1e5 highlight needs ≈ 280 bits per channel — 10× the memory of the sums.
//! - *f64 sums of f32 values.* Exact only while every value and partial sum fits in 53 bits
//!   relative to the smallest one: 24 bits of mantissa + log2(samples) + the dynamic range
//!   of the contributions, which for HDR light is not bounded. Not provable: not used.
//! - *A fixed binary tree over sample indices* (used here). Every pixel's per-sample values
//!   (one [`leaf`](super::pixel_tree::PixelTree::push_leaf) per eye sample: that sample's
//!   contributions summed in the integrator's own order, the same on every machine) are
//!   combined pairwise in the
//!   tree whose nodes are the aligned dyadic ranges `[k·2^j, (k+1)·2^j)`: a node's value is
//!   `left + right`, its children's values. Above the last sample the tree has no nodes, so
//!   for a bake of `spp` samples the root is the right fold `b₀ + (b₁ + (… + b_m))` of the
//!   maximal aligned blocks of `[0, spp)` (the binary digits of `spp`, largest first).
//!
//! A sample range `[a, b)` holds every complete node inside it; it delivers the maximal ones
//! — at most 2·log2(b − a) + 2 blocks ([`dyadic_blocks`]) — and the combination of the
//! ranges' blocks, merging siblings as they meet ([`super::tile_sums::TileBlocks::push`]), computes the
//! same nodes from the same children, hence the same bits, whatever the split. (Pushing an
//! aligned block is the same as pushing its samples one by one: none of its inner nodes has
//! a sibling outside it.) The combination is pure pairwise addition, which is commutative
//! in IEEE arithmetic, so only the grouping matters, and the grouping is the tree's.
//!
//! Absent values are zeros that are never added. That is exact too: every accumulator starts
//! at +0.0, and an f32 sum is −0.0 only when both operands are −0.0, so no sum is ever −0.0,
//! and `x + (+0.0) == x` bit for bit for every other `x`.
//!
//! The cost: a pixel keeps a stack of up to ≈ log2(spp) partial records while its samples
//! are traced (one record per level, [`super::pixel_tree::PixelTree`]), and each sample
//! adds, amortised, one record's worth of additions — of the layers its samples reached
//! (the tree has one inner node per sample). A one-pass bake folds each pixel's tree in
//! the tile and keeps no store ([`super::stream`]: the tree's root is
//! all it needs), a farm's partition writes each tile's blocks as they are traced and its
//! merge sums one tile's blocks at a time. A progressive bake keeps each tile's blocks
//! between its passes, sparse ([`super::tile_sums`]): popcount(samples so far) blocks per
//! tile, of the layers reached on it ([`crate::bake::schedule::doubling`] of a power-of-two
//! `spp` keeps one).

use std::ops::Range;

use crate::bake::finish::denoise::EyeFeatures;

/// Whether the aligned dyadic ranges `left` and `right` are the two children of one node.
#[inline]
pub(crate) fn siblings(left: &Range<u32>, right: &Range<u32>) -> bool {
    let len = left.end - left.start;
    left.end == right.start
        && right.end - right.start == len
        && (left.start as u64).is_multiple_of(2 * len as u64)
}

/// The maximal aligned dyadic ranges inside `[from, to)`, in order: what a sample range
/// delivers ([`super::pixel_tree::PixelTree`] leaves them on its stack).
pub fn dyadic_blocks(from: u32, to: u32) -> Vec<Range<u32>> {
    let mut out: Vec<Range<u32>> = Vec::new();
    for s in from..to {
        out.push(s..s + 1);
        while out.len() >= 2 && siblings(&out[out.len() - 2], &out[out.len() - 1]) {
            let right = out.pop().expect("two blocks");
            let left = out.last_mut().expect("two blocks");
            left.end = right.end;
        }
    }
    out
}

/// One pixel's record: `layers × 3` sums, then the denoiser's [`FEATURE_STRIDE`](crate::bake::finish::denoise::FEATURE_STRIDE) features.
#[inline]
pub fn combine(into: &mut [f32], from: &[f32], layer_floats: usize) {
    let (a, fa) = into.split_at_mut(layer_floats);
    let (b, fb) = from.split_at(layer_floats);
    for (x, y) in a.iter_mut().zip(b) {
        *x += *y;
    }
    EyeFeatures::merge(fa, fb);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_the_maximal_aligned_ranges() {
        assert_eq!(dyadic_blocks(0, 16), vec![0..16]);
        assert_eq!(dyadic_blocks(0, 21), vec![0..16, 16..20, 20..21]);
        assert_eq!(dyadic_blocks(5, 10), vec![5..6, 6..8, 8..10]);
        assert_eq!(dyadic_blocks(3, 3), Vec::<Range<u32>>::new());
        for (a, b) in [(0u32, 1u32), (1, 2), (2, 9), (9, 16), (7, 100)] {
            let blocks = dyadic_blocks(a, b);
            assert_eq!(blocks.first().unwrap().start, a);
            assert_eq!(blocks.last().unwrap().end, b);
            for r in &blocks {
                let len = r.end - r.start;
                assert!(len.is_power_of_two() && r.start % len == 0, "{r:?}");
            }
            assert!(blocks.len() <= 2 * (32 - (b - a).leading_zeros()) as usize + 2);
        }
    }
}

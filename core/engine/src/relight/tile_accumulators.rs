//! The accumulators one tile of the tiled sum ([`super::tiled_sum`]) adds its entries into,
//! and how they reach the image.
//!
//! - Per-pixel entries: planar R, G, B rows for grey entries and an interleaved RGB row for
//!   RGB ones (the two shapes of [`super::kernels`]), as long as the tile's pixels rounded
//!   up to whole vectors.
//! - Lattice entries ([`crate::stack::tiled::lattice`]): per segment, the same two shapes
//!   over the nodes the segment stores, in the order of an entry's coefficients — so each
//!   of an entry's segments is one contiguous run of values added into one contiguous run
//!   of accumulators, the kernels' vector loops, with no per-node scatter. After the
//!   tile's entries, each node's grey and RGB parts are added, the nodes are expanded to
//!   pixels once (each pixel its segment's ≤ 4 hats), into the RGB row.
//!
//! The expansion's hat weights depend only on the lattice's step and the tile's size, so
//! they are computed once per such shape and kept ([`HatTable`]), not per tile.

use crate::stack::tiled::lattice::MAX_SEGMENTS;
use crate::stack::tiled::{TileLattice, STACK_TILE};

use super::kernels::padded;

/// Values per tile and channel.
pub(super) const TILE_PIXELS: usize = (STACK_TILE * STACK_TILE) as usize;

/// One worker's accumulators, reused tile after tile.
pub(super) struct TileAccumulators {
    /// Grey entries, per channel, per pixel (row-major in the tile).
    pub r: [f32; TILE_PIXELS],
    pub g: [f32; TILE_PIXELS],
    pub b: [f32; TILE_PIXELS],
    /// RGB entries and the expanded lattice, per pixel interleaved.
    pub rgb: [f32; 3 * TILE_PIXELS],
    nodes: NodeAccumulators,
    hats: HatTable,
}

impl TileAccumulators {
    /// Zeroed accumulators (boxed: they are a few kilobytes).
    pub(super) fn new() -> Box<TileAccumulators> {
        Box::new(TileAccumulators {
            r: [0.0; TILE_PIXELS],
            g: [0.0; TILE_PIXELS],
            b: [0.0; TILE_PIXELS],
            rgb: [0.0; 3 * TILE_PIXELS],
            nodes: NodeAccumulators::default(),
            hats: HatTable::default(),
        })
    }

    /// Zeroes the per-pixel accumulators of a tile of `pixels` pixels (with their padding).
    pub(super) fn clear_pixels(&mut self, pixels: usize) {
        let n = padded(pixels);
        self.r[..n].fill(0.0);
        self.g[..n].fill(0.0);
        self.b[..n].fill(0.0);
        self.rgb[..padded(3 * pixels)].fill(0.0);
    }

    /// Lays out and zeroes the node accumulators for `lattice`'s segments.
    pub(super) fn clear_nodes(&mut self, lattice: &TileLattice) {
        self.nodes.clear(lattice);
    }

    /// Segment `s`'s node accumulators: planar R, G, B and interleaved RGB, each padded,
    /// and the number of nodes it stores. Needs [`clear_nodes`](Self::clear_nodes) for the
    /// tile's lattice first.
    ///
    /// # Panics
    /// If `s` is not a segment of that lattice.
    #[inline(always)]
    pub(super) fn segment(&mut self, s: usize) -> SegmentAccumulators<'_> {
        self.nodes.segment(s)
    }

    /// Adds the node accumulators, expanded to the pixels of `lattice` (each pixel the hats
    /// of its own segment), into the RGB row.
    pub(super) fn expand_nodes(&mut self, lattice: &TileLattice) {
        let hats = self.hats.for_lattice(lattice);
        self.nodes.expand(lattice, hats, &mut self.rgb);
    }
}

/// One segment's node accumulators (see [`TileAccumulators::segment`]).
pub(super) struct SegmentAccumulators<'a> {
    pub r: &'a mut [f32],
    pub g: &'a mut [f32],
    pub b: &'a mut [f32],
    pub rgb: &'a mut [f32],
    /// Nodes the segment stores: grey values an entry holds for it (RGB: three per node).
    pub nodes: usize,
}

/// Per segment a block `[R | G | B | RGB]`, each part padded to whole vectors, over the
/// nodes the segment stores (in their order in [`crate::stack::tiled::lattice::SegmentNodes`]).
#[derive(Default)]
struct NodeAccumulators {
    /// Per segment, where its block starts in `data`.
    start: [u32; MAX_SEGMENTS],
    /// Per segment, the nodes it stores.
    len: [u32; MAX_SEGMENTS],
    data: Vec<f32>,
    /// Scratch of [`expand`](Self::expand): per segment, per lattice node, RGB.
    combined: Vec<f32>,
}

impl NodeAccumulators {
    fn clear(&mut self, lattice: &TileLattice) {
        let mut at = 0usize;
        for s in 0..lattice.segment_count() {
            let n = lattice.segment_nodes(s).nodes.len();
            self.start[s] = at as u32;
            self.len[s] = n as u32;
            at += 3 * padded(n) + padded(3 * n);
        }
        self.data.clear();
        self.data.resize(at, 0.0);
    }

    #[inline(always)]
    fn segment(&mut self, s: usize) -> SegmentAccumulators<'_> {
        let (start, n) = (self.start[s] as usize, self.len[s] as usize);
        let p = padded(n);
        let block = &mut self.data[start..start + 3 * p + padded(3 * n)];
        let (r, rest) = block.split_at_mut(p);
        let (g, rest) = rest.split_at_mut(p);
        let (b, rgb) = rest.split_at_mut(p);
        SegmentAccumulators {
            r,
            g,
            b,
            rgb,
            nodes: n,
        }
    }

    /// Adds the nodes expanded to pixels into `out` (interleaved RGB per pixel).
    fn expand(&mut self, lattice: &TileLattice, hats: &[[(u32, f32); 4]], out: &mut [f32]) {
        let lattice_nodes = lattice.node_count();
        let segments = lattice.segment_count();
        // Per segment, per lattice node: grey part + RGB part. Nodes a segment does not
        // store stay 0 and have weight 0 at its pixels.
        self.combined.clear();
        self.combined.resize(segments * lattice_nodes * 3, 0.0);
        for s in 0..segments {
            let (start, n) = (self.start[s] as usize, self.len[s] as usize);
            let p = padded(n);
            let block = &self.data[start..];
            let (r, g, b, rgb) = (
                &block[..n],
                &block[p..p + n],
                &block[2 * p..2 * p + n],
                &block[3 * p..3 * p + 3 * n],
            );
            let combined = &mut self.combined[s * lattice_nodes * 3..(s + 1) * lattice_nodes * 3];
            for (k, &node) in lattice.segment_nodes(s).nodes.iter().enumerate() {
                let c = &mut combined[node as usize * 3..node as usize * 3 + 3];
                c[0] = r[k] + rgb[3 * k];
                c[1] = g[k] + rgb[3 * k + 1];
                c[2] = b[k] + rgb[3 * k + 2];
            }
        }
        for ((&s, pixel_hats), px) in lattice
            .segments()
            .iter()
            .zip(hats)
            .zip(out.chunks_exact_mut(3))
        {
            let base = s as usize * lattice_nodes;
            let mut sum = [0.0f32; 3];
            for &(node, w) in pixel_hats {
                let a = &self.combined[(base + node as usize) * 3..][..3];
                sum[0] += w * a[0];
                sum[1] += w * a[1];
                sum[2] += w * a[2];
            }
            px[0] += sum[0];
            px[1] += sum[1];
            px[2] += sum[2];
        }
    }
}

/// Per pixel of a tile, its ≤ 4 lattice nodes and hat weights, for one lattice shape (step
/// and tile size); rebuilt only when the shape changes.
#[derive(Default)]
struct HatTable {
    shape: Option<(u32, u32, u32)>,
    hats: Vec<[(u32, f32); 4]>,
}

impl HatTable {
    fn for_lattice(&mut self, lattice: &TileLattice) -> &[[(u32, f32); 4]] {
        let (w, h) = lattice.size();
        let shape = (lattice.step(), w, h);
        if self.shape != Some(shape) {
            self.hats.clear();
            for y in 0..h {
                for x in 0..w {
                    self.hats
                        .push(lattice.hats(x, y).map(|(n, w)| (n as u32, w)));
                }
            }
            self.shape = Some(shape);
        }
        &self.hats
    }
}

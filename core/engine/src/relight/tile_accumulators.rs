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
//!   tile's entries, each node's grey and RGB parts are added and the nodes are expanded
//!   to pixels once, into the planar rows.
//!
//! The expansion uses that the hats are separable: per segment that received entries,
//! its nodes are interpolated along x on each row of nodes, then along y for each row of
//! pixels (plain loops over a pixel row, which vectorise), and added to the pixels of that
//! segment. That is the same bilinear sum as each pixel's ≤ 4 hats, grouped differently
//! (so equal to rounding), at a fraction of the per-pixel gathers' cost when a tile has few
//! segments, as most do. The hat weights along each axis depend only on the lattice's step
//! and the tile's size, so they are kept per such shape ([`AxisHats`]), not per tile.

use crate::stack::tiled::lattice::MAX_SEGMENTS;
use crate::stack::tiled::{TileLattice, STACK_TILE};

use super::ahead::Ahead;
use super::kernels::{padded, EntryKernels, GreyEntry, PendingEntry, RgbEntry, Sample};
use super::tile_output::{ColumnHats, TileOutputKernels};

/// Values per tile and channel.
pub(super) const TILE_PIXELS: usize = (STACK_TILE * STACK_TILE) as usize;

/// One worker's accumulators, reused tile after tile.
pub(super) struct TileAccumulators {
    /// Grey entries and the expanded lattice, per channel, per pixel (row-major in the
    /// tile).
    pub r: [f32; TILE_PIXELS],
    pub g: [f32; TILE_PIXELS],
    pub b: [f32; TILE_PIXELS],
    /// RGB entries, per pixel interleaved.
    pub rgb: [f32; 3 * TILE_PIXELS],
    /// Whether `rgb` holds this tile's sum (else it is stale and all zero for the tile).
    rgb_used: bool,
    nodes: NodeAccumulators,
    hats: AxisHats,
    /// The tile's grey lattice entries, gathered to be summed segment by segment.
    pub pending: Vec<PendingEntry>,
    /// The tile's grey per-pixel entries, gathered to be summed a few at a time.
    pub grey: Vec<GreyEntry>,
    /// The RGB entries of a tile with one segment, gathered to be added after its grey
    /// lattice entries.
    pub rgb_entries: Vec<RgbEntry>,
}

impl TileAccumulators {
    /// Sums the gathered grey per-pixel entries `grey` into the rows when the tile added any
    /// entry, and keeps the list's allocation for the next tile: the end of every entry
    /// loop's per-pixel work.
    #[inline(always)]
    pub fn finish_grey<K: EntryKernels, S: Sample>(
        &mut self,
        kernels: K,
        values: &[S],
        pixels: usize,
        grey: Vec<GreyEntry>,
        added: bool,
        ahead: &mut Ahead,
    ) {
        if added {
            kernels.grey_rows(
                &mut self.r,
                &mut self.g,
                &mut self.b,
                values,
                pixels,
                &grey,
                ahead,
            );
        }
        self.grey = grey;
    }

    /// Zeroed accumulators (boxed: they are a few kilobytes).
    pub(super) fn new() -> Box<TileAccumulators> {
        Box::new(TileAccumulators {
            r: [0.0; TILE_PIXELS],
            g: [0.0; TILE_PIXELS],
            b: [0.0; TILE_PIXELS],
            rgb: [0.0; 3 * TILE_PIXELS],
            rgb_used: false,
            nodes: NodeAccumulators::default(),
            hats: AxisHats::default(),
            pending: Vec::new(),
            grey: Vec::new(),
            rgb_entries: Vec::new(),
        })
    }

    /// Zeroes the interleaved RGB accumulator of a tile of `pixels` pixels (with its
    /// padding) and marks it used until [`forget_rgb`](Self::forget_rgb). (The planar rows
    /// need no clearing: [`super::kernels::EntryKernels::grey_rows`] sets them.)
    pub(super) fn clear_rgb(&mut self, pixels: usize) {
        self.rgb[..padded(3 * pixels)].fill(0.0);
        self.rgb_used = true;
    }

    /// Marks the RGB accumulator unused (a new tile), so a tile without RGB entries neither
    /// clears nor reads it.
    pub(super) fn forget_rgb(&mut self) {
        self.rgb_used = false;
    }

    /// Whether the tile added RGB entries into [`rgb`](Self::rgb).
    pub(super) fn rgb_used(&self) -> bool {
        self.rgb_used
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
    /// of its own segment), into the planar rows. Inlined, so that it is compiled with the
    /// features of the tile loop that calls it (AVX2 where that is the loop's).
    #[inline(always)]
    pub(super) fn expand_nodes<K: TileOutputKernels>(&mut self, kernels: K, lattice: &TileLattice) {
        self.hats.set_lattice(lattice);
        self.nodes.expand(
            kernels,
            lattice,
            &self.hats,
            [&mut self.r, &mut self.g, &mut self.b],
        );
    }

    /// Adds the interleaved RGB sums into the planar rows (`r[p] += rgb[3p]`, …) for the
    /// tile's `pixels`, when the tile has them: the image add then reads the planar rows
    /// alone, with per pixel the same two additions in the same order as adding both.
    #[inline(always)]
    pub(super) fn fold_rgb(&mut self, pixels: usize) {
        if !self.rgb_used {
            return;
        }
        let rgb = &self.rgb[..3 * pixels];
        for (p, v) in rgb.chunks_exact(3).enumerate() {
            self.r[p] += v[0];
            self.g[p] += v[1];
            self.b[p] += v[2];
        }
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
    /// Segments [`segment`](Self::segment) handed out since [`clear`](Self::clear).
    touched: u32,
    /// Scratch of [`expand`](Self::expand): one segment's nodes per channel over the whole
    /// lattice, then interpolated along x per row of nodes.
    grid: Vec<f32>,
    along_x: Vec<f32>,
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
        self.touched = 0;
    }

    #[inline(always)]
    fn segment(&mut self, s: usize) -> SegmentAccumulators<'_> {
        let (start, n) = (self.start[s] as usize, self.len[s] as usize);
        self.touched |= 1 << s;
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

    /// Adds the nodes expanded to pixels into `planes` (R, G, B per pixel, row-major).
    #[inline(always)]
    fn expand<K: TileOutputKernels>(
        &mut self,
        kernels: K,
        lattice: &TileLattice,
        hats: &AxisHats,
        planes: [&mut [f32]; 3],
    ) {
        let (nx, ny) = lattice.nodes();
        let (nx, ny) = (nx as usize, ny as usize);
        let (width, height) = lattice.size();
        let (width, height) = (width as usize, height as usize);
        let map = lattice.segments();
        let one_segment = lattice.segment_count() == 1;
        let [r_plane, g_plane, b_plane] = planes;
        let mut bits = self.touched;
        while bits != 0 {
            let s = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            // The segment's nodes, grey part + RGB part, per channel over the lattice;
            // nodes it does not store are 0 (and weigh 0 at its pixels).
            let (start, n) = (self.start[s] as usize, self.len[s] as usize);
            let p = padded(n);
            let block = &self.data[start..];
            let rgb = &block[3 * p..3 * p + 3 * n];
            self.grid.clear();
            self.grid.resize(3 * nx * ny, 0.0);
            for (k, &node) in lattice.segment_nodes(s).nodes.iter().enumerate() {
                for c in 0..3 {
                    self.grid[c * nx * ny + node as usize] = block[c * p + k] + rgb[3 * k + c];
                }
            }
            // Along x: per channel and row of nodes, the value at each pixel column.
            self.along_x.clear();
            self.along_x.resize(3 * ny * width, 0.0);
            for (row, out) in self
                .grid
                .chunks_exact(nx)
                .zip(self.along_x.chunks_exact_mut(width))
            {
                kernels.along_x(row, &hats.x, out);
            }
            // Along y, into the segment's pixels.
            for (c, plane) in [&mut *r_plane, &mut *g_plane, &mut *b_plane]
                .into_iter()
                .enumerate()
            {
                let rows = &self.along_x[c * ny * width..(c + 1) * ny * width];
                for (y, &[(j0, w0), (j1, w1)]) in hats.y.iter().enumerate().take(height) {
                    let a = &rows[j0 as usize * width..][..width];
                    let b = &rows[j1 as usize * width..][..width];
                    let out = &mut plane[y * width..(y + 1) * width];
                    if one_segment {
                        for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
                            *o += w0 * a + w1 * b;
                        }
                    } else {
                        // A select rather than a branch, so the loop vectorises.
                        let ids = &map[y * width..(y + 1) * width];
                        for (((o, a), b), &id) in out.iter_mut().zip(a).zip(b).zip(ids) {
                            let sum = *o + (w0 * a + w1 * b);
                            *o = if id as usize == s { sum } else { *o };
                        }
                    }
                }
            }
        }
    }
}

/// Per pixel column and per pixel row of a tile, its two lattice nodes along that axis and
/// their hat weights, for one lattice shape (step and tile size); rebuilt only when the
/// shape changes.
#[derive(Default)]
struct AxisHats {
    shape: Option<(u32, u32, u32)>,
    x: ColumnHats,
    y: Vec<[(u32, f32); 2]>,
}

impl AxisHats {
    fn set_lattice(&mut self, lattice: &TileLattice) {
        let (w, h) = lattice.size();
        let shape = (lattice.step(), w, h);
        if self.shape == Some(shape) {
            return;
        }
        // A pixel's hats are `(x0, y0), (x1, y0), (x0, y1), (x1, y1)` with weights
        // `wx·wy`; on the first row (column) the y (x) weights are 1 and 0, so the hats
        // there are the axis' own.
        let (nx, _) = lattice.nodes();
        self.x = ColumnHats {
            width: w as usize,
            ..ColumnHats::default()
        };
        for x in 0..w {
            // On the first row the y weights are 1 and 0: the first two hats are x's.
            for (k, &(node, weight)) in lattice.hats(x, 0)[..2].iter().enumerate() {
                self.x.node[k][x as usize] = node as u32;
                self.x.weight[k][x as usize] = weight;
            }
        }
        self.y = (0..h)
            .map(|y| {
                let h = lattice.hats(0, y);
                [(h[0].0 as u32 / nx, h[0].1), (h[2].0 as u32 / nx, h[2].1)]
            })
            .collect();
        self.shape = Some(shape);
    }
}

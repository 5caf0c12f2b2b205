//! Tracing a range of eye samples of one tile: each pixel's samples summed in the canonical
//! tree of [`super::blocks`] into a record of every layer ([`crate::bake::layout`]) while
//! the tile is traced. The one tracing step of every bake: a one-pass bake keeps the tree's
//! root of each tile ([`super::traced_tile`]), a progressive bake and a farm's partitions
//! keep the blocks sparse ([`super::tile_sums`]).

use super::pixel_tree::{Leaf, PixelTree};
use super::tiles;
use crate::bake::finish::denoise;
use crate::bake::layout::DenseLayout;
use crate::bake::path::integrator::{trace_eye_sample, CountingTracer, PathSink};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::progress::Progress;
use crate::{Result, Rgb};

/// Accumulates one eye sample of a pixel into its leaf of the pixel's tree, by layer of
/// the dense layout; the pixel's records are then copied into the tile buffer, which is
/// pixel-major (all layers of a pixel together), then layer, then RGB.
struct TileSink<'a> {
    /// The current eye sample's leaf of the pixel's tree: its layers and eye-hit record.
    leaf: Leaf<'a>,
    layout: DenseLayout,
}

impl TileSink<'_> {
    #[inline]
    fn add(&mut self, layer: usize, v: Rgb) {
        self.leaf.add(layer, v);
    }
}

impl PathSink for TileSink<'_> {
    #[inline]
    fn world(&mut self, group: usize, v: Rgb) {
        self.add(self.layout.world(group), v);
    }
    #[inline]
    fn direct(&mut self, group: usize, slot: u32, v: Rgb) {
        self.add(self.layout.direct(group, slot), v);
    }
    #[inline]
    fn bounce(&mut self, group: usize, eye: u32, bounce: u32, v: Rgb) {
        self.add(self.layout.bounce(group, eye, bounce), v);
    }
    #[inline]
    fn eye_hit(&mut self, region: u32, normal: glam::Vec3, position: glam::Vec3) {
        denoise::EyeFeatures::add(self.leaf.features, region, normal, position);
    }
    #[inline]
    fn tail_edits(&self) -> bool {
        true
    }
    #[inline]
    fn tail_edit(&mut self, group: usize, eye: usize, region: usize, bin: usize, v: Rgb) {
        self.add(self.layout.tail_edit(group, eye, region, bin), v);
    }
}

/// Traces eye samples `samples` of every pixel of `tile` into per-pixel records (layer sums
/// then features, [`super::blocks::combine`]'s layout), `blocks` of them per pixel (the
/// [`super::blocks::dyadic_blocks`] of `samples`, or one when `fold`: the range is a whole bake
/// `[0, spp)` and its tree's root is all that is kept), block-major then pixel-major. Every
/// pixel adds its samples in the canonical tree of [`super::blocks`], so any split of the samples
/// gives the same bits. `None` when `progress` was cancelled midway.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_tile_records(
    ctx: &BakeContext,
    brdf: &BasisBrdf,
    blocks: usize,
    fold: bool,
    tile: &tiles::Tile,
    samples: std::ops::Range<u32>,
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<Option<Vec<f32>>> {
    let layer_count = ctx.layer_count();
    let layout = DenseLayout::of(ctx);
    let tp = tile.pixels();
    let fs = denoise::FEATURE_STRIDE;
    let record = layer_count * 3 + fs;
    let mut buf: Vec<f32> = crate::memory::try_zeroed(blocks * tp * record, "a tile's layer sums")?;
    let mut tree = PixelTree::new(layer_count)?;
    let mut tracer = CountingTracer::default();
    let mut discarded = 0u64;
    for ty in 0..tile.height {
        if progress.is_cancelled() {
            return Ok(None);
        }
        for tx in 0..tile.width {
            let pixel = (ty * tile.width + tx) as usize;
            tree.clear();
            for s in samples.clone() {
                let mut sink = TileSink {
                    leaf: tree.push_leaf(s),
                    layout,
                };
                discarded += trace_eye_sample(
                    ctx,
                    brdf,
                    &mut sink,
                    &mut tracer,
                    tile.x0 + tx,
                    tile.y0 + ty,
                    s,
                ) as u64;
                tree.close_leaf();
            }
            if fold {
                tree.fold();
            }
            debug_assert_eq!(tree.blocks().len(), blocks);
            for b in 0..blocks {
                let dst = (b * tp + pixel) * record;
                tree.copy_record_into_zeros(b, &mut buf[dst..dst + record]);
            }
        }
    }
    rays.fetch_add(tracer.rays, std::sync::atomic::Ordering::Relaxed);
    ctx.non_finite.add_path_contributions(discarded);
    Ok(Some(buf))
}

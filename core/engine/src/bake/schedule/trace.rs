//! Tracing a range of eye samples of every pixel into the bake's sample blocks: tiles in
//! parallel, each pixel's samples summed in the canonical tree of [`super::blocks`] and
//! kept densely per layer ([`crate::bake::layout`]). Shared by the bake and a farm's partitions.

use std::sync::Mutex;

use super::blocks;
use super::tiles;
use crate::bake::finish::denoise;
use crate::bake::layout::DenseLayout;
use crate::bake::path::integrator::{trace_eye_sample, CountingTracer, PathSink};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::progress::Progress;
use crate::{Result, Rgb};

/// Accumulates one pixel of a tile densely: the tile buffer is pixel-major (all layers of
/// a pixel together, so a path's writes stay in a few cache lines), then layer, then RGB.
struct TileSink<'a> {
    /// The layers of the current pixel.
    buf: &'a mut [f32],
    layout: DenseLayout,
    /// The pixel's eye-hit record for the denoiser ([`denoise::EyeFeatures`]).
    features: &'a mut [f32],
}

impl TileSink<'_> {
    #[inline]
    fn add(&mut self, layer: usize, v: Rgb) {
        let i = layer * 3;
        self.buf[i] += v.x;
        self.buf[i + 1] += v.y;
        self.buf[i + 2] += v.z;
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
        denoise::EyeFeatures::add(self.features, region, normal, position);
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
/// then features, [`blocks::combine`]'s layout), `blocks` of them per pixel (the
/// [`blocks::dyadic_blocks`] of `samples`, or one when `fold`: the range is a whole bake
/// `[0, spp)` and its tree's root is all that is kept), block-major then pixel-major. Every
/// pixel adds its samples in the canonical tree of [`blocks`], so any split of the samples
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
    let mut tree = blocks::PixelTree::new(layer_count)?;
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
                let (layers, features) = tree.push_leaf(s);
                let mut sink = TileSink {
                    buf: layers,
                    layout,
                    features,
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
                buf[dst..dst + record].copy_from_slice(tree.record(b));
            }
        }
    }
    rays.fetch_add(tracer.rays, std::sync::atomic::Ordering::Relaxed);
    ctx.non_finite.add_path_contributions(discarded);
    Ok(Some(buf))
}

/// Traces eye samples `samples` of every pixel of `tile` into the pass's full-frame
/// `blocks` ([`trace_tile_records`], then scattered per layer).
#[allow(clippy::too_many_arguments)]
fn trace_tile(
    ctx: &BakeContext,
    brdf: &BasisBrdf,
    blocks: &[blocks::Block],
    fold: bool,
    tile: &tiles::Tile,
    samples: std::ops::Range<u32>,
    width: usize,
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<bool> {
    let layer_count = ctx.layer_count();
    let height = ctx.resolution.height as usize;
    let tp = tile.pixels();
    let fs = denoise::FEATURE_STRIDE;
    let record = layer_count * 3 + fs;
    let Some(buf) =
        trace_tile_records(ctx, brdf, blocks.len(), fold, tile, samples, progress, rays)?
    else {
        return Ok(false);
    };
    for (b, block) in blocks.iter().enumerate() {
        let records = &buf[b * tp * record..(b + 1) * tp * record];
        {
            let mut all = block.features.lock().unwrap_or_else(|e| e.into_inner());
            for ty in 0..tile.height as usize {
                for tx in 0..tile.width as usize {
                    let src = (ty * tile.width as usize + tx) * record + layer_count * 3;
                    let dst = ((tile.y0 as usize + ty) * width + tile.x0 as usize + tx) * fs;
                    all[dst..dst + fs].copy_from_slice(&records[src..src + fs]);
                }
            }
        }
        for (layer, slot) in block.layers.iter().enumerate() {
            let texel = |p: usize| &records[p * record + layer * 3..p * record + layer * 3 + 3];
            if (0..tp).all(|p| texel(p) == [0.0; 3]) {
                continue;
            }
            let mut image = slot.lock().unwrap_or_else(|e| e.into_inner());
            let image = match &mut *image {
                Some(image) => image,
                empty => empty.insert(crate::memory::try_zeroed(
                    width * height * 3,
                    "a layer's full-frame sums",
                )?),
            };
            for ty in 0..tile.height as usize {
                for tx in 0..tile.width as usize {
                    let dst = ((tile.y0 as usize + ty) * width + tile.x0 as usize + tx) * 3;
                    image[dst..dst + 3].copy_from_slice(texel(ty * tile.width as usize + tx));
                }
            }
        }
    }
    Ok(true)
}

/// Traces eye samples `from..to` of every pixel into `store` (see [`blocks`]); `fold` when
/// the range is a whole one-pass bake. Shared by the bake and a farm's partitions
/// ([`partition`]). Progress advances by `to − from` per tile.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_range(
    ctx: &BakeContext,
    store: &mut blocks::BlockStore,
    from: u32,
    to: u32,
    fold: bool,
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<()> {
    let res = ctx.resolution;
    let (width, height) = (res.width as usize, res.height as usize);
    let layer_count = ctx.layer_count();
    #[allow(clippy::single_range_in_vec_init)]
    let ranges = if fold {
        vec![from..to]
    } else {
        blocks::dyadic_blocks(from, to)
    };
    let pass_blocks = ranges
        .into_iter()
        .map(|r| blocks::Block::new(r, layer_count, width * height))
        .collect::<Result<Vec<_>>>()?;
    let alloc_failure: Mutex<Option<crate::RelumeError>> = Mutex::new(None);
    let brdf = BasisBrdf { ctx };
    tiles::run_tiles(
        res,
        ctx.settings.threads,
        progress,
        (to - from) as u64,
        |tile| {
            if alloc_failure.lock().map_or(true, |f| f.is_some()) {
                return false;
            }
            match trace_tile(
                ctx,
                &brdf,
                &pass_blocks,
                fold,
                tile,
                from..to,
                width,
                progress,
                rays,
            ) {
                Ok(done) => done,
                Err(e) => {
                    if let Ok(mut slot) = alloc_failure.lock() {
                        slot.get_or_insert(e);
                    }
                    false
                }
            }
        },
    )?;
    if let Some(e) = alloc_failure
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take()
    {
        return Err(e);
    }
    for b in pass_blocks {
        store.push(b);
    }
    Ok(())
}

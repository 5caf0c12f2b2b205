//! A bake's passes, each ending in the one streaming finish: one pass streams
//! ([`super::stream`]) and finishes tile rows as they are traced; several passes trace their
//! sample ranges tile by tile into per-tile sparse sums kept between the passes
//! ([`super::tile_sums`]) and finish a complete stack from them after each
//! (`super::summed_finish`). The bake's outline ([`crate::bake`]) calls one of them once the
//! preparation is done.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::blocks::dyadic_blocks;
use super::summed_finish::finish_summed_tiles;
use super::tile_sums::{TileBlocks, TileSums};
use crate::bake::finish;
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::bake::report::SetupFacts;
use crate::bake::{BakeReport, BakeSettings, PassReport};
use crate::progress::{Progress, Stage};
use crate::scene::Scene;
use crate::stack::tiled::TiledStack;
use crate::Result;

/// A one-pass bake: tile rows traced in bands of `band_rows` (`None`: enough tiles for the
/// threads) and finished as soon as their denoiser window is traced.
#[allow(clippy::too_many_arguments)]
pub(crate) fn one_streaming_pass(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    band_rows: Option<usize>,
    pool: &rayon::ThreadPool,
    progress: &Progress,
    setup: &SetupFacts,
    mut on_pass: impl FnMut(&TiledStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TiledStack, BakeReport, Vec<PassReport>)> {
    let res = ctx.resolution;
    let rays = AtomicU64::new(0);
    let band = band_rows.unwrap_or_else(|| {
        pool.install(|| {
            super::band::default_band_rows(
                res.width,
                settings.threads,
                super::band::apron_rows(&settings.denoise),
            )
        })
    });
    let streamed =
        super::stream::bake_streaming(ctx, scene, settings, band, pool, progress, &rays)?;
    progress.set_stage(Stage::Finishing);
    let (stack, mut report) = finish::describe::layer_report(
        ctx,
        streamed.finished,
        streamed.assembly_seconds,
        streamed.denoise_seconds,
    );
    report.peak_accounted_bytes = streamed.peak_accounted_bytes;
    if !settings.adaptive.is_off() {
        report.adaptive = Some(crate::bake::report::AdaptiveReport::new(
            settings,
            res,
            streamed.tile_samples,
        ));
    }
    setup.finish_report(&mut report, rays.load(Ordering::Relaxed));
    let pass_report = PassReport {
        pass: 0,
        spp: settings.spp,
        seconds: report.seconds,
        estimated_rel_error: None,
    };
    progress.check()?;
    on_pass(&stack, &report, &pass_report)?;
    Ok((stack, report, vec![pass_report]))
}

/// A progressive bake: after pass k the stack holds `passes[k]` eye samples per pixel and
/// `on_pass` gets it. Between the passes each tile keeps its samples' sums sparse — per
/// block of the canonical tree, the layers reached on it ([`TileBlocks`], what a farm
/// partition writes) — and each pass is finished from them through the one streaming finish
/// (`super::summed_finish`, which a farm's merge runs too), so no layer is ever held as a
/// full frame and the last pass holds the bits of a one-pass bake of the same samples.
#[allow(clippy::too_many_arguments)]
pub(crate) fn progressive_passes(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    pool: &rayon::ThreadPool,
    progress: &Progress,
    setup: &SetupFacts,
    mut on_pass: impl FnMut(&TiledStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TiledStack, BakeReport, Vec<PassReport>)> {
    let all = super::tiles::tiles(ctx.resolution);
    let mut kept: Vec<TileBlocks> = all.iter().map(|_| TileBlocks::default()).collect();
    let rays = AtomicU64::new(0);
    let mut pass_reports = Vec::new();
    let mut previous_image: Option<Vec<f64>> = None;
    let mut done = 0u32;
    let mut result: Option<(TiledStack, BakeReport)> = None;
    for (pass, &upto) in passes.iter().enumerate() {
        let (from, to) = (done, upto);
        progress.set_stage(Stage::Tracing);
        trace_into(ctx, &all, &mut kept, from..to, pool, progress, &rays)?;
        done = upto;
        let kept_bytes: usize = kept.iter().map(TileBlocks::bytes).sum();
        // The previous pass's stack is the caller's now: it is not held while this one is
        // built.
        drop(result.take());
        let last_pass = pass + 1 == passes.len();
        let pass_settings = BakeSettings {
            spp: done,
            ..settings.clone()
        };
        let summed =
            finish_summed_tiles(ctx, scene, &pass_settings, pool, progress, true, |tile| {
                let blocks = &mut kept[tile.index];
                // The last pass needs no sums after it: each tile's go as it is finished.
                Ok(if last_pass {
                    std::mem::take(blocks).fold()
                } else {
                    blocks.folded_copy()
                })
            })?;
        let mut report = summed.report;
        report.peak_accounted_bytes += kept_bytes;
        let image = summed.image.unwrap_or_default();
        let estimated_rel_error = previous_image
            .as_ref()
            .map(|prev| remaining_rel_error(prev, &image, from, to));
        previous_image = Some(image);
        setup.finish_report(&mut report, rays.load(Ordering::Relaxed));
        let pass_report = PassReport {
            pass,
            spp: done,
            seconds: report.seconds,
            estimated_rel_error,
        };
        progress.check()?;
        on_pass(&summed.stack, &report, &pass_report)?;
        pass_reports.push(pass_report);
        result = Some((summed.stack, report));
    }
    let (stack, report) = result.expect("at least one pass");
    Ok((stack, report, pass_reports))
}

/// Traces eye samples `samples` of every tile of `all` (tiles in parallel) and adds them to
/// each tile's kept blocks, sparse. Progress advances by the samples per tile.
fn trace_into(
    ctx: &BakeContext,
    all: &[super::tiles::Tile],
    kept: &mut [TileBlocks],
    samples: Range<u32>,
    pool: &rayon::ThreadPool,
    progress: &Progress,
    rays: &AtomicU64,
) -> Result<()> {
    let blocks = dyadic_blocks(samples.start, samples.end);
    let brdf = BasisBrdf { ctx };
    pool.install(|| {
        all.par_iter()
            .zip(kept.par_iter_mut())
            .try_for_each(|(tile, store)| -> Result<()> {
                progress.check()?;
                let sums = TileSums::traced(
                    ctx,
                    &brdf,
                    blocks.len(),
                    tile,
                    samples.clone(),
                    progress,
                    rays,
                )?;
                for (range, block) in blocks.iter().zip(sums) {
                    store.push(range.clone(), block);
                }
                progress.advance(samples.len() as u64);
                Ok(())
            })
    })
}

/// The relative error left in the image of `to` samples, from its change since the image of
/// `from` samples (both at the bake-time materials): with independent samples the earlier
/// image's noise is the later one's plus the new samples', so `‖now − before‖` scales to the
/// remaining noise by `√(r / (1 − r))`, `r = from / to`.
fn remaining_rel_error(before: &[f64], now: &[f64], from: u32, to: u32) -> f64 {
    let norm = now.iter().map(|v| v * v).sum::<f64>().sqrt();
    let diff = before
        .iter()
        .zip(now)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt();
    let r = from as f64 / to as f64;
    diff * (r / (1.0 - r)).sqrt() / norm.max(1e-300)
}

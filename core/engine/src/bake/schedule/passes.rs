//! A bake's passes on the two schedules, each ending in the finishing stage: one pass
//! streams ([`super::stream`]) and finishes tile rows as it goes; several passes trace
//! their sample ranges into dense blocks ([`super::trace`], [`super::blocks`]) and
//! assemble a complete stack after each ([`crate::bake::finish::assemble`]). The bake's
//! outline ([`crate::bake`]) calls one of them once the preparation is done.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::bake::finish;
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
    let (stack, mut report) = finish::assemble::layer_report(
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

/// A progressive bake: after pass k the stack holds `passes[k]` eye samples per pixel,
/// summed in full-frame blocks kept between the passes, and `on_pass` gets it.
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
    let mut store = super::blocks::BlockStore::default();
    let rays = AtomicU64::new(0);
    let mut pass_reports = Vec::new();
    let mut previous_image: Option<Vec<f64>> = None;
    let mut done = 0u32;
    let mut result = None;
    for (pass, &upto) in passes.iter().enumerate() {
        let (from, to) = (done, upto);
        progress.set_stage(Stage::Tracing);
        let last_pass = pass + 1 == passes.len();
        // A one-pass bake keeps only its tree's root per pixel (one image per layer).
        super::trace::trace_range(
            ctx,
            &mut store,
            from,
            to,
            last_pass && from == 0,
            progress,
            &rays,
        )?;
        done = upto;
        let (sums, feature_sums) = if last_pass {
            std::mem::take(&mut store).fold()
        } else {
            store.fold_copy()?
        };
        let eye_features = finish::denoise::EyeFeatures::from_sums(ctx, &feature_sums, done);
        drop(feature_sums);
        let (stack, mut report, image) = finish::assemble::assemble(
            ctx,
            scene,
            settings,
            &sums,
            &eye_features,
            done,
            pool,
            progress,
            last_pass,
            true,
        )?;
        drop(sums);
        let image = image.unwrap_or_default();
        let norm = image.iter().map(|v| v * v).sum::<f64>().sqrt();
        let estimated_rel_error = previous_image.as_ref().map(|prev| {
            let diff = prev
                .iter()
                .zip(&image)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            let r = from as f64 / to as f64;
            diff * (r / (1.0 - r)).sqrt() / norm.max(1e-300)
        });
        previous_image = Some(image);
        setup.finish_report(&mut report, rays.load(Ordering::Relaxed));
        let pass_report = PassReport {
            pass,
            spp: done,
            seconds: report.seconds,
            estimated_rel_error,
        };
        progress.check()?;
        on_pass(&stack, &report, &pass_report)?;
        pass_reports.push(pass_report);
        result = Some((stack, report));
    }
    let (stack, report) = result.expect("at least one pass");
    Ok((stack, report, pass_reports))
}

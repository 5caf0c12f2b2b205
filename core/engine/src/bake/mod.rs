//! The bake: one path-tracing pass that fills every layer of the transfer stack.
//!
//! For each pixel and eye sample, the integrator ([`integrator`]) gives radiance per slot
//! (direct) and per slot pair (one bounce); a tile accumulates them densely, then hands every
//! layer that received anything to the whole-image layer store. At the end a layer whose
//! three channels are bit-identical everywhere (its paths met no colour: Table 1's grey
//! layers) is stored with one channel, an all-zero layer is dropped, and the rest are RGB.

pub mod assemble;
pub mod bench;
pub mod blocks;
pub mod bounce_budget;
pub mod bounces;
pub mod context;
pub mod denoise;
pub mod drop;
pub mod estimate;
pub mod farm_file;
pub mod frozen;
pub mod guide;
pub mod guide_file;
pub mod guide_pass;
pub mod guide_tree;
pub mod integrator;
pub mod layout;
pub mod mixture;
pub mod partial;
pub mod partition;
pub mod presets;
pub mod progress;
pub mod reference;
pub mod report;
pub mod settings;
pub mod setup;
pub mod signature;
pub mod subsurface;
pub mod subsurface_light;
pub mod tiles;
pub mod to_file;
pub mod trace;
pub mod vertex_brdf;

use std::time::Instant;

use crate::progress::{Progress, Stage};
use crate::scene::Scene;
use crate::stack::TransferStack;
use crate::Result;
pub(crate) use assemble::assemble;
pub use layout::layer_key;
pub use report::{BakeReport, PassReport};
pub use settings::{BakeSettings, Denoise, IndirectSampling, LightGrouping};
pub(crate) use trace::trace_range;

/// Bakes `scene` into a transfer stack. `progress` reports and cancels from other threads.
pub fn bake(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
) -> Result<(TransferStack, BakeReport)> {
    let (stack, report, _) =
        bake_progressive(scene, settings, &[settings.spp], progress, |_, _, _| Ok(()))?;
    Ok((stack, report))
}

/// Sample counts of a progressive bake of `passes` passes ending at `spp`: doubling, so
/// each pass's estimate of the remaining noise is plain (see [`PassReport`]).
pub fn doubling_passes(spp: u32, passes: u32) -> Vec<u32> {
    let mut out: Vec<u32> = (0..passes.max(1))
        .rev()
        .map(|k| (spp >> k).max(1))
        .collect();
    out.dedup();
    out
}

/// A bake in passes: after pass k the stack holds `passes[k]` eye samples per pixel
/// (cumulative, increasing, the last one is the bake) and `on_pass` gets it — complete and
/// usable, e.g. to write it (atomically) and relight a first noisy image within seconds.
/// The paths are the same as one bake of `passes.last()` samples.
pub fn bake_progressive(
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    progress: &Progress,
    mut on_pass: impl FnMut(&TransferStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TransferStack, BakeReport, Vec<PassReport>)> {
    settings.validate()?;
    if passes.is_empty() || passes.windows(2).any(|w| w[0] >= w[1]) || passes[0] == 0 {
        return Err(crate::RelumeError::invalid(
            "bake passes",
            format!("{passes:?}: sample counts must increase from ≥ 1"),
        ));
    }
    let start = Instant::now();
    progress.set_stage(Stage::Setup);
    let mut settings = settings.clone();
    settings.spp = *passes.last().unwrap_or(&1);
    let (mut ctx, validation, prepared) = estimate::prepare_measured(scene, &settings, progress)?;
    // The forecast and the budget come before the guide pass and the trace, so a bake that
    // cannot fit is refused in a second, not after minutes of tracing.
    let forecast = estimate::estimate(&ctx, scene, passes.len(), prepared);
    crate::memory::check_budget(
        &format!(
            "this bake ({}×{}, {} of {} possible layers reached by a probe; stack ≈ {})",
            forecast.width,
            forecast.height,
            forecast.layers_reached,
            forecast.layers_possible,
            crate::memory::human_bytes(forecast.stack_bytes)
        ),
        forecast.peak_bytes,
        settings.memory_budget,
    )?;
    ctx.build_guide(scene, progress)?;
    let setup_seconds = start.elapsed().as_secs_f64();
    let res = ctx.resolution;
    let (width, height) = (res.width as usize, res.height as usize);
    let mut store = blocks::BlockStore::default();
    let rays = std::sync::atomic::AtomicU64::new(0);
    let tile_count = tiles::tiles(res).len() as u64;
    progress.set_stage(Stage::Tracing);
    progress.start(tile_count * settings.spp as u64);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| crate::RelumeError::invalid("threads", e.to_string()))?;
    let mut pass_reports = Vec::new();
    let mut previous_image: Option<Vec<f64>> = None;
    let mut done = 0u32;
    let mut result = None;
    for (pass, &upto) in passes.iter().enumerate() {
        let trace_start = Instant::now();
        let (from, to) = (done, upto);
        progress.set_stage(Stage::Tracing);
        let last_pass = pass + 1 == passes.len();
        // A one-pass bake keeps only its tree's root per pixel (one image per layer).
        trace_range(
            &ctx,
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
        let eye_features = denoise::EyeFeatures::from_sums(&ctx, &feature_sums, done);
        drop(feature_sums);
        let (stack, mut report, image) = assemble(
            &ctx,
            scene,
            &settings,
            &sums,
            &eye_features,
            done,
            &pool,
            width,
            height,
            progress,
            true,
        )?;
        drop(sums);
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
        let trace_seconds = trace_start.elapsed().as_secs_f64();
        let total_rays = rays.load(std::sync::atomic::Ordering::Relaxed);
        report.seconds = start.elapsed().as_secs_f64();
        report.setup_seconds = setup_seconds;
        report.trace_seconds = report.seconds - setup_seconds;
        report.rays = total_rays;
        report.rays_per_second = total_rays as f64 / report.trace_seconds.max(1e-9);
        report.triangles = validation.triangles;
        report.degenerate_triangles = validation.degenerate_triangles;
        report.warnings = validation.warnings.clone();
        report.estimate = Some(forecast.clone());
        let _ = trace_seconds;
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
    progress.set_stage(Stage::Done);
    let (stack, report) = result.expect("at least one pass");
    Ok((stack, report, pass_reports))
}

//! The bake: one path-tracing pass that fills every layer of the transfer stack.
//!
//! For each pixel and eye sample, the integrator ([`integrator`]) gives radiance per slot
//! (direct) and per slot pair (one bounce). Every bake ends in a [`TiledStack`]: per 16×16
//! tile only the layers non-zero there ([`finalise`]). A one-pass bake streams
//! ([`stream`]): tile rows are traced in bands and finalised as soon as their denoiser
//! window is traced, so its memory follows the data. A progressive bake (several passes)
//! and a farm's merge keep full-frame accumulators per reached layer ([`blocks`]) — their
//! memory stays dense, ≈ 12 bytes × reached layers × pixels — and cut the assembled layers
//! into the same tiles with the same code, so they give the same stack. A layer whose three
//! channels are bit-identical everywhere (its paths met no colour: Table 1's grey layers)
//! is stored with one channel, an all-zero layer is dropped, and the rest are RGB.

pub mod farm;
pub mod finish;
pub mod layout;
pub mod non_finite;
pub mod path;
pub mod prepare;
pub mod presets;
pub mod reference;
pub mod report;
pub mod schedule;
pub mod settings;
pub mod to_file;

use std::time::Instant;

use crate::progress::{Progress, Stage};
use crate::scene::Scene;
use crate::stack::tiled::TiledStack;
use crate::stack::TransferStack;
use crate::Result;
pub use layout::layer_key;
pub use non_finite::NonFiniteReport;
pub use report::{BakeReport, PassReport};
pub use settings::{BakeSettings, Denoise, IndirectSampling, LightGrouping};

/// Bakes `scene` into a dense transfer stack: [`bake_tiled`] expanded with
/// [`TiledStack::to_dense`] (every layer a full frame: for tests and small bakes).
pub fn bake(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
) -> Result<(TransferStack, BakeReport)> {
    let (stack, report) = bake_tiled(scene, settings, progress)?;
    Ok((stack.to_dense()?, report))
}

/// Bakes `scene` into a tiled stack in one streaming pass ([`stream`]): memory is the
/// stack plus the tile rows in flight. `progress` reports and cancels from other threads.
pub fn bake_tiled(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
) -> Result<(TiledStack, BakeReport)> {
    bake_tiled_banded(scene, settings, None, progress)
}

/// [`bake_tiled`] tracing `band_rows` tile rows at a time (`None`: enough tiles for the
/// threads). The stack does not depend on it.
pub fn bake_tiled_banded(
    scene: &Scene,
    settings: &BakeSettings,
    band_rows: Option<usize>,
    progress: &Progress,
) -> Result<(TiledStack, BakeReport)> {
    let (stack, report, _) = run_passes(
        scene,
        settings,
        &[settings.spp],
        band_rows,
        progress,
        |_, _, _| Ok(()),
    )?;
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
/// The paths are the same as one bake of `passes.last()` samples. Dense stacks:
/// [`bake_progressive_tiled`] expanded per pass with [`TiledStack::to_dense`].
pub fn bake_progressive(
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    progress: &Progress,
    mut on_pass: impl FnMut(&TransferStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TransferStack, BakeReport, Vec<PassReport>)> {
    let (stack, report, reports) =
        bake_progressive_tiled(scene, settings, passes, progress, |stack, report, pass| {
            on_pass(&stack.to_dense()?, report, pass)
        })?;
    Ok((stack.to_dense()?, report, reports))
}

/// [`bake_progressive`] in tiled stacks. One pass streams ([`bake_tiled`]); several keep
/// full-frame accumulators between the passes (their memory stays dense) and cut each
/// pass's layers into tiles.
pub fn bake_progressive_tiled(
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    progress: &Progress,
    on_pass: impl FnMut(&TiledStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TiledStack, BakeReport, Vec<PassReport>)> {
    run_passes(scene, settings, passes, None, progress, on_pass)
}

fn run_passes(
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    band_rows: Option<usize>,
    progress: &Progress,
    mut on_pass: impl FnMut(&TiledStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TiledStack, BakeReport, Vec<PassReport>)> {
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
    let (mut ctx, validation, prepared) =
        prepare::estimate::prepare_measured(scene, &settings, progress)?;
    // The forecast and the budget come before the guide pass and the trace, so a bake that
    // cannot fit is refused in a second, not after minutes of tracing.
    let forecast = prepare::estimate::estimate(&mut ctx, scene, passes.len(), prepared, progress)?;
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
    let mut store = schedule::blocks::BlockStore::default();
    let rays = std::sync::atomic::AtomicU64::new(0);
    let tile_count = schedule::tiles::tiles(res).len() as u64;
    progress.set_stage(Stage::Tracing);
    progress.start(tile_count * settings.spp as u64);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| crate::RelumeError::invalid("threads", e.to_string()))?;
    let finish_report = |report: &mut BakeReport, rays: u64| {
        report.seconds = start.elapsed().as_secs_f64();
        report.setup_seconds = setup_seconds;
        report.trace_seconds = report.seconds - setup_seconds;
        report.rays = rays;
        report.rays_per_second = rays as f64 / report.trace_seconds.max(1e-9);
        report.triangles = validation.triangles;
        report.degenerate_triangles = validation.degenerate_triangles;
        // The validation's warnings first, then those of the bake itself.
        let own = std::mem::take(&mut report.warnings);
        report.warnings = validation.warnings.iter().cloned().chain(own).collect();
        report.estimate = Some(forecast.clone());
    };
    if passes.len() == 1 {
        let band = band_rows.unwrap_or_else(|| {
            pool.install(|| {
                schedule::band::default_band_rows(
                    res.width,
                    settings.threads,
                    schedule::band::apron_rows(&settings.denoise),
                )
            })
        });
        let streamed =
            schedule::stream::bake_streaming(&ctx, scene, &settings, band, &pool, progress, &rays)?;
        progress.set_stage(Stage::Finishing);
        let (stack, mut report) = finish::assemble::layer_report(
            &ctx,
            streamed.finished,
            streamed.assembly_seconds,
            streamed.denoise_seconds,
        );
        report.peak_accounted_bytes = streamed.peak_accounted_bytes;
        finish_report(&mut report, rays.load(std::sync::atomic::Ordering::Relaxed));
        let pass_report = PassReport {
            pass: 0,
            spp: settings.spp,
            seconds: report.seconds,
            estimated_rel_error: None,
        };
        progress.check()?;
        on_pass(&stack, &report, &pass_report)?;
        progress.set_stage(Stage::Done);
        return Ok((stack, report, vec![pass_report]));
    }
    let mut pass_reports = Vec::new();
    let mut previous_image: Option<Vec<f64>> = None;
    let mut done = 0u32;
    let mut result = None;
    for (pass, &upto) in passes.iter().enumerate() {
        let (from, to) = (done, upto);
        progress.set_stage(Stage::Tracing);
        let last_pass = pass + 1 == passes.len();
        // A one-pass bake keeps only its tree's root per pixel (one image per layer).
        schedule::trace::trace_range(
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
        let eye_features = finish::denoise::EyeFeatures::from_sums(&ctx, &feature_sums, done);
        drop(feature_sums);
        let (stack, mut report, image) = finish::assemble::assemble(
            &ctx,
            scene,
            &settings,
            &sums,
            &eye_features,
            done,
            &pool,
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
        finish_report(&mut report, rays.load(std::sync::atomic::Ordering::Relaxed));
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

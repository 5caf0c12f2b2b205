//! The bake: one path-tracing pass that fills every layer of the transfer stack.
//!
//! For each pixel and eye sample, the integrator ([`path::integrator`]) gives radiance per
//! slot (direct) and per slot pair (one bounce). Every bake ends in a [`TiledStack`]: per
//! 16×16 tile only the layers non-zero there ([`finish::finalise`]), finished tile row by tile
//! row by one streaming finish ([`schedule::stream`]), so no bake holds any layer as a full
//! frame. A one-pass bake traces tile rows in bands and finalises them as soon as their
//! denoiser window is traced, so its memory follows the data. A farm's partitions write
//! their tiles' sample sums to files as they are traced and its merge feeds the parts'
//! summed tiles to the same finish ([`farm`]). A progressive bake (several passes) keeps the
//! same per-tile sums in memory between its passes ([`schedule::tile_sums`]) and feeds them
//! to the same finish after each pass, so it gives the same stack. A layer whose three
//! channels are bit-identical everywhere on a tile (its paths met no colour: Table 1's grey
//! layers) is stored there with one channel, an all-zero layer is dropped, and the rest are
//! RGB.
//!
//! The folders are the stages, in the order a bake runs them (`run_passes`, below, is the
//! outline every entry point runs):
//! 1. [`prepare`]: the context, the set-up steps that trace, the memory forecast;
//! 2. [`path`]: what one eye sample traces and where its light goes;
//! 3. [`schedule`]: which samples are traced when, and how their light is held;
//! 4. [`finish`]: denoising, the tiled stack, layer dropping.
//!
//! [`farm`] runs the same stages split over machines. Beside them: the settings
//! ([`settings`], their flat face [`fields`], [`presets`]), what a bake reports
//! ([`report`], [`non_finite`]), the layer index arithmetic the stages share ([`layout`]),
//! a bake written to a stack file ([`to_file`]) and the reference renderer
//! ([`reference`](mod@reference)).

pub mod farm;
pub mod fields;
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
pub use report::{AdaptiveReport, BakeReport, PassReport};
pub use schedule::doubling::doubling_passes;
pub use settings::{AdaptiveSampling, BakeSettings, Denoise, IndirectSampling, LightGrouping};

/// Bakes `scene` into a dense transfer stack: [`bake_tiled`] expanded with
/// [`TiledStack::to_dense`], which builds every layer as a full frame — a helper for tests
/// and reports on small frames, never the bake's own path (use [`bake_tiled`]).
pub fn bake(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
) -> Result<(TransferStack, BakeReport)> {
    let (stack, report) = bake_tiled(scene, settings, progress)?;
    Ok((stack.to_dense()?, report))
}

/// Bakes `scene` into a tiled stack in one streaming pass ([`schedule::stream`]): memory is the
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

/// A bake in passes: after pass k the stack holds `passes[k]` eye samples per pixel
/// (cumulative, increasing, the last one is the bake) and `on_pass` gets it — complete and
/// usable, e.g. to write it (atomically) and relight a first noisy image within seconds.
/// The paths are the same as one bake of `passes.last()` samples. Dense stacks:
/// [`bake_progressive_tiled`] expanded per pass with [`TiledStack::to_dense`], which builds
/// every layer as a full frame — a helper for tests and reports on small frames, never the
/// bake's own path (use [`bake_progressive_tiled`]).
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
/// each tile's sparse sample sums between the passes ([`schedule::tile_sums`]) and finish
/// each pass from them through the same streaming finish.
pub fn bake_progressive_tiled(
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    progress: &Progress,
    on_pass: impl FnMut(&TiledStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TiledStack, BakeReport, Vec<PassReport>)> {
    run_passes(scene, settings, passes, None, progress, on_pass)
}

/// The bake's outline, which every entry point above runs: prepare ([`prepare`]), trace
/// through the path stage ([`path`]) on one of two schedules ([`schedule`]), finish each
/// pass into a tiled stack ([`finish`]) and hand it to `on_pass` with its report.
fn run_passes(
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    band_rows: Option<usize>,
    progress: &Progress,
    on_pass: impl FnMut(&TiledStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TiledStack, BakeReport, Vec<PassReport>)> {
    settings.validate()?;
    if passes.is_empty() || passes.windows(2).any(|w| w[0] >= w[1]) || passes[0] == 0 {
        return Err(crate::RelumeError::invalid(
            "bake passes",
            format!("{passes:?}: sample counts must increase from ≥ 1"),
        ));
    }
    if passes.len() > 1 && !settings.adaptive.is_off() {
        return Err(crate::RelumeError::invalid(
            "adaptive_threshold",
            format!(
                "adaptive sampling bakes in one pass; a progressive bake ({} passes) keeps every pixel's samples for its next pass: give one pass or an adaptive threshold of 0",
                passes.len()
            ),
        ));
    }
    let start = Instant::now();
    progress.set_stage(Stage::Setup);
    let mut settings = settings.clone();
    settings.spp = *passes.last().unwrap_or(&1);
    // 1. Prepare: the context and the set-up steps that trace (the light entering
    // translucent regions, the bounce pre-pass), the memory forecast, then the guide pass.
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
    let setup = report::SetupFacts {
        start,
        setup_seconds,
        validation,
        forecast,
    };
    // 2. Trace and 3. finish: one pass streams, tile rows finished as soon as their
    // denoiser window is traced; several passes keep per-tile sparse sums and finish from
    // them after each.
    let tile_count = schedule::tiles::tiles(ctx.resolution).len() as u64;
    progress.set_stage(Stage::Tracing);
    progress.start(tile_count * settings.spp as u64);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| crate::RelumeError::invalid("threads", e.to_string()))?;
    let baked = if passes.len() == 1 {
        schedule::passes::one_streaming_pass(
            &ctx, scene, &settings, band_rows, &pool, progress, &setup, on_pass,
        )?
    } else {
        schedule::passes::progressive_passes(
            &ctx, scene, &settings, passes, &pool, progress, &setup, on_pass,
        )?
    };
    progress.set_stage(Stage::Done);
    Ok(baked)
}

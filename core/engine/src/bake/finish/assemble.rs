//! From the traced sums to a stack, in named steps: average the sums into layers (grey where
//! the three channels agree everywhere), denoise them, leave out the negligible ones,
//! store them at the bake's precision, and write the header and the report.

use rayon::prelude::*;
use std::sync::Mutex;
use std::time::Instant;

use super::denoise::EyeFeatures;
use super::drop::RawLayer;
use super::finalise::{
    builder_for, finalise_dense, finish_stack, layer_weights, Finished, LatticePlan, LayerFacts,
    StackTally,
};
use crate::bake::layout::layer_key;
use crate::bake::prepare::context::{basis_config_for, BakeContext, RegionModel};
use crate::bake::report::BakeReport;
use crate::bake::settings::BakeSettings;
use crate::layer_key::LayerKey;
use crate::options::LightGrouping;
use crate::progress::{Progress, Stage};
use crate::scene::{hash::scene_hash, Scene};
use crate::stack::tiled::TiledStack;
use crate::stack::{LightGroupInfo, RegionInfo, StackHeader, STACK_FORMAT_VERSION};
use crate::Result;

/// Turns the store (sums over `spp` eye samples, full-frame layers: a progressive bake's
/// passes, a farm's merge) into a tiled stack, the report of its layers, and — when
/// `keep_image` — the image at the bake-time materials (for the progressive error
/// estimate). The layers are averaged and denoised as full frames (this path's memory
/// stays dense), then cut into tiles by the same [`finalise_tile`] as the streaming bake.
#[allow(clippy::too_many_arguments)]
pub(crate) fn assemble(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    store: &[Mutex<Vec<f32>>],
    eye_features: &EyeFeatures,
    spp: u32,
    pool: &rayon::ThreadPool,
    progress: &Progress,
    last_pass: bool,
    keep_image: bool,
) -> Result<(TiledStack, BakeReport, Option<Vec<f64>>)> {
    let assembly_start = Instant::now();
    progress.set_stage(Stage::Assembly);
    let res = ctx.resolution;
    let (mut reached, facts) = average_layers(ctx, store, spp, pool, progress, last_pass)?;
    let denoise_start = Instant::now();
    progress.set_stage(Stage::Denoising);
    {
        let mut raw: Vec<&mut RawLayer> = reached.iter_mut().map(|(_, l)| l).collect();
        denoise_layers(settings, eye_features, &mut raw, pool, progress)?;
    }
    let denoise_seconds = denoise_start.elapsed().as_secs_f64();
    progress.set_stage(Stage::Finishing);
    let builder = builder_for(ctx, stack_header(ctx, scene, settings, spp))?;
    let weights = layer_weights(ctx, scene)?;
    let pixels = res.width as usize * res.height as usize;
    let mut tally = StackTally::new(
        store.len(),
        res.width as usize,
        pixels,
        settings.precision,
        keep_image,
    );
    let layers: Vec<(u32, u8, &[f32])> = reached
        .iter()
        .map(|(i, l)| (*i as u32, l.channels as u8, &l.data[..]))
        .collect();
    let plan = LatticePlan::new(ctx, settings.compression, &weights);
    finalise_dense(
        &builder,
        &layers,
        res.width,
        res.height,
        &weights,
        &mut tally,
        plan.as_ref().map(|p| (p, eye_features)),
        pool,
        progress,
    )?;
    drop(layers);
    drop(reached);
    progress.check()?;
    let finished = finish_stack(
        ctx,
        builder,
        tally,
        &facts,
        &weights,
        settings.drop_budget as f64,
    )?;
    let assembly_seconds = assembly_start.elapsed().as_secs_f64();
    let image = finished.image.clone();
    let (stack, report) = layer_report(ctx, finished, assembly_seconds, denoise_seconds);
    Ok((stack, report, image))
}

/// What one dense layer's sums became.
enum Averaged {
    Layer(usize, RawLayer),
    /// No path reached it.
    Empty,
    /// Cancelled before it was looked at.
    Skipped,
}

/// Whole-image layers: averaged over the `spp` eye samples, grey when the three channels are
/// bit-identical everywhere (the path met no colour), and the keys of those nothing
/// reached. The last pass averages each accumulator in place (its sums are not needed
/// again), so assembly adds no second full copy of the layers to the bake's peak memory.
fn average_layers(
    ctx: &BakeContext,
    store: &[Mutex<Vec<f32>>],
    spp: u32,
    pool: &rayon::ThreadPool,
    progress: &Progress,
    last_pass: bool,
) -> Result<(Vec<(usize, RawLayer)>, LayerFacts)> {
    let inv_spp = 1.0 / spp as f32;
    let average = |(index, slot): (usize, &Mutex<Vec<f32>>)| -> Result<Averaged> {
        if progress.is_cancelled() {
            return Ok(Averaged::Skipped);
        }
        let mut sums = slot.lock().unwrap_or_else(|e| e.into_inner());
        let key = layer_key(ctx, index);
        if sums.is_empty() || sums.iter().all(|v| *v == 0.0) {
            return Ok(Averaged::Empty);
        }
        let mut image: Vec<f32> = if last_pass {
            std::mem::take(&mut *sums)
        } else {
            let mut copy = crate::memory::try_with_capacity(sums.len(), "an averaged layer")?;
            copy.extend_from_slice(&sums);
            copy
        };
        std::mem::drop(sums);
        for v in image.iter_mut() {
            *v *= inv_spp;
        }
        Ok(Averaged::Layer(index, grey_or_rgb(key, image)?))
    };
    let averaged: Vec<Result<Averaged>> =
        pool.install(|| store.par_iter().enumerate().map(average).collect());
    progress.check()?;
    let mut reached = Vec::new();
    let mut facts = LayerFacts {
        reached: vec![false; store.len()],
        coloured: vec![false; store.len()],
    };
    for a in averaged {
        match a? {
            Averaged::Layer(i, l) => {
                facts.reached[i] = true;
                facts.coloured[i] = l.channels == 3;
                reached.push((i, l));
            }
            Averaged::Empty => {}
            Averaged::Skipped => return Err(crate::RelumeError::Cancelled),
        }
    }
    Ok((reached, facts))
}

/// One channel when the three are bit-identical at every pixel (Table 1's grey layers: the
/// path met no colour), else the RGB image as it is.
fn grey_or_rgb(key: LayerKey, image: Vec<f32>) -> Result<RawLayer> {
    if image.chunks_exact(3).all(|c| c[0] == c[1] && c[1] == c[2]) {
        let mut y = crate::memory::try_with_capacity(image.len() / 3, "a grey layer")?;
        y.extend(image.chunks_exact(3).map(|c| c[0]));
        Ok(RawLayer {
            key,
            channels: 1,
            data: y,
        })
    } else {
        Ok(RawLayer {
            key,
            channels: 3,
            data: image,
        })
    }
}

/// Runs the settings' denoiser: its direct iterations on the layers lit at the eye vertex
/// (one-vertex paths), its bounce iterations on the one-bounce layers.
pub(crate) fn denoise_layers(
    settings: &BakeSettings,
    eye_features: &EyeFeatures,
    reached: &mut [&mut RawLayer],
    pool: &rayon::ThreadPool,
    progress: &Progress,
) -> Result<()> {
    pool.install(|| -> Result<()> {
        for (vertices, iterations) in [
            (1, settings.denoise.direct_iterations),
            (2, settings.denoise.bounce_iterations),
        ] {
            let mut chosen: Vec<&mut RawLayer> = reached
                .iter_mut()
                .filter(|l| l.key.path.len() == vertices)
                .map(|l| &mut **l)
                .collect();
            eye_features.filter_cancellable(&mut chosen, iterations, progress)?;
        }
        Ok(())
    })
}

/// What the stack records of the bake: image, camera, sampling, the regions with their
/// bases and subsurface layouts, the lights and their groups' tints, the scene's hash.
pub(crate) fn stack_header(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    spp: u32,
) -> StackHeader {
    let res = ctx.resolution;
    StackHeader {
        format_version: STACK_FORMAT_VERSION,
        width: res.width,
        height: res.height,
        camera: scene.camera.clone(),
        spp,
        light_samples: settings.light_samples,
        bounces: ctx.settings.bounces,
        sampling: settings.sampling.name().into(),
        seed: settings.seed,
        regions: scene
            .regions
            .iter()
            .zip(&ctx.translucent)
            .zip(&ctx.regions)
            .map(|((r, t), prepared)| {
                let (principled, with_bake_lobe) = match &prepared.model {
                    RegionModel::Editable { basis, .. } => (
                        basis.principled().map(|b| b.config().clone()),
                        basis.bake_lobe_slot().is_some(),
                    ),
                    _ => (None, false),
                };
                RegionInfo {
                    subsurface: t.as_ref().map(|t| t.info.clone()),
                    ..RegionInfo::from_region(
                        r,
                        (r.editable && principled.is_none())
                            .then(|| basis_config_for(&settings.basis, r.ns_range)),
                    )
                }
                .with_principled(principled, with_bake_lobe)
            })
            .collect(),
        lights: scene.lights.clone(),
        scene_hash: scene_hash(scene),
        precision: settings.precision,
        light_tint: ctx.lights.groups[0].tint.to_array(),
        light_groups: if ctx.settings.light_grouping == LightGrouping::All {
            Vec::new()
        } else {
            ctx.lights
                .groups
                .iter()
                .map(|g| LightGroupInfo {
                    name: g.name.clone(),
                    tint: g.tint.to_array(),
                })
                .collect()
        },
        denoise: settings.denoise,
    }
}

/// The stack and the report of its assembly; timing, ray and validation fields are filled
/// in by the caller.
pub(crate) fn layer_report(
    ctx: &BakeContext,
    finished: Finished,
    assembly_seconds: f64,
    denoise_seconds: f64,
) -> (TiledStack, BakeReport) {
    let res = ctx.resolution;
    let stack = finished.stack;
    let report = BakeReport {
        seconds: 0.0,
        rays: 0,
        setup_seconds: 0.0,
        trace_seconds: 0.0,
        assembly_seconds,
        denoise_seconds,
        rays_per_second: 0.0,
        width: res.width,
        height: res.height,
        triangles: 0,
        degenerate_triangles: 0,
        warnings: finished.non_finite.warning().into_iter().collect(),
        layers_possible: finished.possible,
        layers_grey: finished.grey,
        layers_rgb: finished.rgb,
        layers_empty: finished.empty,
        sample_bytes: finished.dense_bytes,
        tile_entries: stack.entry_count(),
        stored_bytes: stack.sample_bytes(),
        dense_bytes: finished.dense_bytes,
        compression_error: finished.compression_error,
        compression_saved_bytes: finished.compression_saved_bytes,
        peak_accounted_bytes: 0,
        layers: finished.drop,
        estimate: None,
        bounces: ctx.settings.bounces,
        bounce_estimate: ctx.bounce_estimate.clone(),
        non_finite: finished.non_finite,
        adaptive: None,
    };
    (stack, report)
}

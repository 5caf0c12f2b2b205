//! What a finished stack says of its bake: its header (image, camera, sampling, regions,
//! lights, the scene's hash) and the report of its layers. Every schedule ends here — the
//! one-pass bake, a progressive bake's passes and a farm's merge — so their stacks and
//! reports are described alike.

use crate::bake::prepare::context::{basis_config_for, BakeContext, RegionModel};
use crate::bake::report::BakeReport;
use crate::bake::settings::BakeSettings;
use crate::options::LightGrouping;
use crate::scene::{hash::scene_hash, Scene};
use crate::stack::tiled::TiledStack;
use crate::stack::{LightGroupInfo, RegionInfo, StackHeader, STACK_FORMAT_VERSION};

use super::finalise::Finished;

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
        bounce_light_samples: settings.bounce_light_samples,
        bounces: ctx.settings.bounces,
        diffuse_bounces: settings.diffuse_bounces,
        glossy_bounces: settings.glossy_bounces,
        bounce_cap: ctx
            .bounce_estimate
            .as_ref()
            .map_or(ctx.settings.bounces, |e| e.cap),
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

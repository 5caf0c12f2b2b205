//! On every assets stack baked by the streaming bake into the tiled layout, f16 and f32,
//! the GPU relight of that layout (forced: lavapipe in CI) matches the CPU tiled relight
//! within 1e-6 relative L2 — full, then several single-region edits in a row, each
//! compared after it — and across the periodic full re-sum of incremental edits; also
//! with the values spread over many chunks and bind groups.

mod common;

use std::sync::Arc;

use common::*;
use relume_engine::relight::FULL_RESUM_EVERY;
use relume_engine::stack::Precision;
use relume_gpu::{GpuOptions, GpuRelighter};

fn all_assets(precision: Precision) {
    let Some(adapter) = gpu_or_skip("all_assets") else {
        return;
    };
    for (name, stack) in ASSETS.iter().map(|a| asset_tiled(a, precision)) {
        let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
        let worst = compare_with_cpu(&name, &stack, &mut gpu, 6);
        eprintln!(
            "{name}: {} layers, worst GPU/CPU relative L2 {worst:.2e}",
            stack.layers.len()
        );
    }
}

#[test]
fn assets_stacks_f16_agree_full_and_incremental() {
    all_assets(Precision::F16);
}

#[test]
fn assets_stacks_f32_agree_full_and_incremental() {
    all_assets(Precision::F32);
}

/// Chunks the size of the Cornell box's fullest tile spread its 15 tiles over more
/// storage buffers than one bind group binds: one dispatch per group, each over its own
/// tiles.
#[test]
fn many_chunks_and_bind_groups_agree() {
    let Some(adapter) = gpu_or_skip("many_chunks_and_bind_groups_agree") else {
        return;
    };
    let (name, stack) = asset_tiled_sized("cornell", 72, 40, Precision::F16);
    let largest = stack.tiles.iter().map(|t| t.values.bytes()).max().unwrap() as u64;
    let options = GpuOptions {
        max_chunk_bytes: Some(largest.div_ceil(4) * 4),
        timestamps: false,
    };
    let mut gpu = GpuRelighter::new(stack.clone(), &adapter, options).unwrap();
    let (_, chunks) = gpu.layer_bytes_and_chunks();
    assert!(
        chunks > relume_gpu::layout::CHUNKS_PER_GROUP,
        "{name}: only {chunks} chunks, the test needs several bind groups"
    );
    compare_with_cpu(&name, &stack, &mut gpu, 4);
}

/// More edits than FULL_RESUM_EVERY: the periodic full re-sum happens on the GPU too and
/// the image stays within tolerance through it.
#[test]
fn incremental_edits_across_the_full_resum() {
    let Some(adapter) = gpu_or_skip("incremental_edits_across_the_full_resum") else {
        return;
    };
    let (name, stack) = asset_tiled("ring", Precision::F16);
    let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
    compare_with_cpu(&name, &stack, &mut gpu, FULL_RESUM_EVERY + 3);
    assert!(gpu.last_stats().incremental);
}

/// The extremes suite's stacks (core/engine/tests/engine/extremes.rs) on the assets Cornell box:
/// lights 10⁶ times brighter and dimmer (per-layer f16 scales at both ends), the scene at
/// 10⁻³ and 10⁴ scale, a [1, 10 000] exponent range with a tolerance basis (9 bases), and
/// per-light groups. GPU and CPU agree within 1e-6, full and incremental.
#[test]
fn extremes_stacks_agree_full_and_incremental() {
    use relume_engine::bake::{bake_tiled, BakeSettings, LightGrouping};
    use relume_engine::brdf::{BasisConfig, BasisCount};
    use relume_engine::progress::Progress;
    use relume_engine::scene::{file::load_scene, Light, Resolution};
    let Some(adapter) = gpu_or_skip("extremes_stacks_agree_full_and_incremental") else {
        return;
    };
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets");
    let base = load_scene(&root.join("cornell.scene.json")).unwrap();
    let small = BakeSettings {
        spp: 2,
        light_samples: 1,
        resolution: Some(Resolution {
            width: 32,
            height: 32,
        }),
        ..Default::default()
    };
    let mut cases: Vec<(String, relume_engine::scene::Scene, BakeSettings)> = Vec::new();
    for factor in [1e6f32, 1e-6] {
        let mut scene = base.clone();
        for light in &mut scene.lights {
            if let Light::Area { power, .. } = light {
                *power *= factor;
            }
        }
        cases.push((format!("light × {factor}"), scene, small.clone()));
    }
    for s in [1e-3f32, 1e4] {
        let mut scene = base.clone();
        for mesh in &mut scene.meshes {
            mesh.positions.iter_mut().flatten().for_each(|c| *c *= s);
        }
        for light in &mut scene.lights {
            if let Light::Area {
                position,
                size_x,
                size_y,
                power,
                ..
            } = light
            {
                position.iter_mut().for_each(|c| *c *= s);
                *size_x *= s;
                if let Some(y) = size_y {
                    *y *= s;
                }
                *power *= s * s;
            }
        }
        for row in &mut scene.camera.matrix_world[..3] {
            row[3] *= s;
        }
        scene.camera.clip_start *= s;
        scene.camera.clip_end *= s;
        cases.push((format!("scale {s}"), scene, small.clone()));
    }
    let wide = BasisConfig {
        ns_min: 1.0,
        ns_max: 10_000.0,
        count: BasisCount::Tolerance(0.03),
        ..BasisConfig::default()
    };
    cases.push((
        "ns up to 10 000".into(),
        base.clone(),
        BakeSettings {
            basis: wide,
            ..small.clone()
        },
    ));
    cases.push((
        "per-light groups".into(),
        base.clone(),
        BakeSettings {
            light_grouping: LightGrouping::PerLight,
            ..small.clone()
        },
    ));
    for (name, scene, settings) in cases {
        let (stack, _) = bake_tiled(&scene, &settings, &Progress::new())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let stack = Arc::new(stack);
        let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
        let worst = compare_with_cpu(&name, &stack, &mut gpu, 4);
        eprintln!(
            "{name}: {} layers, worst GPU/CPU relative L2 {worst:.2e}",
            stack.layers.len()
        );
    }
}

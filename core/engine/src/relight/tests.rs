//! Unit tests that need the crate-private kernel choice; the behavioural tests are in
//! `core/engine/tests/relight_*.rs`.

use std::sync::Arc;

use super::kernels::Kernels;
use super::*;
use crate::bake::signature::{LayerKey, PathVertex};
use crate::brdf::{BlinnPhong, MaterialSpec};
use crate::stack::{
    Layer, Precision, RegionInfo, StackHeader, TransferStack, STACK_FORMAT_VERSION,
};
use crate::Rgb;

fn header(width: u32, height: u32) -> StackHeader {
    let camera = serde_json::from_str(
        r#"{"projection":"perspective","matrix_world":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#,
    )
    .unwrap();
    let region = |name: &str, editable| RegionInfo {
        name: name.into(),
        editable,
        material: MaterialSpec::BlinnPhong(BlinnPhong {
            kd: [0.5; 3],
            ks: [0.1; 3],
            ns: 10.0,
        }),
        basis: None,
        textured: false,
        subsurface: None,
    };
    StackHeader {
        format_version: STACK_FORMAT_VERSION,
        width,
        height,
        camera,
        spp: 1,
        light_samples: 1,
        bounces: 1,
        sampling: "uniform".into(),
        seed: 0,
        regions: vec![region("A", true), region("Walls", false), region("B", true)],
        lights: vec![],
        scene_hash: String::new(),
        precision: Precision::F16,
        light_tint: [1.0; 3],
        light_groups: Vec::new(),
        denoise: Default::default(),
    }
}

/// The SIMD kernels and the portable ones give the same image (up to FMA's single rounding)
/// on odd widths (tails), partial spans, f16 and f32, grey and RGB, full and incremental.
#[test]
fn simd_and_portable_paths_agree() {
    let (w, h) = (37u32, 21u32);
    let e = |region, basis| PathVertex::Editable { region, basis };
    let keys = [
        vec![],
        vec![PathVertex::Fixed],
        vec![e(0, 0)],
        vec![e(0, 1), e(1, 0)],
        vec![e(1, 2), PathVertex::Fixed],
    ];
    let mut layers = Vec::new();
    let mut names = std::collections::HashSet::new();
    let mut x = 12345u32;
    for (i, k) in keys.iter().enumerate() {
        for (j, (ch, prec)) in [
            (1u32, Precision::F16),
            (3, Precision::F32),
            (3, Precision::F16),
        ]
        .into_iter()
        .enumerate()
        {
            // Layer names are unique in a stack: the variants differ by trailing fixed
            // vertices, which weigh 1.
            let mut key = k.clone();
            key.extend(std::iter::repeat_n(PathVertex::Fixed, j));
            if !names.insert(LayerKey::new(key.clone()).layer_name()) {
                continue;
            }
            let vals: Vec<f32> = (0..(w * h * ch) as usize)
                .map(|j| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    // Zero the left third of every row of some layers: partial spans.
                    if i % 2 == 1 && ((j / ch as usize) % w as usize).is_multiple_of(3) {
                        0.0
                    } else {
                        (x % 1000) as f32 / 250.0 - 1.0
                    }
                })
                .collect();
            layers.push(Layer::from_f32(LayerKey::new(key), ch, &vals, prec));
        }
    }
    let stack = Arc::new(TransferStack {
        header: header(w, h),
        layers,
    });
    let fast = Kernels::detect();
    let mut a = CpuRelighter::with_kernels(stack.clone(), fast).unwrap();
    let mut b = CpuRelighter::with_kernels(stack, Kernels::Portable).unwrap();
    let coefs = vec![
        vec![Rgb::new(0.3, 0.5, 0.7), Rgb::new(-0.2, 0.1, 0.4)],
        vec![
            Rgb::new(0.9, 0.2, 0.1),
            Rgb::splat(0.5),
            Rgb::new(0.05, -0.3, 0.6),
        ],
    ];
    let check = |a: &[f32], b: &[f32]| {
        let scale = b.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        for (i, (x, y)) in a.iter().zip(b).enumerate() {
            assert!((x - y).abs() <= 2e-6 * scale, "pixel value {i}: {x} vs {y}");
        }
    };
    let ia = a.relight(&coefs).unwrap().to_vec();
    let ib = b.relight(&coefs).unwrap().to_vec();
    check(&ia, &ib);
    let c1 = vec![Rgb::new(0.1, 0.2, 0.3), Rgb::ZERO, Rgb::ONE];
    let ia = a.relight_region(1, &c1).unwrap().to_vec();
    let ib = b.relight_region(1, &c1).unwrap().to_vec();
    check(&ia, &ib);
}

//! A bake is never lost to a value that is not finite: each stage keeps its output finite by
//! construction and the report counts what it changed. Values are injected at each stage —
//! the path's contributions (lights so bright their radiance overflows f32), the averaged
//! and denoised layers, the f16 encoder (lights so faint that an entry's scale is
//! subnormal), the stack builder that stands before the writer — and every bake must
//! complete with a finite stack, a finite relit image and the counts in its report.
use crate::common;

use std::sync::Arc;

use relume_engine::bake::to_file::bake_to_file;
use relume_engine::bake::{BakeSettings, Denoise};
use relume_engine::layer_key::{LayerKey, PathVertex};
use relume_engine::options::Precision;
use relume_engine::progress::Progress;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{Light, Resolution, Scene};
use relume_engine::stack::tiled::file::{read_tiled, write_tiled};
use relume_engine::stack::tiled::{TileRadiance, TileValues, TiledStack, TiledStackBuilder};

const SIZE: u32 = 32;

fn cornell_with_power(power: f32) -> Scene {
    let mut scene = common::cornell(SIZE);
    for light in &mut scene.lights {
        if let Light::Area { power: p, .. } = light {
            *p = power;
        }
    }
    scene
}

/// Small, with both denoisers on (their tails made the subnormal entries that lost bakes)
/// and bounce compression at its default.
fn settings(precision: Precision, seed: u64) -> BakeSettings {
    BakeSettings {
        spp: 2,
        light_samples: 1,
        seed,
        threads: 2,
        precision,
        resolution: Some(Resolution {
            width: SIZE,
            height: SIZE,
        }),
        denoise: Denoise {
            direct_iterations: 2,
            bounce_iterations: 2,
        },
        ..BakeSettings::default()
    }
}

fn all_values_finite(stack: &TiledStack) -> bool {
    stack.tiles.iter().all(|t| match &t.values {
        TileValues::F16(v) => v.iter().all(|s| s.is_finite()),
        TileValues::F32(v) => v.iter().all(|s| s.is_finite()),
    }) && stack.tiles.iter().all(|t| {
        t.entries
            .iter()
            .all(|e| e.scale.is_finite() && e.scale > 0.0)
    })
}

/// Bakes to a file, reads it back and relights it at the bake-time materials.
fn bake_and_relight(
    scene: &Scene,
    s: &BakeSettings,
) -> (relume_engine::bake::BakeReport, Vec<f32>) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.exr");
    let baked = bake_to_file(scene, s, 1, &path, &Progress::new(), |_, _| {})
        .unwrap_or_else(|e| panic!("the bake was lost: {e}"));
    let stack = read_tiled(&path).unwrap();
    assert!(all_values_finite(&stack));
    let coefs = common::bake_material_coefs(&stack.header, scene);
    let mut r = CpuRelighter::from_tiled(Arc::new(stack)).unwrap();
    let image = r.relight(&coefs).unwrap().to_vec();
    (baked.report, image)
}

fn mean_rgb(image: &[f32]) -> f64 {
    let px: Vec<&[f32]> = image.chunks_exact(4).collect();
    px.iter()
        .map(|p| p[..3].iter().map(|v| *v as f64).sum::<f64>())
        .sum::<f64>()
        / (3 * px.len()) as f64
}

/// A light 1e-30 to 1e-36 times as strong: every entry's f16 scale is tiny (subnormal for
/// the faintest), once making `1/scale` infinite and the stored values NaN or inf, which the
/// writer refused after the whole bake. The same paths (same seed) must give the same
/// image, scaled by the power, to the quantisation's precision.
#[test]
fn faint_lights_bake_and_relight_in_proportion_at_both_precisions() {
    for precision in [Precision::F16, Precision::F32] {
        let s = settings(precision, 0);
        let (_, reference) = bake_and_relight(&cornell_with_power(40.0), &s);
        let m_ref = mean_rgb(&reference);
        assert!(m_ref > 0.0);
        for (power, tolerance) in [(1e-30f32, 1e-3), (1e-33, 1e-3), (1e-36, 0.05)] {
            let (report, image) = bake_and_relight(&cornell_with_power(power), &s);
            assert!(image.iter().all(|v| v.is_finite()), "{power} {precision:?}");
            assert_eq!(report.non_finite.total(), 0, "{:?}", report.non_finite);
            let ratio = mean_rgb(&image) / m_ref / (power as f64 / 40.0);
            assert!(
                (ratio - 1.0).abs() < tolerance,
                "power {power} {precision:?}: image / reference {ratio}"
            );
        }
    }
}

/// A light whose radiance overflows f32 (3e38 W on a 0.5 m square): the paths that carry
/// an infinite contribution are discarded and counted, the bake completes, the report says
/// so in its counts and its warnings.
#[test]
fn an_overflowing_light_loses_paths_not_the_bake() {
    for precision in [Precision::F16, Precision::F32] {
        let (report, image) = bake_and_relight(&cornell_with_power(3e38), &settings(precision, 1));
        let n = &report.non_finite;
        assert!(n.path_contributions > 0, "{n:?}");
        assert_eq!(
            n.stored_values, 0,
            "{n:?}: the stages before the writer let one through"
        );
        assert!(
            report
                .warnings
                .iter()
                .any(|w| w.contains("path contributions discarded")),
            "{:?}",
            report.warnings
        );
        // The relight may overflow where the light's own radiance is near f32's limit; what
        // it gives is either finite or is the relight's to report, never the bake's loss.
        assert!(image.iter().any(|v| v.is_finite() && *v > 0.0));
    }
}

/// The builder, the last stage before the writer: a NaN, an infinity and subnormal values
/// handed to it are stored finite (the non-finite ones as 0, counted), the stack passes
/// the writer's check, and what is read back is what was given.
#[test]
fn the_builder_stores_nan_inf_and_subnormals_finite_and_counts_them() {
    for precision in [Precision::F16, Precision::F32] {
        let mut header = common::stack_header::stack_header(16, 16, Vec::new());
        header.precision = precision;
        let layers = vec![
            (LayerKey::new(vec![]), 1u8),
            (LayerKey::new(vec![PathVertex::Fixed]), 1u8),
        ];
        let builder = TiledStackBuilder::new(header, layers).unwrap();
        let mut poisoned = vec![1e-3f32; 256];
        poisoned[3] = f32::NAN;
        poisoned[7] = f32::INFINITY;
        // Largest magnitude 1e-40 (subnormal): its f16 scale is 6e-45, `1/scale` beyond f32.
        let subnormal: Vec<f32> = (0..256).map(|i| 1e-40 * (1 + i % 4) as f32 / 4.0).collect();
        builder
            .insert(
                0,
                &[
                    TileRadiance {
                        layer: 0,
                        channels: 1,
                        radiance: &poisoned,
                    },
                    TileRadiance {
                        layer: 1,
                        channels: 1,
                        radiance: &subnormal,
                    },
                ],
            )
            .unwrap();
        assert_eq!(builder.non_finite_zeroed(), 2);
        let stack = builder.finish().unwrap();
        assert!(all_values_finite(&stack));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.exr");
        write_tiled(&path, &stack).unwrap();
        let back = read_tiled(&path).unwrap().to_dense().unwrap();
        let value = |layer: usize, i: usize| back.layers[layer].value(i) as f64;
        assert_eq!(value(0, 3), 0.0);
        assert_eq!(value(0, 7), 0.0);
        assert!((value(0, 0) - 1e-3).abs() < 1e-6, "{}", value(0, 0));
        for (i, &want) in subnormal.iter().enumerate().take(8) {
            let want = want as f64;
            let got = value(1, i);
            assert!(
                (got - want).abs() <= 0.02 * want,
                "{precision:?} subnormal value {i}: {got} for {want}"
            );
        }
    }
}

//! OpenImageDenoise on a real bake (the Cornell asset scene, a few samples a pixel): the
//! shown image is much closer to a converged bake than the relit one, before and after a
//! material edit, and stays finite; `none` and `linear` are the relit image bit for bit.
mod common;

use std::time::Instant;

use relume_denoise::oidn::{DeviceChoice, Quality};
use relume_denoise::{DenoiseMode, FeatureImages, ShownImage};
use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::features::{albedo_of, PixelFeatures, FEATURE_SAMPLES_PER_AXIS};
use relume_engine::image_io::compare_rgb;

const SIZE: u32 = 96;

fn edits() -> Vec<(&'static str, MaterialSpec)> {
    vec![
        (
            "Object",
            MaterialSpec::BlinnPhong(BlinnPhong {
                kd: [0.6, 0.1, 0.05],
                ks: [0.3, 0.3, 0.3],
                ns: 60.0,
            }),
        ),
        (
            "White walls",
            MaterialSpec::BlinnPhong(BlinnPhong {
                kd: [0.55, 0.5, 0.3],
                ks: [0.0; 3],
                ns: 10.0,
            }),
        ),
    ]
}

#[test]
fn oidn_brings_a_noisy_bake_much_closer_to_a_converged_one_before_and_after_an_edit() {
    let Some(search) = common::oidn_search("oidn_cornell") else {
        return;
    };
    let scene = common::cornell(SIZE);
    let t = Instant::now();
    let noisy = common::bake(&scene, 4, 1, 1, 1);
    let noisy_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let converged = common::bake(&scene, 128, 4, 4, 2);
    let converged_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let features = PixelFeatures::trace(&scene, SIZE, SIZE, FEATURE_SAMPLES_PER_AXIS).unwrap();
    let features_ms = t.elapsed().as_secs_f64() * 1e3;
    eprintln!("bakes {noisy_s:.1} s (noisy), {converged_s:.1} s (converged); features {features_ms:.0} ms");
    let mut shown = ShownImage::new(search, DeviceChoice::Default);
    for (label, edit) in [("bake-time materials", vec![]), ("edited", edits())] {
        let materials = common::materials(&noisy, &edit);
        let raw = common::relight(&noisy, &materials);
        let reference = common::relight(&converged, &materials);
        let albedo = albedo_of(&features, &materials).unwrap();
        let (image, report) = shown
            .show(
                &raw,
                SIZE,
                SIZE,
                DenoiseMode::Oidn,
                FeatureImages::Clean {
                    albedo: &albedo,
                    normal: features.normal(),
                },
            )
            .unwrap();
        assert_eq!(report.ran, DenoiseMode::Oidn, "{:?}", report.note);
        assert_eq!(report.features, "albedo+normal");
        assert!(image.iter().all(|v| v.is_finite()));
        let (colour_only, _) = shown
            .show(
                &raw,
                SIZE,
                SIZE,
                DenoiseMode::Oidn,
                FeatureImages::Missing("test".into()),
            )
            .unwrap();
        let e_raw = compare_rgb(&raw, &reference, 4).unwrap().rel_l2;
        let e_oidn = compare_rgb(&image, &reference, 4).unwrap().rel_l2;
        let e_colour = compare_rgb(&colour_only, &reference, 4).unwrap().rel_l2;
        eprintln!(
            "{label}: rel. L2 against the converged bake {e_raw:.4} relit, {e_oidn:.4} OIDN with features, {e_colour:.4} OIDN on colour alone ({})",
            report.summary()
        );
        assert!(e_oidn < 0.5 * e_raw, "OIDN {e_oidn} against relit {e_raw}");
        // OIDN's balanced quality (the add-on's live image): close to the high one.
        shown.set_quality(Quality::Balanced);
        let (balanced, report) = shown
            .show(
                &raw,
                SIZE,
                SIZE,
                DenoiseMode::Oidn,
                FeatureImages::Clean {
                    albedo: &albedo,
                    normal: features.normal(),
                },
            )
            .unwrap();
        shown.set_quality(Quality::High);
        assert_eq!(report.quality, Some(Quality::Balanced));
        let e_balanced = compare_rgb(&balanced, &reference, 4).unwrap().rel_l2;
        eprintln!("{label}: balanced quality {e_balanced:.4}");
        assert!(
            e_balanced < 0.5 * e_raw,
            "balanced {e_balanced} against relit {e_raw}"
        );
    }
}

//! The stack's linear denoiser on a real bake: it lowers the error against a converged
//! bake, touches only the layers it is asked to, and the header says it ran.
use crate::common;

use relume_engine::bake::{bake, BakeSettings, Denoise};
use relume_engine::image_io::compare_rgb;
use relume_engine::progress::Progress;
use relume_engine::stack::TransferStack;

fn relight(stack: &TransferStack, scene: &relume_engine::scene::Scene) -> Vec<f32> {
    common::relight_at_bake_materials(stack, scene)
}

#[test]
fn denoising_the_bounce_layers_lowers_the_error_and_leaves_direct_layers_alone() {
    let scene = common::cornell(64);
    let settings = BakeSettings {
        spp: 8,
        indirect_samples: 2,
        ..Default::default()
    };
    let bake_with = |s: &BakeSettings| bake(&scene, s, &Progress::new()).unwrap().0;
    let converged = relight(
        &bake_with(&BakeSettings {
            spp: 256,
            seed: 99,
            ..settings.clone()
        }),
        &scene,
    );
    let raw = bake_with(&settings);
    let denoised = bake_with(&BakeSettings {
        denoise: Denoise {
            direct_iterations: 0,
            bounce_iterations: 2,
        },
        ..settings.clone()
    });
    assert_eq!(raw.header.denoise, Denoise::OFF);
    assert_eq!(denoised.header.denoise.bounce_iterations, 2);

    let (img_raw, img_dn) = (relight(&raw, &scene), relight(&denoised, &scene));
    assert!(img_dn.iter().all(|v| v.is_finite() && *v >= 0.0));
    let e_raw = compare_rgb(&img_raw, &converged, 4).unwrap().rel_l2;
    let e_dn = compare_rgb(&img_dn, &converged, 4).unwrap().rel_l2;
    eprintln!("Cornell 64², 8 spp × 2 indirect: rel. L2 {e_raw:.4} raw, {e_dn:.4} denoised");
    assert!(e_dn < 0.7 * e_raw, "denoised {e_dn} against raw {e_raw}");

    // Same seed, same paths: the direct layers (one path vertex) are bit-identical, and
    // the bounce layers changed.
    let mut bounce_changed = 0;
    for (a, b) in raw.layers.iter().zip(&denoised.layers) {
        assert_eq!(a.key, b.key);
        if a.key.path.len() < 2 {
            assert!(a.samples == b.samples, "{} changed", a.key.layer_name());
        } else if a.samples != b.samples {
            bounce_changed += 1;
        }
    }
    assert!(bounce_changed > 0);
}

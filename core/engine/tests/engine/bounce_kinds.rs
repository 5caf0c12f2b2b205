//! Cycles' per-kind light path limits (`bake::path::bounce_kinds`): a path stops at its
//! diffuse limit whatever the total allows, a limit a path cannot reach changes nothing, and
//! the bake records the limits for a refinement.
//!
//! Inside a closed diffuse sphere with a point light at its centre every bounce brings
//! `albedo` times the light of the one before (`frozen_tail.rs` says why), so a diffuse
//! limit of d bounces under a total of 12 must give `L₀ · Σ_{k=0..d} aᵏ`, the series cut at d.
use crate::common;

use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::bake::{bake, BakeSettings, IndirectSampling};
use relume_engine::progress::Progress;
use relume_engine::stack::Precision;

const SIZE: u32 = 24;

fn settings(bounces: u32, diffuse: Option<u32>, glossy: Option<u32>) -> BakeSettings {
    BakeSettings {
        spp: 8,
        light_samples: 1,
        indirect_samples: 2,
        bounces,
        diffuse_bounces: diffuse,
        glossy_bounces: glossy,
        sampling: IndirectSampling::Mixture,
        precision: Precision::F32,
        ..Default::default()
    }
}

fn mean_red(rgba: &[f32]) -> f64 {
    rgba.chunks(4).map(|p| p[0] as f64).sum::<f64>() / (rgba.len() / 4) as f64
}

fn render(settings: &BakeSettings) -> Vec<f32> {
    render_scene(&common::closed_sphere(0.7, false, SIZE), settings)
}

fn render_scene(scene: &relume_engine::scene::Scene, settings: &BakeSettings) -> Vec<f32> {
    render_reference(scene, settings, &[], ReferenceBrdf::True, &Progress::new())
        .unwrap()
        .rgba
}

/// A glossy sphere (no diffuse part): every bounce is labelled glossy, so a glossy limit of
/// g under a total of 12 is a total of g, and a diffuse limit never binds.
#[test]
fn a_glossy_path_stops_at_the_glossy_limit() {
    let mut scene = common::closed_sphere(0.7, false, SIZE);
    scene.regions[0].material = common::bp(0.0, 0.8, 8.0);
    let cut = mean_red(&render_scene(&scene, &settings(2, None, None)));
    let limited = mean_red(&render_scene(&scene, &settings(12, Some(0), Some(2))));
    let free = mean_red(&render_scene(&scene, &settings(12, None, None)));
    eprintln!("closed glossy sphere: 2 bounces {cut:.5}, 12 with glossy limit 2 {limited:.5}, 12 free {free:.5}");
    assert!(
        free > cut * 1.03,
        "the later bounces hold light: {free} vs {cut}"
    );
    assert!(
        (limited / cut - 1.0).abs() < 1e-4,
        "glossy limit 2 under 12 bounces {limited} vs 2 bounces {cut}"
    );
}

#[test]
fn a_diffuse_path_stops_at_the_diffuse_limit() {
    let a = 0.7f64;
    let direct = mean_red(&render(&settings(0, None, None)));
    assert!(direct > 0.0);
    for (diffuse, glossy) in [(Some(2), Some(4)), (Some(3), None), (None, Some(0))] {
        let ratio = mean_red(&render(&settings(12, diffuse, glossy))) / direct;
        // A diffuse sphere labels every bounce diffuse: the glossy limit never binds.
        let cut = diffuse.unwrap_or(12);
        let expected: f64 = (0..=cut).map(|k| a.powi(k as i32)).sum();
        eprintln!(
            "closed sphere, 12 bounces, diffuse {diffuse:?} glossy {glossy:?}: L/L₀ {ratio:.4}, Σ aᵏ to {cut}: {expected:.4}"
        );
        assert!(
            (ratio / expected - 1.0).abs() < 0.01,
            "diffuse {diffuse:?} glossy {glossy:?}: {ratio} vs {expected}"
        );
    }
}

#[test]
fn limits_a_path_cannot_reach_change_nothing() {
    let free = render(&settings(3, None, None));
    for (d, g) in [(Some(3), Some(3)), (Some(7), None), (None, Some(12))] {
        assert_eq!(
            render(&settings(3, d, g)),
            free,
            "limits {d:?}/{g:?} at 3 bounces"
        );
    }
}

#[test]
fn the_stack_records_the_limits_for_a_refinement() {
    let scene = common::closed_sphere(0.7, true, 8);
    let s = BakeSettings {
        spp: 1,
        ..settings(6, Some(2), Some(3))
    };
    let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
    assert_eq!(
        (stack.header.diffuse_bounces, stack.header.glossy_bounces),
        (Some(2), Some(3))
    );
    let json = serde_json::to_string(&stack.header).unwrap();
    let back: relume_engine::stack::StackHeader = serde_json::from_str(&json).unwrap();
    assert_eq!(back, stack.header);
}

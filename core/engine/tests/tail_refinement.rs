//! The background refinement of an edit's tail (`relume_engine::refine`): what it adds is
//! exactly what the relight misses past the second vertex, along the bake's own paths.
//!
//! The reference renderer traces the bake's paths with the given materials at every vertex;
//! in its projected mode the first two vertices are the basis' reconstruction, as the
//! relight has them. After as many refinement passes as the bake had samples per pixel,
//! the refinement has traced the same paths, so relit + refinement must equal that
//! reference up to rounding for any edit — lobe shapes, mirrors, several regions at once —
//! while the relight alone is off by what docs/bounces.md measures.
mod common;

use std::sync::Arc;

use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::bake::{bake, BakeSettings, IndirectSampling};
use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::image_io::compare_rgb;
use relume_engine::progress::Progress;
use relume_engine::refine::TailRefiner;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::Scene;
use relume_engine::stack::{bases::StackBases, Precision, TransferStack};

fn settings(spp: u32, bounces: u32) -> BakeSettings {
    BakeSettings {
        spp,
        light_samples: 2,
        indirect_samples: 2,
        bounces,
        sampling: IndirectSampling::Mixture,
        precision: Precision::F32,
        ..Default::default()
    }
}

fn specs(mats: &[BlinnPhong]) -> Vec<MaterialSpec> {
    mats.iter().map(|m| MaterialSpec::BlinnPhong(*m)).collect()
}

fn relight(stack: &TransferStack, mats: &[BlinnPhong]) -> Vec<f32> {
    let bases = StackBases::from_header(&stack.header).unwrap();
    let coefs = bases.coefficients(&specs(mats)).unwrap();
    CpuRelighter::new(Arc::new(stack.clone()))
        .unwrap()
        .relight(&coefs)
        .unwrap()
        .to_vec()
}

/// The relit image with `passes` refinement passes added.
fn refined(
    refiner: &TailRefiner,
    stack: &TransferStack,
    mats: &[BlinnPhong],
    passes: u32,
) -> Vec<f32> {
    let mut r = refiner.start(&specs(mats), None).unwrap();
    let mut img = relight(stack, mats);
    refiner
        .refine_for(&mut r, f64::INFINITY, passes, &Progress::new())
        .unwrap();
    assert_eq!(r.passes(), passes);
    refiner.add_to(&r, &mut img).unwrap();
    img
}

fn mean_red(rgba: &[f32]) -> f64 {
    rgba.chunks(4).map(|p| p[0] as f64).sum::<f64>() / (rgba.len() / 4) as f64
}

fn bp(kd: f32, ks: f32, ns: f32) -> BlinnPhong {
    BlinnPhong {
        kd: [kd; 3],
        ks: [ks; 3],
        ns,
    }
}

#[test]
fn an_edit_the_light_cannot_see_refines_to_exactly_zero() {
    // A diffuse shell's exponent is not part of its BRDF: a new spec, the same light.
    let scene = common::closed_sphere(0.7, true, 16);
    let s = settings(4, 6);
    let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
    let refiner = TailRefiner::new(&scene, &s, &stack.header).unwrap();
    let mut r = refiner.start(&specs(&[bp(0.7, 0.0, 50.0)]), None).unwrap();
    assert!(r.is_needed());
    refiner
        .refine_for(&mut r, f64::INFINITY, 4, &Progress::new())
        .unwrap();
    assert!(refiner.correction_rgba(&r).iter().all(|v| *v == 0.0));
    // The bake-time materials themselves leave nothing to trace.
    let r = refiner.start(&specs(&[bp(0.7, 0.0, 1.0)]), None).unwrap();
    assert!(!r.is_needed());
}

#[test]
fn refined_closed_sphere_follows_the_geometric_series() {
    let (a, e, n) = (0.7f32, 0.4f32, 8u32);
    let scene: Scene = common::closed_sphere(a, true, 24);
    let s = settings(8, n);
    let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
    let direct = mean_red(
        &render_reference(
            &scene,
            &settings(8, 0),
            &[bp(e, 0.0, 1.0)],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap()
        .rgba,
    );
    let truth = mean_red(
        &render_reference(
            &scene,
            &s,
            &[bp(e, 0.0, 1.0)],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap()
        .rgba,
    ) / direct;
    let refiner = TailRefiner::new(&scene, &s, &stack.header).unwrap();
    let relit = mean_red(&relight(&stack, &[bp(e, 0.0, 1.0)])) / direct;
    let exact: f64 = (0..=n).map(|k| (e as f64).powi(k as i32)).sum();
    for passes in [1u32, 2, 4, 8] {
        let img = refined(&refiner, &stack, &[bp(e, 0.0, 1.0)], passes);
        let ratio = mean_red(&img) / direct;
        eprintln!(
            "closed sphere baked at {a}, relit at {e}, {n} bounces: relit {relit:.4}, refined \
             ({passes} passes) {ratio:.4}, reference {truth:.4}, Σ a′ᵏ {exact:.4}"
        );
        if passes == 8 {
            assert!((ratio / truth - 1.0).abs() < 1e-4, "{ratio} vs {truth}");
            assert!((ratio / exact - 1.0).abs() < 0.01, "{ratio} vs {exact}");
        }
    }
    assert!(
        (relit / truth - 1.0).abs() > 1e-3,
        "the relight alone must miss the cap"
    );
}

/// The Cornell grid of docs/bounces.md: every edit, refined over the bake's own samples,
/// equals the projected reference along the same paths; printed after 1, 2 and 4 passes.
#[test]
fn refined_edits_match_the_projected_reference() {
    let scene = common::cornell(32);
    let edits: Vec<(&str, [BlinnPhong; 2])> = vec![
        ("glossy ns 180", [bp(0.3, 0.3, 180.0), bp(0.2, 0.4, 180.0)]),
        ("Kd 1 / Ks 1", [bp(1.0, 0.0, 1.0), bp(0.0, 1.0, 1.0)]),
        (
            "Ks 1 ns 200 / Kd 1",
            [bp(0.0, 1.0, 200.0), bp(1.0, 0.0, 200.0)],
        ),
        ("Kd 0.9 walls", [bp(0.9, 0.0, 1.0), bp(0.2, 0.4, 5.0)]),
        ("black walls", [bp(0.0, 0.0, 1.0), bp(0.5, 0.5, 60.0)]),
        (
            "coloured",
            [
                BlinnPhong {
                    kd: [0.7, 0.2, 0.1],
                    ks: [0.1, 0.3, 0.5],
                    ns: 12.0,
                },
                bp(0.4, 0.6, 100.0),
            ],
        ),
    ];
    let s = settings(8, 12);
    let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
    let refiner = TailRefiner::new(&scene, &s, &stack.header).unwrap();
    for (name, mats) in &edits {
        let projected =
            render_reference(&scene, &s, mats, ReferenceBrdf::Projected, &Progress::new())
                .unwrap()
                .rgba;
        let err = |img: &[f32]| compare_rgb(img, &projected, 4).unwrap().rel_l2 * 100.0;
        let relit = err(&relight(&stack, mats));
        let steps: Vec<f64> = [1u32, 2, 4, 8]
            .iter()
            .map(|&p| err(&refined(&refiner, &stack, mats, p)))
            .collect();
        eprintln!(
            "Cornell 32², 12 bounces, {name:<20}: relit {relit:6.2} %, refined after 1/2/4/8 \
             passes {:.2} / {:.2} / {:.2} / {:.4} %",
            steps[0], steps[1], steps[2], steps[3]
        );
        assert!(
            steps[3] < 0.1,
            "{name}: {} % after the bake's samples",
            steps[3]
        );
        assert!(steps[3] < relit, "{name}");
    }
}

#[test]
fn a_one_bounce_stack_has_nothing_to_refine() {
    let scene = common::cornell(16);
    let s = settings(2, 1);
    let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
    let refiner = TailRefiner::new(&scene, &s, &stack.header).unwrap();
    let r = refiner
        .start(&specs(&[bp(0.0, 1.0, 200.0), bp(1.0, 0.0, 1.0)]), None)
        .unwrap();
    assert!(!r.is_needed());
}

#[test]
fn another_scene_is_refused() {
    let scene = common::cornell(16);
    let s = settings(2, 3);
    let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
    let mut other = scene.clone();
    other.lights.clear();
    let err = TailRefiner::new(&other, &s, &stack.header).err().unwrap();
    assert!(err.to_string().contains("another scene"), "{err}");
}

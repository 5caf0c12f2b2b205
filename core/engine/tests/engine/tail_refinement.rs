//! The background refinement of an edit's tail (`relume_engine::refine`): what it adds is
//! exactly what the relight misses past the second vertex, along the bake's own paths.
//!
//! The reference renderer traces the bake's paths with the given materials at every vertex;
//! in its projected mode the first two vertices are the basis' reconstruction, as the
//! relight has them. After as many refinement passes as the bake had samples per pixel,
//! the refinement has traced the same paths, so relit + refinement must equal that
//! reference up to rounding for any edit — lobe shapes, mirrors, several regions at once —
//! while the relight alone is off by what docs/bounces.md measures.
use crate::common;

use std::sync::Arc;

use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::bake::{bake, BakeSettings, Denoise, IndirectSampling};
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

/// The relit image with `passes` refinement passes added: their mean correction (the
/// exact one along the bake's paths), and the correction shown (shrunk where it is within
/// its noise).
fn refined(
    refiner: &TailRefiner,
    stack: &TransferStack,
    mats: &[BlinnPhong],
    passes: u32,
) -> (Vec<f32>, Vec<f32>) {
    let mut r = refiner.start(&specs(mats), None).unwrap();
    let relit = relight(stack, mats);
    refiner
        .refine_for(&mut r, f64::INFINITY, passes, &Progress::new())
        .unwrap();
    assert_eq!(r.passes(), passes);
    let mut mean = relit.clone();
    for (p, d) in mean.chunks_exact_mut(4).zip(refiner.mean_correction(&r)) {
        p[0] += d.x;
        p[1] += d.y;
        p[2] += d.z;
    }
    let mut shown = relit;
    refiner.add_to(&r, &mut shown).unwrap();
    (mean, shown)
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
        let (img, shown) = refined(&refiner, &stack, &[bp(e, 0.0, 1.0)], passes);
        let ratio = mean_red(&img) / direct;
        let shown = mean_red(&shown) / direct;
        eprintln!(
            "closed sphere baked at {a}, relit at {e}, {n} bounces: relit {relit:.4}, refined \
             ({passes} passes) {ratio:.4}, shown {shown:.4}, reference {truth:.4}, Σ a′ᵏ \
             {exact:.4}"
        );
        if passes == 8 {
            assert!((ratio / truth - 1.0).abs() < 1e-4, "{ratio} vs {truth}");
            assert!((ratio / exact - 1.0).abs() < 0.01, "{ratio} vs {exact}");
            // The correction stands far out of its noise here: shown nearly in full.
            assert!((shown / truth - 1.0).abs() < 2e-3, "{shown} vs {truth}");
        }
    }
    assert!(
        (relit / truth - 1.0).abs() > 1e-3,
        "the relight alone must miss the cap"
    );
}

/// A closed sphere of albedo `a` baked under a 5 % bounce budget with a cap of `cap`, then
/// relit at albedo `e` and refined over the bake's 8 samples: (bounces baked, the header's
/// cap, and the mean red of the direct light, the relit image, the refined one and the
/// reference at `cap` bounces, all at `e`).
fn refined_under_a_budget(a: f32, e: f32, cap: u32) -> (u32, u32, [f64; 4]) {
    let scene: Scene = common::closed_sphere(a, true, 24);
    let s = BakeSettings {
        bounce_budget: 0.05,
        ..settings(8, cap)
    };
    let (stack, report) = bake(&scene, &s, &Progress::new()).unwrap();
    eprintln!("bounce pre-pass: {:?}", report.bounce_estimate);
    let reference = |s: &BakeSettings| {
        mean_red(
            &render_reference(
                &scene,
                s,
                &[bp(e, 0.0, 1.0)],
                ReferenceBrdf::True,
                &Progress::new(),
            )
            .unwrap()
            .rgba,
        )
    };
    let refiner = TailRefiner::new(&scene, &s, &stack.header).unwrap();
    let relit = mean_red(&relight(&stack, &[bp(e, 0.0, 1.0)]));
    let (img, _) = refined(&refiner, &stack, &[bp(e, 0.0, 1.0)], 8);
    let figures = [
        reference(&settings(8, 0)),
        relit,
        mean_red(&img),
        reference(&settings(8, cap)),
    ];
    (stack.header.bounces, stack.header.bounce_cap, figures)
}

/// A bounce budget judges the later bounces at the bake-time materials: a dark sphere
/// (a = 0.3) keeps two or three of its cap of eight. Made bright (0.8), the bounces left out
/// hold a large share of its light; the refinement traces the edit to the cap, so the
/// refined image is the reference at eight bounces along the same paths.
#[test]
fn bounces_a_budget_left_out_are_refined_with_the_edit() {
    let (a, e, cap) = (0.3f32, 0.8f32, 8u32);
    let (bounces, bounce_cap, [direct, relit, ratio, truth]) = refined_under_a_budget(a, e, cap);
    assert!(bounces < cap);
    assert_eq!(bounce_cap, cap);
    let (relit, ratio, truth) = (relit / direct, ratio / direct, truth / direct);
    eprintln!(
        "closed sphere baked at {a} ({bounces} of {cap} bounces), relit at {e}: relit \
         {relit:.4}, refined {ratio:.4}, reference at {cap} bounces {truth:.4}"
    );
    assert!((ratio / truth - 1.0).abs() < 1e-4, "{ratio} vs {truth}");
    assert!(
        relit / truth < 0.9,
        "the relight alone lacks the bounces left out"
    );
}

/// A sphere dark enough (a = 0.1) that the budget keeps one bounce: an explicit one-bounce
/// bake has nothing to refine, but this one's cap is eight, so an edit that brightens it
/// refines to the eight-bounce reference along the same paths, from the bounce vertex on.
#[test]
fn a_one_bounce_bake_under_a_budget_refines_to_its_cap() {
    let (a, e, cap) = (0.1f32, 0.8f32, 8u32);
    let (bounces, _, [_, relit, ratio, truth]) = refined_under_a_budget(a, e, cap);
    assert_eq!(bounces, 1);
    eprintln!(
        "closed sphere baked at {a} (1 of {cap} bounces), relit at {e}: relit {relit:.5}, \
         refined {ratio:.5}, reference at {cap} bounces {truth:.5}"
    );
    assert!((ratio / truth - 1.0).abs() < 1e-4, "{ratio} vs {truth}");
    assert!(
        relit / truth < 0.9,
        "the relight alone lacks the bounces left out"
    );
}

/// The Cornell grid of docs/bounces.md: every edit, refined over the bake's own samples,
/// equals the projected reference along the same paths; printed after 1, 2 and 4 passes.
#[test]
fn refined_edits_match_the_projected_reference() {
    let scene = common::cornell(32);
    // Every edit of the grid but the bake-time materials (nothing to refine there).
    let edits: Vec<_> = common::cornell_edits().into_iter().skip(1).collect();
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
        let (steps, shown): (Vec<f64>, Vec<f64>) = [1u32, 2, 4, 8]
            .iter()
            .map(|&p| {
                let (mean, shown) = refined(&refiner, &stack, mats, p);
                (err(&mean), err(&shown))
            })
            .unzip();
        eprintln!(
            "Cornell 32², 12 bounces, {name:<20}: relit {relit:6.2} %, refined after 1/2/4/8 \
             passes {:.2} / {:.2} / {:.2} / {:.4} %, shown {:.2} / {:.2} / {:.2} / {:.2} %",
            steps[0], steps[1], steps[2], steps[3], shown[0], shown[1], shown[2], shown[3]
        );
        assert!(
            steps[3] < 0.1,
            "{name}: {} % after the bake's samples",
            steps[3]
        );
        assert!(steps[3] < relit, "{name}");
        // After the bake's samples the shown correction is the exact one scaled by a weight
        // in [0, 1] per pixel: each pixel lies between the relit image and the reference
        // along these paths.
        assert!(
            shown[3] <= relit + 1e-6,
            "{name}: shown {} % vs relit {relit} %",
            shown[3]
        );
    }
}

#[test]
fn the_denoised_correction_does_not_depend_on_which_edit_refined_first() {
    // The correction's denoiser stops at each pixel's reach, traced once per refiner from
    // the first pass any edit traces: eye hits do not depend on the materials, so an
    // edit's correction is the same whether another edit was refined (and shown) first.
    let scene = common::cornell(24);
    let s = BakeSettings {
        denoise: Denoise {
            direct_iterations: 0,
            bounce_iterations: 2,
        },
        ..settings(4, 6)
    };
    let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
    let edits = common::cornell_edits();
    let (first, second) = (&edits[2].1, &edits[1].1);
    let correction_of_second = |refine_first: bool| {
        let refiner = TailRefiner::new(&scene, &s, &stack.header).unwrap();
        if refine_first {
            let mut r = refiner.start(&specs(first), None).unwrap();
            refiner
                .refine_for(&mut r, f64::INFINITY, 2, &Progress::new())
                .unwrap();
            assert!(refiner.correction(&r).iter().all(|d| d.is_finite()));
        }
        let mut r = refiner.start(&specs(second), None).unwrap();
        refiner
            .refine_for(&mut r, f64::INFINITY, 3, &Progress::new())
            .unwrap();
        refiner.correction(&r)
    };
    let alone = correction_of_second(false);
    assert!(alone.iter().any(|d| d.x != 0.0), "a correction to compare");
    assert_eq!(alone, correction_of_second(true));
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

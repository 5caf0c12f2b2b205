//! Bounces beyond the first (the "frozen tail", `bake::path::integrator`): physics and the
//! approximation's measured error under material edits.
//!
//! Inside a closed diffuse sphere the light of every bounce after the first is uniform
//! (the form factor between two patches of a sphere is the same for all pairs), so with a
//! point light at its centre each bounce brings exactly `albedo` times the previous one:
//! the image is `L₀ · Σ_{k=0..n} aᵏ`, a geometric series. The bake keys the eye vertex and
//! the first-bounce vertex and freezes later ones at their bake-time albedo `a`: relit with
//! another albedo `a′` it gives `L₀′ · (1 + a′ Σ_{k=1..n} a^{k−1})` exactly, while the truth is
//! `L₀′ Σ a′ᵏ` — the test checks both, so the approximation is pinned by physics, not by
//! a snapshot.
use crate::common;

use std::sync::Arc;

use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::bake::{bake, BakeSettings, IndirectSampling};
use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::image_io::compare_rgb;
use relume_engine::progress::Progress;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::*;
use relume_engine::stack::{bases::StackBases, Precision};

const SIZE: u32 = 24;

fn closed_sphere(a: f32, editable: bool) -> Scene {
    common::closed_sphere(a, editable, SIZE)
}

fn settings(bounces: u32) -> BakeSettings {
    BakeSettings {
        spp: 8,
        light_samples: 1,
        indirect_samples: 2,
        bounces,
        sampling: IndirectSampling::Mixture,
        precision: Precision::F32,
        ..Default::default()
    }
}

fn mean_red(rgba: &[f32]) -> f64 {
    rgba.chunks(4).map(|p| p[0] as f64).sum::<f64>() / (rgba.len() / 4) as f64
}

fn diffuse(a: f32) -> BlinnPhong {
    BlinnPhong {
        kd: [a; 3],
        ks: [0.0; 3],
        ns: 1.0,
    }
}

fn relight(stack: relume_engine::stack::TransferStack, mats: &[BlinnPhong]) -> Vec<f32> {
    let bases = StackBases::from_header(&stack.header).unwrap();
    let specs: Vec<MaterialSpec> = mats.iter().map(|m| MaterialSpec::BlinnPhong(*m)).collect();
    let coefs = bases.coefficients(&specs).unwrap();
    CpuRelighter::new(Arc::new(stack))
        .unwrap()
        .relight(&coefs)
        .unwrap()
        .to_vec()
}

#[test]
fn closed_sphere_bounces_follow_the_geometric_series() {
    let a = 0.7f32;
    let scene = closed_sphere(a, false);
    let direct = mean_red(
        &render_reference(
            &scene,
            &settings(0),
            &[],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap()
        .rgba,
    );
    assert!(direct > 0.0);
    for n in [1u32, 2, 3, 6, 12] {
        let img = render_reference(
            &scene,
            &settings(n),
            &[],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap();
        let ratio = mean_red(&img.rgba) / direct;
        let expected: f64 = (0..=n).map(|k| (a as f64).powi(k as i32)).sum();
        eprintln!("closed sphere a = {a}, {n:>2} bounces: L/L₀ {ratio:.4}, Σ aᵏ {expected:.4}");
        assert!(
            (ratio / expected - 1.0).abs() < 0.01,
            "{n} bounces: {ratio} vs {expected}"
        );
    }
}

#[test]
fn relit_tail_follows_an_albedo_edit() {
    let (a, edited) = (0.7f32, 0.4f32);
    let scene = closed_sphere(a, true);
    let n = 8u32;
    let direct = mean_red(
        &render_reference(
            &scene,
            &settings(0),
            &[diffuse(edited)],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap()
        .rgba,
    );
    let (stack, _) = bake(&scene, &settings(n), &Progress::new()).unwrap();
    assert_eq!(stack.header.bounces, n);
    let relit = mean_red(&relight(stack.clone(), &[diffuse(edited)])) / direct;
    let at_bake = mean_red(&relight(stack, &[diffuse(a)]));
    let truth = mean_red(
        &render_reference(
            &scene,
            &settings(n),
            &[diffuse(edited)],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap()
        .rgba,
    ) / direct;
    let (a, e) = (a as f64, edited as f64);
    let frozen: f64 = 1.0 + e * (1..=n).map(|k| a.powi(k as i32 - 1)).sum::<f64>();
    let exact: f64 = (0..=n).map(|k| e.powi(k as i32)).sum();
    // What the tail-edit layers give: exact while a path has at most MAX_TAIL_COUNT tail
    // vertices on the region; later ones keep the bake-time albedo.
    let m = relume_engine::bake::path::tail_edits::MAX_TAIL_COUNT as i32;
    let lumped: f64 = (0..=n as i32)
        .map(|k| {
            let t = (k - 1).max(0);
            if t <= m {
                e.powi(k)
            } else {
                e.powi(m + 1) * a.powi(t - m)
            }
        })
        .sum();
    eprintln!(
        "albedo {a} baked, relit at {e}, {n} bounces: relit/L₀′ {relit:.4} (the tail-edit \
         layers predict {lumped:.4}; a frozen tail would give {frozen:.4}), reference \
         {truth:.4} (Σ a′ᵏ {exact:.4}): {:+.2} % off the truth",
        (relit / truth - 1.0) * 100.0
    );
    assert!((relit / lumped - 1.0).abs() < 0.01, "{relit} vs {lumped}");
    assert!((relit / truth - 1.0).abs() < 0.015, "{relit} vs {truth}");
    assert!(
        (frozen / truth - 1.0) > 0.3,
        "the edit must be one the frozen tail misses"
    );
    assert!((truth / exact - 1.0).abs() < 0.01, "{truth} vs {exact}");
    // At the bake-time albedo the relit image is the full path-traced one.
    let expected_at_bake: f64 = (0..=n).map(|k| a.powi(k as i32)).sum::<f64>() / (1.0 - 0.0);
    let direct_at_bake = direct * a / e;
    assert!(
        (at_bake / direct_at_bake / expected_at_bake - 1.0).abs() < 0.01,
        "{} vs {expected_at_bake}",
        at_bake / direct_at_bake
    );
}

/// The approximation measured: the test Cornell box (two editable regions, coloured fixed
/// walls), baked with 12 bounces at its bake-time materials and relit with materials across
/// the editable range, against the reference render with the edited materials at every
/// vertex, along the same paths. "vs projected" isolates the frozen tail (the reference
/// reconstructs the keyed vertices through the same basis and evaluates later vertices
/// exactly); "vs true" adds the basis error; the one-bounce bake shows the basis error alone.
#[test]
fn frozen_tail_error_under_edits_is_measured() {
    let scene = common::cornell(32);
    let edits = common::cornell_edits();
    let mut worst_tail = 0.0f64;
    for bounces in [1u32, 12] {
        let s = BakeSettings {
            spp: 8,
            light_samples: 2,
            indirect_samples: 2,
            bounces,
            sampling: IndirectSampling::Mixture,
            precision: Precision::F32,
            ..Default::default()
        };
        let (stack, _) = bake(&scene, &s, &Progress::new()).unwrap();
        for (name, mats) in &edits {
            let relit = relight(stack.clone(), mats);
            let reference = |brdf| {
                render_reference(&scene, &s, mats, brdf, &Progress::new())
                    .unwrap()
                    .rgba
            };
            let projected = reference(ReferenceBrdf::Projected);
            let truth = reference(ReferenceBrdf::True);
            let dp = compare_rgb(&relit, &projected, 4).unwrap();
            let dt = compare_rgb(&relit, &truth, 4).unwrap();
            let ratio = mean_red(&relit) / mean_red(&truth);
            eprintln!(
                "Cornell 32², {bounces:>2} bounce(s), {name:<20}: relit vs projected {:6.2} %, \
                 vs true {:6.2} %, mean relit/true {ratio:.4}",
                dp.rel_l2 * 100.0,
                dt.rel_l2 * 100.0
            );
            assert!(relit.iter().all(|v| v.is_finite()));
            if bounces == 1 {
                // One bounce is exact under edits (up to the basis): linearity.
                assert!(dp.rel_l2 < 1e-3, "{name}: {}", dp.rel_l2);
            } else {
                worst_tail = worst_tail.max(dp.rel_l2);
            }
            if *name == "bake-time" {
                assert!(dp.rel_l2 < 1e-3, "{name}, {bounces}: {}", dp.rel_l2);
            }
        }
    }
    eprintln!(
        "worst frozen-tail error over the edits: {:.2} %",
        worst_tail * 100.0
    );
    assert!(worst_tail.is_finite());
}

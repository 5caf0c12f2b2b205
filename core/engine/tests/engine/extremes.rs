//! The extremes suite: slider ends, grazing views, tiny and huge scenes, blinding lights,
//! lights inside geometry, slivers and coincident surfaces. Every case bakes, relights and
//! renders the reference along the same paths, and checks the relit image is finite,
//! non-negative (to the basis' rounding) and close to the reference.
use crate::common;

use std::sync::Arc;

use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::bake::{bake, BakeSettings};
use relume_engine::brdf::{
    principled_to_blinn_phong, BasisConfig, BasisCount, BlinnPhong, MaterialSpec, Principled,
};
use relume_engine::image_io::compare_rgb;
use relume_engine::progress::Progress;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{Light, Scene};
use relume_engine::stack::bases::StackBases;
use relume_engine::stack::Precision;

struct Outcome {
    relit: Vec<f32>,
    vs_projected: f64,
    vs_true: f64,
}

/// Bakes `scene`, relights it with `materials` (editable order) and compares with both
/// references. Asserts every stored layer value and every relit pixel is finite.
fn run(scene: &Scene, settings: &BakeSettings, materials: &[BlinnPhong]) -> Outcome {
    let (stack, _) = bake(scene, settings, &Progress::new()).unwrap();
    for layer in &stack.layers {
        assert!(
            layer.scale.is_finite() && layer.scale > 0.0,
            "{}",
            layer.key.layer_name()
        );
        for i in 0..layer.samples.len() {
            assert!(
                layer.value(i).is_finite(),
                "layer {} value {i}",
                layer.key.layer_name()
            );
        }
    }
    let bases = StackBases::from_header(&stack.header).unwrap();
    let specs: Vec<MaterialSpec> = materials
        .iter()
        .map(|m| MaterialSpec::BlinnPhong(*m))
        .collect();
    let coefs = bases.coefficients(&specs).unwrap();
    let mut r = CpuRelighter::new(Arc::new(stack)).unwrap();
    let relit = r.relight(&coefs).unwrap().to_vec();
    assert!(
        relit.iter().all(|v| v.is_finite()),
        "relit image has NaN/Inf"
    );
    let projected = render_reference(
        scene,
        settings,
        materials,
        ReferenceBrdf::Projected,
        &Progress::new(),
    )
    .unwrap();
    let truth = render_reference(
        scene,
        settings,
        materials,
        ReferenceBrdf::True,
        &Progress::new(),
    )
    .unwrap();
    assert!(
        truth.rgba.iter().all(|v| v.is_finite() && *v >= 0.0),
        "the true reference must be finite and ≥ 0"
    );
    let vs_projected = compare_rgb(&relit, &projected.rgba, 4).unwrap().rel_l2;
    let vs_true = compare_rgb(&relit, &truth.rgba, 4).unwrap().rel_l2;
    Outcome {
        relit,
        vs_projected,
        vs_true,
    }
}

/// The most negative relit value relative to the image's largest value (PCA bases can dip
/// below zero; the reconstruction of a non-negative lobe stays within its error).
fn worst_negative(img: &[f32]) -> f32 {
    let max = img.iter().fold(0.0f32, |m, v| m.max(*v));
    let min = img
        .chunks_exact(4)
        .flat_map(|p| p[..3].iter().copied())
        .fold(0.0f32, f32::min);
    -min / max.max(1e-30)
}

/// The paper's exponent range [1, 200] (`BasisConfig::default()`), pinned: these cases
/// bound the basis error of 6 bases, which the bake's default range (roughness 0.1–1, ns up
/// to ≈ 20 000) would need 9–12 bases for.
fn settings() -> BakeSettings {
    BakeSettings {
        spp: 2,
        light_samples: 2,
        basis: relume_engine::brdf::BasisConfig::default(),
        ..Default::default()
    }
}

fn bp(kd: f32, ks: f32, ns: f32) -> BlinnPhong {
    BlinnPhong {
        kd: [kd; 3],
        ks: [ks; 3],
        ns,
    }
}

/// Linearity within f16 rounding, the basis error within `true_bound`, and negative relit
/// values (ringing of the truncated PCA on glossy lobes) within 3 % of the image's peak, the
/// N_b = 6 basis' worst lobe error.
fn check(name: &str, o: &Outcome, true_bound: f64) {
    eprintln!(
        "{name}: relit vs projected {:.2e}, vs true {:.2e}, negative {:.1e}",
        o.vs_projected,
        o.vs_true,
        worst_negative(&o.relit)
    );
    assert!(
        o.vs_projected <= 5e-4,
        "{name}: linearity {}",
        o.vs_projected
    );
    assert!(
        o.vs_true <= true_bound,
        "{name}: basis error {} > {true_bound}",
        o.vs_true
    );
    assert!(
        worst_negative(&o.relit) <= 0.03,
        "{name}: negative relit pixels {}",
        worst_negative(&o.relit)
    );
}

#[test]
fn slider_ends() {
    let scene = common::cornell(24);
    // ns at both ends of the default range, Kd + Ks = 1, black.
    for (name, m) in [
        ("ns = 1", [bp(0.0, 1.0, 1.0), bp(0.0, 1.0, 1.0)]),
        ("ns = 200", [bp(0.0, 1.0, 200.0), bp(0.0, 1.0, 200.0)]),
        ("Kd + Ks = 1", [bp(0.5, 0.5, 50.0), bp(0.9, 0.1, 10.0)]),
        ("black", [bp(0.0, 0.0, 1.0), bp(0.0, 0.0, 1.0)]),
    ] {
        check(name, &run(&scene, &settings(), &m), 0.03);
    }
}

#[test]
fn principled_ends() {
    // Roughness 0 (ns far above the range: clamped to it) and 1, metallic 1 with a black base.
    let scene = common::cornell(24);
    let p = |base: [f32; 3], metallic: f32, roughness: f32| {
        principled_to_blinn_phong(&Principled {
            base_color: base,
            metallic,
            roughness,
            ior: 1.5,
            specular_ior_level: 0.5,
        })
    };
    for (name, m) in [
        (
            "roughness 0",
            [p([0.8; 3], 0.0, 0.0), p([0.8; 3], 1.0, 0.0)],
        ),
        (
            "roughness 1",
            [p([0.8; 3], 0.0, 1.0), p([0.8; 3], 1.0, 1.0)],
        ),
        (
            // A black metal still reflects Schlick's grazing Fresnel in the fitted mapping,
            // so both roughness values stay inside the basis range (ns ≤ 200).
            "metallic black",
            [p([0.0; 3], 1.0, 0.5), p([0.0; 3], 1.0, 0.4)],
        ),
    ] {
        for b in &m {
            assert!(
                b.kd.iter()
                    .chain(b.ks.iter())
                    .all(|v| v.is_finite() && *v >= 0.0)
                    && b.ns.is_finite()
                    && b.ns > 0.0,
                "{name}: {b:?}"
            );
        }
        // Roughness 0 maps past the basis range, where the basis clamps ns: the true-BRDF
        // reference is then a mirror the basis cannot hold, so only linearity is bounded.
        let bound = match name {
            "roughness 0" => f64::INFINITY,
            // Roughness 1 maps to ns = 1e-3, below the paper's range [1, 200], where the
            // basis clamps it to 1: the difference to the true lobe is that clamp (4 %).
            "roughness 1" => 0.05,
            _ => 0.03,
        };
        check(name, &run(&scene, &settings(), &m), bound);
    }
}

#[test]
fn grazing_camera() {
    // The eye a hair above the floor, looking along it.
    let mut scene = common::cornell(24);
    scene.camera = common::look_at([0.0, -0.999, -0.995], [0.0, 1.0, -0.99], 20.0);
    check(
        "grazing camera",
        &run(
            &scene,
            &settings(),
            &[bp(0.2, 0.8, 150.0), bp(0.5, 0.5, 20.0)],
        ),
        0.03,
    );
}

/// The Cornell box scaled by `s` in length with light power scaled by s² (same radiance).
fn scaled(s: f32) -> Scene {
    common::cornell_scaled(24, s)
}

#[test]
fn tiny_and_huge_scenes_give_the_same_image() {
    let m = [bp(0.3, 0.3, 20.0), bp(0.2, 0.6, 100.0)];
    let unit = run(&scaled(1.0), &settings(), &m);
    // The noise level: the same scene with another seed.
    let other_seed = run(
        &scaled(1.0),
        &BakeSettings {
            seed: 1,
            ..settings()
        },
        &m,
    );
    let noise = compare_rgb(&other_seed.relit, &unit.relit, 4)
        .unwrap()
        .rel_l2;
    for s in [1e-3f32, 1e4] {
        let o = run(&scaled(s), &settings(), &m);
        check(&format!("scale {s}"), &o, 0.03);
        // Radiance is scale invariant and the same seeds trace the same paths: the images
        // differ only where rounding sends a path the other way at an edge, far below the
        // difference two seeds make.
        let d = compare_rgb(&o.relit, &unit.relit, 4).unwrap().rel_l2;
        eprintln!("scale {s}: against scale 1 {d:.2e} (another seed: {noise:.2e})");
        assert!(
            d <= 0.25 * noise,
            "scale {s}: {d} against a noise level of {noise}"
        );
    }
}

#[test]
fn blinding_lights_do_not_overflow_half_floats() {
    let m = [bp(0.3, 0.3, 20.0), bp(0.2, 0.6, 100.0)];
    let normal = run(&common::cornell(24), &settings(), &m);
    for factor in [1e6f32, 1e-6] {
        let mut scene = common::cornell(24);
        if let Light::Area { power, .. } = &mut scene.lights[0] {
            *power *= factor;
        }
        let settings = BakeSettings {
            precision: Precision::F16,
            ..settings()
        };
        let o = run(&scene, &settings, &m);
        check(&format!("light × {factor}"), &o, 0.03);
        let expect: Vec<f32> = normal
            .relit
            .iter()
            .enumerate()
            .map(|(i, v)| if i % 4 == 3 { *v } else { v * factor })
            .collect();
        let d = compare_rgb(&o.relit, &expect, 4).unwrap().rel_l2;
        assert!(d <= 1e-3, "light × {factor}: {d}");
    }
}

#[test]
fn light_inside_geometry() {
    // A point light inside the closed sphere: no light escapes it.
    let mut scene = common::cornell(24);
    scene.lights = vec![Light::Point {
        position: [0.0, 0.2, -0.55],
        power: 100.0,
        color: [1.0; 3],
        radius: 0.01,
    }];
    let o = run(
        &scene,
        &settings(),
        &[bp(0.5, 0.5, 10.0), bp(0.5, 0.5, 10.0)],
    );
    assert!(
        o.relit.chunks_exact(4).all(|p| p[..3] == [0.0; 3]),
        "light leaked out of the closed sphere"
    );
}

#[test]
fn slivers_and_coincident_surfaces() {
    let mut scene = common::cornell(24);
    // A fan of sliver triangles (aspect 1e5) on the back wall, and a quad coincident with the floor.
    let mut sliver = common::quad(
        "sliver",
        [-0.5, 0.999, 0.0],
        [0.5, 0.999, 0.0],
        [0.5, 0.999, 1e-5],
        [-0.5, 0.999, 1e-5],
        0,
    );
    sliver.uvs = None;
    scene.meshes.push(sliver);
    scene.meshes.push(common::quad(
        "floor twin",
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
        1,
    ));
    let report = relume_engine::scene::validate::validate_scene(&scene).unwrap();
    assert_eq!(report.degenerate_triangles, 0, "slivers are kept");
    check(
        "slivers and coincident surfaces",
        &run(
            &scene,
            &settings(),
            &[bp(0.4, 0.4, 30.0), bp(0.6, 0.2, 5.0)],
        ),
        0.03,
    );
}

#[test]
fn wide_range_top_exponent() {
    // The top of a [1, 10 000] range (roughness ≈ 0.1) with bases chosen by tolerance. The
    // relight stays finite and linear; against the true BRDF the error of a mirror-like
    // highlight is not bounded by the lobe tolerance (measured 0.5–15 % here, not monotonic
    // in the tolerance: the grid L2 gives a 0.8° peak little weight), so it is printed, and
    // only bounded loosely.
    let scene = common::cornell(24);
    for tol in [0.03f32, 0.003] {
        let basis = BasisConfig {
            ns_min: 1.0,
            ns_max: 10_000.0,
            count: BasisCount::Tolerance(tol),
            ..BasisConfig::default()
        };
        let settings = BakeSettings {
            basis,
            ..settings()
        };
        let o = run(
            &scene,
            &settings,
            &[bp(0.0, 1.0, 10_000.0), bp(0.1, 0.9, 5_000.0)],
        );
        eprintln!(
            "ns = 10 000, tolerance {tol}: vs true {:.3e}, negative {:.2e}, vs projected {:.2e}",
            o.vs_true,
            worst_negative(&o.relit),
            o.vs_projected
        );
        // f16 layers round to 2⁻¹¹ ≈ 4.9e-4 relative each; at ns = 10 000 the PCA layers
        // ring with opposite signs and cancel in the sum, so the image's rounding error is a
        // small multiple of that (figures in docs/measurements.md, "Extremes").
        assert!(o.vs_projected <= 1.5e-3, "linearity {}", o.vs_projected);
        assert!(
            // The README's known limit: a mirror-like highlight against the true BRDF is not
            // bounded by the lobe tolerance (25.3 % measured, 2026-11-23); this guards
            // against it growing, not a quality target.
            o.vs_true <= 0.3 && worst_negative(&o.relit) <= 0.3,
            "tolerance {tol}: {} / {}",
            o.vs_true,
            worst_negative(&o.relit)
        );
    }
}

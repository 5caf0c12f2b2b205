//! Physical properties of the bake and the reference render: white furnace, no energy
//! created, determinism whatever the thread count, cancellation.
use crate::common;

use std::sync::Arc;

use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::bake::{bake, BakeSettings, IndirectSampling};
use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::progress::Progress;
use relume_engine::RelumeError;

/// The red channel of the pixels well inside the furnace's sphere.
fn sphere_pixels(img: &[f32], size: u32) -> Vec<f32> {
    common::inside_furnace_sphere(size)
        .into_iter()
        .map(|i| img[i * 4])
        .collect()
}

#[test]
fn white_furnace_diffuse_is_exact() {
    // A white Lambertian sphere in a white world reflects exactly the world's radiance; with
    // cosine-sampled world light the estimator has zero variance.
    let size = 32;
    let scene = common::furnace(common::bp(1.0, 0.0, 1.0), false, size);
    let img = render_reference(
        &scene,
        &BakeSettings {
            spp: 2,
            light_samples: 2,
            ..Default::default()
        },
        &[],
        ReferenceBrdf::True,
        &Progress::new(),
    )
    .unwrap();
    let px = sphere_pixels(&img.rgba, size);
    assert!(px.len() > 100);
    for v in px {
        assert!((v - 1.0).abs() < 1e-4, "{v}");
    }
}

#[test]
fn white_furnace_through_bake_and_relight() {
    // The same furnace with the sphere editable: bake once, relight as white Lambertian.
    // The relit image must be 1 on the sphere up to f16 storage rounding (2⁻¹¹).
    use relume_engine::relight::CpuRelighter;
    use relume_engine::stack::bases::StackBases;
    let size = 32;
    let scene = common::furnace(common::bp(0.3, 0.5, 40.0), true, size);
    let settings = BakeSettings {
        spp: 2,
        light_samples: 2,
        ..Default::default()
    };
    let (stack, _) = bake(&scene, &settings, &Progress::new()).unwrap();
    let bases = StackBases::from_header(&stack.header).unwrap();
    let white = MaterialSpec::BlinnPhong(BlinnPhong {
        kd: [1.0; 3],
        ks: [0.0; 3],
        ns: 1.0,
    });
    let coefs = bases.coefficients(&[white]).unwrap();
    let mut relighter = CpuRelighter::new(Arc::new(stack)).unwrap();
    let img = relighter.relight(&coefs).unwrap();
    let px = sphere_pixels(img, size);
    assert!(px.len() > 100);
    for v in px {
        assert!((v - 1.0).abs() < 1e-3, "{v}");
    }
}

#[test]
fn white_furnace_of_fixed_principled_materials_as_cycles() {
    // A fixed Principled material is evaluated as Cycles evaluates it (GGX with multiple
    // scattering, the diffuse base weighted by what the specular layer leaves): a white
    // metal and a white dielectric both reflect all the light in a white world, at every
    // roughness, in the reference render and through the bake and relight alike. The
    // Blinn–Phong mapping they had before reflects less (Kd + Ks ≤ 1 with a lobe that loses
    // energy at grazing views) — printed for the record.
    use relume_engine::brdf::{Principled, PrincipledMaterial};
    use relume_engine::relight::CpuRelighter;
    let size = 32;
    let settings = BakeSettings {
        spp: 16,
        light_samples: 8,
        ..Default::default()
    };
    for (metallic, roughness) in [(1.0, 0.2), (1.0, 0.5), (1.0, 1.0), (0.0, 0.3), (0.0, 0.8)] {
        let bsdf = Principled {
            base_color: [1.0; 3],
            metallic,
            roughness,
            ior: 1.5,
            specular_ior_level: 0.5,
        };
        let material = MaterialSpec::Principled(PrincipledMaterial::from(bsdf));
        let scene = common::furnace(material.clone(), false, size);
        let mean = |px: Vec<f32>| px.iter().map(|v| *v as f64).sum::<f64>() / px.len() as f64;
        let reference = render_reference(
            &scene,
            &settings,
            &[],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap();
        let (stack, _) = bake(&scene, &settings, &Progress::new()).unwrap();
        let mut relighter = CpuRelighter::new(Arc::new(stack)).unwrap();
        let relit = relighter.relight(&[]).unwrap();
        let mapped = common::furnace(
            MaterialSpec::BlinnPhong(material.to_blinn_phong()),
            false,
            size,
        );
        let before = render_reference(
            &mapped,
            &settings,
            &[],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap();
        let (r, b, m) = (
            mean(sphere_pixels(&reference.rgba, size)),
            mean(sphere_pixels(relit, size)),
            mean(sphere_pixels(&before.rgba, size)),
        );
        eprintln!(
            "white furnace, metallic {metallic}, roughness {roughness}: reference {r:.4}, \
             bake + relight {b:.4}, Blinn–Phong mapping {m:.4}"
        );
        for v in [r, b] {
            assert!(
                (v - 1.0).abs() < 0.01,
                "metallic {metallic}, roughness {roughness}: {v}"
            );
        }
    }
}

#[test]
fn no_energy_is_created_when_kd_plus_ks_is_one() {
    let size = 32;
    for (kd, ks, ns) in [
        (0.0, 1.0, 1.0),
        (0.0, 1.0, 20.0),
        (0.0, 1.0, 200.0),
        (0.5, 0.5, 50.0),
        (0.0, 1.0, 5000.0),
    ] {
        let scene = common::furnace(common::bp(kd, ks, ns), false, size);
        let settings = BakeSettings {
            spp: 16,
            light_samples: 8,
            ..Default::default()
        };
        let img = render_reference(
            &scene,
            &settings,
            &[],
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap();
        let px = sphere_pixels(&img.rgba, size);
        let n = px.len() as f64;
        let mean = px.iter().map(|v| *v as f64).sum::<f64>() / n;
        let var = px.iter().map(|v| (*v as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let se = (var / n).sqrt();
        assert!(px.iter().all(|v| v.is_finite() && *v >= 0.0));
        assert!(
            mean <= 1.0 + 4.0 * se + 1e-3,
            "Kd {kd} Ks {ks} ns {ns}: mean {mean} ± {se}"
        );
    }
}

#[test]
fn bake_is_identical_for_any_thread_count() {
    let scene = common::cornell(24);
    for sampling in [IndirectSampling::Uniform, IndirectSampling::Mixture] {
        let one = BakeSettings {
            spp: 2,
            threads: 1,
            sampling,
            ..Default::default()
        };
        let two = BakeSettings {
            threads: 2,
            ..one.clone()
        };
        let three = BakeSettings {
            threads: 3,
            ..one.clone()
        };
        let (a, _) = bake(&scene, &one, &Progress::new()).unwrap();
        let (b, _) = bake(&scene, &two, &Progress::new()).unwrap();
        let (c, _) = bake(&scene, &three, &Progress::new()).unwrap();
        assert!(!a.layers.is_empty());
        assert!(
            a == b && b == c,
            "stacks differ across thread counts ({sampling:?})"
        );
    }
}

#[test]
fn reference_is_identical_for_any_thread_count() {
    let scene = common::cornell(24);
    let m = vec![
        BlinnPhong {
            kd: [0.5; 3],
            ks: [0.2; 3],
            ns: 30.0
        };
        2
    ];
    let one = BakeSettings {
        spp: 2,
        threads: 1,
        ..Default::default()
    };
    let a = render_reference(&scene, &one, &m, ReferenceBrdf::True, &Progress::new()).unwrap();
    let b = render_reference(
        &scene,
        &BakeSettings { threads: 2, ..one },
        &m,
        ReferenceBrdf::True,
        &Progress::new(),
    )
    .unwrap();
    assert_eq!(a.rgba, b.rgba);
}

#[test]
fn cancel_stops_a_bake_within_a_second() {
    let scene = common::cornell(256);
    let progress = Arc::new(Progress::new());
    let p = progress.clone();
    let settings = BakeSettings {
        spp: 64,
        ..Default::default()
    };
    let worker = std::thread::spawn(move || bake(&scene, &settings, &p));
    while progress.fraction() <= 0.0 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let t = std::time::Instant::now();
    progress.cancel();
    let result = worker.join().unwrap();
    let waited = t.elapsed().as_secs_f64();
    assert!(matches!(result, Err(RelumeError::Cancelled)));
    assert!(waited < 1.0, "cancel took {waited} s");
    assert!(progress.fraction() < 1.0);
}

#[test]
fn progress_reports_fraction_and_eta() {
    let scene = common::cornell(32);
    let progress = Progress::new();
    bake(
        &scene,
        &BakeSettings {
            spp: 1,
            ..Default::default()
        },
        &progress,
    )
    .unwrap();
    assert_eq!(progress.fraction(), 1.0);
    assert_eq!(progress.eta_seconds(), Some(0.0));
}

#[test]
fn editable_material_changes_do_not_change_the_hash_but_geometry_does() {
    use relume_engine::scene::hash::scene_hash;
    let a = common::cornell(16);
    let mut b = a.clone();
    b.regions[1].material = MaterialSpec::BlinnPhong(BlinnPhong {
        kd: [0.9; 3],
        ks: [0.0; 3],
        ns: 3.0,
    });
    assert_eq!(scene_hash(&a), scene_hash(&b));
    let mut c = a.clone();
    c.meshes[0].positions[0][0] += 1e-3;
    assert_ne!(scene_hash(&a), scene_hash(&c));
    let mut d = a.clone();
    d.regions[2].material = MaterialSpec::BlinnPhong(BlinnPhong {
        kd: [0.1; 3],
        ks: [0.0; 3],
        ns: 1.0,
    });
    assert_ne!(
        scene_hash(&a),
        scene_hash(&d),
        "a fixed region's material is baked in"
    );
}

#[test]
fn a_shared_light_colour_is_factored_out_of_the_layers() {
    use relume_engine::scene::Light;
    let mut scene = common::cornell(16);
    if let Light::Area { color, .. } = &mut scene.lights[0] {
        *color = [1.0, 0.8, 0.5];
    }
    let settings = BakeSettings {
        spp: 1,
        ..Default::default()
    };
    let (stack, report) = bake(&scene, &settings, &Progress::new()).unwrap();
    assert_eq!(stack.header.light_tint, [1.0, 0.8, 0.5]);
    // Paths that meet only editable regions stay grey even under a warm light.
    assert!(
        report.layers_grey > 0 && report.layers_rgb > 0,
        "{report:?}"
    );
    let key = stack
        .layers
        .iter()
        .find(|l| l.key.layer_name() == "E0b0")
        .unwrap();
    assert_eq!(key.channels, 1);
    // Two lights of different colours share no tint: everything is RGB.
    scene.lights.push(Light::Point {
        position: [0.0, 0.0, 0.5],
        power: 5.0,
        color: [0.2, 0.4, 1.0],
        radius: 0.0,
    });
    let (stack, report) = bake(&scene, &settings, &Progress::new()).unwrap();
    assert_eq!(stack.header.light_tint, [1.0; 3]);
    assert_eq!(report.layers_grey, 0);
}

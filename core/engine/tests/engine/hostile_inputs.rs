//! Untrusted sizes and values, refused by name before they are used: texture sizes that
//! overflow, bases no build could afford, light-group gains that overflow the relight,
//! scene materials under the materials file's rule, duplicate light groups; and tiny
//! square lights as bright as tiny disks.
use crate::common;

use std::f64::consts::PI;

use glam::Vec3;
use relume_engine::bake::{bake, BakeSettings, LightGrouping};
use relume_engine::brdf::{BasisConfig, BasisCount, BrdfBasis, MaterialSpec, Principled};
use relume_engine::geometry::lights::{AreaSampling, LightSet};
use relume_engine::materials::{parse_materials, resolve_light_gains};
use relume_engine::progress::Progress;
use relume_engine::scene::validate::validate_scene;
use relume_engine::scene::{AreaShape, ImageRef, Light, LightGroupSpec, Scene, World};
use relume_engine::stack::exr_file::{read_stack_header, write_stack};
use relume_engine::stack::hostile::with_header_edit;
use relume_engine::stack::tiled::file::read_tiled;
use relume_engine::stack::LightGroupInfo;
use relume_engine::RelumeError;

/// Sides whose product × 3 wraps to 13 in 64 bits: 3 384 208 571 × 3 633 886 365 × 3 ≡ 13.
const WRAPPING: (u32, u32) = (3_384_208_571, 3_633_886_365);

fn invalid(scene: &Scene) -> String {
    match validate_scene(scene) {
        Err(e @ RelumeError::InvalidValue { .. })
        | Err(e @ RelumeError::IndexOutOfRange { .. }) => e.to_string(),
        other => panic!("expected a named refusal, got {other:?}"),
    }
}

#[test]
fn image_sizes_that_overflow_are_refused_with_the_numbers() {
    let (w, h) = WRAPPING;
    let image = ImageRef::Inline {
        width: w,
        height: h,
        rgb: vec![0.5; 13],
    };
    let mut s = common::cornell(16);
    s.regions[0].albedo_texture = Some(image.clone());
    let e = invalid(&s);
    assert!(
        e.contains("albedo texture")
            && e.contains("3384208571×3633886365×3")
            && e.contains("more than 2⁶⁴")
            && e.contains("has 13"),
        "{e}"
    );
    let mut s = common::cornell(16);
    s.world = World::Equirect {
        image,
        strength: 1.0,
    };
    let e = invalid(&s);
    assert!(
        e.contains("world environment image") && e.contains("has 13"),
        "{e}"
    );
    // A product that fits but is not what was given names both numbers.
    s.world = World::Equirect {
        image: ImageRef::Inline {
            width: 4,
            height: 2,
            rgb: vec![0.5; 13],
        },
        strength: 1.0,
    };
    let e = invalid(&s);
    assert!(e.contains("4×2×3 needs 24") && e.contains("has 13"), "{e}");
}

fn small_stack_bytes() -> Vec<u8> {
    let (stack, _) = bake(
        &common::cornell(16),
        &BakeSettings {
            spp: 1,
            light_samples: 1,
            ..BakeSettings::default()
        },
        &Progress::new(),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.relume.exr");
    write_stack(&path, &stack).unwrap();
    std::fs::read(&path).unwrap()
}

#[test]
fn basis_limits_refuse_hostile_headers_and_configurations_before_building() {
    let bytes = small_stack_bytes();
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, serde_json::Value, &str); 3] = [
        (
            "lobes",
            4_000_000_000u64.into(),
            "4000000000 specular lobes exceed the limit of 2048",
        ),
        (
            "grid",
            serde_json::json!([4000, 4000, 4000]),
            "64000000000 cells, above the limit of 67108864",
        ),
        (
            "grid",
            serde_json::json!([3000, 3000, 6000]),
            "grid side 6000",
        ),
    ];
    for (i, (field, value, words)) in cases.into_iter().enumerate() {
        let hostile = with_header_edit(&bytes, |h| {
            for r in h["regions"].as_array_mut().unwrap() {
                if r["basis"].is_object() {
                    r["basis"][field] = value.clone();
                }
            }
        })
        .unwrap();
        let path = dir.path().join(format!("hostile-{i}.exr"));
        std::fs::write(&path, hostile).unwrap();
        let t = std::time::Instant::now();
        let e = read_stack_header(&path).unwrap_err().to_string();
        assert!(e.contains(words), "{e}");
        let Err(e) = read_tiled(&path) else {
            panic!("{field} {value}: read")
        };
        let e = e.to_string();
        assert!(e.contains(words), "{e}");
        assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
    }
    // The same rule for a configuration built directly (the command line's `relume basis`).
    for (cfg, words) in [
        (
            BasisConfig {
                grid: [100_000; 3],
                ..BasisConfig::default()
            },
            "grid side 100000",
        ),
        (
            BasisConfig {
                lobes: 4_000_000_000,
                ..BasisConfig::default()
            },
            "exceed the limit of 2048",
        ),
    ] {
        let e = BrdfBasis::build(&cfg).err().unwrap().to_string();
        assert!(e.contains(words), "{e}");
    }
    // A grid too coarse to see the narrowest lobe: refused, not reported as "inf %".
    let e = BrdfBasis::build(&BasisConfig {
        ns_max: 35_000.0,
        grid: [2, 2, 2],
        count: BasisCount::Fixed(2),
        ..BasisConfig::default()
    })
    .err()
    .expect("refused")
    .to_string();
    assert!(
        e.contains("zero at every cell of the 2×2×2 grid") && e.contains("inf %"),
        "{e}"
    );
}

#[test]
fn light_group_gains_that_overflow_the_relight_are_refused() {
    let mut header = common::stack_header::stack_header(4, 4, vec![]);
    header.light_groups = vec![LightGroupInfo {
        name: "key".into(),
        tint: [1.0; 3],
    }];
    let edits = |s: &str| {
        parse_materials(&format!(
            r#"{{"format":"relume-materials","version":1,"light_groups":{{"key":{s}}}}}"#
        ))
        .unwrap()
    };
    let e = resolve_light_gains(&header, &edits(r#"{"strength":3e38}"#))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("light group \"key\"") && e.contains("exceeds the limit of 1e6"),
        "{e}"
    );
    let e = resolve_light_gains(&header, &edits(r#"{"strength":2e3,"color":[1,1000,1]}"#))
        .unwrap_err()
        .to_string();
    assert!(e.contains("2e6") && e.contains("1e6"), "{e}");
    assert!(resolve_light_gains(&header, &edits(r#"{"strength":1e6}"#)).is_ok());
}

fn grey() -> Principled {
    Principled {
        base_color: [0.5; 3],
        metallic: 0.0,
        roughness: 0.5,
        ior: 1.5,
        specular_ior_level: 0.5,
    }
}

#[test]
fn scene_materials_follow_the_materials_file_rule_in_its_words() {
    for (field, p, words) in [
        (
            "ior",
            Principled {
                ior: -1.0,
                ..grey()
            },
            "must be finite and > 0, got -1",
        ),
        (
            "base_color",
            Principled {
                base_color: [-5.0, 0.5, 0.5],
                ..grey()
            },
            "channel 0 must be finite and ≥ 0, got -5",
        ),
        (
            "metallic",
            Principled {
                metallic: 5.0,
                ..grey()
            },
            "must be in [0, 1], got 5",
        ),
    ] {
        let spec = MaterialSpec::principled(p);
        let mut s = common::cornell(16);
        s.regions[1].material = spec.clone();
        let name = s.regions[1].name.clone();
        let from_scene = invalid(&s);
        let from_edit = spec
            .validate(&format!("region \"{name}\""))
            .unwrap_err()
            .to_string();
        assert_eq!(from_scene, from_edit, "{field}");
        assert!(
            from_scene.contains(&format!("region \"{name}\".{field}"))
                && from_scene.contains(words),
            "{from_scene}"
        );
    }
    // Blinn–Phong Kd + Ks > 1: a warning in a scene before, refused as in a materials file.
    let mut s = common::cornell(16);
    s.regions[0].material = common::bp(0.8, 0.5, 10.0);
    assert!(invalid(&s).contains("Kd + Ks = 1.3 > 1"), "{}", invalid(&s));
}

#[test]
fn light_groups_with_one_name_are_refused() {
    let mut s = common::cornell_two_lights(16);
    s.light_groups = vec![
        LightGroupSpec {
            name: "key".into(),
            lights: vec![0],
            world: false,
        },
        LightGroupSpec {
            name: "key".into(),
            lights: vec![1],
            world: false,
        },
    ];
    let e = invalid(&s);
    assert!(
        e.contains("light group 1 \"key\"")
            && e.contains("duplicate light group name")
            && e.contains("group 0"),
        "{e}"
    );
    s.light_groups[1].name = "fill".into();
    validate_scene(&s).unwrap();
    // A group naming a light the scene does not have.
    s.light_groups[1].lights = vec![7];
    let e = invalid(&s);
    assert!(e.contains("\"fill\" light: index 7 is out of range"), "{e}");
}

fn area_light(shape: AreaShape, side: f32, power: f32) -> Light {
    Light::Area {
        position: [0.3, -0.2, 1.0],
        axis_u: [1.0, 0.0, 0.0],
        axis_v: [0.0, 1.0, 0.0],
        shape,
        size_x: side,
        size_y: None,
        power,
        color: [1.0; 3],
        visible_camera: false,
    }
}

/// Irradiance at `p` (normal +Z) from light 0 of `lights`, by `n` stratified light samples.
fn irradiance(lights: &LightSet, p: Vec3, n: usize) -> f64 {
    let k = (n as f64).sqrt() as usize;
    let mut sum = 0.0;
    for i in 0..k {
        for j in 0..k {
            let (u1, u2) = ((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
            if let Some(s) = lights.sample(0, p, Vec3::Z, u1, u2) {
                sum += s.radiance_over_pdf.x as f64 * s.wi.z.max(0.0) as f64;
            }
        }
    }
    sum / (k * k) as f64
}

#[test]
fn tiny_square_lights_emit_what_tiny_disks_of_the_same_area_and_power_do() {
    // 1 m below the light's centre; a light small against 1 m gives E = P/(π d²) whatever
    // its shape (L = P/(π A), Ω = A/d²).
    let power = 10.0f32;
    let exact = power as f64 / PI;
    let p = Vec3::new(0.3, -0.2, 0.0);
    for exp in 3..=9 {
        let side = 10f32.powi(-exp);
        // A disk of the square's area: diameter 2·side/√π.
        let diameter = 2.0 * side / (PI as f32).sqrt();
        let mut got = vec![];
        for (shape, size) in [(AreaShape::Square, side), (AreaShape::Disk, diameter)] {
            let mut scene = common::cornell(16);
            scene.lights = vec![area_light(shape, size, power)];
            for sampling in [AreaSampling::SolidAngle, AreaSampling::Area] {
                let mut lights = LightSet::new(&scene, LightGrouping::All);
                lights.set_area_sampling(sampling);
                got.push((shape, sampling, irradiance(&lights, p, 1024)));
            }
        }
        for (shape, sampling, e) in &got {
            println!("side 1e-{exp}: {shape:?} by {sampling:?}: E = {e:.6} (exact {exact:.6})");
            assert!(
                (e / exact - 1.0).abs() < 1e-3,
                "side 1e-{exp} {shape:?} {sampling:?}: E = {e}, exact {exact}"
            );
        }
    }
}

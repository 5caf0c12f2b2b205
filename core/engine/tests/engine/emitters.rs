//! Emitters seen directly and emissive surfaces (issue 15): a visible area light shows its
//! radiance P/(π·A) on its front face only; an emissive quad of radiance L lights a floor
//! as an area light of power π·L·A does (same one-sided Lambertian emission towards the
//! floor); what the camera sees of an emitter is constant light that follows its group's gain.
use crate::common;

use relume_engine::bake::{bake, BakeSettings, LightGrouping};
use relume_engine::progress::Progress;
use relume_engine::scene::{AreaShape, Light, Scene, World};
use relume_engine::Rgb;

use common::{bp, look_at, quad, region};

fn floor_scene(camera_up: bool) -> Scene {
    Scene {
        meshes: vec![quad(
            "floor",
            [-2.0, -2.0, 0.0],
            [2.0, -2.0, 0.0],
            [2.0, 2.0, 0.0],
            [-2.0, 2.0, 0.0],
            0,
        )],
        regions: vec![region("Floor", false, bp(0.5, 0.0, 1.0))],
        lights: vec![],
        world: World::Color {
            color: [0.0; 3],
            strength: 1.0,
        },
        camera: if camera_up {
            look_at([0.0, 0.0, 0.2], [0.0, 0.0, 1.0], 50.0)
        } else {
            // Looks down at the floor from the side; the light plane (z = 1) stays out of view.
            look_at([0.0, -2.0, 0.6], [0.0, 0.0, 0.0], 50.0)
        },
        resolution: relume_engine::scene::Resolution {
            width: 16,
            height: 16,
        },
        light_groups: Vec::new(),
    }
}

fn area(size: f32, power: f32, facing_down: bool, visible: bool) -> Light {
    let (u, v) = if facing_down {
        ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    } else {
        ([0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    };
    Light::Area {
        position: [0.0, 0.0, 1.0],
        axis_u: u,
        axis_v: v,
        shape: AreaShape::Square,
        size_x: size,
        size_y: None,
        power,
        color: [1.0, 1.0, 1.0],
        visible_camera: visible,
    }
}

fn mean(img: &[f32]) -> f64 {
    let n = img.len() / 4;
    img.chunks(4).map(|p| p[0] as f64).sum::<f64>() / n as f64
}

#[test]
fn a_visible_area_light_shows_its_radiance_on_its_front_face_only() {
    let settings = BakeSettings {
        spp: 2,
        bounces: 0,
        ..Default::default()
    };
    let (size, power) = (3.0f32, 90.0f32);
    let expected = power / (std::f32::consts::PI * size * size);
    for (facing_down, visible, want) in [
        (true, true, expected),
        (false, true, 0.0),
        (true, false, 0.0),
    ] {
        let mut scene = floor_scene(true);
        scene.lights = vec![area(size, power, facing_down, visible)];
        let (stack, _) = bake(&scene, &settings, &Progress::new()).unwrap();
        let img = common::relight_at_bake_materials(&stack, &scene);
        for p in img.chunks(4) {
            assert!(
                (p[0] - want).abs() <= 1e-4 * want.max(1.0),
                "facing down {facing_down}, visible {visible}: {} vs {want}",
                p[0]
            );
        }
    }
}

#[test]
fn an_emissive_quad_lights_like_the_area_light_of_the_same_power_and_is_seen() {
    let settings = BakeSettings {
        spp: 32,
        light_samples: 4,
        bounces: 0,
        ..Default::default()
    };
    let (size, power) = (0.6f32, 30.0f32);
    let radiance = power / (std::f32::consts::PI * size * size);
    let mut with_area = floor_scene(false);
    with_area.lights = vec![area(size, power, true, true)];
    let mut with_mesh = floor_scene(false);
    let h = 0.5 * size;
    with_mesh.meshes.push(quad(
        "emitter",
        [-h, -h, 1.0],
        [h, -h, 1.0],
        [h, h, 1.0],
        [-h, h, 1.0],
        1,
    ));
    with_mesh
        .regions
        .push(region("Emission", false, bp(0.0, 0.0, 1.0)));
    with_mesh.lights = vec![Light::Emissive {
        region: 1,
        strength: radiance,
        color: [1.0, 1.0, 1.0],
        visible_camera: true,
    }];
    let (a, _) = bake(&with_area, &settings, &Progress::new()).unwrap();
    let (m, _) = bake(&with_mesh, &settings, &Progress::new()).unwrap();
    let (ia, im) = (
        common::relight_at_bake_materials(&a, &with_area),
        common::relight_at_bake_materials(&m, &with_mesh),
    );
    let (ma, mm) = (mean(&ia), mean(&im));
    eprintln!("floor lit by the area light {ma:.5}, by the emissive quad {mm:.5}");
    assert!(ma > 0.0 && ((mm - ma) / ma).abs() < 0.02, "{ma} vs {mm}");

    // Seen from below, the quad shows its radiance (two-sided); per-light groups: the
    // emitter's gain scales what the camera sees.
    let mut seen = with_mesh.clone();
    seen.camera = look_at([0.0, 0.0, 0.5], [0.0, 0.0, 1.0], 50.0);
    let (stack, _) = bake(
        &seen,
        &BakeSettings {
            spp: 2,
            bounces: 0,
            light_grouping: LightGrouping::PerLight,
            ..Default::default()
        },
        &Progress::new(),
    )
    .unwrap();
    let bases = relume_engine::stack::bases::StackBases::from_header(&stack.header).unwrap();
    let coefs = bases.coefficients(&[]).unwrap();
    let mut r = relume_engine::relight::CpuRelighter::new(std::sync::Arc::new(stack)).unwrap();
    let img = r.relight(&coefs).unwrap().to_vec();
    let centre = (8 * 16 + 8) * 4;
    assert!(
        (img[centre] - radiance).abs() < 1e-3 * radiance,
        "{}",
        img[centre]
    );
    let groups = r.stack().header.light_groups.len();
    let mut gains = vec![Rgb::ONE; groups];
    gains[0] = Rgb::splat(0.5);
    let img = r.set_light_group_gains(&gains).unwrap().to_vec();
    assert!((img[centre] - 0.5 * radiance).abs() < 1e-3 * radiance);
}

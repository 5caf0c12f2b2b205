//! Light groups: radiance is linear in each light's emission, so a stack baked with its
//! lights kept apart relights with any group strength and colour exactly as a bake with
//! the lights changed the same way (same seeds, same paths).
use crate::common;

use std::sync::Arc;

use relume_engine::bake::{bake, BakeSettings, LightGrouping};
use relume_engine::image_io::compare_rgb;
use relume_engine::progress::Progress;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{Light, LightGroupSpec, Scene, World};
use relume_engine::stack::TransferStack;
use relume_engine::Rgb;

fn two_lights() -> Scene {
    common::cornell_two_lights(32)
}

fn relighter(stack: TransferStack, scene: &Scene) -> CpuRelighter {
    let coefs = common::bake_material_coefs(&stack.header, scene);
    let mut r = CpuRelighter::new(Arc::new(stack)).unwrap();
    r.relight(&coefs).unwrap();
    r
}

#[test]
fn per_light_gains_equal_a_bake_with_the_lights_changed() {
    let scene = two_lights();
    let settings = BakeSettings {
        spp: 2,
        ..Default::default()
    };
    let (grouped, report) = bake(
        &scene,
        &BakeSettings {
            light_grouping: LightGrouping::PerLight,
            ..settings.clone()
        },
        &Progress::new(),
    )
    .unwrap();
    assert_eq!(
        grouped.header.light_groups.len(),
        3,
        "two lights and the world"
    );
    assert!(
        report.layers_grey > 0,
        "each group's own colour is factored out"
    );
    let (plain, _) = bake(&scene, &settings, &Progress::new()).unwrap();
    let mut r = relighter(grouped, &scene);
    // Unit gains: the grouped stack relights like the plain one.
    let same = r.image().to_vec();
    let plain_img = relighter(plain, &scene).image().to_vec();
    let d = compare_rgb(&same, &plain_img, 4).unwrap().rel_l2;
    assert!(d < 1e-3, "grouped at unit gains vs plain: {d}");

    // (A group switched off entirely would also change which emitters the bake samples,
    // hence its random numbers; dimming keeps the paths.)
    let gains = [Rgb::splat(2.5), Rgb::new(0.2, 1.0, 0.4), Rgb::splat(0.5)];
    let edited = r.set_light_group_gains(&gains).unwrap().to_vec();
    let mut changed = scene.clone();
    if let Light::Area { power, .. } = &mut changed.lights[0] {
        *power *= 2.5;
    }
    if let Light::Point { color, .. } = &mut changed.lights[1] {
        *color = [color[0] * 0.2, color[1], color[2] * 0.4];
    }
    changed.world = World::Color {
        color: [0.01, 0.01, 0.015],
        strength: 1.0,
    };
    let (rebaked, _) = bake(&changed, &settings, &Progress::new()).unwrap();
    let truth = relighter(rebaked, &changed).image().to_vec();
    let d = compare_rgb(&edited, &truth, 4).unwrap().rel_l2;
    eprintln!("relit with group gains vs a bake with the lights changed: {d:.2e}");
    assert!(d < 1e-3, "{d}");
    assert!(
        r.set_light_group_gains(&gains[..2]).is_err(),
        "one gain per group"
    );
}

#[test]
fn scene_groups_and_the_default_group() {
    let mut scene = two_lights();
    scene.light_groups = vec![LightGroupSpec {
        name: "key".into(),
        lights: vec![0],
        world: false,
    }];
    let (stack, _) = bake(
        &scene,
        &BakeSettings {
            spp: 1,
            light_grouping: LightGrouping::Scene,
            ..Default::default()
        },
        &Progress::new(),
    )
    .unwrap();
    let names: Vec<&str> = stack
        .header
        .light_groups
        .iter()
        .map(|g| g.name.as_str())
        .collect();
    assert_eq!(names, ["key", "default"]);
    assert!(stack
        .layers
        .iter()
        .all(|l| l.key.light_group == 1 || l.key.light_group == 2));
    assert!(stack
        .layers
        .iter()
        .any(|l| l.key.layer_name().starts_with("G1_")));
}

/// A scene light group named "default" is the default group, not a second group of that
/// name: its lights, the ungrouped ones and the world share it, and edits by name stay
/// unambiguous.
#[test]
fn a_scene_group_named_default_is_the_default_group() {
    let mut scene = two_lights();
    let group_names = |scene: &Scene| -> Vec<String> {
        let (stack, _) = bake(
            scene,
            &BakeSettings {
                spp: 1,
                light_grouping: LightGrouping::Scene,
                ..Default::default()
            },
            &Progress::new(),
        )
        .unwrap();
        assert!(stack.layers.iter().all(|l| l.key.light_group >= 1
            && (l.key.light_group as usize) <= stack.header.light_groups.len()));
        stack
            .header
            .light_groups
            .iter()
            .map(|g| g.name.clone())
            .collect()
    };
    scene.light_groups = vec![LightGroupSpec {
        name: "default".into(),
        lights: vec![0],
        world: false,
    }];
    assert_eq!(group_names(&scene), ["default"]);
    scene.light_groups = vec![
        LightGroupSpec {
            name: "default".into(),
            lights: vec![1],
            world: true,
        },
        LightGroupSpec {
            name: "key".into(),
            lights: vec![0],
            world: false,
        },
    ];
    assert_eq!(group_names(&scene), ["default", "key"]);
}

#[test]
fn materials_files_edit_light_groups_by_name() {
    use relume_engine::materials::{parse_materials, resolve_light_gains};
    let scene = two_lights();
    let (stack, _) = bake(
        &scene,
        &BakeSettings {
            spp: 1,
            light_grouping: LightGrouping::PerLight,
            ..Default::default()
        },
        &Progress::new(),
    )
    .unwrap();
    let edits = parse_materials(r#"{"format": "relume-materials", "version": 1, "light_groups": {"light 1": {"strength": 3, "color": [1, 0.5, 0]}}}"#).unwrap();
    let gains = resolve_light_gains(&stack.header, &edits).unwrap().unwrap();
    assert_eq!(gains, vec![Rgb::ONE, Rgb::new(3.0, 1.5, 0.0), Rgb::ONE]);
    let bad = parse_materials(
        r#"{"format": "relume-materials", "version": 1, "light_groups": {"sun": {"strength": 3}}}"#,
    )
    .unwrap();
    let err = resolve_light_gains(&stack.header, &bad)
        .unwrap_err()
        .to_string();
    assert!(err.contains("sun") && err.contains("light 0"), "{err}");
    let none = parse_materials(r#"{"format": "relume-materials", "version": 1}"#).unwrap();
    assert_eq!(resolve_light_gains(&stack.header, &none).unwrap(), None);
}

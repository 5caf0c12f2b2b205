//! Every bad input gets its specific error (or a warning and a black image), never a panic.
use crate::common;

use std::path::Path;

use relume_engine::bake::{bake, BakeSettings};
use relume_engine::progress::Progress;
use relume_engine::scene::file::parse_scene;
use relume_engine::scene::validate::validate_scene;
use relume_engine::scene::{Light, Resolution, World};
use relume_engine::RelumeError;

fn small() -> relume_engine::scene::Scene {
    common::cornell(16)
}

#[test]
fn nan_position_is_named() {
    let mut s = small();
    s.meshes[2].positions[1][2] = f32::NAN;
    match validate_scene(&s) {
        Err(RelumeError::NonFinite { what }) => assert!(
            what.contains("mesh 2") && what.contains("back") && what.contains("positions"),
            "{what}"
        ),
        other => panic!("expected NonFinite, got {other:?}"),
    }
}

#[test]
fn infinite_light_power_is_named() {
    let mut s = small();
    s.lights.push(Light::Point {
        position: [0.0; 3],
        power: f32::INFINITY,
        color: [1.0; 3],
        radius: 0.0,
    });
    match validate_scene(&s) {
        Err(RelumeError::NonFinite { what }) => assert_eq!(what, "light 1"),
        other => panic!("expected NonFinite, got {other:?}"),
    }
}

#[test]
fn vertex_index_out_of_range() {
    let mut s = small();
    s.meshes[0].indices[1] = [0, 2, 9];
    match validate_scene(&s) {
        Err(RelumeError::IndexOutOfRange { what, index, len }) => {
            assert!(what.contains("triangle 1 vertex index"), "{what}");
            assert_eq!((index, len), (9, 4));
        }
        other => panic!("expected IndexOutOfRange, got {other:?}"),
    }
}

#[test]
fn region_index_out_of_range() {
    let mut s = small();
    s.meshes[1].region = 17;
    match validate_scene(&s) {
        Err(RelumeError::IndexOutOfRange { what, index, len }) => {
            assert!(what.contains("region"), "{what}");
            assert_eq!((index, len), (17, 4));
        }
        other => panic!("expected IndexOutOfRange, got {other:?}"),
    }
}

#[test]
fn empty_scenes() {
    let mut s = small();
    s.meshes.clear();
    assert!(matches!(
        validate_scene(&s),
        Err(RelumeError::EmptyScene(_))
    ));
    let mut s = small();
    s.regions.clear();
    assert!(matches!(
        validate_scene(&s),
        Err(RelumeError::EmptyScene(_))
    ));
    // Only degenerate triangles: empty too, and it says so.
    let mut s = small();
    s.meshes.truncate(1);
    s.meshes[0].positions = vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
    match validate_scene(&s) {
        Err(RelumeError::EmptyScene(m)) => assert!(m.contains("degenerate"), "{m}"),
        other => panic!("expected EmptyScene, got {other:?}"),
    }
}

#[test]
fn degenerate_triangles_are_skipped_and_counted() {
    let mut s = small();
    let m = &mut s.meshes[0];
    let base = m.positions.len() as u32;
    m.positions
        .extend([[0.0, 0.0, -1.0], [0.5, 0.0, -1.0], [1.0, 0.0, -1.0]]); // collinear
    m.positions.push([0.2, 0.2, -1.0]);
    m.indices.push([base, base + 1, base + 2]);
    m.indices.push([base + 3, base + 3, base + 3]); // a point
    m.uvs = None;
    let report = validate_scene(&s).unwrap();
    assert_eq!(report.degenerate_triangles, 2);
    let (_, bake_report) = bake(
        &s,
        &BakeSettings {
            spp: 1,
            ..Default::default()
        },
        &Progress::new(),
    )
    .unwrap();
    assert_eq!(bake_report.degenerate_triangles, 2);
    assert_eq!(bake_report.triangles, common::cornell(16).triangle_count());
}

#[test]
fn no_light_warns_and_bakes_black() {
    let mut s = small();
    s.lights.clear();
    s.world = World::Color {
        color: [0.0; 3],
        strength: 1.0,
    };
    let report = validate_scene(&s).unwrap();
    assert!(
        report.warnings.iter().any(|w| w.contains("no light")),
        "{:?}",
        report.warnings
    );
    let (stack, report) = bake(
        &s,
        &BakeSettings {
            spp: 1,
            ..Default::default()
        },
        &Progress::new(),
    )
    .unwrap();
    assert_eq!(
        report.layers_grey + report.layers_rgb,
        0,
        "no path carried light"
    );
    // The stack still writes, reads back and relights to black.
    let dir = std::env::temp_dir().join(format!("relume-black-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("black.exr");
    relume_engine::stack::exr_file::write_stack(&path, &stack).unwrap();
    let back = relume_engine::stack::exr_file::read_stack(&path).unwrap();
    let coefs = common::bake_material_coefs(&back.header, &s);
    let mut relighter =
        relume_engine::relight::CpuRelighter::new(std::sync::Arc::new(back)).unwrap();
    let img = relighter.relight(&coefs).unwrap();
    assert!(img.chunks_exact(4).all(|p| p == [0.0, 0.0, 0.0, 1.0]));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_settings_are_refused() {
    let s = small();
    for settings in [
        BakeSettings {
            spp: 0,
            ..Default::default()
        },
        // Past the highest count this build bakes (2 was refused before bounces beyond the
        // first existed).
        BakeSettings {
            bounces: relume_engine::bake::settings::MAX_BOUNCES + 1,
            ..Default::default()
        },
        BakeSettings {
            resolution: Some(Resolution {
                width: 0,
                height: 4,
            }),
            ..Default::default()
        },
    ] {
        assert!(matches!(
            bake(&s, &settings, &Progress::new()),
            Err(RelumeError::InvalidValue { .. })
        ));
    }
}

#[test]
fn scene_file_errors() {
    let p = Path::new("test.scene.json");
    let d = Path::new(".");
    assert!(matches!(
        parse_scene("{", p, d),
        Err(RelumeError::SceneFormat { .. })
    ));
    assert!(
        matches!(parse_scene(r#"{"meshes": []}"#, p, d), Err(RelumeError::SceneFormat { message, .. }) if message.contains("not a Relume scene"))
    );
    assert!(matches!(
        parse_scene(r#"{"format": "other", "version": 1}"#, p, d),
        Err(RelumeError::SceneFormat { .. })
    ));
    assert!(matches!(
        parse_scene(r#"{"format": "relume-scene", "version": 7}"#, p, d),
        Err(RelumeError::SceneVersion {
            found: 7,
            supported: relume_engine::scene::file::SCENE_VERSION,
            ..
        })
    ));
    match parse_scene(
        r#"{"format": "relume-scene", "version": 1, "meshes": []}"#,
        p,
        d,
    ) {
        Err(RelumeError::SceneFormat { message, .. }) => assert!(
            message.contains("regions") || message.contains("missing"),
            "{message}"
        ),
        other => panic!("expected SceneFormat, got {other:?}"),
    }
}

#[test]
fn scene_file_round_trips() {
    let s = small();
    let dir = std::env::temp_dir().join(format!("relume-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("cornell.scene.json");
    relume_engine::scene::file::save_scene(&path, &s).unwrap();
    let back = relume_engine::scene::file::load_scene(&path).unwrap();
    assert_eq!(
        relume_engine::scene::hash::scene_hash(&back),
        relume_engine::scene::hash::scene_hash(&s)
    );
    std::fs::remove_dir_all(&dir).ok();
}

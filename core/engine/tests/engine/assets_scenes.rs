//! The assets/ scenes load, validate and bake (tiny resolution) through the public API.

use std::path::Path;

use relume_engine::bake::{bake, BakeSettings};
use relume_engine::progress::Progress;
use relume_engine::scene::{file::load_scene, validate::validate_scene, Resolution};

fn assets() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets")
}

#[test]
fn committed_scenes_load_validate_and_bake() {
    for name in ["cornell", "ring", "textured", "hdri"] {
        let path = assets().join(format!("{name}.scene.json"));
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let report = validate_scene(&scene).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(report.degenerate_triangles, 0, "{name}");
        assert!(report.warnings.is_empty(), "{name}: {:?}", report.warnings);
        assert!(
            scene.regions.iter().filter(|r| r.editable).count() >= 2,
            "{name}: two editable regions as in the paper"
        );
        let settings = BakeSettings {
            spp: 1,
            light_samples: 1,
            resolution: Some(Resolution {
                width: 24,
                height: 24,
            }),
            ..Default::default()
        };
        let (stack, report) = bake(&scene, &settings, &Progress::new()).unwrap();
        assert!(report.rays > 0);
        assert!(!stack.layers.is_empty(), "{name}: the bake stored no layer");
        for layer in &stack.layers {
            for i in 0..layer.samples.len() {
                assert!(
                    layer.value(i).is_finite(),
                    "{name}: {}",
                    layer.key.layer_name()
                );
            }
        }
    }
}

#[test]
fn translucent_scene_bakes_subsurface_layers_that_survive_the_stack_file() {
    use relume_engine::layer_key::PathVertex;
    use relume_engine::relight::CpuRelighter;
    use relume_engine::stack::bases::StackBases;
    use relume_engine::stack::exr_file::{read_stack, write_stack};

    let scene = load_scene(&assets().join("translucent.scene.json")).unwrap();
    let report = validate_scene(&scene).unwrap();
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    assert!(scene.regions[1].is_translucent());
    let settings = BakeSettings {
        spp: 1,
        light_samples: 1,
        subsurface_samples: 4096,
        resolution: Some(Resolution {
            width: 24,
            height: 24,
        }),
        ..Default::default()
    };
    let mut scene = scene;
    scene.regions[1].subsurface.as_mut().unwrap().samples = Some(4096);
    let (stack, _) = bake(&scene, &settings, &Progress::new()).unwrap();
    let sss = stack
        .layers
        .iter()
        .filter(|l| matches!(l.key.path[..], [PathVertex::Subsurface { .. }]))
        .count();
    let info = stack.header.regions[1]
        .subsurface
        .clone()
        .expect("subsurface info");
    assert!(sss >= 8, "{sss} subsurface layers");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.exr");
    write_stack(&path, &stack).unwrap();
    let back = read_stack(&path).unwrap();
    assert_eq!(back.header.regions[1].subsurface.as_ref(), Some(&info));
    let relit = |s: relume_engine::stack::TransferStack| {
        let bases = StackBases::from_header(&s.header).unwrap();
        let mats =
            relume_engine::materials::resolve_materials(&s.header.regions, &Default::default())
                .unwrap();
        let coefs = bases.coefficients(&mats).unwrap();
        let mut r = CpuRelighter::new(std::sync::Arc::new(s)).unwrap();
        r.relight(&coefs).unwrap().to_vec()
    };
    let (a, b) = (relit(stack), relit(back));
    assert!(a.iter().all(|v| v.is_finite()));
    assert_eq!(
        a, b,
        "the stack file keeps the subsurface layers and their basis"
    );
}

//! The assets/ scenes load, validate and bake (tiny resolution) through the public API.

use std::path::Path;

use relume_engine::bake::{bake, progress::Progress, BakeSettings};
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

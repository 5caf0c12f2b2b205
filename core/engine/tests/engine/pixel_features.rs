//! The pixel features (what a denoiser of the shown image is given): coverage that sums to
//! the pixel, albedo that follows the editable materials exactly and the fixed ones not at
//! all, unit normals inside a surface, and the same features on every trace.
use crate::common;

use relume_engine::features::{albedo_of, PixelFeatures, FEATURE_SAMPLES_PER_AXIS};

#[test]
fn coverage_albedo_and_normals_follow_the_scene_and_the_materials() {
    let scene = common::cornell(40);
    let f = PixelFeatures::trace(&scene, 40, 40, FEATURE_SAMPLES_PER_AXIS).unwrap();
    assert_eq!(f.size(), (40, 40));
    assert_eq!(f.editable_regions(), 2);
    let white = common::bp(0.3, 0.3, 5.0);
    let object = common::bp(0.2, 0.4, 5.0);
    let a = albedo_of(&f, &[white.clone(), object.clone()]).unwrap();
    let (mut inside_object, mut mixed) = (0, 0);
    for i in 0..40 * 40 {
        let shares = f.shares(i);
        let editable: f32 = shares.iter().map(|s| s.coverage).sum();
        assert!(
            editable <= 1.0 + 1e-5,
            "pixel {i}: editable coverage {editable}"
        );
        let n = &f.normal()[3 * i..3 * i + 3];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!(len <= 1.0 + 1e-4, "pixel {i}: normal length {len}");
        if shares.len() == 1 && shares[0].region == 1 && shares[0].coverage == 1.0 {
            inside_object += 1;
            // Kd + Ks of the sphere's material, grey.
            for c in 0..3 {
                assert!(
                    (a[3 * i + c] - 0.6).abs() < 1e-6,
                    "pixel {i}: {}",
                    a[3 * i + c]
                );
            }
            // Inside one surface the mean of unit normals is nearly unit (the sphere
            // curves within a pixel near its rim).
            assert!(
                len > 0.95,
                "pixel {i}: normal length {len} inside the sphere"
            );
        }
        if shares.len() == 2 || (shares.len() == 1 && shares[0].coverage < 1.0) {
            mixed += 1;
        }
    }
    assert!(
        inside_object > 30,
        "{inside_object} pixels inside the sphere"
    );
    assert!(mixed > 10, "{mixed} pixels on an edge");

    // An edit of the sphere changes the albedo where the sphere is, by its coverage, and
    // nowhere else; the fixed walls' albedo never changes.
    let red_sphere = common::bp_rgb([0.7, 0.1, 0.0], [0.2; 3], 50.0);
    let b = albedo_of(&f, &[white.clone(), red_sphere]).unwrap();
    for i in 0..40 * 40 {
        let cov = f
            .shares(i)
            .iter()
            .find(|s| s.region == 1)
            .map_or(0.0, |s| s.coverage);
        let want = [0.3 * cov, -0.3 * cov, -0.4 * cov];
        for c in 0..3 {
            let d = b[3 * i + c] - a[3 * i + c];
            assert!(
                (d - want[c]).abs() < 1e-5,
                "pixel {i} channel {c}: {d} for coverage {cov}"
            );
        }
    }

    // Deterministic: the same features on every trace (no noise for OIDN's cleanAux).
    assert_eq!(
        PixelFeatures::trace(&scene, 40, 40, FEATURE_SAMPLES_PER_AXIS).unwrap(),
        f
    );
    // The wrong material count (another scene's) is refused, naming both counts.
    let err = albedo_of(&f, &[white]).unwrap_err().to_string();
    assert!(
        err.contains("1 editable materials") && err.contains("2 editable regions"),
        "{err}"
    );
    assert!(PixelFeatures::trace(&scene, 0, 40, 4).is_err());
}

//! The one `StackHeader` builder of the tests that write stacks by hand (no bake involved):
//! every field with a plain value, for a test to override what it is about with struct
//! update syntax (`StackHeader { spp: 64, ..stack_header(w, h, regions) }`).

use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::stack::{Precision, RegionInfo, StackHeader, STACK_FORMAT_VERSION};

/// A `width`×`height` header with `regions`: an identity perspective camera, one eye and
/// light sample, one bounce, uniform sampling, seed 0, no lights, f16, no light groups.
pub fn stack_header(width: u32, height: u32, regions: Vec<RegionInfo>) -> StackHeader {
    let camera = serde_json::from_str(
        r#"{"projection":"perspective","matrix_world":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#,
    )
    .unwrap();
    StackHeader {
        format_version: STACK_FORMAT_VERSION,
        width,
        height,
        camera,
        spp: 1,
        light_samples: 1,
        bounce_light_samples: None,
        diffuse_bounces: None,
        glossy_bounces: None,
        bounces: 1,
        sampling: "uniform".into(),
        seed: 0,
        regions,
        lights: vec![],
        scene_hash: String::new(),
        precision: Precision::F16,
        light_tint: [1.0; 3],
        light_groups: Vec::new(),
        denoise: Default::default(),
        bounce_cap: 0,
    }
}

/// An untextured Blinn–Phong region without a basis or subsurface.
pub fn blinn_phong_region(
    name: &str,
    editable: bool,
    kd: [f32; 3],
    ks: [f32; 3],
    ns: f32,
) -> RegionInfo {
    RegionInfo {
        name: name.into(),
        editable,
        material: MaterialSpec::BlinnPhong(BlinnPhong { kd, ks, ns }),
        basis: None,
        textured: false,
        subsurface: None,
        principled_basis: None,
        principled_basis_with_bake_lobe: None,
    }
}

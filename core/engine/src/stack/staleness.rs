//! What differs between a stack and the scene it is about to be used with, in words, for the
//! message of a stale stack ([`crate::RelumeError::StackStale`] only carries the two hashes).
//!
//! The header keeps the camera, the lights, the regions and the size, so those are named
//! precisely; geometry, the world and textures are only in the hash, so when the hashes
//! differ and nothing named does, the message says it is one of those.

use super::StackHeader;
use crate::scene::{hash::scene_hash, Scene};

/// The parts of `scene` that differ from what `header` was baked from; empty when the scene
/// hashes equal. The last resort entry is "geometry, world or textures".
pub fn scene_differences(header: &StackHeader, scene: &Scene) -> Vec<String> {
    if header.scene_hash == scene_hash(scene) {
        return Vec::new();
    }
    let mut out = Vec::new();
    if header.camera != scene.camera {
        out.push("camera".to_string());
    }
    if header.lights.len() != scene.lights.len() {
        out.push(format!(
            "lights ({} in the stack, {} in the scene)",
            header.lights.len(),
            scene.lights.len()
        ));
    } else if let Some(i) = (0..scene.lights.len()).find(|&i| header.lights[i] != scene.lights[i]) {
        out.push(format!("light {i}"));
    }
    let names = |it: &mut dyn Iterator<Item = (&str, bool)>| -> Vec<String> {
        it.map(|(n, e)| format!("{n}{}", if e { " (editable)" } else { "" }))
            .collect()
    };
    let stack_regions = names(&mut header.regions.iter().map(|r| (r.name.as_str(), r.editable)));
    let scene_regions = names(&mut scene.regions.iter().map(|r| (r.name.as_str(), r.editable)));
    if stack_regions != scene_regions {
        out.push(format!(
            "regions (stack: {}; scene: {})",
            stack_regions.join(", "),
            scene_regions.join(", ")
        ));
    } else {
        for (h, s) in header.regions.iter().zip(&scene.regions) {
            if !s.editable && h.material != s.material {
                out.push(format!("material of fixed region \"{}\"", s.name));
            }
        }
    }
    let res = scene.resolution;
    if (header.width, header.height) != (res.width, res.height) {
        out.push(format!(
            "resolution (stack {}×{}, scene {}×{})",
            header.width, header.height, res.width, res.height
        ));
    }
    if out.is_empty() {
        out.push("geometry, world or textures".to_string());
    }
    out
}

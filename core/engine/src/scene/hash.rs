//! The scene hash: what a stack remembers of the scene it was baked from.
//!
//! It covers everything the bake depends on — geometry, regions (names, editability, basis
//! ranges, the materials of fixed regions, textures), lights, world, camera, resolution —
//! and leaves out the materials of editable regions, which are free at relight time.
//! A stack whose hash differs from the scene's is stale and never used silently.

use super::Scene;

/// 64-bit FNV-1a of the canonical JSON of the bake-relevant part of `scene`, in hex.
/// JSON of f32 values is exact (shortest round-trip form), so equal scenes hash equal.
pub fn scene_hash(scene: &Scene) -> String {
    let mut s = scene.clone();
    for region in &mut s.regions {
        if region.editable {
            region.material = crate::brdf::MaterialSpec::BlinnPhong(crate::brdf::BlinnPhong {
                kd: [0.0; 3],
                ks: [0.0; 3],
                ns: 1.0,
            });
        }
    }
    let bytes = serde_json::to_vec(&s).unwrap_or_default();
    format!("{:016x}", fnv1a(&bytes))
}

/// FNV-1a, 64 bit.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf29ce484222325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100000001b3);
    }
    h
}

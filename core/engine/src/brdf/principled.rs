//! Principled BSDF → Blinn–Phong: the one mapping (DESIGN.md §3).
//! HELPER A: implement.

use serde::{Deserialize, Serialize};

use super::BlinnPhong;

/// The Principled BSDF inputs Relume reads (Blender names in the docs of each field).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Principled {
    /// "Base Color", scene-linear.
    pub base_color: [f32; 3],
    /// "Metallic" ∈ [0, 1].
    #[serde(default)]
    pub metallic: f32,
    /// "Roughness" ∈ [0, 1].
    #[serde(default = "half")]
    pub roughness: f32,
    /// "IOR".
    #[serde(default = "ior")]
    pub ior: f32,
    /// "Specular IOR Level" (0.5 leaves F0 as the IOR gives it).
    #[serde(default = "half")]
    pub specular_ior_level: f32,
}
fn half() -> f32 {
    0.5
}
fn ior() -> f32 {
    1.5
}

/// Maps Principled inputs to Blinn–Phong.
pub fn principled_to_blinn_phong(_p: &Principled) -> BlinnPhong {
    unimplemented_mapping(_p)
}
fn unimplemented_mapping(_p: &Principled) -> BlinnPhong {
    BlinnPhong { kd: [0.0; 3], ks: [0.0; 3], ns: 1.0 }
}

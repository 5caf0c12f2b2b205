//! TEMPORARY stub (replaced by the brdf branch).
use serde::{Deserialize, Serialize};
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct BlinnPhong {
    pub kd: [f32; 3],
    pub ks: [f32; 3],
    pub ns: f32,
}
pub fn lobe(ns: f64, cos_delta: f64) -> f64 {
    if cos_delta <= 0.0 { 0.0 } else { (ns + 2.0) / (8.0 * std::f64::consts::PI) * (ns * cos_delta.ln()).exp() }
}
impl BlinnPhong {
    pub fn eval(&self, n: glam::Vec3, wi: glam::Vec3, wo: glam::Vec3) -> glam::Vec3 {
        let h = (wi + wo).normalize_or_zero();
        glam::Vec3::from(self.kd) / std::f32::consts::PI + glam::Vec3::from(self.ks) * lobe(self.ns as f64, n.dot(h) as f64) as f32
    }
}

//! TEMPORARY interface stub (replaced by the brdf branch): same API, diffuse-only.
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BasisConfig {
    pub ns_min: f32,
    pub ns_max: f32,
    pub lobes: u32,
    pub grid: [u32; 3],
    pub count: BasisCount,
}
impl Default for BasisConfig {
    fn default() -> Self {
        BasisConfig { ns_min: 1.0, ns_max: 200.0, lobes: 200, grid: [30, 30, 60], count: BasisCount::Fixed(6) }
    }
}
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub enum BasisCount {
    Fixed(u32),
    Tolerance(f32),
}
pub struct BrdfBasis {
    cfg: BasisConfig,
}
impl BrdfBasis {
    pub fn build(cfg: &BasisConfig) -> crate::Result<BrdfBasis> {
        Ok(BrdfBasis { cfg: cfg.clone() })
    }
    pub fn config(&self) -> &BasisConfig {
        &self.cfg
    }
    pub fn count(&self) -> usize {
        1
    }
    pub fn eval(&self, _cos_delta: f32, out: &mut [f32]) {
        out[0] = std::f32::consts::FRAC_1_PI;
    }
    pub fn spec_coefficients(&self, _ns: f32, out: &mut [f32]) {
        out[0] = 0.0;
    }
    pub fn material_coefficients(&self, m: &crate::brdf::BlinnPhong) -> Vec<glam::Vec3> {
        vec![glam::Vec3::from(m.kd)]
    }
    pub fn reconstruct(&self, m: &crate::brdf::BlinnPhong, _cos_delta: f32) -> glam::Vec3 {
        glam::Vec3::from(m.kd) * std::f32::consts::FRAC_1_PI
    }
}

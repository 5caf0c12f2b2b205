//! The subsurface part of a bake: for every translucent editable region, surface samples,
//! the light entering at each (`E′`), the octree over them, and per eye hit the layers
//! `B_k(x_o) = (1/π)·F_t(η₀, ω_o)·Σᵢ E′ᵢ Aᵢ b_k(|xᵢ − x_o|)` (see [`crate::bssrdf`]).
//!
//! **Light.** `E′(xᵢ) = Σ_lights L·cos θ·F_t(η₀, θ)/pdf` with the bake's light samples and
//! shadow rays — direct light only, from every light and the world, kept per light group.
//! Light reaching the translucent surface after a bounce (the bake's `bounces = 1`) is **not**
//! included in E′: it would need one set of subsurface layers per (bounce region, basis)
//! pair to stay editable. The surface BRDF part of the region still gets its bounce. The
//! light is traced by [`super::subsurface_light`]; this file holds the region's data, its
//! basis configuration and the gather at an eye hit.

use glam::Vec3;
use std::sync::Arc;

use crate::bake::settings::BakeSettings;
use crate::brdf::MaterialSpec;
use crate::bssrdf::basis::{default_tolerance, SssBasis, SssBasisConfig};
use crate::bssrdf::dipole::fresnel_transmittance;
use crate::bssrdf::mapping::eta_of_ior;
use crate::bssrdf::samples::{region_extent, SurfacePoints};
use crate::bssrdf::tree::ScatterTree;
use crate::bssrdf::SubsurfaceInfo;
use crate::scene::{Region, Scene};
use crate::{RelumeError, Result, Rgb};

/// A translucent region ready for the integrator.
pub struct TranslucentRegion {
    /// Index among the editable regions.
    pub editable_index: u16,
    pub basis: Arc<SssBasis>,
    pub info: SubsurfaceInfo,
    /// Global slot of the eye-diffuse layer and of s_0.
    pub eye_diffuse_slot: u32,
    pub first_slot: u32,
    /// η₀: the bake-time relative index.
    pub eta: f64,
    pub points: SurfacePoints,
    /// E′ per point and light group (point-major).
    pub irradiance: Vec<Rgb>,
    pub tree: ScatterTree,
}

/// The subsurface basis configuration of `region` (the scene's region number `index`) for
/// `settings`: ρ from its area and sample count, the mean-free-path range from its
/// `subsurface` block or its bake-time material (×½ … ×2 of its channels, within [ρ,
/// diameter]), IOR range [1, 2] unless given. `Err` for a region with no area.
pub fn basis_config(
    scene: &Scene,
    index: usize,
    region: &Region,
    settings: &BakeSettings,
) -> Result<(SssBasisConfig, u32)> {
    let s = region.subsurface.clone().unwrap_or_default();
    let samples = s.samples.unwrap_or(settings.subsurface_samples).max(16);
    let (area, diameter) = region_extent(scene, index as u32);
    if !(area > 0.0) || !(diameter > 0.0) {
        return Err(RelumeError::invalid(
            format!("region \"{}\"", region.name),
            "translucent region has no surface area",
        ));
    }
    let rho = (area / (std::f64::consts::PI * samples as f64)).sqrt();
    let (mut lo, mut hi) = match s.mfp_range {
        Some([a, b]) => (a as f64, b as f64),
        None => {
            let mfps: Vec<f64> = match &region.material {
                MaterialSpec::Principled(p) => p
                    .subsurface
                    .mean_free_paths()
                    .into_iter()
                    .filter(|m| *m > 0.0 && m.is_finite())
                    .collect(),
                MaterialSpec::BlinnPhong(_) => vec![],
            };
            if mfps.is_empty() {
                (rho, (diameter / 10.0).max(2.0 * rho))
            } else {
                let a = mfps.iter().cloned().fold(f64::INFINITY, f64::min);
                let b = mfps.iter().cloned().fold(0.0, f64::max);
                (0.5 * a, 2.0 * b)
            }
        }
    };
    if s.mfp_range.is_none() {
        lo = lo.max(rho).min(diameter);
        hi = hi.min(diameter).max(lo);
    }
    let (eta_min, eta_max) = match s.ior_range {
        Some([a, b]) => (a.max(1.0) as f64, b.max(a).max(1.0) as f64),
        None => (1.0, 2.0),
    };
    Ok((
        SssBasisConfig {
            rho,
            r_max: diameter * 1.0001,
            mfp_min: lo,
            mfp_max: hi,
            eta_min,
            eta_max,
            bases: s.bases,
            tolerance: s.tolerance.map_or(default_tolerance(), |t| t as f64),
        },
        samples,
    ))
}

/// Adds the subsurface layers of eye hit `x` (shading normal `n`, towards-eye `wo`) on
/// translucent region `t` into `out[g·K + k]`: `(1/π)·F_t(η₀, n·wo)·Σ E′A b_k`.
pub fn gather_at(t: &TranslucentRegion, x: Vec3, n: Vec3, wo: Vec3, out: &mut [Rgb]) {
    let k = t.basis.count();
    out.fill(Rgb::ZERO);
    let cos_o = n.dot(wo);
    if !(cos_o > 0.0) || t.tree.is_empty() {
        return;
    }
    let basis = &t.basis;
    t.tree.gather(x, k, &|r, b| basis.eval(r, b), out);
    let f = (fresnel_transmittance(t.eta, cos_o as f64) / std::f64::consts::PI) as f32;
    out.iter_mut().for_each(|v| *v *= f);
}

/// η₀ of a region's bake-time material (1.5 for Blinn–Phong materials, which have no IOR).
pub fn bake_eta(material: &MaterialSpec) -> (f64, f32) {
    match material {
        MaterialSpec::Principled(p) => (eta_of_ior(p.bsdf.ior), p.bsdf.ior),
        MaterialSpec::BlinnPhong(_) => (1.5, 1.5),
    }
}

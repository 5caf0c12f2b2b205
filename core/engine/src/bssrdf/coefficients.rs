//! The relight weights of a translucent region: its surface BRDF slots, the eye-diffuse slot
//! and the subsurface slots, for a material. Shared by the bake (layer dropping, the
//! bake-time image), the CPU relight and the GPU relight, so every path weighs layers alike.
//!
//! Slot layout of a translucent editable region (region-local coefficient indices):
//! `[BRDF slots … | eye diffuse | s_0 … s_{K−1}]`.
//! - BRDF slots carry the material's surface BRDF at every vertex where the region is *not*
//!   seen by the eye (bounce vertices) and the specular part at the eye. At a bounce vertex
//!   the subsurface light is approximated as leaving where it entered (a diffuse BRDF with
//!   the base colour as albedo, which the albedo inversion makes its total reflectance).
//! - The eye-diffuse slot holds the diffuse basis at the eye; its weight is the diffuse
//!   coefficient of `Kd·(1 − w)`, w = Subsurface Weight × (1 − Metallic).
//! - Subsurface slot k has weight `w · s_k(σ_c) · (T̄(η)/T̄(η₀))²` per channel c, where the
//!   layer holds `(1/π)·F_t(η₀, ω_o)·Σᵢ E′ᵢ Aᵢ b_k(|xᵢ − x_o|)` baked with the bake-time IOR
//!   η₀ (entry and exit Fresnel). Changing the IOR rescales by the ratio of the mean
//!   transmittances — exact at η = η₀, an approximation elsewhere (documented: the exit
//!   Fresnel's angular shape stays that of η₀); the profile's own dependence on η (the
//!   boundary term A) is exact through s_k.

use serde::{Deserialize, Serialize};

use super::basis::{SssBasis, SssBasisConfig};
use super::dipole::mean_transmittance;
use super::mapping::eta_of_ior;
use crate::brdf::basis::coefficients::slot_coefficients;
use crate::brdf::material::MaterialSpec;
use crate::brdf::RegionBasis;
use crate::{RelumeError, Result, Rgb};

/// What a stack records of a translucent region (in its [`crate::stack::RegionInfo`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SubsurfaceInfo {
    /// The subsurface basis (rebuilt from this on load).
    pub basis: SssBasisConfig,
    /// The IOR at bake time (η₀ of the baked Fresnel transmittance).
    pub bake_ior: f32,
    /// Region-local slot of the eye-diffuse layer (= the number of BRDF slots).
    pub eye_diffuse_slot: u32,
    /// Region-local slot of s_0.
    pub first_slot: u32,
    /// Surface samples the layers were gathered from.
    pub samples: u32,
}

/// Coefficients of every slot of an editable region for material `m`: the BRDF slots
/// ([`slot_coefficients`]) and, for a translucent region, the eye-diffuse and subsurface
/// slots (module docs).
pub fn region_slot_coefficients(
    basis: &RegionBasis,
    textured: bool,
    subsurface: Option<(&SssBasis, &SubsurfaceInfo)>,
    m: &MaterialSpec,
) -> Result<Vec<Rgb>> {
    let mut c = basis.slot_coefficients(textured, m)?.slots;
    let Some((sss, info)) = subsurface else {
        return Ok(c);
    };
    let Some(basis) = basis.blinn_phong() else {
        return Err(RelumeError::Materials(
            "a translucent region cannot use the Principled basis".into(),
        ));
    };
    let eye = slot_coefficients(basis, textured, &m.eye_blinn_phong())[0];
    let first = info.first_slot as usize;
    c.resize(first + sss.count(), Rgb::ZERO);
    c[info.eye_diffuse_slot as usize] = eye;
    let w = m.subsurface_weight() as f64;
    if let (true, Some(params)) = (w > 0.0, m.dipole_params()) {
        let t0 = mean_transmittance(eta_of_ior(info.bake_ior).min(sss.config().eta_max));
        let t = mean_transmittance(
            params[0]
                .eta
                .clamp(sss.config().eta_min, sss.config().eta_max),
        );
        let fresnel = if t0 > 0.0 { (t / t0) * (t / t0) } else { 1.0 };
        let mut s = vec![0.0f64; sss.count()];
        for (ch, p) in params.iter().enumerate() {
            sss.coefficients(p, &mut s);
            for (k, v) in s.iter().enumerate() {
                c[first + k][ch] = (w * fresnel * v) as f32;
            }
        }
    }
    Ok(c)
}

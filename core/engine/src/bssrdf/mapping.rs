//! Blender's Principled subsurface inputs → dipole parameters, per RGB channel.
//!
//! Blender gives Subsurface Weight w, Radius (RGB), Scale s, IOR and Base Color. The mapping
//! (an assumption, documented, not Cycles' random walk):
//! - **Mean free path.** `ld_c = radius_c · s` is taken as the *diffuse* mean free path
//!   `1/σ_tr` of channel c (Jensen & Buhler 2002's `ld`), in scene units. Blender's manual
//!   calls the radius "the average distance light scatters below the surface", which is the
//!   same length up to a constant of order one.
//! - **Albedo inversion.** The reduced albedo α′_c is the one whose dipole total diffuse
//!   reflectance equals the base colour: `total_reflectance(α′, η) = base_c` (bisection,
//!   monotone in α′). So, seen from far away, the material reflects its base colour like a
//!   diffuse surface would (before the Fresnel transmittance at entry and exit, which the
//!   BSSRDF applies as Jensen does: ≈ 0.96 each at normal incidence for IOR 1.5). Base colours
//!   beyond `total_reflectance(ALPHA_MAX, η)` (0.994 at η = 1.5) are clamped there.
//! - **Coefficients.** `σ′t = σ_tr/√(3(1−α′))`, `σ′s = α′σ′t`, `σa = σ′t − σ′s`. Blender's
//!   Subsurface Anisotropy g only enters through `σ′s = (1−g)σs`, i.e. it is already folded in.
//! - **η** is the material's IOR, mirrored below 1 (`max(ior, 1/ior)`).
//! - **Weight.** The surface's diffuse is scaled by `1 − w·(1 − metallic)` at the eye and the
//!   subsurface term by `w·(1 − metallic)` (metals do not scatter below the surface).

use serde::{Deserialize, Serialize};

use super::dipole::{total_reflectance, DipoleParams};
use crate::{RelumeError, Result};

/// Blender's Principled subsurface inputs (materials and scene files: `subsurface_weight`,
/// `subsurface_radius`, `subsurface_scale`, beside the Principled fields). Defaults are
/// Blender's: weight 0, radius (1, 0.2, 0.1), scale 0.05. Default values are not written
/// out, so scenes and stacks without translucency serialise (and hash) as before.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Subsurface {
    /// "Subsurface Weight" ∈ [0, 1]: the share of the diffuse that scatters below the surface.
    #[serde(default, rename = "subsurface_weight", skip_serializing_if = "is_zero")]
    pub weight: f32,
    /// "Subsurface Radius" (RGB, ≥ 0): mean free path per channel in units of `scale`.
    #[serde(
        default = "default_radius",
        rename = "subsurface_radius",
        skip_serializing_if = "is_default_radius"
    )]
    pub radius: [f32; 3],
    /// "Subsurface Scale" (≥ 0, scene units): multiplies the radius.
    #[serde(
        default = "default_scale",
        rename = "subsurface_scale",
        skip_serializing_if = "is_default_scale"
    )]
    pub scale: f32,
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}
fn default_radius() -> [f32; 3] {
    [1.0, 0.2, 0.1]
}
fn is_default_radius(r: &[f32; 3]) -> bool {
    *r == default_radius()
}
fn default_scale() -> f32 {
    0.05
}
fn is_default_scale(s: &f32) -> bool {
    *s == default_scale()
}

impl Default for Subsurface {
    fn default() -> Self {
        Subsurface {
            weight: 0.0,
            radius: default_radius(),
            scale: default_scale(),
        }
    }
}

impl Subsurface {
    /// The JSON keys of these fields (the materials file accepts them on "principled").
    pub const KEYS: [&'static str; 3] =
        ["subsurface_weight", "subsurface_radius", "subsurface_scale"];

    /// Errors (naming `"{what}.field"`): weight outside [0, 1], a negative or non-finite
    /// radius or scale.
    pub fn validate(&self, what: &str) -> Result<()> {
        if !(0.0..=1.0).contains(&self.weight) {
            return Err(RelumeError::invalid(
                format!("{what}.subsurface_weight"),
                format!("must be in [0, 1], got {}", self.weight),
            ));
        }
        if self.radius.iter().any(|r| !r.is_finite() || *r < 0.0) {
            return Err(RelumeError::invalid(
                format!("{what}.subsurface_radius"),
                format!("must be finite and ≥ 0, got {:?}", self.radius),
            ));
        }
        if !self.scale.is_finite() || self.scale < 0.0 {
            return Err(RelumeError::invalid(
                format!("{what}.subsurface_scale"),
                format!("must be finite and ≥ 0, got {}", self.scale),
            ));
        }
        Ok(())
    }

    /// Mean free path `radius_c · scale` per channel (scene units).
    pub fn mean_free_paths(&self) -> [f64; 3] {
        self.radius.map(|r| r as f64 * self.scale as f64)
    }
}

/// Largest reduced albedo used: `1 − 10⁻⁶`, so σa > 0 and the profile decays (σ_tr finite).
pub const ALPHA_MAX: f64 = 1.0 - 1e-6;

/// The α′ whose total diffuse reflectance at index `eta` is `albedo` (clamped to
/// [0, total_reflectance(ALPHA_MAX, η)]); 48 bisection steps, enough for f64 and cheap
/// enough to run on every edit.
pub fn invert_albedo(albedo: f64, eta: f64) -> f64 {
    let target = if albedo.is_nan() { 0.0 } else { albedo };
    if !(target > 0.0) {
        return 0.0;
    }
    if target >= total_reflectance(ALPHA_MAX, eta) {
        return ALPHA_MAX;
    }
    let (mut lo, mut hi) = (0.0f64, ALPHA_MAX);
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if total_reflectance(mid, eta) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The relative index of a Blender IOR: `max(ior, 1/ior)`, 1.5 for a non-finite or ≤ 0 IOR.
pub fn eta_of_ior(ior: f32) -> f64 {
    let i = ior as f64;
    if !(i > 0.0) || !i.is_finite() {
        return 1.5;
    }
    i.max(1.0 / i)
}

/// Dipole parameters of one channel from base colour `albedo`, mean free path
/// `mfp = radius · scale` (scene units, > 0) and IOR.
pub fn channel_params(albedo: f32, mfp: f64, ior: f32) -> DipoleParams {
    let eta = eta_of_ior(ior);
    DipoleParams::from_mfp(mfp, invert_albedo(albedo as f64, eta), eta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn albedo_inversion_round_trips() {
        for eta in [1.0, 1.3, 1.5, 2.0] {
            for a in [0.01, 0.2, 0.5, 0.8, 0.95] {
                let ap = invert_albedo(a, eta);
                assert!((total_reflectance(ap, eta) - a).abs() < 1e-9, "{eta} {a}");
            }
            assert_eq!(invert_albedo(0.0, eta), 0.0);
            assert_eq!(invert_albedo(1.5, eta), ALPHA_MAX);
        }
        assert!(total_reflectance(ALPHA_MAX, 1.5) > 0.99);
    }

    #[test]
    fn coefficients_follow() {
        let p = channel_params(0.5, 0.01, 1.4);
        let st = p.sigma_t_p();
        let (ssp, sa) = (p.alpha_p * st, (1.0 - p.alpha_p) * st);
        assert!(((3.0 * sa * st).sqrt() - 100.0).abs() < 1e-9);
        assert!(ssp > 0.0 && sa > 0.0);
        assert_eq!(eta_of_ior(0.5), 2.0);
    }
}

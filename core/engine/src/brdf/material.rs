//! A material as the user edits it: Blinn–Phong values or Principled BSDF inputs (with
//! Blender's subsurface inputs), the rules an edit must meet, and what it stands for at a
//! path vertex (its Blinn–Phong BRDF, the share that scatters below the surface, its dipole
//! parameters).

use serde::{Deserialize, Serialize};

use super::blinn_phong::BlinnPhong;
use super::principled::Principled;
use super::principled_fit::principled_to_blinn_phong;
use crate::bssrdf::dipole::DipoleParams;
use crate::bssrdf::mapping::{channel_params, Subsurface};

/// A material as written in a scene file or a materials file: Blinn–Phong values directly,
/// or Principled BSDF inputs that go through [`principled_to_blinn_phong`] (with, optionally,
/// Blender's subsurface inputs for translucent regions).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum MaterialSpec {
    BlinnPhong(BlinnPhong),
    Principled(PrincipledMaterial),
}

/// The Principled inputs of a material: the surface BSDF and the subsurface scattering, in
/// one flat JSON object (`{"model": "principled", "base_color": …, "subsurface_weight": …}`).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct PrincipledMaterial {
    #[serde(flatten)]
    pub bsdf: Principled,
    #[serde(flatten)]
    pub subsurface: Subsurface,
}

impl From<Principled> for PrincipledMaterial {
    fn from(bsdf: Principled) -> Self {
        PrincipledMaterial {
            bsdf,
            subsurface: Subsurface::default(),
        }
    }
}

/// Tolerance on Kd + Ks ≤ 1 (the Principled mapping's own rounding stays far below it).
pub const ENERGY_SLACK: f32 = 1e-6;

impl MaterialSpec {
    /// The rules a material edit must meet, the same for the command line's materials file,
    /// the Python bindings and the add-on; errors name `"{what}.field"`: Blinn–Phong values
    /// finite with Kd, Ks ≥ 0, ns > 0 ([`BlinnPhong::validate`]) and Kd + Ks ≤ 1 per channel
    /// (a surface that reflects more than it receives makes relit light grow without bound);
    /// Principled inputs in their ranges ([`Principled::validate`], nothing clamped
    /// silently) and subsurface inputs ([`Subsurface::validate`]).
    pub fn validate(&self, what: &str) -> crate::Result<()> {
        if let MaterialSpec::Principled(p) = self {
            p.bsdf.validate(what)?;
            p.subsurface.validate(what)?;
        }
        let m = self.to_blinn_phong();
        m.validate(what)?;
        if let Some(c) = (0..3).find(|&c| m.kd[c] + m.ks[c] > 1.0 + ENERGY_SLACK) {
            return Err(crate::RelumeError::invalid(
                format!("{what}.kd + ks"),
                format!(
                    "Kd + Ks = {} > 1 in channel {c}: the surface would reflect more light than it receives",
                    m.kd[c] + m.ks[c]
                ),
            ));
        }
        Ok(())
    }

    /// A Principled material without subsurface scattering.
    pub fn principled(p: Principled) -> MaterialSpec {
        MaterialSpec::Principled(p.into())
    }

    /// The Blinn–Phong parameters this material stands for (its surface BRDF, as every path
    /// vertex but a translucent region's eye vertex sees it; see [`Self::eye_blinn_phong`]).
    pub fn to_blinn_phong(&self) -> BlinnPhong {
        match self {
            MaterialSpec::BlinnPhong(b) => *b,
            MaterialSpec::Principled(p) => principled_to_blinn_phong(&p.bsdf),
        }
    }

    /// The share of the diffuse that scatters below the surface: Subsurface Weight ×
    /// (1 − Metallic), in [0, 1]; 0 for Blinn–Phong materials.
    pub fn subsurface_weight(&self) -> f32 {
        match self {
            MaterialSpec::BlinnPhong(_) => 0.0,
            MaterialSpec::Principled(p) => {
                let w = p.subsurface.weight * (1.0 - p.bsdf.metallic.clamp(0.0, 1.0));
                if w.is_nan() {
                    0.0
                } else {
                    w.clamp(0.0, 1.0)
                }
            }
        }
    }

    /// The surface BRDF at a translucent region's eye vertex: Kd scaled by
    /// `1 −` [`Self::subsurface_weight`] (that share leaves through the BSSRDF instead).
    pub fn eye_blinn_phong(&self) -> BlinnPhong {
        let mut b = self.to_blinn_phong();
        let keep = 1.0 - self.subsurface_weight();
        b.kd = b.kd.map(|k| k * keep);
        b
    }

    /// Dipole parameters per RGB channel (base colour as the diffuse albedo, radius × scale
    /// as mean free path, IOR; see [`crate::bssrdf::mapping`]); `None` for Blinn–Phong.
    pub fn dipole_params(&self) -> Option<[DipoleParams; 3]> {
        match self {
            MaterialSpec::BlinnPhong(_) => None,
            MaterialSpec::Principled(p) => {
                let mfp = p.subsurface.mean_free_paths();
                Some(std::array::from_fn(|c| {
                    channel_params(p.bsdf.base_color[c].min(1.0), mfp[c], p.bsdf.ior)
                }))
            }
        }
    }
}

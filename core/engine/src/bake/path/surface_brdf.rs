//! The BRDF a region has at bake time, as the bake evaluates it at path vertices where the
//! material is not edited (fixed regions everywhere, every region beyond the first bounce).
//!
//! A Principled material there is evaluated as Cycles evaluates it
//! ([`CyclesPrincipled`]: GGX, Fresnel, multiple scattering, the diffuse base's
//! view-dependent weight), not through its Blinn–Phong mapping: nothing needs such a
//! material to be linear in a basis, and no Blinn–Phong matches Cycles' Principled under
//! every lighting (docs/principled_fit.md). Editable regions' first bounce keeps the
//! Blinn–Phong basis; their bake-time material elsewhere keeps the mapped Blinn–Phong too,
//! so that a relit edit and the frozen tail stay one model (docs/bounces.md).

use std::f32::consts::FRAC_1_PI;
use std::sync::Arc;

use glam::Vec3;

use crate::brdf::blinn_phong::lobe;
use crate::brdf::cycles_principled::CyclesPrincipled;
use crate::brdf::{BlinnPhong, MaterialSpec};
use crate::Rgb;

/// A region's bake-time BRDF.
#[derive(Clone, Debug)]
pub enum SurfaceBrdf {
    BlinnPhong(BlinnPhong),
    /// Cycles' Principled reflection (its tables built once per region).
    Principled(Arc<CyclesPrincipled>),
}

impl SurfaceBrdf {
    /// Blinn–Phong materials as they are; Principled ones evaluated as Cycles does.
    pub fn exact(material: &MaterialSpec) -> SurfaceBrdf {
        match material {
            MaterialSpec::BlinnPhong(m) => SurfaceBrdf::BlinnPhong(*m),
            MaterialSpec::Principled(p) => {
                SurfaceBrdf::Principled(Arc::new(CyclesPrincipled::new(&p.bsdf)))
            }
        }
    }

    /// The BRDF (no cosine factor) for light from `wi` seen from `wo` at normal `n`, with the
    /// diffuse part scaled by `albedo` (the region's texture). A Principled surface is zero
    /// when either direction is below the surface (as Cycles' microfacet closures are).
    #[inline]
    pub fn value(&self, albedo: Rgb, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb {
        SurfaceBrdf::sum(self.parts(albedo, n, wi, wo))
    }

    /// The value from its [`Self::parts`]: one order of addition for every caller, so a value
    /// summed from parts evaluated once is bit for bit [`Self::value`].
    #[inline]
    pub fn sum([diffuse, glossy]: [Rgb; 2]) -> Rgb {
        glossy + diffuse
    }

    /// [`Self::value`] as its diffuse and glossy parts (their sum is the value): what the
    /// tail-edit layers label each later vertex with.
    #[inline]
    pub fn parts(&self, albedo: Rgb, n: Vec3, wi: Vec3, wo: Vec3) -> [Rgb; 2] {
        match self {
            SurfaceBrdf::BlinnPhong(m) => {
                let h = (wi + wo).normalize_or_zero();
                [
                    Rgb::from(m.kd) * albedo * FRAC_1_PI,
                    Rgb::from(m.ks) * lobe(m.ns as f64, n.dot(h) as f64) as f32,
                ]
            }
            SurfaceBrdf::Principled(p) => {
                let (cos_i, cos_o) = (n.dot(wi), n.dot(wo));
                if !(cos_i > 0.0 && cos_o > 0.0) {
                    return [Rgb::ZERO; 2];
                }
                let h = (wi + wo).normalize_or_zero();
                let (glossy, diffuse) = p.eval_parts(
                    cos_i as f64,
                    cos_o as f64,
                    n.dot(h) as f64,
                    wo.dot(h) as f64,
                );
                [
                    Rgb::new(diffuse[0] as f32, diffuse[1] as f32, diffuse[2] as f32) * albedo,
                    Rgb::new(glossy[0] as f32, glossy[1] as f32, glossy[2] as f32),
                ]
            }
        }
    }
}

//! The basis an editable region is baked in, and a material's coefficients on it: the
//! paper's PCA of Blinn–Phong lobes ([`BrdfBasis`], the default) or a PCA of Cycles'
//! Principled lobes ([`PrincipledBasis`], chosen by the bake settings; opaque, untextured
//! Principled regions only for now).

use std::sync::Arc;

use glam::Vec3;

use super::basis::coefficients::slot_coefficients;
use super::basis::BrdfBasis;
use super::blinn_phong::{self, BlinnPhong};
use super::material::MaterialSpec;
use super::principled_basis::bake_lobe::BakeLobe;
use super::principled_basis::{Cosines, PrincipledBasis, MAX_SLOTS};
use crate::{RelumeError, Result, Rgb};

/// An editable region's basis.
#[derive(Clone)]
pub enum RegionBasis {
    BlinnPhong(Arc<BrdfBasis>),
    /// The Principled basis alone (stacks baked before the bake-time slot).
    Principled(Arc<PrincipledBasis>),
    /// The Principled basis with the region's bake-time lobe as one more slot, last
    /// ([`BakeLobe`]): what a bake in the Principled basis makes. The bake evaluates that
    /// slot exactly (its value is RGB, so [`Self::eval`] leaves it to the caller).
    PrincipledWithBakeLobe(Arc<PrincipledBasis>, Arc<BakeLobe>),
}

/// A material's coefficients on a region's basis, and what it could not be given exactly.
pub struct RegionCoefficients {
    pub slots: Vec<Rgb>,
    /// A Principled material smoother than a Principled basis' range (its metal part is
    /// relit with the range's smoothest lobe); reported, never silent.
    pub below_range: bool,
}

impl RegionBasis {
    /// Basis functions, the diffuse constant included (slots before any textured or
    /// subsurface extras).
    pub fn count(&self) -> usize {
        match self {
            RegionBasis::BlinnPhong(b) => b.count(),
            RegionBasis::Principled(b) => b.count(),
            RegionBasis::PrincipledWithBakeLobe(b, _) => b.count() + 1,
        }
    }

    /// The Principled basis, if this is one (with or without the bake-time slot).
    pub fn principled(&self) -> Option<&Arc<PrincipledBasis>> {
        match self {
            RegionBasis::BlinnPhong(_) => None,
            RegionBasis::Principled(b) | RegionBasis::PrincipledWithBakeLobe(b, _) => Some(b),
        }
    }

    /// The slot of the bake-time lobe, if this basis has one.
    pub fn bake_lobe_slot(&self) -> Option<usize> {
        match self {
            RegionBasis::PrincipledWithBakeLobe(b, _) => Some(b.count()),
            _ => None,
        }
    }

    /// Whether basis 0 carries part of the specular fit (then a textured region keeps that
    /// part in a slot of its own).
    pub fn spec_constant(&self) -> bool {
        match self {
            RegionBasis::BlinnPhong(b) => b.spec_constant(),
            RegionBasis::Principled(_) | RegionBasis::PrincipledWithBakeLobe(..) => true,
        }
    }

    /// The Blinn–Phong basis, if this is one.
    pub fn blinn_phong(&self) -> Option<&Arc<BrdfBasis>> {
        match self {
            RegionBasis::BlinnPhong(b) => Some(b),
            RegionBasis::Principled(_) | RegionBasis::PrincipledWithBakeLobe(..) => None,
        }
    }

    /// Every basis function's value for light from `wi` seen from `wo` at normal `n` (the
    /// bake-time slot, which is RGB, set to 0: see [`RegionBasis::PrincipledWithBakeLobe`]).
    #[inline]
    pub fn eval(&self, n: Vec3, wi: Vec3, wo: Vec3, out: &mut [f32]) {
        let h = (wi + wo).normalize_or_zero();
        match self {
            RegionBasis::BlinnPhong(b) => b.eval(n.dot(h), out),
            RegionBasis::Principled(b) | RegionBasis::PrincipledWithBakeLobe(b, _) => {
                let count = b.count();
                let mut v = [0.0f64; MAX_SLOTS];
                b.eval(
                    Cosines {
                        cos_i: n.dot(wi) as f64,
                        cos_o: n.dot(wo) as f64,
                        cos_h: n.dot(h) as f64,
                        cos_d: wo.dot(h) as f64,
                    },
                    &mut v[..count],
                );
                for (o, x) in out.iter_mut().zip(&v[..count]) {
                    *o = *x as f32;
                }
                if let Some(extra) = out.get_mut(count) {
                    *extra = 0.0;
                }
            }
        }
    }

    /// The coefficient of every BRDF slot for material `m` (a textured region's extra
    /// constant slot included, see [`slot_coefficients`]). A Principled basis takes
    /// Principled materials of untextured regions only (what the bake allows it for); any
    /// other pairing is an error naming the region's basis.
    pub fn slot_coefficients(
        &self,
        textured: bool,
        m: &MaterialSpec,
    ) -> Result<RegionCoefficients> {
        match self {
            RegionBasis::BlinnPhong(b) => Ok(RegionCoefficients {
                slots: slot_coefficients(b, textured, &m.to_blinn_phong()),
                below_range: false,
            }),
            RegionBasis::Principled(_) | RegionBasis::PrincipledWithBakeLobe(..) => {
                if textured {
                    return Err(RelumeError::Materials(
                        "a textured region cannot use the Principled basis".into(),
                    ));
                }
                let (slots, below_range) = match (self, m) {
                    (RegionBasis::PrincipledWithBakeLobe(b, lobe), MaterialSpec::Principled(p)) => {
                        let c = b.anchored_coefficients(lobe, &p.bsdf);
                        (c.slots, c.below_range)
                    }
                    (RegionBasis::Principled(b), MaterialSpec::Principled(p)) => {
                        let c = b.material_coefficients(&p.bsdf);
                        (c.slots, c.below_range)
                    }
                    (
                        RegionBasis::PrincipledWithBakeLobe(b, lobe),
                        MaterialSpec::BlinnPhong(bp),
                    ) => (
                        b.anchored_coefficients_of(lobe, blinn_phong_brdf(bp)),
                        blinn_phong_below_range(b, bp),
                    ),
                    (RegionBasis::Principled(b), MaterialSpec::BlinnPhong(bp)) => (
                        blinn_phong_coefficients(b, bp),
                        blinn_phong_below_range(b, bp),
                    ),
                    (RegionBasis::BlinnPhong(_), _) => unreachable!("matched above"),
                };
                Ok(RegionCoefficients {
                    slots: slots
                        .iter()
                        .map(|s| Rgb::new(s[0] as f32, s[1] as f32, s[2] as f32))
                        .collect(),
                    below_range,
                })
            }
        }
    }

    /// `coefs` (this basis' slot coefficients) with the bake-time slot's weight folded into
    /// the basis slots it projects to: the same material seen through the basis alone, for
    /// what reads energies off the basis slots ([`crate::relight::part_scales`]). Other
    /// bases: `coefs` as they are.
    pub fn fold_bake_lobe(&self, coefs: &[Rgb]) -> Vec<Rgb> {
        let RegionBasis::PrincipledWithBakeLobe(b, lobe) = self else {
            return coefs.to_vec();
        };
        let n = b.count();
        let alpha = coefs.get(n).copied().unwrap_or(Rgb::ZERO);
        let mut out: Vec<Rgb> = coefs.iter().take(n).copied().collect();
        for (k, o) in out.iter_mut().enumerate() {
            let p = lobe.projection(k);
            *o += alpha * Rgb::new(p[0] as f32, p[1] as f32, p[2] as f32);
        }
        out.extend(coefs.iter().skip(n + 1).copied());
        out
    }
}

/// A material given as Blinn–Phong values (`Kd/π + Ks·f_s(δ)`, Relume's normalisation) as a
/// function of the four cosines: a region baked in the Principled basis projects it like
/// any other lobe (the add-on's per-material Kd / Ks / ns override, a materials file's
/// Blinn–Phong entry).
fn blinn_phong_brdf(m: &BlinnPhong) -> impl Fn(Cosines) -> [f64; 3] + Sync {
    let (kd, ks, ns) = (m.kd, m.ks, m.ns as f64);
    move |c: Cosines| {
        if !(c.cos_i > 0.0 && c.cos_o > 0.0) {
            return [0.0; 3];
        }
        let s = blinn_phong::lobe(ns, c.cos_h);
        std::array::from_fn(|ch| kd[ch] as f64 * std::f64::consts::FRAC_1_PI + ks[ch] as f64 * s)
    }
}

/// The plain projection of Blinn–Phong values on a Principled basis: the specular lobe once
/// (its shape is the same in every channel), scaled by `Ks`; `Kd` on the constant slot.
fn blinn_phong_coefficients(b: &PrincipledBasis, m: &BlinnPhong) -> Vec<[f64; 3]> {
    let ns = m.ns as f64;
    let lobe = b.project_many(1, |c, out: &mut [f64]| {
        out[0] = blinn_phong::lobe(ns, c.cos_h);
    });
    lobe.iter()
        .enumerate()
        .map(|(k, s)| {
            std::array::from_fn(|ch| {
                let diffuse = if k == 0 { m.kd[ch] as f64 } else { 0.0 };
                diffuse + m.ks[ch] as f64 * s
            })
        })
        .collect()
}

/// Whether a Blinn–Phong lobe is narrower than the basis' smoothest roughness (by the
/// fitted mapping's exponent there): relit, and warned of, as the range allows.
fn blinn_phong_below_range(b: &PrincipledBasis, m: &BlinnPhong) -> bool {
    m.ns > b.config().fitted_ns_range().1
}

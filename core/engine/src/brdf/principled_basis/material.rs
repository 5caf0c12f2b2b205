//! A Principled material's coefficients on the basis: what a relight weighs an editable
//! region's layers by.
//!
//! The material is Cycles' Principled BSDF as [`CyclesPrincipled`] evaluates it, which is
//! linear in Metallic: `m·metal + (1 − m)·(dielectric specular + base colour·diffuse base)`.
//! The metal part comes from the curves in roughness (per channel, F0 = base colour); the
//! dielectric specular and the diffuse base (whose weight `1 − albedo(μo)` depends on the
//! view) are projected onto the basis for the material's roughness, IOR and Specular IOR
//! Level, so whatever of them the basis cannot hold is the projection's error, not a
//! mapping's.

use super::lobes::Cosines;
use super::PrincipledBasis;
use crate::brdf::cycles_principled::CyclesPrincipled;
use crate::brdf::Principled;

/// Per-slot RGB coefficients of a Principled material, and whether its roughness lay below
/// the basis' range (the metal part then uses the range's smoothest lobe; the specular
/// projections are exact but the basis holds such a lobe poorly).
pub struct MaterialCoefficients {
    pub slots: Vec<[f64; 3]>,
    pub below_range: bool,
}

impl PrincipledBasis {
    /// The coefficients of `p` on this basis (module docs).
    pub fn material_coefficients(&self, p: &Principled) -> MaterialCoefficients {
        let r = (p.roughness as f64).clamp(0.0, 1.0);
        let below_range = r < self.config().roughness_min - 1e-9;
        let m = (p.metallic as f64).clamp(0.0, 1.0);
        let base = p.base_color.map(|b| (b as f64).max(0.0));
        let n = self.count();
        let mut slots = vec![[0.0f64; 3]; n];
        if m > 0.0 {
            let (metal, _) = self.metal_coefficients(base, r);
            for (s, c) in slots.iter_mut().zip(&metal) {
                for ch in 0..3 {
                    s[ch] += m * c[ch];
                }
            }
        }
        if m < 1.0 {
            let dielectric = CyclesPrincipled::new(&Principled {
                base_color: [1.0; 3],
                metallic: 0.0,
                ..*p
            });
            let parts = self.project_many(2, |c: Cosines, out: &mut [f64]| {
                let (glossy, diffuse) = dielectric.eval_parts(c.cos_i, c.cos_o, c.cos_h, c.cos_d);
                out[0] = glossy[0];
                out[1] = diffuse[0];
            });
            let (spec, diffuse) = parts.split_at(n);
            for (k, s) in slots.iter_mut().enumerate() {
                for ch in 0..3 {
                    s[ch] += (1.0 - m) * (spec[k] + base[ch] * diffuse[k]);
                }
            }
        }
        MaterialCoefficients { slots, below_range }
    }
}

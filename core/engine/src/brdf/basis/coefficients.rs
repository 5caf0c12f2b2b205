//! A material's coefficients on a basis: per basis, with basis 0 split into its diffuse and
//! specular parts, and per slot of an editable region (where a textured region keeps the
//! specular part of basis 0 in a slot of its own).

use glam::Vec3;

use super::BrdfBasis;
use crate::brdf::blinn_phong::BlinnPhong;
use crate::Rgb;

impl BrdfBasis {
    /// Per-basis RGB coefficients of a material: `[Kd + Ks·c₀(ns), Ks·c̃_1(ns), …,
    /// Ks·c̃_{N_b−1}(ns)]`, length [`Self::count`] (`c₀ = 0` unless [`Self::spec_constant`]).
    pub fn material_coefficients(&self, m: &BlinnPhong) -> Vec<Vec3> {
        let (kd, ks0, spec) = self.split_coefficients(m);
        let mut out = Vec::with_capacity(self.count);
        out.push(kd + ks0);
        out.extend(spec);
        out
    }

    /// The coefficients of [`Self::material_coefficients`] with basis 0 split into its diffuse
    /// and specular parts: `(Kd, Ks·c₀(ns), [Ks·c̃_1(ns), …, Ks·c̃_{N_b−1}(ns)])`, the last of
    /// length `count() − 1`. `Ks·c₀` is zero unless [`Self::spec_constant`]; a textured region
    /// multiplies only `Kd` by its albedo.
    pub fn split_coefficients(&self, m: &BlinnPhong) -> (Vec3, Vec3, Vec<Vec3>) {
        let mut c = vec![0.0f32; self.count];
        self.spec_coefficients(m.ns, &mut c);
        let ks = Vec3::from(m.ks);
        (
            Vec3::from(m.kd),
            ks * c[0],
            c[1..].iter().map(|&x| ks * x).collect(),
        )
    }
}

/// The coefficient of every slot of an editable region for material `m`: the basis
/// coefficients, except that a textured region (with the diffuse basis in the specular fit)
/// has [Kd (textured diffuse layer), Ks·c̃₁, …, Ks·c₀ (untextured constant layer)].
pub fn slot_coefficients(basis: &BrdfBasis, textured: bool, m: &BlinnPhong) -> Vec<Rgb> {
    if textured && basis.spec_constant() {
        let (kd, ks_c0, mut rest) = basis.split_coefficients(m);
        rest.insert(0, kd);
        rest.push(ks_c0);
        rest
    } else {
        basis.material_coefficients(m)
    }
}

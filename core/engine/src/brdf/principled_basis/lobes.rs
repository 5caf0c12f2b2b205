//! The training lobes: Cycles' Principled specular reflection (GGX, height-correlated Smith
//! shadowing, Fresnel, Kulla–Conty multiple scattering, as [`crate::brdf::cycles_principled`]
//! evaluates it) at a set of roughness values, for metals at several F0 and dielectrics at
//! several IORs. A basis trained on them represents every lobe of the family between them.

use std::f64::consts::PI;

use crate::brdf::cycles_principled::ggx::{
    fresnel_dielectric, fresnel_dielectric_average, fresnel_schlick_average, ggx_single,
    multiscatter_fresnel,
};
use crate::brdf::cycles_principled::{single_scatter_albedo, MuTable};

/// The four cosines an isotropic BRDF needs: light `cos θi`, view `cos θo`, half vector
/// `cos θh` (from the normal) and `cos θd = ωi·h = ωo·h`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cosines {
    pub cos_i: f64,
    pub cos_o: f64,
    pub cos_h: f64,
    pub cos_d: f64,
}

/// One family of specular lobes over roughness: which Fresnel it has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Family {
    /// A conductor with Schlick's Fresnel from `F0` (Cycles' F82-tint model at white tint).
    Metal { f0: f64 },
    /// A dielectric with the exact Fresnel of `ior` (Specular IOR Level 0.5).
    Dielectric { ior: f64 },
}

impl Family {
    fn fresnel(&self, cos_d: f64) -> f64 {
        match *self {
            Family::Metal { f0 } => {
                let w = (1.0 - cos_d).clamp(0.0, 1.0).powi(5);
                f0 * (1.0 - w) + w
            }
            Family::Dielectric { ior } => fresnel_dielectric(cos_d, ior),
        }
    }

    /// Kulla–Conty's `Fms` for a GGX lobe whose cosine-weighted albedo is `e_avg`.
    pub fn multiscatter(&self, e_avg: f64) -> f64 {
        let f_avg = match *self {
            Family::Metal { f0 } => fresnel_schlick_average(f0),
            Family::Dielectric { ior } => fresnel_dielectric_average(ior),
        };
        multiscatter_fresnel(f_avg, e_avg)
    }
}

/// One roughness value with what every lobe at it shares: α and the albedo table `E(μo)`.
#[derive(Clone, Debug)]
pub(crate) struct Roughness {
    pub alpha: f64,
    pub energy: MuTable,
    pub e_avg: f64,
}

impl Roughness {
    pub(crate) fn new(roughness: f64) -> Roughness {
        let alpha = roughness * roughness;
        let energy = single_scatter_albedo(alpha);
        let e_avg = energy.cosine_mean();
        Roughness {
            alpha,
            energy,
            e_avg,
        }
    }

    /// The lobe of `family` at this roughness (no cosine factor; 0 below either horizon).
    pub(crate) fn lobe(&self, family: &Family, c: Cosines) -> f64 {
        let single = self.single(c);
        if single == 0.0 {
            return 0.0;
        }
        single * family.fresnel(c.cos_d) * (1.0 + family.multiscatter(self.e_avg) * self.miss(c))
    }

    /// The single-scattering lobe with Fresnel 1, and [`Self::miss`] (0 where the lobe is).
    pub(crate) fn single_and_miss(&self, c: Cosines) -> (f64, f64) {
        let single = self.single(c);
        if single == 0.0 {
            (0.0, 0.0)
        } else {
            (single, self.miss(c))
        }
    }

    fn single(&self, c: Cosines) -> f64 {
        if !(c.cos_i > 0.0) || !(c.cos_o > 0.0) {
            return 0.0;
        }
        ggx_single(self.alpha, c.cos_i, c.cos_o, c.cos_h)
    }

    /// `(1 − E(μo))/E(μo)`: the energy single scattering misses, relative to what it keeps.
    fn miss(&self, c: Cosines) -> f64 {
        let e = self.energy.at(c.cos_o);
        (1.0 - e) / e
    }
}

/// Roughness values uniform in `ln r` over `[r_min, 1]`: the lobe shape changes with the
/// relative change of roughness, as a Blinn–Phong lobe's does with that of ns.
pub(crate) fn roughness_nodes(r_min: f64, count: usize) -> Vec<f64> {
    let (lo, hi) = (r_min.ln(), 0.0f64);
    (0..count)
        .map(|i| {
            let t = if count > 1 {
                i as f64 / (count - 1) as f64
            } else {
                0.0
            };
            (lo + (hi - lo) * t).exp()
        })
        .collect()
}

/// The training set: every family at every roughness, column `a·families + b` for roughness
/// `a` and family `b`.
#[derive(Clone, Debug)]
pub(crate) struct LobeSet {
    pub roughness: Vec<Roughness>,
    pub families: Vec<Family>,
    /// `Fms` of every column (it depends on the roughness' `Eavg` and the family alone, so it
    /// is computed once, not at every node the Gram matrix and the tables visit).
    multiscatter: Vec<f64>,
}

/// Most training families [`LobeSet::eval`] holds per-node Fresnel values for.
const MAX_FAMILIES: usize = 16;

impl LobeSet {
    pub(crate) fn new(roughness: &[f64], families: &[Family]) -> LobeSet {
        use rayon::prelude::*;
        assert!(
            families.len() <= MAX_FAMILIES,
            "at most {MAX_FAMILIES} families"
        );
        let roughness: Vec<Roughness> = roughness.par_iter().map(|&r| Roughness::new(r)).collect();
        let multiscatter = roughness
            .iter()
            .flat_map(|r| families.iter().map(|f| f.multiscatter(r.e_avg)))
            .collect();
        LobeSet {
            roughness,
            families: families.to_vec(),
            multiscatter,
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.roughness.len() * self.families.len()
    }

    /// Every lobe at `c`, into `out` (`len()` values). The Fresnel factor depends on the
    /// family and `cos θd` alone, so it is evaluated once per family, not per roughness.
    pub(crate) fn eval(&self, c: Cosines, out: &mut [f64]) {
        let nf = self.families.len();
        let mut fresnel = [0.0f64; MAX_FAMILIES];
        for (f, family) in fresnel.iter_mut().zip(&self.families) {
            *f = family.fresnel(c.cos_d);
        }
        for (a, r) in self.roughness.iter().enumerate() {
            let single = r.single(c);
            let row = &mut out[a * nf..(a + 1) * nf];
            if single == 0.0 {
                row.fill(0.0);
                continue;
            }
            let miss = r.miss(c);
            let fms = &self.multiscatter[a * nf..(a + 1) * nf];
            for ((o, f), m) in row.iter_mut().zip(&fresnel).zip(fms) {
                *o = single * f * (1.0 + m * miss);
            }
        }
    }
}

/// The default training families: metals at F0 0, ¼, ½, ¾, 1 (a metal lobe is exactly a
/// combination of four functions per roughness, which five F0 values span) and dielectrics
/// at IOR 1.33, 1.5 and 1.8 (one IOR's basis does not cover the others; three together do).
pub fn default_families() -> Vec<Family> {
    let mut f: Vec<Family> = [0.0, 0.25, 0.5, 0.75, 1.0]
        .iter()
        .map(|&f0| Family::Metal { f0 })
        .collect();
    f.extend(
        [1.5, 1.33, 1.8]
            .iter()
            .map(|&ior| Family::Dielectric { ior }),
    );
    f
}

/// `1/π`: the value of the constant basis (the diffuse slot), as in the Blinn–Phong basis.
pub const DIFFUSE: f64 = 1.0 / PI;

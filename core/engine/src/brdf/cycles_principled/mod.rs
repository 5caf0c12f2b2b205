//! Cycles' Principled BSDF reflection (Blender 4.x/5.x), evaluated in Rust as the reference
//! the Blinn–Phong fit is measured against (docs/principled_fit.md). Not used to render.
//!
//! What it evaluates, from Cycles' `svm/closure.h` (Principled), `closure/bsdf_microfacet.h`
//! and `closure/bsdf_util.h` (facts and formulas, no code carried over):
//!
//! * **Metallic layer** (weight `metallic`): GGX reflection, `α = roughness²`, Fresnel the
//!   F82-tint model with `F0 = base colour`, which at the default white Specular Tint is
//!   Schlick's.
//! * **Dielectric layer** (weight `1 − metallic`): GGX reflection with the exact dielectric
//!   Fresnel of an IOR that Specular IOR Level rescales (`F0 = F0(ior)·2·level`, the IOR
//!   recomputed from that F0), over a Lambertian base `base colour/π` (Diffuse Roughness 0)
//!   whose weight is `1 − (the specular layer's estimated albedo for the view direction)`.
//! * **Multiple scattering**: each GGX lobe is scaled by `1 + Fms·(1 − E)/E` with `E(μo)`
//!   the single-scattering albedo of GGX with Fresnel 1 at the view direction, `Eavg` its
//!   cosine-weighted mean, `Fms = Favg·Eavg/(1 − Favg(1 − Eavg))` (Kulla & Conty).
//!
//! Approximations against Cycles, stated: `E`, `Eavg` and the layer's Fresnel factor come
//! from this crate's quadrature instead of Cycles' Monte Carlo lookup tables (which are
//! interpolated on 32² and 16³ grids); the Fresnel factor of the layer's albedo is averaged
//! with the single-scattering lobe as weight rather than over visible normals; roughness is
//! clamped to [`ROUGHNESS_MIN`] (Cycles turns α ≤ 10⁻⁴ into a perfect mirror, which a
//! quadrature cannot integrate); Specular Tint is white, Diffuse Roughness 0, no coat,
//! sheen, transmission, thin film or anisotropy. Like Cycles' own Principled BSDF, the
//! energy compensation and the diffuse layer's weight depend on the view direction only,
//! so the whole BSDF is **not** reciprocal; its GGX lobe with Fresnel is.

pub mod ggx;
pub mod quadrature;

use std::f64::consts::PI;

use ggx::*;
use quadrature::{incident_nodes, Resolution};

use super::principled::Principled;

/// The smallest roughness the reference model evaluates (α = 0.0025); smaller is clamped.
pub const ROUGHNESS_MIN: f64 = 0.05;

/// Values of a function of `cos θo` on a uniform grid, interpolated linearly.
#[derive(Clone, Debug)]
pub(crate) struct MuTable(Vec<f64>);

const MU_NODES: usize = 48;

impl MuTable {
    fn build(f: impl FnMut(f64) -> f64) -> MuTable {
        MuTable((0..MU_NODES).map(mu_node).map(f).collect())
    }
    pub(crate) fn at(&self, mu: f64) -> f64 {
        let x = (mu.clamp(0.0, 1.0) * MU_NODES as f64 - 0.5).clamp(0.0, (MU_NODES - 1) as f64);
        let i = (x.floor() as usize).min(MU_NODES - 2);
        let t = x - i as f64;
        self.0[i] * (1.0 - t) + self.0[i + 1] * t
    }
    /// `∫ 2μ f(μ) dμ` by the midpoint rule on the nodes.
    pub(crate) fn cosine_mean(&self) -> f64 {
        self.0
            .iter()
            .enumerate()
            .map(|(k, v)| 2.0 * mu_node(k) * v / MU_NODES as f64)
            .sum()
    }
}

fn mu_node(k: usize) -> f64 {
    (k as f64 + 0.5) / MU_NODES as f64
}

/// `E(μo)`: the single-scattering albedo of GGX at `alpha` with Fresnel 1, per view cosine;
/// its [`MuTable::cosine_mean`] is `Eavg`. The multiple-scattering factor of every
/// Principled lobe is built from these two.
pub(crate) fn single_scatter_albedo(alpha: f64) -> MuTable {
    MuTable::build(|mu| {
        let mut e = 0.0;
        incident_nodes(mu, alpha, Resolution::FINE, |n| {
            e += ggx_single(alpha, n.cos_i, mu, n.cos_h) * n.cos_i * n.d_omega_i;
        });
        e.clamp(1e-6, 1.0)
    })
}

/// The view-dependent tables of a Principled material, which depend on its roughness and
/// IOR only: `E(μo)` ([`single_scatter_albedo`]) and the dielectric Fresnel's lobe-averaged
/// interpolation factor per `μo`. About 10⁶ BRDF evaluations, most of what building a
/// material costs, so they are kept for the last few (α, η) pairs: a slider that moves a
/// material's colour or metallic (the relight rebuilds the material at every step) builds
/// them once. The same numbers either way.
fn view_tables(alpha: f64, eta: f64) -> (MuTable, MuTable) {
    type Entry = ((u64, u64), MuTable, MuTable);
    /// Pairs kept: a few materials edited in turn, each at its own roughness and IOR.
    const KEPT: usize = 16;
    static TABLES: std::sync::Mutex<Vec<Entry>> = std::sync::Mutex::new(Vec::new());
    let key = (alpha.to_bits(), eta.to_bits());
    {
        let tables = TABLES.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, energy, layer_s)) = tables.iter().find(|(k, _, _)| *k == key) {
            return (energy.clone(), layer_s.clone());
        }
    }
    // Built outside the lock: two threads racing on one pair build it twice, which is
    // correct, rather than one holding every other material's build up.
    let energy = single_scatter_albedo(alpha);
    let f0_real = f0_from_ior(eta);
    let layer_s = MuTable::build(|mu| {
        let (mut num, mut den) = (0.0, 0.0);
        incident_nodes(mu, alpha, Resolution::FINE, |n| {
            let w = ggx_single(alpha, n.cos_i, mu, n.cos_h) * n.cos_i * n.d_omega_i;
            let f = fresnel_dielectric(n.cos_d, eta);
            num += w * ((f - f0_real) / (1.0 - f0_real).max(1e-12)).clamp(0.0, 1.0);
            den += w;
        });
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    });
    let mut tables = TABLES.lock().unwrap_or_else(|e| e.into_inner());
    if tables.len() >= KEPT {
        tables.remove(0);
    }
    tables.push((key, energy.clone(), layer_s.clone()));
    (energy, layer_s)
}

/// Cycles' Principled reflection for one set of inputs, ready to evaluate.
#[derive(Clone, Debug)]
pub struct CyclesPrincipled {
    base: [f64; 3],
    metallic: f64,
    alpha: f64,
    /// Dielectric specular: its F0 (after Specular IOR Level) and the IOR Cycles derives.
    spec_f0: f64,
    eta: f64,
    /// `E(μo)`: single-scattering GGX albedo with Fresnel 1.
    energy: MuTable,
    fms_metal: [f64; 3],
    fms_dielectric: f64,
    /// The dielectric Fresnel's interpolation factor between F0 and 1, lobe-averaged, per μo.
    layer_s: MuTable,
}

/// Dielectric specular F0 and IOR as Cycles' Principled derives them; IOR below 1 is mirrored
/// to `1/ior` (the same F0) and NaN inputs take Blender's defaults.
fn dielectric_spec(ior: f32, level: f32) -> (f64, f64) {
    let mut eta = if ior.is_nan() || !(ior > 0.0) {
        1.5
    } else {
        ior as f64
    };
    if eta < 1.0 {
        eta = 1.0 / eta;
    }
    let level = if level.is_nan() {
        0.5
    } else {
        (level as f64).max(0.0)
    };
    let mut f0 = if eta.is_finite() {
        f0_from_ior(eta)
    } else {
        1.0
    };
    if level != 0.5 {
        f0 *= 2.0 * level;
        eta = ior_from_f0(f0);
    }
    (f0.min(1.0), eta.min(1e6))
}

fn finite_or(x: f32, default: f32, lo: f32, hi: f32) -> f64 {
    (if x.is_nan() { default } else { x.clamp(lo, hi) }) as f64
}

impl CyclesPrincipled {
    /// Precomputes the view-dependent tables for `p` (about 10⁶ BRDF evaluations, kept for
    /// the last few roughness and IOR pairs: [`view_tables`]).
    pub fn new(p: &Principled) -> CyclesPrincipled {
        let r = finite_or(p.roughness, 0.5, 0.0, 1.0).max(ROUGHNESS_MIN);
        let alpha = r * r;
        let base = p.base_color.map(|b| finite_or(b, 0.8, 0.0, 1.0));
        let metallic = finite_or(p.metallic, 0.0, 0.0, 1.0);
        let (spec_f0, eta) = dielectric_spec(p.ior, p.specular_ior_level);
        let (energy, layer_s) = view_tables(alpha, eta);
        let e_avg = energy.cosine_mean();
        CyclesPrincipled {
            base,
            metallic,
            alpha,
            spec_f0,
            eta,
            energy,
            fms_metal: base.map(|b| multiscatter_fresnel(fresnel_schlick_average(b), e_avg)),
            fms_dielectric: multiscatter_fresnel(fresnel_dielectric_average(eta), e_avg),
            layer_s,
        }
    }

    /// GGX α (= roughness², roughness clamped to [`ROUGHNESS_MIN`]).
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    fn has_dielectric_spec(&self) -> bool {
        self.eta != 1.0 && self.spec_f0 > 0.0
    }

    /// The dielectric Fresnel as Cycles' Principled applies it (its generalised Schlick with
    /// the real Fresnel curve mapping F0 to 1).
    fn dielectric_fresnel(&self, cos_d: f64) -> f64 {
        let f0_real = f0_from_ior(self.eta);
        let s = ((fresnel_dielectric(cos_d, self.eta) - f0_real) / (1.0 - f0_real).max(1e-12))
            .clamp(0.0, 1.0);
        self.spec_f0 + (1.0 - self.spec_f0) * s
    }

    /// The weight of the diffuse base for view `cos θo`: `1 − ` the specular layer's albedo.
    pub fn diffuse_weight(&self, cos_o: f64) -> f64 {
        if !self.has_dielectric_spec() {
            return 1.0;
        }
        let e = self.energy.at(cos_o);
        let miss = (1.0 - e) / e;
        let darkening = (1.0 + self.fms_dielectric * miss) / (1.0 + miss);
        let albedo = darkening * (self.spec_f0 + (1.0 - self.spec_f0) * self.layer_s.at(cos_o));
        (1.0 - albedo).clamp(0.0, 1.0)
    }

    /// BRDF value (no cosine factor) per RGB channel for light from `cos θi`, view `cos θo`,
    /// half vector at `cos θh` from the normal and `cos θd = ωo·h`. Zero below the surface.
    pub fn eval_cosines(&self, cos_i: f64, cos_o: f64, cos_h: f64, cos_d: f64) -> [f64; 3] {
        let (glossy, diffuse) = self.eval_parts(cos_i, cos_o, cos_h, cos_d);
        std::array::from_fn(|c| glossy[c] + diffuse[c])
    }

    /// [`Self::eval_cosines`] as two parts whose sum it is: the GGX layers (metal and
    /// dielectric specular), and the diffuse base (`base colour/π` times its view-dependent
    /// weight and `1 − metallic`), kept apart so that an albedo texture can scale the diffuse
    /// base alone, as it scales a Blinn–Phong `Kd`.
    pub fn eval_parts(
        &self,
        cos_i: f64,
        cos_o: f64,
        cos_h: f64,
        cos_d: f64,
    ) -> ([f64; 3], [f64; 3]) {
        if !(cos_i > 0.0) || !(cos_o > 0.0) {
            return ([0.0; 3], [0.0; 3]);
        }
        let single = ggx_single(self.alpha, cos_i, cos_o, cos_h);
        let e = self.energy.at(cos_o);
        let miss = (1.0 - e) / e;
        let m = self.metallic;
        let diel_spec = if self.has_dielectric_spec() {
            single * self.dielectric_fresnel(cos_d) * (1.0 + self.fms_dielectric * miss)
        } else {
            0.0
        };
        let diffuse_w = (1.0 - m) * self.diffuse_weight(cos_o) / PI;
        let glossy = std::array::from_fn(|c| {
            let metal =
                single * fresnel_schlick(cos_d, self.base[c]) * (1.0 + self.fms_metal[c] * miss);
            m * metal + (1.0 - m) * diel_spec
        });
        (glossy, self.base.map(|b| b * diffuse_w))
    }

    /// Directional albedo `∫ f cos θi dωi` per channel at view `cos θo`.
    pub fn directional_albedo(&self, cos_o: f64) -> [f64; 3] {
        let mut acc = [0.0; 3];
        incident_nodes(cos_o, self.alpha, Resolution::FINE, |n| {
            let f = self.eval_cosines(n.cos_i, cos_o, n.cos_h, n.cos_d);
            for c in 0..3 {
                acc[c] += f[c] * n.cos_i * n.d_omega_i;
            }
        });
        acc
    }
}

#[cfg(test)]
mod tests;

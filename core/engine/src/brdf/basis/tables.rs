//! The tables a basis is evaluated from at bake time (module docs, "1D table instead of
//! trilinear 3D interpolation" and "Coefficients"): each specular basis tabulated in a
//! warped half angle, and the coefficients of a lobe tabulated in `ln ns`, both filled from
//! the exact PCA bases.

use std::f64::consts::PI;

use super::measure::Atoms;
use super::pca::Pca;
use crate::brdf::blinn_phong::lobe;

/// Nodes of each basis table (in the warped `v`, see the module docs).
pub(super) const TABLE_NODES: usize = 2048;
/// Nodes of the coefficient table (uniform in `ln ns`).
pub(super) const COEF_NODES: usize = 512;

/// `k` of the table warp `v = u(1+k)/(u+k)`: `√u_h`, `u_h = √(1 − cos δ_h)` at ns_max.
pub(super) fn warp_k(ns_max: f64) -> f32 {
    let uh = (1.0 - 0.5f64.powf(1.0 / ns_max)).sqrt();
    uh.sqrt().clamp(1e-3, 1.0) as f32
}

fn cos_delta_of_v(v: f64, k: f64) -> f64 {
    let u = (k * v / (1.0 + k - v)).min(1.0);
    1.0 - u * u
}

/// `TABLE_NODES × nspec`, node-major: the first `nspec` bases of `pca` over the lobes `ns`,
/// `ρ̃_k(δ) = Σ_j B_jk f_j(δ) − off_k` at the nodes of the warp `warp_k`.
pub(super) fn basis_table(ns: &[f64], pca: &Pca, nspec: usize, warp_k: f32) -> Vec<f32> {
    let (l, kmax) = (ns.len(), pca.k);
    let mut table = vec![0.0f32; TABLE_NODES * nspec];
    if nspec > 0 {
        let mut fv = vec![0.0; l];
        for node in 0..TABLE_NODES {
            let v = node as f64 / (TABLE_NODES - 1) as f64;
            let cd = cos_delta_of_v(v, warp_k as f64);
            for (j, f) in fv.iter_mut().enumerate() {
                *f = lobe(ns[j], cd);
            }
            for k in 0..nspec {
                let mut s = -pca.off[k];
                for (j, &f) in fv.iter().enumerate() {
                    s += pca.bmat[j * kmax + k] * f;
                }
                table[node * nspec + k] = s as f32;
            }
        }
    }
    table
}

/// `atoms × nspec`: the first `nspec` bases of `pca` at the atoms where the `l` lobes take
/// the values `f` (sample-major), for exact projections.
pub(super) fn bases_at_atoms(f: &[f64], l: usize, pca: &Pca, nspec: usize) -> Vec<f64> {
    let kmax = pca.k;
    let na = f.len() / l;
    let mut bat = vec![0.0; na * nspec];
    for q in 0..na {
        for k in 0..nspec {
            let mut s = -pca.off[k];
            for j in 0..l {
                s += f[q * l + j] * pca.bmat[j * kmax + k];
            }
            bat[q * nspec + k] = s;
        }
    }
    bat
}

/// `COEF_NODES × count`, node-major: the exact coefficients ([`project`]) of the lobes at
/// nodes uniform in `ln ns` over `[ln_ns_min, ln_ns_max]`.
pub(super) fn coefficient_table(
    ln_ns: [f64; 2],
    atoms: &Atoms,
    bat: &[f64],
    constant: bool,
    count: usize,
) -> Vec<f32> {
    let [ln_ns_min, ln_ns_max] = ln_ns;
    let mut coef = vec![0.0f32; COEF_NODES * count];
    let mut tmp = vec![0.0; count];
    for node in 0..COEF_NODES {
        let t = node as f64 / (COEF_NODES - 1) as f64;
        let nsv = (ln_ns_min + t * (ln_ns_max - ln_ns_min)).exp();
        project(atoms, bat, constant, nsv, &mut tmp);
        for k in 0..count {
            coef[node * count + k] = tmp[k] as f32;
        }
    }
    coef
}

/// Exact coefficients of the lobe `f_ns` under the measure `atoms`: `out[0] = c₀ = π·⟨f_ns, 1⟩`
/// with the constant in the fit (0 otherwise), `out[1 + k] = ⟨f_ns, ρ̃_k⟩ = Σ_q w_q f_ns(x_q)
/// ρ̃_k(x_q)` (`bat` = the `out.len() − 1` bases at the atoms).
pub(super) fn project(atoms: &Atoms, bat: &[f64], constant: bool, ns: f64, out: &mut [f64]) {
    out.fill(0.0);
    let nspec = out.len() - 1;
    let norm = (ns + 2.0) / (8.0 * PI);
    let mut mean = 0.0;
    for (q, (&x, &w)) in atoms.x.iter().zip(&atoms.w).enumerate() {
        let f = w * norm * (ns * x).exp();
        if f == 0.0 {
            continue;
        }
        mean += f;
        for k in 0..nspec {
            out[1 + k] += f * bat[q * nspec + k];
        }
    }
    if constant {
        out[0] = PI * mean;
    }
}

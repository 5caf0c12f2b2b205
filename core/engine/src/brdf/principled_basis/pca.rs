//! The PCA of the training lobes under the quadrature's measure, done on their Gram matrix
//! so that every basis is an exact linear combination of lobes (and can be evaluated at any
//! direction pair, not only at the nodes).
//!
//! As in the Blinn–Phong basis ([`crate::brdf::basis`], "Constant in the fit"): no mean
//! subtraction, the constant takes its own slot and the PCA runs on the lobes' residuals
//! from it, lobes are normalised to unit norm, and each lobe's relative error is capped by
//! Lawson reweighting (the cap at each round's RMS error; the round with the lowest maximum
//! is kept), which trades a little average error for a much lower worst lobe.

use rayon::prelude::*;

use super::lobes::LobeSet;
use super::quadrature::Node;
use crate::linalg::{GramAccumulator, LowRankGram};

/// Nodes per parallel Gram accumulator (each holds an `l×l` matrix).
const NODES_PER_TASK: usize = 8192;
/// Lawson rounds of the capped weighting.
const LAWSON_ROUNDS: usize = 40;

/// The training lobes' statistics under the measure: Gram of the unit-normalised lobes,
/// their norms and their means.
pub(crate) struct LobeGram {
    pub l: usize,
    /// `⟨f̂_i, f̂_j⟩` of the unit-normalised lobes, row-major.
    pub gram: Vec<f64>,
    pub norm: Vec<f64>,
    /// `⟨f̂_j, 1⟩`.
    pub mean: Vec<f64>,
}

impl LobeGram {
    pub(crate) fn new(lobes: &LobeSet, nodes: &[Node]) -> LobeGram {
        let l = lobes.len();
        // Chunks summed in order: the Gram matrix does not depend on the thread count.
        let partial: Vec<(Vec<f64>, Vec<f64>)> = nodes
            .par_chunks(NODES_PER_TASK)
            .map(|chunk| {
                let mut acc = GramAccumulator::new(l);
                let mut sum = vec![0.0; l];
                let mut f = vec![0.0; l];
                for n in chunk {
                    lobes.eval(n.c, &mut f);
                    acc.add(n.weight, &f);
                    for (s, v) in sum.iter_mut().zip(&f) {
                        *s += n.weight * v;
                    }
                }
                (acc.finish(), sum)
            })
            .collect();
        let (mut gram, mut sum) = (vec![0.0; l * l], vec![0.0; l]);
        for (g2, s2) in partial {
            gram.iter_mut().zip(&g2).for_each(|(a, b)| *a += b);
            sum.iter_mut().zip(&s2).for_each(|(a, b)| *a += b);
        }
        let norm: Vec<f64> = (0..l).map(|j| gram[j * l + j].max(1e-300).sqrt()).collect();
        let mut g = gram;
        for i in 0..l {
            for j in 0..l {
                g[i * l + j] /= norm[i] * norm[j];
            }
        }
        let mean = sum.iter().zip(&norm).map(|(s, n)| s / n).collect();
        LobeGram {
            l,
            gram: g,
            norm,
            mean,
        }
    }

    /// `⟨r_i, r_j⟩` of the residuals `r_j = f̂_j − ⟨f̂_j, 1⟩` (the constant has unit norm).
    pub(crate) fn residual(&self) -> Vec<f64> {
        let l = self.l;
        let mut r = self.gram.clone();
        for i in 0..l {
            for j in 0..l {
                r[i * l + j] -= self.mean[i] * self.mean[j];
            }
        }
        r
    }
}

/// The specular bases as combinations of residuals: `φ_k = Σ_j coef[j·nspec + k]·r_j`,
/// orthonormal under the measure and orthogonal to the constant; with each training lobe's
/// relative error when fitted by the constant and the `nspec` bases.
pub(crate) struct Pca {
    pub nspec: usize,
    pub coef: Vec<f64>,
    pub errors: Vec<f64>,
}

/// The capped PCA of `g`'s residuals with `nspec` specular bases.
pub(crate) fn capped_pca(g: &LobeGram, nspec: usize) -> Pca {
    let residual = g.residual();
    let factor = LowRankGram::new(&residual, g.l);
    let l = g.l;
    let mut omega = vec![1.0; l];
    let mut best: Option<(f64, Pca)> = None;
    for _ in 0..LAWSON_ROUNDS {
        let scale: Vec<f64> = omega.iter().map(|w: &f64| w.sqrt()).collect();
        let pca = weighted_pca(&factor, &residual, l, &scale, nspec);
        let max = pca.errors.iter().cloned().fold(0.0, f64::max);
        let rms = (pca.errors.iter().map(|e| e * e).sum::<f64>() / l as f64).sqrt();
        for (w, e) in omega.iter_mut().zip(&pca.errors) {
            if *e > rms {
                *w *= (e / rms) * (e / rms);
            }
        }
        if best.as_ref().is_none_or(|(m, _)| max < *m) {
            best = Some((max, pca));
        }
        if !(rms > 0.0) {
            break;
        }
        let top = omega.iter().cloned().fold(0.0, f64::max);
        omega.iter_mut().for_each(|w| *w /= top);
    }
    best.expect("at least one round").1
}

/// The PCA of the residuals with lobe `j` weighted by `scale[j]²`: eigenvectors of
/// `D R D` through the factor `R ≈ L Lᵀ`, then mapped back so that the bases are
/// combinations of the unweighted residuals.
fn weighted_pca(
    factor: &LowRankGram,
    residual: &[f64],
    l: usize,
    scale: &[f64],
    nspec: usize,
) -> Pca {
    let cols = factor.factor();
    let rank = cols.len();
    let nspec = nspec.min(rank);
    let (lam, y) = factor.reduced_eigen(Some(scale));
    // coef = D² L y / λ: φ_k = Σ_j coef_jk r_j has unit norm (λ = ‖D L y‖²).
    let mut coef = vec![0.0; l * nspec];
    for k in 0..nspec {
        let inv = 1.0 / lam[k].max(1e-300);
        for j in 0..l {
            let mut s = 0.0;
            for (a, col) in cols.iter().enumerate() {
                s += col[j] * y[a * rank + k];
            }
            coef[j * nspec + k] = scale[j] * scale[j] * s * inv;
        }
    }
    let errors = errors_of(residual, l, &coef, nspec);
    Pca {
        nspec,
        coef,
        errors,
    }
}

/// Each lobe's relative error (lobes are unit-norm) when fitted by the constant and the
/// bases: `‖r_j‖² − Σ_k ⟨r_j, φ_k⟩²`.
fn errors_of(residual: &[f64], l: usize, coef: &[f64], nspec: usize) -> Vec<f64> {
    (0..l)
        .into_par_iter()
        .map(|j| {
            let row = &residual[j * l..(j + 1) * l];
            let mut e2 = row[j];
            for k in 0..nspec {
                let p: f64 = row
                    .iter()
                    .enumerate()
                    .map(|(i, r)| r * coef[i * nspec + k])
                    .sum();
                e2 -= p * p;
            }
            e2.max(0.0).sqrt()
        })
        .collect()
}

//! The PCA of the sampled lobes (module docs, "Gram → eigenvectors exactly in δ" and
//! "Weighting"): the lobes' values at the atoms of a measure, their Gram matrix (of the
//! residuals after the constant when it is in the fit), its low-rank factor, and a PCA for
//! each lobe weighting — every basis a linear combination of lobes, so exact in δ.

use std::f64::consts::PI;

use crate::linalg::{gram_matrix, LowRankGram};

/// `F[q·l + j] = f_j(x_q)`.
pub(super) fn lobe_matrix(ns: &[f64], x: &[f64]) -> Vec<f64> {
    let l = ns.len();
    let norm: Vec<f64> = ns.iter().map(|n| (n + 2.0) / (8.0 * PI)).collect();
    let mut f = vec![0.0; x.len() * l];
    for (q, &xq) in x.iter().enumerate() {
        for j in 0..l {
            f[q * l + j] = norm[j] * (ns[j] * xq).exp();
        }
    }
    f
}

/// The sampled lobes under the PCA measure: what every PCA of them needs.
pub(super) struct Lobes {
    pub l: usize,
    /// Gram matrix of what the PCA fits (`l×l`): the lobes `f_j`, or with the constant in
    /// the fit their residuals `r_j = f_j − m_j` (`G − m mᵀ`).
    pub gram: Vec<f64>,
    /// `‖f_j‖²` (the denominators of the relative errors).
    pub norm2: Vec<f64>,
    /// `m_j = ⟨f_j, 1⟩` (the mean; the measure has total weight 1) with the constant in the
    /// fit, 0 otherwise.
    pub mean: Vec<f64>,
    pub constant: bool,
    /// Pivoted Cholesky factor of `gram`: every weighting's PCA is solved at its rank.
    factor: LowRankGram,
}

impl Lobes {
    /// The lobes `f` (sample-major, `l` per atom) under the atom weights `w`.
    pub fn new(f: &[f64], w: &[f64], l: usize, constant: bool) -> Lobes {
        let mut gram = gram_matrix(f, w, l);
        let norm2: Vec<f64> = (0..l).map(|j| gram[j * l + j]).collect();
        let mut mean = vec![0.0; l];
        if constant {
            for (q, &wq) in w.iter().enumerate() {
                for (m, &x) in mean.iter_mut().zip(&f[q * l..(q + 1) * l]) {
                    *m += wq * x;
                }
            }
            for j in 0..l {
                for k in 0..l {
                    gram[j * l + k] -= mean[j] * mean[k];
                }
            }
        }
        let factor = LowRankGram::new(&gram, l);
        Lobes {
            l,
            gram,
            norm2,
            mean,
            constant,
            factor,
        }
    }

    /// Lobe scales of [`super::LobeWeighting::Energy`]: every lobe as it is.
    pub fn energy_scale(&self) -> Vec<f64> {
        vec![1.0; self.l]
    }

    /// Lobe scales of [`super::LobeWeighting::Unit`]: every lobe to unit norm.
    pub fn unit_scale(&self) -> Vec<f64> {
        self.norm2
            .iter()
            .map(|n2| 1.0 / n2.sqrt().max(1e-300))
            .collect()
    }
}

/// A PCA solution: `bmat` (l×k) with `ρ̃_k = Σ_j B_jk f_j − off_k` (`off_k = Σ_j m_j B_jk`,
/// 0 without the constant), orthonormal under the PCA measure (and orthogonal to the
/// constant when it is in the fit), and the exact projections `c = G·B` (l×k) of the sampled
/// lobes (`⟨f_j, ρ̃_k⟩ = ⟨r_j, ρ̃_k⟩`).
pub(super) struct Pca {
    pub k: usize,
    pub bmat: Vec<f64>,
    pub off: Vec<f64>,
    pub c: Vec<f64>,
}

impl Pca {
    /// PCA of the fitted lobes scaled by `scale` (`G_s = S G S = (S R)(S R)ᵀ`), keeping at
    /// most `kwant` eigenpairs above 1e-12 of the largest (their eigenvectors are accurate).
    pub fn new(lobes: &Lobes, scale: &[f64], kwant: usize) -> Pca {
        let (gram, l) = (&lobes.gram, lobes.l);
        let (chol, r) = (lobes.factor.factor(), lobes.factor.rank());
        let (lam, u) = lobes.factor.reduced_eigen(Some(scale));
        let rank = lam.iter().take_while(|&&x| x > 1e-12 * lam[0]).count();
        let k = kwant.min(rank).min(l);
        // Eigenvectors of G_s: v = S R u / √λ; bases B = S v / √λ = S² R u / λ.
        let mut bmat = vec![0.0; l * k];
        for i in 0..l {
            for kk in 0..k {
                let mut s = 0.0;
                for a in 0..r {
                    s += chol[a][i] * u[a * r + kk];
                }
                bmat[i * k + kk] = scale[i] * scale[i] * s / lam[kk];
            }
        }
        let mut off = vec![0.0; k];
        for (i, &mi) in lobes.mean.iter().enumerate() {
            for kk in 0..k {
                off[kk] += mi * bmat[i * k + kk];
            }
        }
        let mut c = vec![0.0; l * k];
        for j in 0..l {
            for i in 0..l {
                let g = gram[j * l + i];
                if g == 0.0 {
                    continue;
                }
                for kk in 0..k {
                    c[j * k + kk] += g * bmat[i * k + kk];
                }
            }
        }
        Pca { k, bmat, off, c }
    }

    /// Relative errors of the sampled lobes with `nspec` bases (plus the constant when it is
    /// in the fit) under the PCA measure, where the bases are orthonormal:
    /// `√((‖r_j‖² − Σ c²) / ‖f_j‖²)`.
    pub fn own_errors(&self, lobes: &Lobes, nspec: usize) -> Vec<f64> {
        let l = lobes.l;
        (0..l)
            .map(|j| {
                let r2 = lobes.gram[j * l + j];
                let s: f64 = self.c[j * self.k..j * self.k + nspec.min(self.k)]
                    .iter()
                    .map(|x| x * x)
                    .sum();
                ((r2 - s).max(0.0) / lobes.norm2[j]).sqrt()
            })
            .collect()
    }
}

/// Lobe scales of [`super::LobeWeighting::Capped`] for `nspec` specular bases.
///
/// Lawson reweighting from two starts, the lobes as they are and the lobes at unit norm (the
/// PCA with the lowest average relative error), keeping the one that meets the cap with the
/// lower average error (or, if neither meets it, the lower maximum; "meets" to within
/// [`CAP_ACCURACY`]). Over a narrow exponent
/// range the two end close together; over a wide one the sharp lobes dominate the first PCA
/// of the lobes as they are and the search pulls every broad lobe towards the cap, so the
/// unit start ends far lower on average (docs/measurements.md, "Presets").
pub(super) fn capped_scale(lobes: &Lobes, nspec: usize, cap: f64) -> Vec<f64> {
    let unit = lobes.unit_scale();
    let as_they_are = lawson(lobes, nspec, cap, lobes.energy_scale());
    let from_unit = lawson(lobes, nspec, cap, unit);
    // A maximum within the iteration's accuracy of the cap counts as meeting it.
    let meets = |r: &Capped| r.max <= CAP_ACCURACY * cap;
    let rank = |r: &Capped| (!meets(r), if meets(r) { r.mean } else { r.max });
    if rank(&from_unit) < rank(&as_they_are) {
        from_unit.scale
    } else {
        as_they_are.scale
    }
}

/// How far above its cap Lawson's iteration may stop (it stops when it stalls): a search
/// within this of the cap is taken to meet it when the two starts are compared.
const CAP_ACCURACY: f64 = 1.05;

/// The outcome of one capped search: its lobe scales and their errors' maximum and mean.
struct Capped {
    scale: Vec<f64>,
    max: f64,
    mean: f64,
}

/// Lawson reweighting from the lobe scales `start`: raises only the weights of lobes above
/// the cap and stops as soon as none is (or when it stalls, keeping the best so far).
fn lawson(lobes: &Lobes, nspec: usize, cap: f64, start: Vec<f64>) -> Capped {
    let l = lobes.l;
    let top = start.iter().map(|s| s * s).fold(0.0, f64::max);
    let mut omega: Vec<f64> = start.iter().map(|s| s * s / top).collect();
    let mut best = Capped {
        scale: start,
        max: f64::INFINITY,
        mean: f64::INFINITY,
    };
    let mut history = vec![];
    for _ in 0..40 {
        let scale: Vec<f64> = omega.iter().map(|w| w.sqrt()).collect();
        let p = Pca::new(lobes, &scale, nspec);
        let e = p.own_errors(lobes, nspec);
        let max = e.iter().cloned().fold(0.0, f64::max);
        if max < best.max {
            let mean = e.iter().sum::<f64>() / l as f64;
            best = Capped { scale, max, mean };
        }
        if max <= cap {
            break;
        }
        // Stalled (the cap is out of reach for this count): keep the best so far.
        history.push(max);
        if history.len() > 4 && max > 0.99 * history[history.len() - 5] {
            break;
        }
        for j in 0..l {
            if e[j] > cap {
                omega[j] *= (e[j] / cap).powi(2);
            }
        }
        let top = omega.iter().cloned().fold(0.0, f64::max);
        omega.iter_mut().for_each(|w| *w /= top);
    }
    best
}

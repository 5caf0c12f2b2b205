//! Principal components of a large PSD Gram matrix through its low-rank factor.

use super::{jacobi_eigen, pivoted_cholesky};

/// A symmetric PSD `l×l` Gram matrix `G` with its pivoted Cholesky factor `G ≈ R Rᵀ`
/// (`r` columns, `r` its numerical rank). The nonzero eigenvalues of `G` are those of the
/// small `r×r` matrix `Rᵀ R`, and an eigenvector `u` of `Rᵀ R` gives `v = R u / √λ` of `G`:
/// so a PCA of hundreds of samples costs an eigensolve of the rank's size, not of `l`.
pub struct LowRankGram {
    l: usize,
    cols: Vec<Vec<f64>>,
}

impl LowRankGram {
    /// Factors `g` (`l×l`, row-major).
    pub fn new(g: &[f64], l: usize) -> LowRankGram {
        LowRankGram {
            l,
            cols: pivoted_cholesky(g, l),
        }
    }

    /// The numerical rank `r`.
    pub fn rank(&self) -> usize {
        self.cols.len()
    }

    /// The columns of `R`, each of length `l`.
    pub fn factor(&self) -> &[Vec<f64>] {
        &self.cols
    }

    /// Eigenpairs of `Rᵀ S² R` (`S = diag(scale)`, or the identity for `None`), descending:
    /// (λ, U as `r×r` row-major). Its eigenvalues are those of `S G S`, the Gram matrix of the
    /// samples re-weighted by `scale`, so one factorisation serves every weighting.
    pub fn reduced_eigen(&self, scale: Option<&[f64]>) -> (Vec<f64>, Vec<f64>) {
        let (cols, r) = (&self.cols, self.cols.len());
        let mut m = vec![0.0; r * r];
        for a in 0..r {
            for b in 0..=a {
                let s: f64 = match scale {
                    Some(scale) => (0..self.l)
                        .map(|i| cols[a][i] * cols[b][i] * scale[i] * scale[i])
                        .sum(),
                    None => cols[a].iter().zip(&cols[b]).map(|(x, y)| x * y).sum(),
                };
                m[a * r + b] = s;
                m[b * r + a] = s;
            }
        }
        jacobi_eigen(&m, r)
    }

    /// All `r` eigenpairs of `G`, descending: (λ, V as `l×r` row-major), `v = R u / √λ`.
    pub fn eigenpairs(&self) -> (Vec<f64>, Vec<f64>) {
        let (cols, l, r) = (&self.cols, self.l, self.cols.len());
        let (lam, u) = self.reduced_eigen(None);
        let mut v = vec![0.0; l * r];
        for k in 0..r {
            let inv = 1.0 / lam[k].max(1e-300).sqrt();
            for i in 0..l {
                let mut s = 0.0;
                for a in 0..r {
                    s += cols[a][i] * u[a * r + k];
                }
                v[i * r + k] = s * inv;
            }
        }
        (lam, v)
    }
}

/// Leading eigenpairs of a symmetric PSD `l×l` matrix, descending, via [`LowRankGram`]:
/// (λ, V as `l×r` row-major, `r` the numerical rank).
pub fn top_eigenpairs(g: &[f64], l: usize) -> (Vec<f64>, Vec<f64>) {
    LowRankGram::new(g, l).eigenpairs()
}

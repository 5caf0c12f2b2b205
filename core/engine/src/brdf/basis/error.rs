//! The reconstruction errors of a basis: per lobe and count under a measure, their
//! statistics, and the report a build hands back (on the configured grid as asked, and under
//! the continuum when the PCA ran under it; module docs, "Narrow lobes and the grid").

use serde::Serialize;

use super::config::BasisConfig;
use super::pca::{Lobes, Pca};
use crate::{RelumeError, Result};

/// Counts the error report lists: `N_b = 2..=REPORT_MAX_COUNT`.
pub(super) const REPORT_MAX_COUNT: usize = 20;

/// Reconstruction error of one basis count.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CountError {
    pub bases: u32,
    pub avg_rel_l2: f64,
    pub max_rel_l2: f64,
}

/// Relative L2 reconstruction errors `‖f − c₀/π − Σ c̃ᵢ ρ̃ᵢ‖ / ‖f‖` of the sampled lobes
/// (`c₀ = 0` without the constant in the fit), with the exact projection coefficients, on
/// the configured grid.
#[derive(Clone, Debug, Serialize)]
pub struct BasisErrorReport {
    pub ns_min: f32,
    pub ns_max: f32,
    pub grid: [u32; 3],
    pub lobes: u32,
    /// `N_b` (diffuse included).
    pub bases: u32,
    pub avg_rel_l2: f64,
    pub max_rel_l2: f64,
    /// The ns of the lobe with the largest error.
    pub worst_ns: f64,
    /// `N_b = 2..=min(20, lobes+1)` (fewer when the lobes have a lower numerical rank).
    pub per_count: Vec<CountError>,
    /// Wall time of [`super::BrdfBasis::build`].
    pub build_ms: f64,
    /// "grid" or "continuum": the measure the PCA ran under.
    pub pca_measure: String,
    /// Average error under the continuum measure, when the PCA ran under it.
    pub continuum_avg_rel_l2: Option<f64>,
    /// Maximum error under the continuum measure, when the PCA ran under it.
    pub continuum_max_rel_l2: Option<f64>,
}

/// Where a fit's errors are measured: the lobes' values and the atom weights of the grid and,
/// when the PCA ran under it, of the continuum.
pub(super) struct ErrorMeasures<'a> {
    pub grid_f: &'a [f64],
    pub grid_w: &'a [f64],
    pub continuum: Option<(&'a [f64], &'a [f64])>,
}

/// `err[j][n]` of every lobe j and count n ([`errors_under`]) on the grid and, when the PCA
/// ran under it, the continuum.
pub(super) struct FitErrors {
    pub grid: Vec<Vec<f64>>,
    pub continuum: Option<Vec<Vec<f64>>>,
}

impl ErrorMeasures<'_> {
    /// The errors of the PCA `p` of `lobes` under every measure.
    pub fn errors(&self, lobes: &Lobes, p: &Pca) -> FitErrors {
        FitErrors {
            grid: errors_under(self.grid_f, self.grid_w, lobes, p),
            continuum: self.continuum.map(|(f, w)| errors_under(f, w, lobes, p)),
        }
    }
}

impl FitErrors {
    /// The largest error at `N_b = n` over the lobes and the measures: what a tolerance is
    /// checked against.
    pub fn worst(&self, n: usize) -> f64 {
        let g = max_of(&self.grid, n);
        match &self.continuum {
            Some(c) => g.max(max_of(c, n)),
            None => g,
        }
    }

    /// The report of a basis of `count` bases from a PCA with `kmax` bases over the lobes
    /// `ns` (`build_ms` is filled in by the caller once the build is done).
    pub fn report(
        &self,
        cfg: &BasisConfig,
        ns: &[f64],
        count: usize,
        kmax: usize,
    ) -> BasisErrorReport {
        let l = ns.len();
        let (avg, max, worst_j) = stats_of(&self.grid, count);
        let per_count = (2..=REPORT_MAX_COUNT.min(l + 1).min(kmax + 1))
            .map(|n| {
                let (a, m, _) = stats_of(&self.grid, n);
                CountError {
                    bases: n as u32,
                    avg_rel_l2: a,
                    max_rel_l2: m,
                }
            })
            .collect();
        let (cavg, cmax) = match &self.continuum {
            Some(e) => {
                let (a, m, _) = stats_of(e, count);
                (Some(a), Some(m))
            }
            None => (None, None),
        };
        BasisErrorReport {
            ns_min: cfg.ns_min,
            ns_max: cfg.ns_max,
            grid: cfg.grid,
            lobes: cfg.lobes,
            bases: count as u32,
            avg_rel_l2: avg,
            max_rel_l2: max,
            worst_ns: ns[worst_j],
            per_count,
            build_ms: 0.0,
            pca_measure: if self.continuum.is_none() {
                "grid"
            } else {
                "continuum"
            }
            .to_string(),
            continuum_avg_rel_l2: cavg,
            continuum_max_rel_l2: cmax,
        }
    }
}

/// Errors unless every sampled lobe has a non-zero norm on the error grid (lobe values `f`,
/// atom-major, at the grid's atoms of weights `w`). A grid too coarse for the narrowest
/// lobes sees them as zero at every cell, where a relative error is 0/0: it was reported as
/// "inf %" (e.g. `--grid 2x2x2` with the bake's ns_max ≈ 35 000), which says nothing about
/// the basis. Refused instead, naming the lobe and the grid.
pub(super) fn check_lobes_measurable(
    cfg: &BasisConfig,
    ns: &[f64],
    f: &[f64],
    w: &[f64],
) -> Result<()> {
    let l = ns.len();
    let mut norm = vec![0.0f64; l];
    for (q, &wq) in w.iter().enumerate() {
        for (j, n) in norm.iter_mut().enumerate() {
            let x = f[q * l + j];
            *n += wq * x * x;
        }
    }
    match norm.iter().position(|n| !(*n > 0.0 && n.is_finite())) {
        None => Ok(()),
        Some(j) => Err(RelumeError::Basis(format!(
            "the lobe ns = {:.4} is zero at every cell of the {}×{}×{} grid, so its relative error cannot be measured (it would read inf %): use a finer grid (bakes use 30×30×60) or a lower ns_max",
            ns[j], cfg.grid[0], cfg.grid[1], cfg.grid[2]
        ))),
    }
}

/// Squared-error bookkeeping of every lobe under a measure (atoms `w`, lobe values `f` at
/// them): `err[j][n]` = relative L2 error of lobe j with `N_b = n`, the coefficients being
/// the PCA's (`m_j` on the constant, `c` on the bases). Without the constant, n = 1 (no
/// specular basis) → 1.
fn errors_under(f: &[f64], w: &[f64], lobes: &Lobes, p: &Pca) -> Vec<Vec<f64>> {
    let (l, kmax) = (lobes.l, p.k);
    // Columns: [the constant 1,] then the bases. A = Fᵀ W Bν, C = Bνᵀ W Bν, N_j = Σ w f_j².
    let o = usize::from(lobes.constant);
    let kc = kmax + o;
    let nq = w.len();
    let mut bq = vec![0.0; kc];
    let mut a = vec![0.0; l * kc];
    let mut cc = vec![0.0; kc * kc];
    let mut nn = vec![0.0; l];
    for q in 0..nq {
        let fq = &f[q * l..(q + 1) * l];
        if o == 1 {
            bq[0] = 1.0;
        }
        for (b, &off) in bq[o..].iter_mut().zip(&p.off) {
            *b = -off;
        }
        for (j, &x) in fq.iter().enumerate() {
            for k in 0..kmax {
                bq[o + k] += x * p.bmat[j * kmax + k];
            }
        }
        let wq = w[q];
        for j in 0..l {
            let x = wq * fq[j];
            nn[j] += x * fq[j];
            for k in 0..kc {
                a[j * kc + k] += x * bq[k];
            }
        }
        for k in 0..kc {
            for m in 0..kc {
                cc[k * kc + m] += wq * bq[k] * bq[m];
            }
        }
    }
    let mut cj = vec![0.0; kc];
    (0..l)
        .map(|j| {
            if o == 1 {
                cj[0] = lobes.mean[j];
            }
            cj[o..].copy_from_slice(&p.c[j * kmax..(j + 1) * kmax]);
            let mut e = nn[j];
            let mut out = vec![1.0; kmax + 2];
            for k in 0..kc {
                // add column k: −2 c_k A_jk + c_k² C_kk + 2 c_k Σ_{m<k} c_m C_km
                let mut cross = 0.0;
                for m in 0..k {
                    cross += cj[m] * cc[k * kc + m];
                }
                e += -2.0 * cj[k] * a[j * kc + k]
                    + cj[k] * cj[k] * cc[k * kc + k]
                    + 2.0 * cj[k] * cross;
                // Column k completes N_b = k + 2 − o (the constant alone is N_b = 1).
                out[k + 2 - o] = (e.max(0.0) / nn[j]).sqrt();
            }
            out
        })
        .collect()
}

fn max_of(err: &[Vec<f64>], n: usize) -> f64 {
    err.iter().map(|e| e[n]).fold(0.0, f64::max)
}

/// (average, maximum, index of the worst lobe) at `N_b = n`.
fn stats_of(err: &[Vec<f64>], n: usize) -> (f64, f64, usize) {
    let mut worst = 0;
    let mut sum = 0.0;
    for (j, e) in err.iter().enumerate() {
        sum += e[n];
        if e[n] > err[worst][n] {
            worst = j;
        }
    }
    (sum / err.len() as f64, err[worst][n], worst)
}

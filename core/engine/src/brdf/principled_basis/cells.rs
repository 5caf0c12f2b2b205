//! The fit that rebuilds an edited material from the basis: least squares plus a
//! chi-square term over cells of the (θh, θd) plane, so that every part of the lobe a light
//! can see keeps its energy.
//!
//! # Why
//!
//! The basis holds every Principled lobe of its range to about 1 % in L2, but an image is
//! not an L2 norm: a pixel, or a sphere's highlight, integrates the lobe against the light
//! it sees. A narrow lobe's squared error is nearly all peak, so the least-squares fit
//! gives up what the measure weighs little — the difference angles near the view (the
//! measure's `sin θd`) and the far field, where the lobe is small but a large light gathers
//! it over much of the sphere. A roughness-0.3 metal edited to 0.1 and rebuilt that way
//! showed a sphere under a light beside the camera at half its brightness
//! (`cargo run --release -p relume-engine --example sphere_highlights`; the real bake and
//! relight on that sphere: `scripts/sphere_edit_check.py`).
//!
//! Holding each θd slice's energy mends a distant light but not a near one, which sees the
//! peak at one difference angle and the far field at others. What bounds every light is a
//! relative error everywhere: for any region `A` of the domain,
//! `|∫_A e| ≤ (∫ e²/f)^{1/2} (∫_A f)^{1/2}` (Cauchy–Schwarz), so a small chi-square
//! `∫ e²/f` keeps the energy of every region the lobe lights, relative to that energy.
//!
//! # What it is
//!
//! Cells: the quadrature's θd rows, each split in [`THETA_H_GROUPS`] groups of its graded θh
//! axis (fine at the peak, coarse in the far field). Per channel the coefficients minimise
//!
//! `‖e‖² + CHI_WEIGHT · ‖f‖²/‖f‖₁ · Σ_cells ∫_cell e² / (f̄_cell + τ)`
//!
//! with `f̄_cell` the target's mean over the cell and `τ` = [`MEAN_FLOOR`] of its mean over
//! the domain (a cell the material barely lights is not held to a relative error it cannot
//! show). Both terms are quadratic in the coefficients, so the fit is one small linear
//! solve from per-cell Gram matrices made once per basis and per bake-time lobe. The target
//! itself gives zero in both terms, so a material the span holds exactly is rebuilt exactly.
//! The L2 error this leaves is larger than the projection's (the peak's shape gives way a
//! little to hold its energy); [`super::PrincipledBasis::rebuild_error_with_bake_lobe`]
//! reports it.

use super::lobes::DIFFUSE;
use super::quadrature::Node;
use super::PrincipledBasis;
use crate::linalg::{cholesky_in_place, cholesky_solve};

/// θh groups per θd row: uniform in the quadrature's graded θh index, so the narrowest lobe's
/// peak and shoulders fall in groups of their own.
pub(crate) const THETA_H_GROUPS: usize = 16;
/// The chi-square term's weight against the L2 term (chosen on the sphere model and checks
/// named in the module docs: heavier holds energy no better and loses more of the shape).
pub(super) const CHI_WEIGHT: f64 = 0.3;
/// `τ` as a share of the target's mean over the domain.
pub(super) const MEAN_FLOOR: f64 = 0.01;

impl PrincipledBasis {
    pub(crate) fn cell_count(&self) -> usize {
        self.config().quadrature.theta_d * THETA_H_GROUPS
    }

    pub(crate) fn cell_of(&self, node: &Node) -> usize {
        let nh = self.config().quadrature.theta_h;
        let group = node.theta_h_index as usize * THETA_H_GROUPS / nh;
        node.theta_d_index as usize * THETA_H_GROUPS + group.min(THETA_H_GROUPS - 1)
    }

    /// Every slot pair's inner product per cell, `cell_count() × count() × count()` (slot 0
    /// the constant `1/π`); computed once per basis.
    pub(crate) fn cell_grams(&self) -> &[f64] {
        self.cell_grams.get_or_init(|| {
            let n = self.count();
            self.sum_over_nodes(n * n * self.cell_count(), |node, phi, acc| {
                let cell = self.cell_of(node);
                let g = &mut acc[cell * n * n..(cell + 1) * n * n];
                let mut v = [0.0f64; super::MAX_SLOTS];
                v[0] = DIFFUSE;
                v[1..n].copy_from_slice(&phi[..n - 1]);
                for k in 0..n {
                    let wk = node.weight * v[k];
                    for l in 0..n {
                        g[k * n + l] += wk * v[l];
                    }
                }
            })
        })
    }
}

/// One channel's fit over `m` functions (the basis' slots, and the bake-time lobe when it
/// takes part).
pub(crate) struct CellFit {
    pub m: usize,
    /// The L2 term: Gram matrix (`m × m`, row-major) and right-hand side over the domain.
    pub gram: Vec<f64>,
    pub rhs: Vec<f64>,
    /// Per cell: Gram matrix, right-hand side, the target's integral and the cell's measure.
    pub cell_grams: Vec<f64>,
    pub cell_rhs: Vec<f64>,
    pub cell_integral: Vec<f64>,
    pub cell_measure: Vec<f64>,
    /// The target's squared norm over the domain.
    pub norm2: f64,
}

impl CellFit {
    /// The coefficients, and the relative L2 error they leave.
    pub fn solve(&self) -> (Vec<f64>, f64) {
        let m = self.m;
        let mut a = self.gram.clone();
        let mut x = self.rhs.clone();
        let l1: f64 = self.cell_integral.iter().sum();
        let measure: f64 = self.cell_measure.iter().sum();
        if l1 > 0.0 && measure > 0.0 && self.norm2 > 0.0 {
            let tau = MEAN_FLOOR * l1 / measure;
            let scale = CHI_WEIGHT * self.norm2 / l1;
            for (cell, (&integral, &mu)) in self
                .cell_integral
                .iter()
                .zip(&self.cell_measure)
                .enumerate()
            {
                if mu <= 0.0 {
                    continue;
                }
                let w = scale / ((integral / mu).max(0.0) + tau);
                let g = &self.cell_grams[cell * m * m..(cell + 1) * m * m];
                let r = &self.cell_rhs[cell * m..(cell + 1) * m];
                for k in 0..m {
                    x[k] += w * r[k];
                    for l in 0..m {
                        a[k * m + l] += w * g[k * m + l];
                    }
                }
            }
        }
        let largest = (0..m).map(|k| a[k * m + k]).fold(0.0, f64::max);
        cholesky_in_place(&mut a, m, largest * 1e-14);
        cholesky_solve(&a, m, &mut x);
        // ‖f − Σ x ψ‖² = ‖f‖² − 2 xᵀr + xᵀ G x.
        let mut residual = self.norm2;
        for k in 0..m {
            residual -= 2.0 * x[k] * self.rhs[k];
            for l in 0..m {
                residual += x[k] * self.gram[k * m + l] * x[l];
            }
        }
        let error = if self.norm2 > 0.0 {
            (residual.max(0.0) / self.norm2).sqrt()
        } else {
            0.0
        };
        (x, error)
    }
}

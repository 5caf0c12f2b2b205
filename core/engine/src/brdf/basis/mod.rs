//! The PCA basis of Blinn–Phong lobes (section 3 of the paper, eqs. 17–22).
//!
//! # What the paper does
//!
//! Sample the isotropic BRDF domain `(θi, θo, φ) ∈ [0, π/2]² × [0, π]` uniformly on a
//! 30×30×60 grid (eq. 17), take `N_s − 1 = 200` specular lobes with `ns` uniform in [1, 200]
//! plus the diffuse sample, keep the diffuse `1/π` as basis 1 and run a PCA (no mean
//! subtraction, so the coefficients stay linear) on the specular lobes for the other
//! `N_b − 1` bases. A BRDF is then `ρ ≈ Kd·ρ̃₁ + Ks·Σ_{i≥2} c̃ᵢ(ns)·ρ̃ᵢ` (eq. 22). With
//! `N_b = 6` the paper reports a relative L2 error of 0.7979 % on average, 6.747 % at worst.
//!
//! # What Relume does, and why
//!
//! Every lobe `(ns+2)/(8π)·cos^ns δ` ([`super::blinn_phong::lobe`]) depends on the half
//! angle δ alone, so every PCA basis — a linear combination of lobes — does too. Only the
//! *distribution of δ* under the sampling measure matters, so:
//!
//! * **Measures as atoms in δ.** A measure is a list of atoms `(x = ln cos δ, weight)`,
//!   weights summing to 1 (the inner product is the *mean* over the grid, so a basis has unit
//!   RMS over the domain rather than the tiny entries of a unit 54,000-vector). The grid
//!   measure is the configured (θi, θo, φ) grid's cell centres, binned on a fine graded δ mesh
//!   (1024 bins, graded from the narrowest lobe of the range) with the mean `x` of each bin
//!   kept: lobes are exponentials in `x`, so this barely changes inner products (tested
//!   against the exact grid sums), and makes everything below independent of the 54,000
//!   grid points.
//! * **Gram → eigenvectors exactly in δ.** The Gram matrix of the lobes under the measure
//!   (f64) is factored by a pivoted Cholesky (its numerical rank is a small fraction of the
//!   lobe count) and the reduced matrix is diagonalised by a cyclic Jacobi solver; the
//!   eigenvectors of the reduced matrix give those of the Gram matrix, and
//!   `ρ̃_k(δ) = Σ_j B_jk f_j(δ)` exactly as a function of δ, orthonormal under the measure.
//!   The reduction gives the same leading eigenpairs as a Jacobi of the full Gram matrix
//!   (tested) at a small fraction of its cost ([`crate::linalg`]).
//! * **1D table instead of trilinear 3D interpolation** (the deviation from the paper's
//!   bake, which interpolates ρ̃ on the 30×30×60 grid). Each basis is tabulated at 2048 nodes
//!   of `v = u(1+k)/(u+k)`, `u = √(1 − cos δ)` (≈ δ/√2, computed with one `sqrt` from the
//!   `cos δ` the bake already has), `k` chosen from `ns_max` so that the narrowest lobe of the
//!   range gets ≥ 50 nodes across its half width (≥ 200 for ns ≤ 10⁴). Linear interpolation
//!   between nodes. This is exact in θ and φ and resolves lobes the 3° grid cannot
//!   (ns = 10⁴ has a 0.67° half width).
//! * **Narrow lobes and the grid.** When the narrowest lobe's half width is below the grid's
//!   θ spacing (ns_max ≳ 450 on 30×30×60), the grid sees each narrow lobe at a handful of
//!   cells near the mirror direction and its Gram matrix no longer describes the lobes.
//!   [`PcaMeasure::Auto`] then runs the PCA under the **continuum limit** of the grid measure
//!   (uniform in (θi, θo, φ)) instead: its δ distribution is computed per bin of the fine δ
//!   mesh by exact integration over φ (for fixed θi, θo, δ is monotone in φ, so
//!   `P(δ < t)` has a closed form in φ) and Gauss–Legendre quadrature over (θi, θo) on
//!   intervals adapted to t. This was chosen over refining the grid because its cost does
//!   not grow with ns_max and it has no aliasing at all. The errors are reported **on the
//!   configured grid** as asked ([`BasisErrorReport::avg_rel_l2`], `max_rel_l2`) and also
//!   under the continuum measure (`continuum_*`), and a tolerance must be met by both.
//! * **Lobe spacing.** Uniform in ns as in the paper when `ns_max/ns_min ≤ 256`; wider
//!   ranges space the lobes geometrically ([`LobeSpacing::Auto`]), because the lobe shape
//!   changes with the *relative* change of ns: uniform spacing over [1, 10⁴] leaves
//!   [1, 51] with two samples.
//! * **Coefficients** `c̃_k(ns) = ⟨f_ns, ρ̃_k⟩` (least squares onto orthonormal bases), tabulated
//!   at 512 nodes uniform in `ln ns` over `[ns_min, ns_max]` and interpolated linearly
//!   (error ≤ 1e-4 of the lobe norm, tested). `ns` outside the range is **clamped** to it: a
//!   material rougher/smoother than the basis was built for is rendered with the nearest lobe
//!   the basis represents (extrapolating the PCA coefficients would give arbitrary lobes).
//!   Callers that need wider ranges build a basis for them; the relighters report every
//!   clamped material (`stack::bases::StackBases::ns_out_of_range`).
//! * **Constant in the fit** ([`BasisConfig::constant_in_fit`], default on). The paper
//!   keeps `1/π` for `Kd` alone and fits every specular lobe with the other `N_b − 1` bases.
//!   But every lobe has a large constant component (its mean over the domain), and the
//!   diffuse basis is evaluated anyway: Relume lets the specular fit use it, a lobe being
//!   `c₀(ns)/π + Σ_{i≥1} c̃ᵢ(ns)·ρ̃ᵢ` with `c₀ = π·⟨f_ns, 1⟩` and the PCA run on the residuals
//!   `f_j − ⟨f_j, 1⟩` (Gram `G − m mᵀ`), so the `ρ̃ᵢ` are orthogonal to the constant and
//!   `{1/π, ρ̃ᵢ}` is still an orthogonal least-squares basis. Same count, same per-vertex
//!   transfer data, linear coefficients; the material's basis-0 coefficient becomes
//!   `Kd + Ks·c₀(ns)`. The catch: an albedo texture multiplies basis 0 and should act on
//!   `Kd` only, so a textured region needs the `Ks·c₀` part in its own untextured slot
//!   ([`BrdfBasis::spec_constant`], [`BrdfBasis::split_coefficients`]).
//! * **Weighting.** The literal PCA ([`LobeWeighting::Energy`]) minimises the sum of squared
//!   *absolute* errors, which favours the sharp lobes (their norm grows like √ns) and leaves
//!   the broadest one badly represented. Normalising the lobes ([`LobeWeighting::Unit`])
//!   evens that out; capping each lobe's relative error by Lawson reweighting
//!   ([`LobeWeighting::Capped`], the default) trades a little average error for a much lower
//!   maximum. Without the constant no weighting tried meets both of the paper's figures (the
//!   caps trade average for maximum, and the maximum passes the paper's before the average
//!   reaches it); with the constant the default meets both, the maximum with a wide margin,
//!   and the report is checked against a direct evaluation on the grid cells (tabulated bases
//!   included) in the tests. The cap sits low rather than at the balance point because a
//!   visible error on the worst lobe matters more than a little of the average. The figures
//!   of every weighting, and of wide ranges built to a tolerance, are in docs/measurements.md
//!   ("BRDF basis").
//!
//! # Where it lives
//!
//! [`BrdfBasis::build`] runs the steps in order, one file each: the configuration and its
//! checks (`config`), the measures on δ (`measure`), the PCA of the sampled lobes (`pca`),
//! the choice of count and weighting (`fit`), the error statistics and report (`error`), the
//! tables the bake evaluates (`tables`), and a material's coefficients per slot
//! (`coefficients`). The eigen-solvers are in [`crate::linalg`].

use std::time::Instant;

use glam::Vec3;

use super::blinn_phong::BlinnPhong;
use crate::Result;

pub(crate) mod coefficients;
mod config;
mod error;
mod fit;
mod measure;
mod pca;
mod tables;

pub use config::{
    check_basis_limits, BasisConfig, BasisCount, LobeSpacing, LobeWeighting, PcaMeasure,
    MAX_GRID_CELLS, MAX_GRID_SIDE, MAX_LOBES,
};
pub use error::{BasisErrorReport, CountError};

pub(crate) use config::check_config;
use config::sample_ns;
use error::ErrorMeasures;
use fit::{fit, Fit};
use measure::{Atoms, Measures};
use pca::{lobe_matrix, Lobes};
use tables::{
    bases_at_atoms, basis_table, coefficient_table, project, warp_k, COEF_NODES, TABLE_NODES,
};

// What the unit tests reach for beside the public items.
#[cfg(test)]
use crate::linalg::{gram_matrix, jacobi_eigen, top_eigenpairs};
#[cfg(test)]
use crate::RelumeError;
#[cfg(test)]
use measure::{continuum_cdf, gauss_legendre, grid_atoms, Mesh, MESH_BINS};
#[cfg(test)]
use std::f64::consts::{FRAC_PI_2, PI};

/// The basis: the diffuse `1/π` and `N_b − 1` tabulated specular bases with their
/// coefficient tables (`c₀` for `1/π` too, with the constant in the fit).
pub struct BrdfBasis {
    cfg: BasisConfig,
    count: usize,
    /// `TABLE_NODES × (count−1)`, node-major.
    table: Vec<f32>,
    /// `cfg.constant_in_fit`: `c₀(ns)` (coefficient column 0) is used.
    constant: bool,
    /// The `k` of the table warp.
    warp_k: f32,
    /// `COEF_NODES × count`, node-major; column 0 is `c₀(ns)` (0 without the constant).
    coef: Vec<f32>,
    ln_ns_min: f64,
    ln_ns_max: f64,
    /// The PCA measure and the bases at its atoms (for exact projections).
    pca_atoms: Atoms,
    /// `atoms × (count−1)`.
    pca_basis_at_atoms: Vec<f64>,
    report: BasisErrorReport,
}

impl BrdfBasis {
    /// Builds the basis for `cfg` (timed in [`BasisErrorReport::build_ms`]).
    ///
    /// Errors ([`crate::RelumeError::Basis`]) for `ns_min ≤ 0`, `ns_min ≥ ns_max`, non-finite
    /// values, zero lobes or grid sizes, a count of 0 or above `lobes + 1` (or above the
    /// numerical rank of the lobes + 1), a tolerance that is not finite and > 0, or one no
    /// count up to 64 reaches (the message gives the best count and its error).
    pub fn build(cfg: &BasisConfig) -> Result<BrdfBasis> {
        let start = Instant::now();
        check_config(cfg)?;
        let ns = sample_ns(cfg);
        let l = ns.len();
        let measures = Measures::new(cfg);
        let pca_atoms = measures.pca();

        // Lobe values at the PCA atoms (and at the grid's, when the PCA runs elsewhere).
        let f_pca = lobe_matrix(&ns, &pca_atoms.x);
        let f_grid = (!measures.pca_on_grid()).then(|| lobe_matrix(&ns, &measures.grid.x));
        let constant = cfg.constant_in_fit;
        let lobes = Lobes::new(&f_pca, &pca_atoms.w, l, constant);
        let error_measures = ErrorMeasures {
            grid_f: f_grid.as_deref().unwrap_or(&f_pca),
            grid_w: &measures.grid.w,
            continuum: measures.continuum.as_ref().map(|a| (&f_pca[..], &a.w[..])),
        };

        error::check_lobes_measurable(cfg, &ns, error_measures.grid_f, error_measures.grid_w)?;
        let Fit { count, pca, errors } = fit(cfg, &lobes, &error_measures)?;
        let report = errors.report(cfg, &ns, count, pca.k);

        let nspec = count - 1;
        let warp_k = warp_k(cfg.ns_max as f64);
        let table = basis_table(&ns, &pca, nspec, warp_k);
        let bat = bases_at_atoms(&f_pca, l, &pca, nspec);
        let ln_ns_min = (cfg.ns_min as f64).ln();
        let ln_ns_max = (cfg.ns_max as f64).ln();
        let coef = coefficient_table([ln_ns_min, ln_ns_max], pca_atoms, &bat, constant, count);

        let mut basis = BrdfBasis {
            cfg: cfg.clone(),
            count,
            table,
            constant,
            warp_k,
            coef,
            ln_ns_min,
            ln_ns_max,
            pca_atoms: pca_atoms.clone(),
            pca_basis_at_atoms: bat,
            report,
        };
        basis.report.build_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(basis)
    }

    /// The configuration this basis was built from.
    pub fn config(&self) -> &BasisConfig {
        &self.cfg
    }

    /// `N_b` (≥ 1); index 0 is the diffuse basis `1/π`.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Basis values at `cos δ`: `out[0] = 1/π`, `out[i] = ρ̃_i(δ)` for `1 ≤ i < N_b`. For
    /// `cos δ ≤ 0` (and NaN) the specular bases take their value at `cos δ = 0` (δ = π/2, the
    /// edge of the domain): 0 without the constant in the fit, a constant offset with it (the
    /// bases are orthogonal to `1/π`), so the reconstruction stays continuous. Cost: one `sqrt`, one division and
    /// `N_b − 1` lerps over contiguous memory. `f32` `cos δ` resolves δ down to ≈ 3.5e-4 rad,
    /// i.e. ≥ 3 samples per half width for lobes up to ns ≈ 10⁶.
    ///
    /// # Panics
    /// If `out.len() < self.count()`.
    pub fn eval(&self, cos_delta: f32, out: &mut [f32]) {
        self.check_out(out.len(), "BrdfBasis::eval");
        out[0] = std::f32::consts::FRAC_1_PI;
        let nspec = self.count - 1;
        let spec = &mut out[1..self.count];
        if !(cos_delta > 0.0) {
            spec.copy_from_slice(&self.table[(TABLE_NODES - 1) * nspec..TABLE_NODES * nspec]);
            return;
        }
        let u = (1.0 - cos_delta.min(1.0)).max(0.0).sqrt();
        let k = self.warp_k;
        let v = u * (1.0 + k) / (u + k);
        let pos = (v * (TABLE_NODES - 1) as f32).clamp(0.0, (TABLE_NODES - 1) as f32);
        let i = (pos as usize).min(TABLE_NODES - 2);
        let t = pos - i as f32;
        let a = &self.table[i * nspec..(i + 1) * nspec];
        let b = &self.table[(i + 1) * nspec..(i + 2) * nspec];
        for ((o, &x), &y) in spec.iter_mut().zip(a).zip(b) {
            *o = x + t * (y - x);
        }
    }

    /// Specular coefficients of a lobe with exponent `ns` (interpolated from the table):
    /// `out[0] = c₀(ns)`, the lobe's coefficient on the diffuse basis `1/π` (0 unless
    /// [`Self::spec_constant`]), `out[i] = c̃_i(ns)`. `ns` is clamped to `[ns_min, ns_max]` (module docs);
    /// NaN is treated as `ns_min`.
    ///
    /// # Panics
    /// If `out.len() < self.count()`.
    pub fn spec_coefficients(&self, ns: f32, out: &mut [f32]) {
        self.check_out(out.len(), "BrdfBasis::spec_coefficients");
        let n = self.count;
        let ns = if ns.is_nan() {
            self.cfg.ns_min
        } else {
            ns.clamp(self.cfg.ns_min, self.cfg.ns_max)
        };
        let t = ((ns as f64).ln() - self.ln_ns_min) / (self.ln_ns_max - self.ln_ns_min);
        let pos = (t * (COEF_NODES - 1) as f64).clamp(0.0, (COEF_NODES - 1) as f64);
        let i = (pos as usize).min(COEF_NODES - 2);
        let f = (pos - i as f64) as f32;
        let a = &self.coef[i * n..(i + 1) * n];
        let b = &self.coef[(i + 1) * n..(i + 2) * n];
        for ((o, &x), &y) in out[..n].iter_mut().zip(a).zip(b) {
            *o = x + f * (y - x);
        }
    }

    /// Whether the specular fit uses the diffuse basis (`out[0]` of
    /// [`Self::spec_coefficients`] is `c₀(ns)` rather than 0; [`BasisConfig::constant_in_fit`]).
    /// A caller that scales basis 0 by an albedo texture (which acts on the diffuse part only)
    /// then needs a separate, untextured constant slot for `Ks·c₀`: see
    /// [`Self::split_coefficients`].
    pub fn spec_constant(&self) -> bool {
        self.constant
    }

    /// Exact projection coefficients under the PCA measure, `out[0] = c₀ = π·⟨f_ns, 1⟩` (0
    /// unless [`Self::spec_constant`]) and `out[k] = ⟨f_ns, ρ̃_k⟩` (no table, no clamping;
    /// `O(atoms·N_b)`): what [`Self::spec_coefficients`] interpolates. For tests and
    /// diagnostics.
    pub fn exact_spec_coefficients(&self, ns: f64, out: &mut [f64]) {
        assert!(out.len() >= self.count);
        project(
            &self.pca_atoms,
            &self.pca_basis_at_atoms,
            self.constant,
            ns,
            &mut out[..self.count],
        );
    }

    /// The projected BRDF value `Σ coef_i·ρ̃_i(δ)` of a material (what the relight of a
    /// layer sum amounts to at one shading point).
    pub fn reconstruct(&self, m: &BlinnPhong, cos_delta: f32) -> Vec3 {
        let coef = self.material_coefficients(m);
        let mut b = vec![0.0f32; self.count];
        self.eval(cos_delta, &mut b);
        coef.iter().zip(&b).map(|(c, &x)| *c * x).sum()
    }

    /// Panics unless an output slice of `len` holds one value per basis.
    #[inline]
    fn check_out(&self, len: usize, caller: &str) {
        assert!(
            len >= self.count,
            "{caller}: out has {len} slots, need {}",
            self.count
        );
    }

    /// Reconstruction errors measured when the basis was built.
    pub fn error_report(&self) -> BasisErrorReport {
        self.report.clone()
    }
}

#[cfg(test)]
mod tests;

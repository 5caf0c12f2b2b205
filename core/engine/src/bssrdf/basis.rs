//! The PCA basis of the dipole profile: `K(r, σ) ≈ Σ_k s_k(σ)·b_k(r)` (translucency paper §2.2).
//!
//! **What is factored.** Not the bare `Rd` but `Rd` blurred at the scale of the surface
//! samples: the 2D convolution of the profile with an isotropic Gaussian of standard deviation
//! 3ρ ([`BLUR_PER_RHO`]), ρ the radius of the area element of one sample (`√(A/(πN))`). The bake sums the profile at
//! sample points ρ apart, which cannot resolve anything finer; unblurred, the α′ → 1 spike
//! (width z_r, down to 10⁻³ mean free paths) makes the image depend on which sample happens to
//! lie nearest, and the PCA needs a basis function per octave of z_r (docs/measurements.md,
//! "Subsurface basis", compares the errors with and without the blur). The blur keeps the
//! total reflectance exactly (columns of the blur matrix are normalised to unit mass) and
//! changes `Rd(r)` by O(ρ²/ℓ²) where it varies on the scale ℓ. It is computed exactly on the
//! profile's *masses* per annulus (from the closed-form disc integral), so no spike is ever
//! point-sampled. It is an approximation of the model, documented as such; the brute-force
//! reference of the tests uses the same blurred profile ([`SssBasis::blurred_profile`]).
//!
//! **Family and measure.** σ ranges over a declared box: diffuse mean free path
//! `ld ∈ [mfp_min, mfp_max]` (log-spaced), reduced albedo α′ ∈ [0.02, 1 − 10⁻⁶] (log-spaced in
//! 1 − α′), η ∈ [eta_min, eta_max]. Profiles are sampled at `R_NODES` radii warped towards
//! r = 0 (an asinh grid from a fraction of the smallest length, ρ or mfp_min, out to the
//! region's diameter `r_max`), each with the area of its annulus as weight (so the inner
//! product is `∫ f g dA` over the plane), and every profile is normalised to unit norm before
//! the PCA: the basis minimises the *relative* error of each σ, not the error of the brightest.
//!
//! **Coefficients.** The b_k are orthonormal under that inner product, so
//! `s_k(σ) = ∫ (B·Rd_σ) b_k dA = Σ_m mass_m(σ)·c_mk` with `c = Bᵀ·b` precomputed — `R_NODES`
//! annulus masses and `R_NODES·K` multiply-adds, cheap enough for every edit. σ outside the box
//! is clamped into it (documented in [`SssBasis::coefficients`]).
//!
//! **Count.** The smallest K whose worst relative L2 error over a test set of σ *between* the
//! training samples is ≤ the tolerance, at most [`MAX_SSS_BASES`].

use serde::{Deserialize, Serialize};

use super::blur::{annulus_masses, apply_blur, blur_matrix, blur_row, BlurRows};
use super::dipole::DipoleParams;
use super::mapping::ALPHA_MAX;
use crate::linalg::{top_eigenpairs, GramAccumulator};
use crate::{RelumeError, Result};

/// Standard deviation of the sample-scale blur in units of ρ. Samples are `h = ρ√π` apart
/// on average; a Gaussian of σ = 3ρ ≈ 1.7h holds ≈ 35 samples within 2σ, so the sum over
/// (stratified, jittered) samples of the blurred profile is a smooth quadrature, where σ = ρ
/// (≈ 1 sample) leaves the image at the mercy of the nearest sample (tests/engine/subsurface.rs
/// checks a uniformly lit plane; figures in docs/measurements.md, "Subsurface basis").
pub const BLUR_PER_RHO: f64 = 3.0;
/// Radii at which the profiles are sampled (and the basis tabulated).
pub const R_NODES: usize = 384;
/// Most subsurface bases one region may use.
pub const MAX_SSS_BASES: usize = 24;
/// Mean free paths sampled across [mfp_min, mfp_max] for the PCA.
const N_MFP: usize = 40;
/// Reduced albedos sampled for the PCA.
const N_ALPHA: usize = 10;
/// Indices of refraction sampled for the PCA.
const N_ETA: usize = 4;
/// Smallest 1 − α′ of the family (α′ = `ALPHA_MAX`) and largest (α′ = 0.02).
const ONE_MINUS_ALPHA: [f64; 2] = [1.0 - ALPHA_MAX, 0.98];

/// Definition of a region's subsurface basis (stored in the stack header; the basis is
/// rebuilt from it deterministically on load).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SssBasisConfig {
    /// Radius of the area element of one surface sample, `√(area/(π·samples))` (scene units).
    pub rho: f64,
    /// Largest distance the profile is needed at: the region's bounding-box diagonal.
    pub r_max: f64,
    /// Range of the diffuse mean free path `1/σ_tr` the basis covers (scene units).
    pub mfp_min: f64,
    pub mfp_max: f64,
    /// Range of the relative index of refraction.
    #[serde(default = "eta_lo")]
    pub eta_min: f64,
    #[serde(default = "eta_hi")]
    pub eta_max: f64,
    /// Fixed basis count, or `None` to choose it by `tolerance`.
    #[serde(default)]
    pub bases: Option<u32>,
    /// Worst relative L2 error of a profile allowed when the count is chosen.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
}

fn eta_lo() -> f64 {
    1.0
}
fn eta_hi() -> f64 {
    2.0
}
/// Default tolerance: 10⁻⁴, the translucency paper's reported L2 at 15 bases.
pub fn default_tolerance() -> f64 {
    1e-4
}

/// One row of the error table: K bases, relative L2 error of the profiles over the test σ.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SssErrorRow {
    pub bases: usize,
    pub mean_rel_l2: f64,
    pub max_rel_l2: f64,
}

/// A built subsurface basis.
#[derive(Clone, Debug)]
pub struct SssBasis {
    cfg: SssBasisConfig,
    count: usize,
    /// Warp length `a` of the radius grid: r(t) = a·sinh(t·asinh(r_max/a)).
    warp_a: f64,
    warp_span: f64,
    /// Radii of the nodes (r(t) at t = (j + ½)/R_NODES) and their annulus areas.
    radii: Vec<f64>,
    areas: Vec<f64>,
    /// Cell edges of the radius grid (R_NODES + 1).
    edges: Vec<f64>,
    /// `b_k(r_j)·√area_j`: orthonormal columns, node-major, `count` per node.
    unit: Vec<f64>,
    /// `c_mk = Σ_j area_j·B_jm·b_k(r_j)`: the coefficient of annulus mass m, node-major.
    mass_coef: Vec<f64>,
    /// Blur matrix B (sparse rows: for output node j, `(first m, weights)`), 1/area units.
    blur: Vec<(usize, Vec<f64>)>,
    /// Column normalisation of the blur (unit mass per source cell).
    blur_norm: Vec<f64>,
    /// `b_k(r_j)` as f32, node-major (what the bake interpolates).
    table: Vec<f32>,
    errors: Vec<SssErrorRow>,
}

fn check(cfg: &SssBasisConfig) -> Result<()> {
    let ok = |x: f64| x.is_finite() && x > 0.0;
    if !ok(cfg.rho) || !ok(cfg.r_max) || !ok(cfg.mfp_min) || !ok(cfg.mfp_max) {
        return Err(RelumeError::Basis(format!(
            "subsurface basis: rho, r_max, mfp_min, mfp_max must be finite and > 0 ({cfg:?})"
        )));
    }
    if cfg.mfp_min > cfg.mfp_max {
        return Err(RelumeError::Basis(format!(
            "subsurface basis: mfp range [{}, {}] is reversed",
            cfg.mfp_min, cfg.mfp_max
        )));
    }
    if !(cfg.eta_min >= 1.0 && cfg.eta_max >= cfg.eta_min && cfg.eta_max.is_finite()) {
        return Err(RelumeError::Basis(format!(
            "subsurface basis: eta range [{}, {}] must satisfy 1 ≤ min ≤ max",
            cfg.eta_min, cfg.eta_max
        )));
    }
    if let Some(b) = cfg.bases {
        if b == 0 || b as usize > MAX_SSS_BASES {
            return Err(RelumeError::Basis(format!(
                "subsurface basis: {b} bases (1 to {MAX_SSS_BASES})"
            )));
        }
    } else if !(cfg.tolerance > 0.0) {
        return Err(RelumeError::Basis(format!(
            "subsurface basis: tolerance {} must be > 0",
            cfg.tolerance
        )));
    }
    Ok(())
}

fn geomspace(lo: f64, hi: f64, n: usize, mid: bool) -> Vec<f64> {
    if n == 1 || lo == hi {
        return vec![(lo * hi).sqrt()];
    }
    let steps = if mid { n } else { n - 1 };
    (0..n)
        .map(|i| {
            let t = (i as f64 + if mid { 0.5 } else { 0.0 }) / steps as f64;
            lo * (hi / lo).powf(t)
        })
        .collect()
}

fn linspace(lo: f64, hi: f64, n: usize, mid: bool) -> Vec<f64> {
    if n == 1 || lo == hi {
        return vec![0.5 * (lo + hi)];
    }
    let steps = if mid { n } else { n - 1 };
    (0..n)
        .map(|i| lo + (hi - lo) * (i as f64 + if mid { 0.5 } else { 0.0 }) / steps as f64)
        .collect()
}

/// The σ samples of the family: training (`mid = false`, grid nodes) or test (`mid = true`,
/// the points between them).
fn family(cfg: &SssBasisConfig, mid: bool) -> Vec<DipoleParams> {
    let (nl, na, ne) = if mid {
        (N_MFP - 1, N_ALPHA - 1, N_ETA - 1)
    } else {
        (N_MFP, N_ALPHA, N_ETA)
    };
    let (l_lo, l_hi) = (cfg.mfp_min, cfg.mfp_max);
    let mfps = if mid && l_lo < l_hi {
        // Geometric midpoints of the training nodes.
        let nodes = geomspace(l_lo, l_hi, N_MFP, false);
        nodes.windows(2).map(|w| (w[0] * w[1]).sqrt()).collect()
    } else {
        geomspace(l_lo, l_hi, nl, false)
    };
    let oma = if mid {
        let nodes = geomspace(ONE_MINUS_ALPHA[0], ONE_MINUS_ALPHA[1], N_ALPHA, false);
        nodes
            .windows(2)
            .map(|w| (w[0] * w[1]).sqrt())
            .collect::<Vec<_>>()
    } else {
        geomspace(ONE_MINUS_ALPHA[0], ONE_MINUS_ALPHA[1], na, false)
    };
    let etas = if mid {
        let mut e = linspace(cfg.eta_min, cfg.eta_max, ne, true);
        e.push(cfg.eta_min);
        e
    } else {
        linspace(cfg.eta_min, cfg.eta_max, ne, false)
    };
    let mut out = Vec::new();
    for &l in &mfps {
        for &o in &oma {
            for &e in &etas {
                out.push(DipoleParams::from_mfp(l, 1.0 - o, e));
            }
        }
    }
    out
}

impl SssBasis {
    /// Builds the basis: a Gram matrix on the radius grid over the blurred training
    /// profiles, a pivoted Cholesky and a small Jacobi eigensolve ([`crate::linalg`]).
    /// Deterministic, so a stack stores only the configuration.
    pub fn build(cfg: &SssBasisConfig) -> Result<SssBasis> {
        check(cfg)?;
        let warp_a = 0.25 * cfg.rho.min(cfg.mfp_min);
        let warp_span = (cfg.r_max / warp_a).asinh();
        let r_of = |t: f64| warp_a * (t * warp_span).sinh();
        let n = R_NODES;
        let radii: Vec<f64> = (0..n).map(|j| r_of((j as f64 + 0.5) / n as f64)).collect();
        let areas: Vec<f64> = (0..n)
            .map(|j| {
                let (a, b) = (r_of(j as f64 / n as f64), r_of((j + 1) as f64 / n as f64));
                std::f64::consts::PI * (b * b - a * a)
            })
            .collect();
        let sqrt_w: Vec<f64> = areas.iter().map(|a| a.sqrt()).collect();
        let edges: Vec<f64> = (0..=n).map(|j| r_of(j as f64 / n as f64)).collect();
        let (blur, blur_norm) = blur_matrix(&radii, &edges, &areas, BLUR_PER_RHO * cfg.rho);
        let profile = |p: &DipoleParams| -> Option<Vec<f64>> {
            let masses = annulus_masses(p, &edges);
            let mut f = apply_blur(&blur, &masses);
            f.iter_mut().zip(&sqrt_w).for_each(|(x, w)| *x *= w);
            let norm = f.iter().map(|x| x * x).sum::<f64>().sqrt();
            if !(norm > 0.0) || !norm.is_finite() {
                return None;
            }
            f.iter_mut().for_each(|x| *x /= norm);
            Some(f)
        };
        // Gram matrix of the radius grid: G = Σ f fᵀ over the training profiles (unweighted:
        // each profile is already normalised; `1.0·f` is `f` exactly).
        let mut gram = GramAccumulator::new(n);
        for p in family(cfg, false) {
            let Some(f) = profile(&p) else { continue };
            gram.add(1.0, &f);
        }
        let gram = gram.finish();
        let (lam, vecs) = top_eigenpairs(&gram, n);
        let rank = lam.len();
        let kmax = rank.min(MAX_SSS_BASES);
        if kmax == 0 {
            return Err(RelumeError::Basis("subsurface basis: empty family".into()));
        }
        // Error table over the test profiles (between the training samples).
        let tests: Vec<Vec<f64>> = family(cfg, true).iter().filter_map(profile).collect();
        let errors = error_table(&tests, &vecs, rank, kmax);
        let count = match cfg.bases {
            Some(b) => (b as usize).min(kmax),
            None => errors
                .iter()
                .find(|e| e.max_rel_l2 <= cfg.tolerance)
                .map_or(kmax, |e| e.bases),
        };
        let mut unit = vec![0.0f64; n * count];
        let mut table = vec![0.0f32; n * count];
        for j in 0..n {
            for k in 0..count {
                let v = vecs[j * rank + k];
                unit[j * count + k] = v;
                table[j * count + k] = (v / sqrt_w[j]) as f32;
            }
        }
        let mass_coef = mass_coefficients(&blur, &sqrt_w, &unit, count);
        Ok(SssBasis {
            cfg: cfg.clone(),
            count,
            warp_a,
            warp_span,
            radii,
            areas,
            edges,
            unit,
            mass_coef,
            blur,
            blur_norm,
            table,
            errors,
        })
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &SssBasisConfig {
        &self.cfg
    }

    /// Number of basis functions K.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Relative L2 error of the profiles over test σ between the training samples, for
    /// K = 1 … (up to [`MAX_SSS_BASES`]).
    pub fn error_table(&self) -> &[SssErrorRow] {
        &self.errors
    }

    /// `b_k(r)` for every k into `out[..count]` (linear interpolation between the nodes in the
    /// warped variable; the first node's value below it, 0 beyond `r_max`).
    #[inline]
    pub fn eval(&self, r: f32, out: &mut [f32]) {
        let k = self.count;
        let r = r as f64;
        if !(r <= self.cfg.r_max) {
            out[..k].fill(0.0);
            return;
        }
        let t = (r / self.warp_a).asinh() / self.warp_span * R_NODES as f64 - 0.5;
        if t <= 0.0 {
            out[..k].copy_from_slice(&self.table[..k]);
            return;
        }
        let j = (t as usize).min(R_NODES - 1);
        if j + 1 >= R_NODES {
            out[..k].copy_from_slice(&self.table[(R_NODES - 1) * k..R_NODES * k]);
            return;
        }
        let f = (t - j as f64) as f32;
        let (a, b) = (
            &self.table[j * k..(j + 1) * k],
            &self.table[(j + 1) * k..(j + 2) * k],
        );
        for ((o, x), y) in out[..k].iter_mut().zip(a).zip(b) {
            *o = x + f * (y - x);
        }
    }

    /// σ clamped into the basis' box: mean free path into [mfp_min, mfp_max], α′ into
    /// [0, ALPHA_MAX], η into [eta_min, eta_max]. Outside the box a profile is replaced by the
    /// nearest one the basis represents: a mean free path below mfp_min renders as a blur of
    /// mfp_min (towards the diffuse limit, see the module docs of `bssrdf`), above mfp_max as
    /// mfp_max.
    pub fn clamp(&self, p: &DipoleParams) -> DipoleParams {
        let mfp = (1.0 / p.sigma_tr).clamp(self.cfg.mfp_min, self.cfg.mfp_max);
        let mfp = if mfp.is_nan() { self.cfg.mfp_max } else { mfp };
        DipoleParams::from_mfp(
            mfp,
            if p.alpha_p.is_nan() {
                0.0
            } else {
                p.alpha_p.clamp(0.0, ALPHA_MAX)
            },
            if p.eta.is_nan() {
                self.cfg.eta_min
            } else {
                p.eta.clamp(self.cfg.eta_min, self.cfg.eta_max)
            },
        )
    }

    /// `s_k(σ) = ∫ (B·Rd_σ)(r) b_k(r) dA` for σ clamped by [`Self::clamp`], into `out[..count]`.
    pub fn coefficients(&self, p: &DipoleParams, out: &mut [f64]) {
        let p = self.clamp(p);
        let k = self.count;
        out[..k].fill(0.0);
        if p.alpha_p == 0.0 {
            return;
        }
        for m in 0..R_NODES {
            let (a, b) = (self.edges[m], self.edges[m + 1]);
            let mass = p.annulus(a * a, (b - a) * (b + a));
            if mass == 0.0 {
                continue;
            }
            for (o, c) in out[..k].iter_mut().zip(&self.mass_coef[m * k..(m + 1) * k]) {
                *o += mass * c;
            }
        }
    }

    /// The blurred profile `(B·Rd_σ)(r)` at any radius (1/area; the exact quantity the basis
    /// approximates, for brute-force references), σ clamped by [`Self::clamp`].
    pub fn blurred_profile(&self, p: &DipoleParams, r: f64) -> f64 {
        self.blurred_profile_fn(p)(r)
    }

    /// The blurred profile of σ as a function of r, with the annulus masses computed once
    /// (for brute-force sums over many radii).
    pub fn blurred_profile_fn(&self, p: &DipoleParams) -> impl Fn(f64) -> f64 + '_ {
        let profiles = self.blurred_profiles_fn(std::slice::from_ref(p));
        move |r: f64| {
            let mut value = [0.0];
            profiles(r, &mut value);
            value[0]
        }
    }

    /// The blurred profiles of several σ at once: `f(r, out)` writes one value per σ. The
    /// blur's weights depend on r alone, so a brute-force sum over many σ (channels,
    /// materials) computes them once per radius instead of once per σ.
    pub fn blurred_profiles_fn(&self, ps: &[DipoleParams]) -> impl Fn(f64, &mut [f64]) + '_ {
        let masses: Vec<Vec<f64>> = ps
            .iter()
            .map(|p| annulus_masses(&self.clamp(p), &self.edges))
            .collect();
        move |r: f64, out: &mut [f64]| {
            let (first, w) = blur_row(
                r,
                &self.radii,
                &self.edges,
                &self.areas,
                BLUR_PER_RHO * self.cfg.rho,
                Some(&self.blur_norm),
            );
            for (o, m) in out.iter_mut().zip(&masses) {
                *o = w.iter().zip(&m[first..]).map(|(w, m)| w * m).sum();
            }
        }
    }

    /// `Σ_k s_k b_k(r)` at radius r (for tests and reports).
    pub fn reconstruct(&self, coefs: &[f64], r: f32) -> f64 {
        let mut b = vec![0.0f32; self.count];
        self.eval(r, &mut b);
        b.iter().zip(coefs).map(|(b, c)| *b as f64 * c).sum()
    }

    /// Relative L2 error (area measure, on the node grid) of the K-term projection of σ's
    /// blurred profile, for σ clamped into the box.
    pub fn profile_error(&self, p: &DipoleParams) -> f64 {
        let p = self.clamp(p);
        let mut c = vec![0.0; self.count];
        self.coefficients(&p, &mut c);
        let f = apply_blur(&self.blur, &annulus_masses(&p, &self.edges));
        let (mut num, mut den) = (0.0, 0.0);
        for (j, fj) in f.iter().enumerate() {
            let g: f64 = (0..self.count)
                .map(|k| c[k] * self.unit[j * self.count + k] / self.areas[j].sqrt())
                .sum();
            num += (fj - g) * (fj - g) * self.areas[j];
            den += fj * fj * self.areas[j];
        }
        if den > 0.0 {
            (num / den).sqrt()
        } else {
            0.0
        }
    }
}

/// Mean and maximum relative L2 error of the unit-norm `tests` projected on the first
/// K = 1…`kmax` eigenvectors (`vecs`, `R_NODES × rank` row-major, orthonormal).
fn error_table(tests: &[Vec<f64>], vecs: &[f64], rank: usize, kmax: usize) -> Vec<SssErrorRow> {
    let n = R_NODES;
    let mut sum_err = vec![0.0f64; kmax + 1];
    let mut max_err = vec![0.0f64; kmax + 1];
    for f in tests {
        let mut resid2 = 1.0f64; // ‖f‖² = 1
        for k in 0..kmax {
            let c: f64 = (0..n).map(|j| f[j] * vecs[j * rank + k]).sum();
            resid2 -= c * c;
            let e = resid2.max(0.0).sqrt();
            sum_err[k + 1] += e;
            max_err[k + 1] = max_err[k + 1].max(e);
        }
    }
    (1..=kmax)
        .map(|k| SssErrorRow {
            bases: k,
            mean_rel_l2: sum_err[k] / tests.len().max(1) as f64,
            max_rel_l2: max_err[k],
        })
        .collect()
}

/// `c_mk = Σ_j √area_j · B_jm · v_jk`: the coefficient of basis k per unit mass in annulus
/// m, so a material's coefficients are a sum over its annulus masses
/// ([`SssBasis::coefficients`]).
fn mass_coefficients(blur: &BlurRows, sqrt_w: &[f64], unit: &[f64], count: usize) -> Vec<f64> {
    let mut mass_coef = vec![0.0f64; R_NODES * count];
    for (j, (first, w)) in blur.iter().enumerate() {
        for (i, bjm) in w.iter().enumerate() {
            let m = first + i;
            let s = bjm * sqrt_w[j];
            for k in 0..count {
                mass_coef[m * count + k] += s * unit[j * count + k];
            }
        }
    }
    mass_coef
}

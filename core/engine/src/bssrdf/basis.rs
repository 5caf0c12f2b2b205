//! The PCA basis of the dipole profile: `K(r, σ) ≈ Σ_k s_k(σ)·b_k(r)` (translucency paper §2.2).
//!
//! **What is factored.** Not the bare `Rd` but `Rd` blurred at the scale of the surface
//! samples: the 2D convolution of the profile with an isotropic Gaussian of standard deviation
//! 3ρ ([`BLUR_PER_RHO`]), ρ the radius of the area element of one sample (`√(A/(πN))`). The bake sums the profile at
//! sample points ρ apart, which cannot resolve anything finer; unblurred, the α′ → 1 spike
//! (width z_r, down to 10⁻³ mean free paths) makes the image depend on which sample happens to
//! lie nearest, and the PCA needs a basis function per octave of z_r (K = 12 left 5·10⁻³
//! relative error over half a decade of mean free path; blurred at 3ρ, 1.2·10⁻⁶). The blur keeps the
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
//! annulus masses and `R_NODES·K` multiply-adds (≈ 10–30 µs per channel in a release build). σ outside the box
//! is clamped into it (documented in [`SssBasis::coefficients`]).
//!
//! **Count.** The smallest K whose worst relative L2 error over a test set of σ *between* the
//! training samples is ≤ the tolerance, at most [`MAX_SSS_BASES`].

use serde::{Deserialize, Serialize};

use super::dipole::DipoleParams;
use super::mapping::ALPHA_MAX;
use crate::brdf::basis::top_eigenpairs;
use crate::{RelumeError, Result};

/// Standard deviation of the sample-scale blur in units of ρ. Samples are `h = ρ√π` apart
/// on average; a Gaussian of σ = 3ρ ≈ 1.7h holds ≈ 35 samples within 2σ, so the sum over
/// (stratified, jittered) samples of the blurred profile is a smooth quadrature: a uniformly
/// lit plane comes out within 2 % of its exact radiance (tests/subsurface.rs), where σ = ρ
/// (≈ 1 sample) gave errors up to 80 %.
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
    /// Builds the basis (≈ 0.3–1.2 s in a dev build: a 384² Gram matrix over 1 600 blurred
    /// profiles, a pivoted Cholesky and a small Jacobi eigensolve; deterministic, so a stack
    /// stores only the configuration).
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
        // Gram matrix of the radius grid: G = Σ f fᵀ over the training profiles.
        let mut gram = vec![0.0f64; n * n];
        for p in family(cfg, false) {
            let Some(f) = profile(&p) else { continue };
            for i in 0..n {
                let fi = f[i];
                if fi == 0.0 {
                    continue;
                }
                let row = &mut gram[i * n..i * n + i + 1];
                for (g, fj) in row.iter_mut().zip(&f[..=i]) {
                    *g += fi * fj;
                }
            }
        }
        for i in 0..n {
            for j in 0..i {
                gram[j * n + i] = gram[i * n + j];
            }
        }
        let (lam, vecs) = top_eigenpairs(&gram, n);
        let rank = lam.len();
        let kmax = rank.min(MAX_SSS_BASES);
        if kmax == 0 {
            return Err(RelumeError::Basis("subsurface basis: empty family".into()));
        }
        let _ = lam;
        // Error table over the test profiles (between the training samples).
        let tests: Vec<Vec<f64>> = family(cfg, true).iter().filter_map(profile).collect();
        let mut sum_err = vec![0.0f64; kmax + 1];
        let mut max_err = vec![0.0f64; kmax + 1];
        for f in &tests {
            let mut resid2 = 1.0f64; // ‖f‖² = 1
            for k in 0..kmax {
                let c: f64 = (0..n).map(|j| f[j] * vecs[j * rank + k]).sum();
                resid2 -= c * c;
                let e = resid2.max(0.0).sqrt();
                sum_err[k + 1] += e;
                max_err[k + 1] = max_err[k + 1].max(e);
            }
        }
        let errors: Vec<SssErrorRow> = (1..=kmax)
            .map(|k| SssErrorRow {
                bases: k,
                mean_rel_l2: sum_err[k] / tests.len().max(1) as f64,
                max_rel_l2: max_err[k],
            })
            .collect();
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
        // c_mk = Σ_j √area_j · B_jm · v_jk.
        let mut mass_coef = vec![0.0f64; n * count];
        for (j, (first, w)) in blur.iter().enumerate() {
            for (i, bjm) in w.iter().enumerate() {
                let m = first + i;
                let s = bjm * sqrt_w[j];
                for k in 0..count {
                    mass_coef[m * count + k] += s * unit[j * count + k];
                }
            }
        }
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
        let p = self.clamp(p);
        let masses = annulus_masses(&p, &self.edges);
        let (first, w) = blur_row(
            r,
            &self.radii,
            &self.edges,
            &self.areas,
            BLUR_PER_RHO * self.cfg.rho,
            Some(&self.blur_norm),
        );
        w.iter().zip(&masses[first..]).map(|(w, m)| w * m).sum()
    }

    /// The blurred profile of σ as a function of r, with the annulus masses computed once
    /// (for brute-force sums over many radii).
    pub fn blurred_profile_fn(&self, p: &DipoleParams) -> impl Fn(f64) -> f64 + '_ {
        let p = self.clamp(p);
        let masses = annulus_masses(&p, &self.edges);
        move |r: f64| {
            let (first, w) = blur_row(
                r,
                &self.radii,
                &self.edges,
                &self.areas,
                BLUR_PER_RHO * self.cfg.rho,
                Some(&self.blur_norm),
            );
            w.iter().zip(&masses[first..]).map(|(w, m)| w * m).sum()
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

/// Mass of `Rd_σ` over every cell (annulus) of the grid: exact, from the disc integral.
fn annulus_masses(p: &DipoleParams, edges: &[f64]) -> Vec<f64> {
    edges
        .windows(2)
        .map(|e| p.annulus(e[0] * e[0], (e[1] - e[0]) * (e[1] + e[0])))
        .collect()
}

fn apply_blur(blur: &[(usize, Vec<f64>)], masses: &[f64]) -> Vec<f64> {
    blur.iter()
        .map(|(first, w)| w.iter().zip(&masses[*first..]).map(|(w, m)| w * m).sum())
        .collect()
}

/// `e^{−x}·I₀(x)` for x ≥ 0 (Abramowitz & Stegun 9.8.1–9.8.2, relative error < 2·10⁻⁷).
fn i0e(x: f64) -> f64 {
    if x <= 3.75 {
        let t = (x / 3.75) * (x / 3.75);
        let i0 = 1.0
            + t * (3.515_622_9
                + t * (3.089_942_4
                    + t * (1.206_749_2 + t * (0.265_973_2 + t * (0.036_076_8 + t * 0.004_581_3)))));
        i0 * (-x).exp()
    } else {
        let t = 3.75 / x;
        let p = 0.398_942_28
            + t * (0.013_285_92
                + t * (0.002_253_19
                    + t * (-0.001_575_65
                        + t * (0.009_162_81
                            + t * (-0.020_577_06
                                + t * (0.026_355_37 + t * (-0.016_476_33 + t * 0.003_923_77)))))));
        p / x.sqrt()
    }
}

/// Angular average of the 2D Gaussian of standard deviation `sd` between a point at radius r
/// and the ring of radius s: `e^{−(r−s)²/(2sd²)}·i0e(rs/sd²)/(2π sd²)`.
fn ring_gauss(r: f64, s: f64, sd: f64) -> f64 {
    let v = sd * sd;
    (-(r - s) * (r - s) / (2.0 * v)).exp() * i0e(r * s / v) / (2.0 * std::f64::consts::PI * v)
}

/// Sub-rings per cell when averaging the Gaussian over a source cell.
const SUB_RINGS: usize = 6;

/// Unnormalised blur weights from every source cell to radius r: the Gaussian averaged over
/// the cell (SUB_RINGS sub-rings, area-weighted) for cells narrower than sd; cells wider
/// than sd (far out, where the profile varies on scales ≫ ρ) are not blurred (weight
/// 1/area for the cell holding r). Optional column normalisation `norm`.
fn blur_row(
    r: f64,
    radii: &[f64],
    edges: &[f64],
    areas: &[f64],
    sd: f64,
    norm: Option<&[f64]>,
) -> (usize, Vec<f64>) {
    let n = radii.len();
    let lo = edges
        .partition_point(|e| *e < r - 8.0 * sd)
        .saturating_sub(1);
    let hi = edges.partition_point(|e| *e <= r + 8.0 * sd).min(n);
    let cell_of_r = edges
        .partition_point(|e| *e <= r)
        .saturating_sub(1)
        .min(n - 1);
    let (lo, hi) = (lo.min(cell_of_r), hi.max(cell_of_r + 1));
    let mut w = vec![0.0; hi - lo];
    for m in lo..hi {
        let (a, b) = (edges[m], edges[m + 1]);
        let v = if b - a > sd {
            if m == cell_of_r {
                1.0 / areas[m]
            } else {
                0.0
            }
        } else {
            let mut acc = 0.0;
            let mut wsum = 0.0;
            for q in 0..SUB_RINGS {
                let s0 = a + (b - a) * q as f64 / SUB_RINGS as f64;
                let s1 = a + (b - a) * (q + 1) as f64 / SUB_RINGS as f64;
                let ws = s1 * s1 - s0 * s0;
                acc += ws * ring_gauss(r, 0.5 * (s0 + s1), sd);
                wsum += ws;
            }
            acc / wsum
        };
        w[m - lo] = v * norm.map_or(1.0, |nm| nm[m]);
    }
    (lo, w)
}

/// The blur matrix on the grid, columns normalised so each source cell's mass is kept:
/// `Σ_j B_jm·area_j = 1`.
type BlurRows = Vec<(usize, Vec<f64>)>;

fn blur_matrix(radii: &[f64], edges: &[f64], areas: &[f64], sd: f64) -> (BlurRows, Vec<f64>) {
    let rows: Vec<(usize, Vec<f64>)> = radii
        .iter()
        .map(|&r| blur_row(r, radii, edges, areas, sd, None))
        .collect();
    let mut colsum = vec![0.0f64; radii.len()];
    for (j, (first, w)) in rows.iter().enumerate() {
        for (i, v) in w.iter().enumerate() {
            colsum[first + i] += v * areas[j];
        }
    }
    let norm: Vec<f64> = colsum
        .iter()
        .map(|c| if *c > 0.0 { 1.0 / c } else { 0.0 })
        .collect();
    let rows = rows
        .into_iter()
        .map(|(first, w)| {
            let w = w
                .iter()
                .enumerate()
                .map(|(i, v)| v * norm[first + i])
                .collect();
            (first, w)
        })
        .collect();
    (rows, norm)
}

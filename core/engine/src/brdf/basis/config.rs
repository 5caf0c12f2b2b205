//! What a basis is built from: the range of exponents, the lobes sampled over it, the grid
//! the errors are measured on, and the choices (count, spacing, measure, weighting, the
//! constant in the fit) with their checks. A stack header stores this configuration and the
//! basis is rebuilt from it on load, so every field has a serde default that keeps older
//! headers meaning what they meant.

use serde::{Deserialize, Serialize};

use crate::{RelumeError, Result};

/// Spacing becomes geometric above this `ns_max/ns_min` ([`LobeSpacing::Auto`]).
const AUTO_LOG_RATIO: f32 = 256.0;

/// How a basis is built. The default is the paper's: ns ∈ [1, 200], 200 lobes, 30×30×60
/// grid, `N_b = 6` — with Relume's default lobe weighting ([`LobeWeighting::Capped`]) and the
/// diffuse basis in the specular fit ([`Self::constant_in_fit`]); set `weighting: Energy`
/// and `constant_in_fit: false` for the paper's literal PCA.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BasisConfig {
    /// Smallest exponent the basis represents (> 0). Principled roughness 1 maps to ~0.
    pub ns_min: f32,
    /// Largest exponent (under the analytic Principled mapping roughness 0.32 ↔ 200 and
    /// 0.1 ↔ 20,000; the fitted mapping the core uses gives about 1.75× those below 0.5).
    pub ns_max: f32,
    /// Specular lobes sampled for the PCA (the paper's `N_s − 1 = 200`); at most
    /// [`MAX_LOBES`], checked as a header is parsed.
    #[serde(deserialize_with = "lobes_within_limits")]
    pub lobes: u32,
    /// (θi, θo, φ) grid the errors are measured on (and, when it resolves the lobes, the
    /// PCA is run on): the paper's 30×30×60 is a 3° grid. Each side at most
    /// [`MAX_GRID_SIDE`], the product at most [`MAX_GRID_CELLS`], checked as a header is
    /// parsed.
    #[serde(deserialize_with = "grid_within_limits")]
    pub grid: [u32; 3],
    /// How many bases (`N_b`, diffuse included).
    pub count: BasisCount,
    /// Spacing of the sampled lobes over [ns_min, ns_max].
    #[serde(default)]
    pub spacing: LobeSpacing,
    /// Measure the PCA runs under.
    #[serde(default)]
    pub measure: PcaMeasure,
    /// Lobe weighting of the PCA.
    #[serde(default)]
    pub weighting: LobeWeighting,
    /// Whether the specular fit also uses the diffuse basis `1/π`: a lobe is approximated
    /// by `c₀(ns)/π + Σ_{i≥1} c̃ᵢ(ns)·ρ̃ᵢ`, the PCA running on the lobes' residuals after
    /// projecting out the constant (so the `ρ̃ᵢ` are orthogonal to it and `N_b` functions
    /// serve the specular part instead of `N_b − 1`). `false` is the paper's eq. 22 (`c₀ = 0`).
    /// Default `true` (module docs, "Constant in the fit"); see [`super::BrdfBasis::spec_constant`].
    #[serde(default = "default_constant_in_fit")]
    pub constant_in_fit: bool,
}

/// Most specular lobes a basis may sample. Every bake and preset uses 200 (the paper's);
/// the build's Gram matrix grows with the square of the count (2048 lobes: 32 MiB and a
/// few seconds), so 10× the real count still builds in seconds, while a stack header or a
/// command line claiming billions would allocate tens of GB before any other check.
pub const MAX_LOBES: u32 = 2048;
/// Largest side of the (θi, θo, φ) error grid: the real grid is 30×30×60 (3°); 4096 cells
/// of 0.02° along θ are far finer than any lobe the basis tables resolve.
pub const MAX_GRID_SIDE: u32 = 4096;
/// Most cells of the error grid (the product of its sides), which the build visits one by
/// one: 2²⁶ ≈ 67 million holds a 300×300×600 grid (0.3°, 1000× the real 54 000 cells,
/// about a second), while 3000×3000×6000 would loop for hours.
pub const MAX_GRID_CELLS: u64 = 1 << 26;

/// The limits on what a basis build allocates and loops over ([`MAX_LOBES`],
/// [`MAX_GRID_SIDE`], [`MAX_GRID_CELLS`]): the one place they are checked, by the stack
/// header's parser (a hostile file), [`super::BrdfBasis::build`] and the command line's
/// `relume basis` alike, before anything of that size is allocated.
pub fn check_basis_limits(lobes: u32, grid: [u32; 3]) -> Result<()> {
    let e = |m: String| Err(RelumeError::Basis(m));
    if lobes > MAX_LOBES {
        return e(format!(
            "{lobes} specular lobes exceed the limit of {MAX_LOBES} (bakes use 200)"
        ));
    }
    if let Some(side) = grid.iter().find(|&&g| g > MAX_GRID_SIDE) {
        return e(format!(
            "grid side {side} (grid {}×{}×{}) exceeds the limit of {MAX_GRID_SIDE} (bakes use 30×30×60)",
            grid[0], grid[1], grid[2]
        ));
    }
    let cells = grid.iter().map(|&g| g as u64).product::<u64>();
    if cells > MAX_GRID_CELLS {
        return e(format!(
            "grid {}×{}×{} has {cells} cells, above the limit of {MAX_GRID_CELLS} (bakes use 30×30×60 = 54000)",
            grid[0], grid[1], grid[2]
        ));
    }
    Ok(())
}

fn lobes_within_limits<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<u32, D::Error> {
    let lobes = u32::deserialize(d)?;
    check_basis_limits(lobes, [1; 3]).map_err(serde::de::Error::custom)?;
    Ok(lobes)
}

fn grid_within_limits<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<[u32; 3], D::Error> {
    let grid = <[u32; 3]>::deserialize(d)?;
    check_basis_limits(0, grid).map_err(serde::de::Error::custom)?;
    Ok(grid)
}

fn default_constant_in_fit() -> bool {
    true
}

impl Default for BasisConfig {
    fn default() -> Self {
        BasisConfig {
            ns_min: 1.0,
            ns_max: 200.0,
            lobes: 200,
            grid: [30, 30, 60],
            count: BasisCount::Fixed(6),
            spacing: LobeSpacing::default(),
            measure: PcaMeasure::default(),
            weighting: LobeWeighting::default(),
            constant_in_fit: default_constant_in_fit(),
        }
    }
}

/// How many bases to keep.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub enum BasisCount {
    /// `N_b`, the diffuse basis included (the paper: 6).
    Fixed(u32),
    /// The smallest `N_b` whose maximum relative L2 error over the lobes is ≤ this
    /// (e.g. 0.03 = 3 %), on the grid and, when the PCA ran under it, the continuum measure.
    Tolerance(f32),
}

/// Spacing of the sampled lobes.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
pub enum LobeSpacing {
    /// Uniform when `ns_max/ns_min ≤ 256` (the paper's [1, 200]), geometric otherwise.
    #[default]
    Auto,
    /// Uniform in ns (the paper).
    Uniform,
    /// Geometric (uniform in ln ns).
    Log,
}

/// The measure the PCA (Gram matrix, coefficients) is computed under.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
pub enum PcaMeasure {
    /// `Grid` when the half width of the narrowest lobe, `acos(2^(−1/ns_max))`, is at least
    /// the grid's coarsest angular step (θ: (π/2)/n, φ: π/n); `Continuum` otherwise.
    #[default]
    Auto,
    /// The configured grid (the paper).
    Grid,
    /// The continuum limit of the uniform (θi, θo, φ) measure.
    Continuum,
}

/// Weighting of the lobes in the PCA.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub enum LobeWeighting {
    /// Each lobe as it is (the paper's literal PCA): the sum of squared absolute errors
    /// is minimised, which favours the sharp lobes (their norm grows like √ns).
    Energy,
    /// Each lobe normalised to unit norm first: the sum of squared relative errors is
    /// minimised. Lower maximum relative error for the same count (see the tests).
    Unit,
    /// `Energy`, then the lobes whose relative error exceeds the cap are re-weighted
    /// (Lawson's iteration, `w_j ← w_j·(e_j/cap)²`, ≤ 40 rounds) until none does or the
    /// maximum stops falling: the sum of squared errors stays as low as the cap allows. In
    /// [`BasisCount::Tolerance`] mode the tolerance is the cap. The default, with 0.029:
    /// the paper's N_b = 6 then stays below 3 % at worst with the constant in the fit
    /// (docs/measurements.md, "BRDF basis").
    Capped(f32),
}

impl Default for LobeWeighting {
    fn default() -> Self {
        LobeWeighting::Capped(0.029)
    }
}

/// The configuration's own consistency (what [`super::BrdfBasis::build`] refuses up front).
pub(crate) fn check_config(cfg: &BasisConfig) -> Result<()> {
    let e = |m: String| Err(RelumeError::Basis(m));
    if !cfg.ns_min.is_finite() || !cfg.ns_max.is_finite() {
        return e(format!(
            "ns range [{}, {}] is not finite",
            cfg.ns_min, cfg.ns_max
        ));
    }
    if !(cfg.ns_min > 0.0) {
        return e(format!("ns_min must be > 0, got {}", cfg.ns_min));
    }
    if !(cfg.ns_min < cfg.ns_max) {
        return e(format!(
            "ns_min ({}) must be < ns_max ({})",
            cfg.ns_min, cfg.ns_max
        ));
    }
    if cfg.lobes < 2 {
        return e(format!(
            "at least 2 specular lobes are needed, got {}",
            cfg.lobes
        ));
    }
    check_basis_limits(cfg.lobes, cfg.grid)?;
    if cfg.grid.contains(&0) {
        return e(format!("grid sizes must be ≥ 1, got {:?}", cfg.grid));
    }
    match cfg.count {
        BasisCount::Fixed(n) => {
            if n == 0 || n > cfg.lobes + 1 {
                return e(format!(
                    "count must be in [1, lobes+1 = {}], got {n}",
                    cfg.lobes + 1
                ));
            }
        }
        BasisCount::Tolerance(t) => {
            if !t.is_finite() || !(t > 0.0) {
                return e(format!("tolerance must be finite and > 0, got {t}"));
            }
        }
    }
    Ok(())
}

/// The exponents of the sampled lobes, `cfg.lobes` of them over `[ns_min, ns_max]`.
pub(super) fn sample_ns(cfg: &BasisConfig) -> Vec<f64> {
    let l = cfg.lobes as usize;
    let (a, b) = (cfg.ns_min as f64, cfg.ns_max as f64);
    let log = match cfg.spacing {
        LobeSpacing::Uniform => false,
        LobeSpacing::Log => true,
        LobeSpacing::Auto => cfg.ns_max / cfg.ns_min > AUTO_LOG_RATIO,
    };
    (0..l)
        .map(|j| {
            let t = j as f64 / (l - 1) as f64;
            if log {
                a * (b / a).powf(t)
            } else {
                a + t * (b - a)
            }
        })
        .collect()
}

//! The measures on δ the PCA and the error statistics are computed under (module docs,
//! "Measures as atoms in δ" and "Narrow lobes and the grid"): the configured (θi, θo, φ)
//! grid and its continuum limit, both as atoms on a fine graded δ mesh, so nothing after
//! this step depends on how many grid points there are.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

use super::config::{BasisConfig, PcaMeasure};

/// Bins of the fine δ mesh the measures live on.
pub(super) const MESH_BINS: usize = 1024;

/// The measures one build works with: the configured grid always (the errors are reported
/// on it), and its continuum limit when the grid cannot resolve the narrowest lobe — the PCA
/// then runs under the continuum.
pub(super) struct Measures {
    pub grid: Atoms,
    pub continuum: Option<Atoms>,
}

impl Measures {
    pub fn new(cfg: &BasisConfig) -> Measures {
        let mesh = Mesh::new(cfg.ns_max as f64);
        let grid = grid_atoms(cfg.grid, &mesh);
        let use_grid = match cfg.measure {
            PcaMeasure::Grid => true,
            PcaMeasure::Continuum => false,
            PcaMeasure::Auto => grid_resolves(cfg),
        };
        let continuum = if use_grid {
            None
        } else {
            Some(continuum_atoms(&mesh))
        };
        Measures { grid, continuum }
    }

    /// The measure the PCA runs under.
    pub fn pca(&self) -> &Atoms {
        self.continuum.as_ref().unwrap_or(&self.grid)
    }

    /// Whether the PCA runs under the grid itself.
    pub fn pca_on_grid(&self) -> bool {
        self.continuum.is_none()
    }
}

/// Half width (radians) of the lobe `cos^ns δ`: where it falls to 1/2.
fn half_width(ns: f64) -> f64 {
    (0.5f64).powf(1.0 / ns).acos()
}

fn grid_resolves(cfg: &BasisConfig) -> bool {
    let step = (FRAC_PI_2 / cfg.grid[0] as f64)
        .max(FRAC_PI_2 / cfg.grid[1] as f64)
        .max(PI / cfg.grid[2] as f64);
    half_width(cfg.ns_max as f64) >= step
}

/// A discrete measure on δ: atoms at `x = ln cos δ` with weights summing to 1.
#[derive(Clone, Debug)]
pub(super) struct Atoms {
    pub(super) x: Vec<f64>,
    pub(super) w: Vec<f64>,
}

/// The fine δ mesh: `δ(u) = s·(e^{βu} − 1)`, `u ∈ [0, 1]`, `δ(1) = π/2`, `s` a quarter of
/// the narrowest lobe's width scale `1/√(ns_max+2)`.
pub(super) struct Mesh {
    s: f64,
    beta: f64,
}

impl Mesh {
    pub(super) fn new(ns_max: f64) -> Mesh {
        let s = 0.25 / (ns_max + 2.0).sqrt();
        Mesh {
            s,
            beta: (1.0 + FRAC_PI_2 / s).ln(),
        }
    }
    pub(super) fn edge(&self, i: usize) -> f64 {
        if i >= MESH_BINS {
            return FRAC_PI_2;
        }
        self.s * ((self.beta * i as f64 / MESH_BINS as f64).exp() - 1.0)
    }
    fn bin(&self, delta: f64) -> usize {
        let u = (1.0 + delta.max(0.0) / self.s).ln() / self.beta;
        ((u * MESH_BINS as f64) as usize).min(MESH_BINS - 1)
    }
}

/// Cell centres of the (θi, θo, φ) grid, binned on the mesh with the mean `x` per bin.
pub(super) fn grid_atoms(grid: [u32; 3], mesh: &Mesh) -> Atoms {
    let [gi, go, gp] = grid.map(|g| g as usize);
    let ti: Vec<(f64, f64)> = (0..gi)
        .map(|a| ((a as f64 + 0.5) * FRAC_PI_2 / gi as f64).sin_cos())
        .collect();
    let to: Vec<(f64, f64)> = (0..go)
        .map(|a| ((a as f64 + 0.5) * FRAC_PI_2 / go as f64).sin_cos())
        .collect();
    let cp: Vec<f64> = (0..gp)
        .map(|c| ((c as f64 + 0.5) * PI / gp as f64).cos())
        .collect();
    let sym = gi == go;
    let mut wsum = vec![0.0; MESH_BINS];
    let mut xsum = vec![0.0; MESH_BINS];
    let total = (gi * go * gp) as f64;
    for (a, &(si, ci)) in ti.iter().enumerate() {
        for (b, &(so, co)) in to.iter().enumerate() {
            let w = if !sym {
                1.0
            } else if b < a {
                continue;
            } else if b == a {
                1.0
            } else {
                2.0
            };
            for &c in &cp {
                let h2 = 2.0 * (1.0 + ci * co + si * so * c);
                let cd = ((ci + co) / h2.sqrt()).min(1.0);
                let bin = mesh.bin(cd.acos());
                wsum[bin] += w;
                xsum[bin] += w * cd.ln();
            }
        }
    }
    let mut atoms = Atoms {
        x: vec![],
        w: vec![],
    };
    for q in 0..MESH_BINS {
        if wsum[q] > 0.0 {
            atoms.x.push(xsum[q] / wsum[q]);
            atoms.w.push(wsum[q] / total);
        }
    }
    atoms
}

/// Gauss–Legendre nodes and weights on [0, 1].
pub(super) fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push(((1.0 - x) / 2.0, w / 2.0));
    }
    out
}

/// φ-measure (out of π) of `{φ : δ(θi, θo, φ) < t}`: δ decreases monotonically in φ, so it is
/// `π − acos(K)` with `K` in closed form.
fn phi_measure(ci: f64, si: f64, co: f64, so: f64, cos2t: f64) -> f64 {
    let num = (ci + co) * (ci + co) / (2.0 * cos2t) - 1.0 - ci * co;
    let den = si * so;
    if num >= den {
        PI
    } else if num <= -den {
        0.0
    } else {
        PI - (num / den).acos()
    }
}

/// `P(δ < t)` under the uniform measure on `[0, π/2]² × [0, π]`: exact in φ, Gauss–Legendre
/// over `a = (θi+θo)/2` (intervals split at t, geometric towards 0 where the integrand goes
/// like 1/sin a) and `d = θo − θi ∈ [0, min(2t, 2a, π−2a)]` (substituted `d = D(1−s²)` to
/// smooth the square-root edge at `d = 2t`).
pub(super) fn continuum_cdf(t: f64, gla: &[(f64, f64)], gld: &[(f64, f64)]) -> f64 {
    if t >= FRAC_PI_2 {
        return 1.0;
    }
    if t <= 0.0 {
        return 0.0;
    }
    let cos2t = t.cos().powi(2);
    let mut cuts = vec![0.0, 0.5 * t.min(FRAC_PI_4)];
    let mut x = t;
    while x < FRAC_PI_4 {
        cuts.push(x);
        x *= 2.0;
    }
    cuts.push(FRAC_PI_4);
    if FRAC_PI_2 - t > FRAC_PI_4 {
        cuts.push(FRAC_PI_2 - t);
    }
    cuts.push(FRAC_PI_2);
    cuts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-15);
    let mut total = 0.0;
    for w in cuts.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        let len = hi - lo;
        if len <= 0.0 {
            continue;
        }
        for &(ua, wa) in gla {
            let a = lo + len * ua;
            let dmax = (2.0 * t).min(2.0 * a).min(PI - 2.0 * a);
            if dmax <= 0.0 {
                continue;
            }
            let mut inner = 0.0;
            for &(us, ws) in gld {
                let d = dmax * (1.0 - us * us);
                let (si, ci) = (a - 0.5 * d).sin_cos();
                let (so, co) = (a + 0.5 * d).sin_cos();
                inner += ws * 2.0 * dmax * us * phi_measure(ci, si, co, so, cos2t);
            }
            total += wa * len * inner;
        }
    }
    // ×2 for d < 0; normalised by the volume π·(π/2)².
    (2.0 * total / (PI * FRAC_PI_2 * FRAC_PI_2)).clamp(0.0, 1.0)
}

/// The continuum limit of the uniform grid measure, as atoms at the mesh bins' midpoints.
fn continuum_atoms(mesh: &Mesh) -> Atoms {
    let gla = gauss_legendre(8);
    let gld = gauss_legendre(12);
    let cdf: Vec<f64> = (0..=MESH_BINS)
        .map(|i| continuum_cdf(mesh.edge(i), &gla, &gld))
        .collect();
    let mut atoms = Atoms {
        x: vec![],
        w: vec![],
    };
    for q in 0..MESH_BINS {
        let w = cdf[q + 1] - cdf[q];
        if w > 0.0 {
            let mid = 0.5 * (mesh.edge(q) + mesh.edge(q + 1));
            atoms.x.push(mid.cos().ln());
            atoms.w.push(w);
        }
    }
    let s: f64 = atoms.w.iter().sum();
    atoms.w.iter_mut().for_each(|w| *w /= s);
    atoms
}

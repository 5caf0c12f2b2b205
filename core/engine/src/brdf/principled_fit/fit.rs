//! The fit behind the table: for each roughness of [`ROUGHNESS`], the Blinn–Phong
//! `Kd/π + Ks·(ns+2)/(8π)·cos^ns δ` closest to [`CyclesPrincipled`] in reflected radiance.
//!
//! **Objective.** `∫∫ (f_BP − f_Cycles)² cos θi cos θo dωi dωo` over both hemispheres: the
//! squared error of reflected radiance under incident light that is white noise over
//! directions, averaged over views in proportion to the projected area they see. It is
//! chosen because the relight has no fixed lighting (any edit is lit by the scene's own
//! lights and bounces) and the weight is symmetric; with `Kd` free, its normal equations
//! make the residual integrate to zero, so the fitted surface reflects the same energy as
//! Cycles' under uniform light whenever the constraints below are not active.
//!
//! **Unknowns.** `ns` per roughness row (a log-scale search, shared by every colour and IOR
//! so the basis range of a material does not depend on its colour), then `Kd, Ks` per
//! target by constrained linear least squares: `Kd, Ks ≥ 0`, `Kd + Ks ≤ 1` (the energy rule
//! every Relume material meets). Targets: metals at base colours [`METAL_BASE`] — below
//! roughness [`METAL_DIFFUSE_FROM`] with `Kd = 0` (Cycles' metallic layer has no diffuse
//! part; on a narrow lobe a `Kd` standing in for the specular energy the lobe cannot carry
//! matches uniform light but lights the whole sphere where Cycles shows a small highlight:
//! measured 1.3× too bright at roughness 0.1, docs/principled_fit.md), above it with `Kd`
//! free for GGX's broad tails; dielectrics at specular F0
//! [`DIELECTRIC_F0`]: base colour 0 constrained, plus the unconstrained fit of the part
//! linear in the base colour (a dielectric's BRDF is linear in it), so that the lookup's
//! clamp only acts near base colour 1.

use std::f64::consts::PI;

use super::grid::{Row, DIELECTRIC_F0, METAL_BASE};
use crate::brdf::blinn_phong::lobe;
use crate::brdf::cycles_principled::quadrature::{incident_nodes, Resolution};
use crate::brdf::cycles_principled::CyclesPrincipled;
use crate::brdf::principled::Principled;
use crate::brdf::principled::{roughness_to_ns, NS_MAX, NS_MIN};

/// Roughness from which a metal's fit may use `Kd` (module docs): an approximation chosen
/// by measurement, stated as such.
pub const METAL_DIFFUSE_FROM: f64 = 0.2;

/// View nodes (midpoints in cos θo) of the objective.
const VIEW_NODES: usize = 24;

/// One (ωi, ωo) configuration of the objective with its weight.
#[derive(Clone, Copy)]
struct Sample {
    cos_i: f64,
    cos_o: f64,
    cos_h: f64,
    cos_d: f64,
    w: f64,
}

/// The quadrature of the objective for GGX width `alpha`.
fn samples(alpha: f64) -> Vec<Sample> {
    let mut out = Vec::new();
    for k in 0..VIEW_NODES {
        let cos_o = (k as f64 + 0.5) / VIEW_NODES as f64;
        let w_o = 2.0 * cos_o / VIEW_NODES as f64;
        incident_nodes(cos_o, alpha, Resolution::FINE, |n| {
            out.push(Sample {
                cos_i: n.cos_i,
                cos_o,
                cos_h: n.cos_h,
                cos_d: n.cos_d,
                w: w_o * n.cos_i * n.d_omega_i,
            })
        });
    }
    out
}

/// Cycles' BRDF (first channel) at every sample.
fn target(model: &CyclesPrincipled, s: &[Sample]) -> Vec<f64> {
    s.iter()
        .map(|s| model.eval_cosines(s.cos_i, s.cos_o, s.cos_h, s.cos_d)[0])
        .collect()
}

fn grey(base: f64, metallic: f32, roughness: f64, f0: f64) -> Principled {
    let sf = f0.clamp(0.0, 1.0).sqrt();
    Principled {
        base_color: [base as f32; 3],
        metallic,
        roughness: roughness as f32,
        ior: if sf >= 1.0 {
            f32::INFINITY
        } else {
            ((1.0 + sf) / (1.0 - sf)) as f32
        },
        specular_ior_level: 0.5,
    }
}

/// The normal equations of `Kd/π + Ks·lobe` against one target.
struct Normal {
    g11: f64,
    g12: f64,
    g22: f64,
    b1: f64,
    b2: f64,
    c: f64,
}

impl Normal {
    fn new(s: &[Sample], lobe_values: &[f64], t: &[f64]) -> Normal {
        let mut n = Normal {
            g11: 0.0,
            g12: 0.0,
            g22: 0.0,
            b1: 0.0,
            b2: 0.0,
            c: 0.0,
        };
        let d = 1.0 / PI;
        for ((s, l), t) in s.iter().zip(lobe_values).zip(t) {
            n.g11 += s.w * d * d;
            n.g12 += s.w * d * l;
            n.g22 += s.w * l * l;
            n.b1 += s.w * d * t;
            n.b2 += s.w * l * t;
            n.c += s.w * t * t;
        }
        n
    }

    fn objective(&self, kd: f64, ks: f64) -> f64 {
        kd * kd * self.g11 + 2.0 * kd * ks * self.g12 + ks * ks * self.g22
            - 2.0 * (kd * self.b1 + ks * self.b2)
            + self.c
    }

    /// The least-squares `Ks` with `Kd = 0`, `0 ≤ Ks ≤ 1`: a metal (Cycles' metallic layer has
    /// no diffuse part, and a `Kd` standing in for its missing specular energy shows as a
    /// matte haze on a smooth metal).
    fn solve_specular(&self) -> (f64, f64) {
        let ks = self.b2 / self.g22;
        (
            0.0,
            if ks.is_finite() {
                ks.clamp(0.0, 1.0)
            } else {
                0.0
            },
        )
    }

    /// The unconstrained least-squares `(Kd, Ks)`, if the two functions are not nearly
    /// collinear (a lobe with `ns → 0` is a constant, like the diffuse term: the system is
    /// then ill-conditioned and would trade huge opposite `Kd`, `Ks`).
    fn solve_free(&self) -> Option<(f64, f64)> {
        let det = self.g11 * self.g22 - self.g12 * self.g12;
        (det > 1e-3 * self.g11 * self.g22).then(|| {
            (
                (self.b1 * self.g22 - self.b2 * self.g12) / det,
                (self.b2 * self.g11 - self.b1 * self.g12) / det,
            )
        })
    }

    /// The least-squares `(Kd, Ks)` with `Kd, Ks ≥ 0`, `Kd + Ks ≤ 1`: the free minimum when
    /// it is feasible, else the best point on the boundary of the triangle.
    fn solve(&self) -> (f64, f64) {
        if let Some((kd, ks)) = self.solve_free() {
            if kd >= 0.0 && ks >= 0.0 && kd + ks <= 1.0 {
                return (kd, ks);
            }
        }
        let clip = |x: f64| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        let ks_only = clip(self.b2 / self.g22);
        let kd_only = clip(self.b1 / self.g11);
        // Kd = 1 − t, Ks = t: minimise the quadratic in t.
        let a = self.g11 - 2.0 * self.g12 + self.g22;
        let b = (self.b2 - self.b1) - (self.g12 - self.g11);
        let t = clip(b / a);
        [(0.0, ks_only), (kd_only, 0.0), (1.0 - t, t)]
            .into_iter()
            .min_by(|x, y| {
                self.objective(x.0, x.1)
                    .total_cmp(&self.objective(y.0, y.1))
            })
            .unwrap_or((0.0, 0.0))
    }
}

/// A fit target: Cycles' values at the samples, and whether it is fitted with `Kd = 0`.
struct Target {
    values: Vec<f64>,
    metal: bool,
}

impl Target {
    fn solve(&self, n: &Normal) -> (f64, f64) {
        if self.metal {
            n.solve_specular()
        } else {
            n.solve()
        }
    }
}

/// Relative residual `‖f_BP − f_C‖/‖f_C‖` of the best constrained `(Kd, Ks)` at `ns`.
fn residual(s: &[Sample], targets: &[Target], ns: f64) -> f64 {
    let l: Vec<f64> = s.iter().map(|s| lobe(ns, s.cos_h)).collect();
    targets
        .iter()
        .map(|t| {
            let n = Normal::new(s, &l, &t.values);
            let (kd, ks) = t.solve(&n);
            (n.objective(kd, ks).max(0.0) / n.c.max(1e-300)).sqrt()
        })
        .sum()
}

/// The exponent minimising [`residual`] for the lobe-shape targets, searched on a log scale
/// around the analytic `ns` (a scan, then golden-section refinement), at most `ns_max` (the
/// previous, smoother row's) so that `ns` falls with roughness.
fn fit_ns(s: &[Sample], shape_targets: &[Target], roughness: f64, ns_max: f64) -> f64 {
    let ns_a = roughness_to_ns(roughness as f32) as f64;
    let lo = (ns_a / 10.0).max(NS_MIN as f64).ln();
    let hi = (ns_a * 10.0)
        .max(200.0)
        .min(NS_MAX as f64)
        .min(ns_max)
        .ln()
        .max(lo);
    let f = |x: f64| residual(s, shape_targets, x.exp());
    let steps = 24;
    let xs: Vec<f64> = (0..=steps)
        .map(|k| lo + (hi - lo) * k as f64 / steps as f64)
        .collect();
    let fs: Vec<f64> = xs.iter().map(|&x| f(x)).collect();
    let best = (0..xs.len())
        .min_by(|&a, &b| fs[a].total_cmp(&fs[b]))
        .unwrap_or(0);
    let (mut a, mut b) = (xs[best.saturating_sub(1)], xs[(best + 1).min(xs.len() - 1)]);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..20 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    (0.5 * (a + b)).exp()
}

/// Figures of one fitted target: relative L2 residual and the ratio of reflected energy
/// under uniform light (`∫∫ f cos θi cos θo`, Blinn–Phong over Cycles), fitted and with the
/// analytic mapping.
#[derive(Clone, Copy, Debug)]
pub struct FitFigures {
    pub rel_l2: f64,
    pub energy_ratio: f64,
    pub rel_l2_analytic: f64,
    pub energy_ratio_analytic: f64,
}

fn figures(s: &[Sample], t: &[f64], ns: f64, kd: f64, ks: f64) -> (f64, f64) {
    let (mut err, mut norm, mut e_bp, mut e_c) = (0.0, 0.0, 0.0, 0.0);
    for (s, t) in s.iter().zip(t) {
        let f = kd / PI + ks * lobe(ns, s.cos_h);
        err += s.w * (f - t) * (f - t);
        norm += s.w * t * t;
        e_bp += s.w * f;
        e_c += s.w * t;
    }
    ((err / norm.max(1e-300)).sqrt(), e_bp / e_c.max(1e-300))
}

fn with_analytic(s: &[Sample], t: &[f64], p: &Principled, ns: f64, kd: f64, ks: f64) -> FitFigures {
    let a = crate::brdf::principled::principled_to_blinn_phong_analytic(p);
    let (rel_l2, energy_ratio) = figures(s, t, ns, kd, ks);
    let (rel_l2_analytic, energy_ratio_analytic) =
        figures(s, t, a.ns as f64, a.kd[0] as f64, a.ks[0] as f64);
    FitFigures {
        rel_l2,
        energy_ratio,
        rel_l2_analytic,
        energy_ratio_analytic,
    }
}

/// A fitted row and the figures of its metal (base 1, 0.5) and dielectric (F0 0.04, base 0.8)
/// targets, for docs/principled_fit.md.
pub struct FittedRow {
    pub row: Row,
    pub figures: Vec<(&'static str, FitFigures)>,
}

/// Fits one roughness row (about 3·10⁵ samples; a few seconds in a debug build), its `ns`
/// at most `ns_max` (the previous row's; `f64::INFINITY` for the first).
pub fn fit_row(roughness: f64, ns_max: f64) -> FittedRow {
    let r = roughness.max(crate::brdf::cycles_principled::ROUGHNESS_MIN);
    let metal_models: Vec<CyclesPrincipled> = METAL_BASE
        .iter()
        .map(|&b| CyclesPrincipled::new(&grey(b as f64, 1.0, r, 0.04)))
        .collect();
    let alpha = metal_models[0].alpha();
    let s = samples(alpha);
    let metal_t: Vec<Vec<f64>> = metal_models.iter().map(|m| target(m, &s)).collect();
    let diel_t: Vec<[Vec<f64>; 2]> = DIELECTRIC_F0
        .iter()
        .map(|&f0| {
            [0.0, 1.0].map(|b| target(&CyclesPrincipled::new(&grey(b, 0.0, r, f0 as f64)), &s))
        })
        .collect();
    let f0_04 = DIELECTRIC_F0.iter().position(|&f| f == 0.04).unwrap_or(0);
    // The lobe's shape: white metal (the bare GGX lobe) and the dielectric's specular alone.
    let shape = [
        Target {
            values: metal_t[METAL_BASE.len() - 1].clone(),
            metal: r < METAL_DIFFUSE_FROM - 1e-9,
        },
        Target {
            values: diel_t[f0_04][0].clone(),
            metal: false,
        },
    ];
    let ns = fit_ns(&s, &shape, r, ns_max);
    let l: Vec<f64> = s.iter().map(|s| lobe(ns, s.cos_h)).collect();
    let solve = |t: &Vec<f64>| {
        let (kd, ks) = Normal::new(&s, &l, t).solve();
        [kd as f32, ks as f32]
    };
    let metal: Vec<[f32; 2]> = metal_t
        .iter()
        .map(|t| {
            let n = Normal::new(&s, &l, t);
            let (kd, ks) = if r < METAL_DIFFUSE_FROM - 1e-9 {
                n.solve_specular()
            } else {
                n.solve()
            };
            [kd as f32, ks as f32]
        })
        .collect();
    // Dielectrics: base colour 0 under the constraints; the part linear in the base colour
    // (the diffuse under the specular layer) unconstrained, so the lookup is exactly linear
    // in the base colour and only clamps (Kd ≤ 1 − Ks) near base colour 1, where it binds.
    let dielectric: Vec<[[f32; 2]; 2]> = diel_t
        .iter()
        .map(|[a, b]| {
            let at0 = solve(a);
            let diff: Vec<f64> = b.iter().zip(a).map(|(b, a)| b - a).collect();
            let n = Normal::new(&s, &l, &diff);
            let (dkd, dks) = n.solve_free().unwrap_or((n.b1 / n.g11, 0.0));
            [at0, [at0[0] + dkd as f32, at0[1] + dks as f32]]
        })
        .collect();
    // Rounding noise of exactly representable targets (e.g. no specular at F0 = 0) is
    // flushed to zero, so that a moot exponent stays moot.
    let flush = |p: [f32; 2]| p.map(|v| if v.abs() < 1e-7 { 0.0 } else { v });
    let metal: Vec<[f32; 2]> = metal.into_iter().map(flush).collect();
    let dielectric: Vec<[[f32; 2]; 2]> = dielectric.into_iter().map(|d| d.map(flush)).collect();
    let row = Row {
        ns: ns as f32,
        metal: std::array::from_fn(|k| metal[k]),
        dielectric: std::array::from_fn(|k| dielectric[k]),
    };
    let mut figs = Vec::new();
    for (name, base, metallic) in [
        ("metal base 1.0", 1.0, 1.0f32),
        ("metal base 0.5", 0.5, 1.0),
    ] {
        let k = METAL_BASE
            .iter()
            .position(|&b| b as f64 == base)
            .unwrap_or(0);
        let [kd, ks] = row.metal[k];
        let p = grey(base, metallic, r, 0.04);
        figs.push((
            name,
            with_analytic(&s, &metal_t[k], &p, ns, kd as f64, ks as f64),
        ));
    }
    {
        let base = 0.8;
        let t: Vec<f64> = diel_t[f0_04][0]
            .iter()
            .zip(&diel_t[f0_04][1])
            .map(|(a, b)| a + base * (b - a))
            .collect();
        let [[kd0, ks0], [kd1, ks1]] = row.dielectric[f0_04];
        let kd = kd0 as f64 + base * (kd1 - kd0) as f64;
        let ks = ks0 as f64 + base * (ks1 - ks0) as f64;
        let p = grey(base, 0.0, r, 0.04);
        figs.push(("dielectric base 0.8", with_analytic(&s, &t, &p, ns, kd, ks)));
    }
    FittedRow { row, figures: figs }
}

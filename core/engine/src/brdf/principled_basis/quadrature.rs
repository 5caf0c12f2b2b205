//! The measure the basis is fitted under: a product midpoint rule over pairs of directions
//! in Rusinkiewicz's half/difference angles `(θh, θd, φd)`, weighted by
//! `cos θi cos θo dωi dωo` (the weight light transport gives a BRDF error: a reflected
//! radiance error under uniform light), normalised to total 1 so inner products are means.
//!
//! Why these coordinates: a narrow GGX lobe lives at small θh for every (θd, φd), so a mesh
//! graded in θh resolves lobes down to the narrowest roughness with a few hundred θh nodes,
//! where a grid in (θi, θo, φ) would need a node spacing of the lobe's width everywhere.
//! `dωi dωo = 4 cos θd dωh dωd`; φd over [0, π] stands for [0, 2π] (the lobes are even in
//! φd); only pairs with both directions above the surface are kept.

use std::f64::consts::{FRAC_PI_2, PI};

use super::lobes::Cosines;

/// Node counts of the rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct QuadratureSize {
    pub theta_h: usize,
    pub theta_d: usize,
    pub phi_d: usize,
}

/// One node: the direction pair, its weight, and where it lies on the rule's grid.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub c: Cosines,
    pub weight: f64,
    /// The node's θh index (graded toward θh = 0) and θd index.
    pub theta_h_index: u32,
    pub theta_d_index: u32,
}

/// The first θh cell's width scale: the graded mesh `s(e^{βu} − 1)` starts with cells of
/// about `s·β/n` radians, fine enough for the GGX distribution at roughness 0.1 (α = 0.01,
/// half width ≈ 0.006 rad).
const GRADE_SCALE: f64 = 0.0015;

/// The rule's nodes with weights summing to 1, and the raw total `∫∫ cos θi cos θo dωi dωo`
/// the rule gives before normalising (exactly π², a check of the rule).
pub(crate) fn nodes(size: QuadratureSize) -> (Vec<Node>, f64) {
    let QuadratureSize {
        theta_h: nh,
        theta_d: nd,
        phi_d: np,
    } = size;
    let beta = (FRAC_PI_2 / GRADE_SCALE).ln_1p();
    let edge = |i: usize| GRADE_SCALE * (beta * i as f64 / nh as f64).exp_m1();
    let dtd = FRAC_PI_2 / nd as f64;
    let dpd = PI / np as f64;
    let mut out = Vec::with_capacity(nh * nd * np);
    let mut total = 0.0;
    for a in 0..nh {
        let (lo, hi) = (edge(a), edge(a + 1));
        let th = 0.5 * (lo + hi);
        let (sh, ch) = th.sin_cos();
        for b in 0..nd {
            let td = (b as f64 + 0.5) * dtd;
            let (sd, cd) = td.sin_cos();
            for c in 0..np {
                let pd = (c as f64 + 0.5) * dpd;
                let cp = pd.cos();
                let cos_i = ch * cd - sh * sd * cp;
                let cos_o = ch * cd + sh * sd * cp;
                if !(cos_i > 0.0 && cos_o > 0.0) {
                    continue;
                }
                // dωh = sin θh dθh · 2π (azimuth of h), dωd = sin θd dθd · 2 dφd.
                let volume = 4.0 * cd * sh * (hi - lo) * 2.0 * PI * sd * dtd * 2.0 * dpd;
                let weight = volume * cos_i * cos_o;
                total += weight;
                out.push(Node {
                    c: Cosines {
                        cos_i,
                        cos_o,
                        cos_h: ch,
                        cos_d: cd,
                    },
                    weight,
                    theta_h_index: a as u32,
                    theta_d_index: b as u32,
                });
            }
        }
    }
    for n in &mut out {
        n.weight /= total;
    }
    (out, total)
}

//! The table each specular basis is evaluated from: a 3D table in coordinates where both
//! horizons are faces of the box (docs/principled_basis_study.md, part 5: "lune, k 0.1,
//! θh blend", the parametrisation that study found best).
//!
//! A GGX lobe is not a function of the half angle alone (Smith's G depends on θi and θo,
//! the multiple-scattering factor on θo), so each basis is a function of three angles. In
//! the half vector's frame write the difference direction `ωd = (cos η sin ψ, sin η,
//! cos η cos ψ)`, x in the plane of the normal and h. Then `cos θi = cos η cos(θh + ψ)`,
//! `cos θo = cos η cos(θh − ψ)` and `cos θd = cos η cos ψ`, and the pairs above both
//! horizons are exactly `|ψ| < π/2 − θh`, `η ∈ [0, π/2]`: the horizon, where G has a layer
//! α wide and the lobe is cut off, lies on the faces `s = ψ/(π/2 − θh) = ±1` and `η = π/2`,
//! and a one-sided warp puts nodes there. Trilinear interpolation across a horizon that
//! cuts a table cell diagonally is what made the (θh, θd, φd) tables converge slowly.
//!
//! The tabulated quantity is `ρ̃_k·cos θi·cos θo`, which stays bounded at grazing (the bases
//! grow like `1/cos` there); [`LuneTable::eval`] divides it back out.

use std::f64::consts::FRAC_PI_2;

use super::lobes::Cosines;

/// Node counts of a table: θh, the lune's width coordinate s, and η.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct TableSize {
    pub theta_h: usize,
    pub s: usize,
    pub eta: usize,
}

impl TableSize {
    pub fn nodes(&self) -> usize {
        self.theta_h * self.s * self.eta
    }
}

/// The warp constant toward both ends of s and toward η = π/2 (the study's k_s = k_η).
const K_LUNE: f64 = 0.1;
/// Weight of the half-angle warp in the θh coordinate; the rest is uniform in θh, so the
/// grazing configurations where rough lobes are large keep nodes of their own.
const THETA_H_BLEND: f64 = 0.5;

/// `x(1+k)/(x+k)` on [0, 1]: slope (1+k)/k at 0, so uniform nodes in the result are dense
/// near x = 0.
fn rwarp(x: f64, k: f64) -> f64 {
    x * (1.0 + k) / (x + k)
}

fn rwarp_inv(t: f64, k: f64) -> f64 {
    k * t / (1.0 + k - t)
}

/// The θh coordinate: a blend of the half-angle warp `u(1+k)/(u+k)`, `u = √(1 − cos θh)`
/// (the Blinn–Phong basis' table warp, k from the narrowest lobe) and θh/(π/2).
#[derive(Clone, Copy, Debug)]
struct ThetaHWarp {
    k: f64,
}

impl ThetaHWarp {
    /// `k` from the narrowest GGX distribution of the range: `√u` at its half width
    /// (`tan² θh = α²(√2 − 1)`).
    fn for_alpha(alpha_min: f64) -> ThetaHWarp {
        let th = (alpha_min * (2f64.sqrt() - 1.0).sqrt()).atan();
        ThetaHWarp {
            k: (1.0 - th.cos()).sqrt().sqrt(),
        }
    }

    fn fwd_cos(&self, cos_h: f64) -> f64 {
        let cos_h = cos_h.clamp(0.0, 1.0);
        let u = (1.0 - cos_h).max(0.0).sqrt();
        let th = cos_h.acos();
        THETA_H_BLEND * rwarp(u, self.k) + (1.0 - THETA_H_BLEND) * th / FRAC_PI_2
    }

    /// The inverse, by bisection (the blend has no closed form; only the table fill uses it).
    fn inv(&self, t: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, FRAC_PI_2);
        for _ in 0..64 {
            let mid = 0.5 * (lo + hi);
            if self.fwd_cos(mid.cos()) < t {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// The lune coordinates of a direction pair and back.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LuneCoords {
    theta_h: ThetaHWarp,
}

/// The smallest cosine a table node's direction gets (the exact horizon has a zero
/// `cos θi cos θo` to divide by).
const COS_FLOOR: f64 = 1e-6;

impl LuneCoords {
    pub(crate) fn new(alpha_min: f64) -> LuneCoords {
        LuneCoords {
            theta_h: ThetaHWarp::for_alpha(alpha_min),
        }
    }

    /// Table coordinates in [0, 1]³ of a pair above both horizons.
    pub(crate) fn coords(&self, c: Cosines) -> [f64; 3] {
        let cos_h = c.cos_h.clamp(0.0, 1.0);
        let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
        let x = if sin_h > 1e-12 {
            ((c.cos_o - c.cos_i) / (2.0 * sin_h)).clamp(-1.0, 1.0)
        } else {
            0.0
        };
        let z = c.cos_d.clamp(0.0, 1.0);
        let cos_eta = (x * x + z * z).sqrt().min(1.0);
        let psi = x.atan2(z);
        let room = (FRAC_PI_2 - cos_h.acos()).max(1e-12);
        let s = (psi / room).clamp(-1.0, 1.0);
        let t1 = 0.5 + 0.5 * s.signum() * (1.0 - rwarp(1.0 - s.abs(), K_LUNE));
        [
            self.theta_h.fwd_cos(cos_h),
            t1,
            1.0 - rwarp(cos_eta, K_LUNE),
        ]
    }

    /// The direction pair at table coordinates `t` (cosines floored just above 0).
    pub(crate) fn cosines(&self, t: [f64; 3]) -> Cosines {
        let th = self.theta_h.inv(t[0]);
        let a = 2.0 * t[1] - 1.0;
        let s = a.signum() * (1.0 - rwarp_inv(1.0 - a.abs(), K_LUNE));
        let psi = s * (FRAC_PI_2 - th);
        let cos_eta = rwarp_inv(1.0 - t[2], K_LUNE);
        Cosines {
            cos_i: (cos_eta * (th + psi).cos()).max(COS_FLOOR),
            cos_o: (cos_eta * (th - psi).cos()).max(COS_FLOOR),
            cos_h: th.cos(),
            cos_d: cos_eta * psi.cos(),
        }
    }
}

/// `nspec` functions tabulated together on one lune grid, node-major (the `nspec` values of
/// a node are adjacent, so one lookup reads eight short runs).
#[derive(Clone, Debug)]
pub(crate) struct LuneTable {
    pub size: TableSize,
    pub coords: LuneCoords,
    pub nspec: usize,
    pub values: Vec<f32>,
}

impl LuneTable {
    /// Fills the table from `f(cosines, out)`, which writes the `nspec` functions' values
    /// (times `cos θi cos θo`) at a node.
    pub(crate) fn fill(
        size: TableSize,
        coords: LuneCoords,
        nspec: usize,
        f: impl Fn(Cosines, &mut [f64]) + Sync,
    ) -> LuneTable {
        use rayon::prelude::*;
        let mut values = vec![0.0f32; size.nodes() * nspec];
        let per_h = size.s * size.eta * nspec;
        values
            .par_chunks_mut(per_h.max(1))
            .enumerate()
            .for_each(|(a, plane)| {
                let mut buf = vec![0.0; nspec];
                let t0 = node_t(a, size.theta_h);
                for b in 0..size.s {
                    for e in 0..size.eta {
                        let t = [t0, node_t(b, size.s), node_t(e, size.eta)];
                        f(coords.cosines(t), &mut buf);
                        let at = (b * size.eta + e) * nspec;
                        for (o, v) in plane[at..at + nspec].iter_mut().zip(&buf) {
                            *o = *v as f32;
                        }
                    }
                }
            });
        LuneTable {
            size,
            coords,
            nspec,
            values,
        }
    }

    /// Trilinear interpolation at the pair `c`, divided by `cos θi cos θo`: the `nspec`
    /// functions' values, into `out`. Pairs below either horizon give 0.
    pub(crate) fn eval(&self, c: Cosines, out: &mut [f64]) {
        out[..self.nspec].fill(0.0);
        if !(c.cos_i > 0.0 && c.cos_o > 0.0) {
            return;
        }
        let t = self.coords.coords(c);
        let dims = [self.size.theta_h, self.size.s, self.size.eta];
        let mut base = [0usize; 3];
        let mut frac = [0.0f64; 3];
        for d in 0..3 {
            let x = t[d].clamp(0.0, 1.0) * (dims[d] - 1) as f64;
            let i = (x.floor() as usize).min(dims[d].saturating_sub(2));
            base[d] = i;
            frac[d] = x - i as f64;
        }
        let inv = 1.0 / (c.cos_i * c.cos_o);
        for corner in 0..8 {
            let pick = |d: usize| (corner >> d) & 1;
            let mut w = inv;
            let mut idx = [0usize; 3];
            for d in 0..3 {
                idx[d] = base[d] + pick(d);
                w *= if pick(d) == 1 { frac[d] } else { 1.0 - frac[d] };
            }
            if w == 0.0 {
                continue;
            }
            let node = (idx[0] * dims[1] + idx[1]) * dims[2] + idx[2];
            let row = &self.values[node * self.nspec..(node + 1) * self.nspec];
            for (o, v) in out.iter_mut().zip(row) {
                *o += w * *v as f64;
            }
        }
    }

    pub(crate) fn bytes(&self) -> usize {
        self.values.len() * std::mem::size_of::<f32>()
    }
}

/// Node `i` of `n` uniform nodes on [0, 1].
fn node_t(i: usize, n: usize) -> f64 {
    if n > 1 {
        i as f64 / (n - 1) as f64
    } else {
        0.0
    }
}

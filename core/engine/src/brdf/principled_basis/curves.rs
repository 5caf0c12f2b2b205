//! A metal's coefficients as curves in roughness, so that a relit edit costs a lookup, not a
//! projection over the quadrature.
//!
//! With Schlick's Fresnel `F = F0(1 − w) + w`, `w = (1 − cos θd)⁵`, a metal lobe is
//! `F0·A + B + Fms·(F0·A + B)·miss`, with `A = single·(1 − w)`, `B = single·w` and
//! `miss = (1 − E(μo))/E(μo)`: four functions per roughness with weights `F0`, `1`,
//! `F0·Fms`, `Fms` (`Fms` a scalar from F0 and `Eavg(r)`). Their projections are tabulated
//! at nodes uniform in `ln r` and interpolated linearly (the study measured ≤ 2e-4 of a
//! lobe at 256 nodes); the weights are applied per colour channel at lookup.

use rayon::prelude::*;

use super::lobes::{roughness_nodes, Cosines, Family, Roughness};

/// Nodes of the curves, uniform in `ln r` over the basis' roughness range.
pub(crate) const CURVE_NODES: usize = 256;
/// The four metal components.
pub(crate) const PARTS: usize = 4;

/// The four components' values at a pair, for a projector.
pub(crate) type Components<'a> = dyn Fn(Cosines, &mut [f64]) + Sync + 'a;

/// The tabulated projections: node-major, then component, then slot.
#[derive(Clone, Debug)]
pub(crate) struct MetalCurves {
    ln_r_min: f64,
    slots: usize,
    e_avg: Vec<f64>,
    values: Vec<f64>,
}

impl MetalCurves {
    /// Curves over `[r_min, 1]` for a basis of `slots` slots; `project` gives the
    /// [`PARTS`] components' coefficients, component-major (the basis' `project_many`).
    pub(crate) fn build(
        r_min: f64,
        slots: usize,
        project: impl Fn(&Components) -> Vec<f64>,
    ) -> MetalCurves {
        let mut e_avg = Vec::with_capacity(CURVE_NODES);
        let mut values = Vec::with_capacity(CURVE_NODES * PARTS * slots);
        // Each roughness' albedo tables first, in parallel (each is an integration of its
        // own); the projections below are parallel inside.
        let roughness: Vec<Roughness> = roughness_nodes(r_min, CURVE_NODES)
            .into_par_iter()
            .map(Roughness::new)
            .collect();
        for rough in &roughness {
            let parts = project(&|c: Cosines, out: &mut [f64]| {
                let (single, miss) = rough.single_and_miss(c);
                let w = (1.0 - c.cos_d).clamp(0.0, 1.0).powi(5);
                out[0] = single * (1.0 - w);
                out[1] = single * w;
                out[2] = out[0] * miss;
                out[3] = out[1] * miss;
            });
            debug_assert_eq!(parts.len(), PARTS * slots);
            e_avg.push(rough.e_avg);
            values.extend(parts);
        }
        MetalCurves {
            ln_r_min: r_min.ln(),
            slots,
            e_avg,
            values,
        }
    }

    /// Curves over `[r_min, 1]` from the values [`Self::parts`] gave (the disk cache).
    pub(crate) fn from_parts(
        r_min: f64,
        slots: usize,
        e_avg: Vec<f64>,
        values: Vec<f64>,
    ) -> MetalCurves {
        MetalCurves {
            ln_r_min: r_min.ln(),
            slots,
            e_avg,
            values,
        }
    }

    /// `Eavg` at every node and the tabulated projections, for the disk cache.
    pub(crate) fn parts(&self) -> (&[f64], &[f64]) {
        (&self.e_avg, &self.values)
    }

    /// Per slot and channel, the coefficients of a metal with `f0` per channel at
    /// `roughness`; `roughness` outside the range is clamped to it and reported (`true`).
    pub(crate) fn coefficients(&self, f0: [f64; 3], roughness: f64) -> (Vec<[f64; 3]>, bool) {
        let ln_r = roughness.max(1e-300).ln();
        let clamped = !(ln_r >= self.ln_r_min - 1e-12 && ln_r <= 1e-12);
        let x =
            ((ln_r - self.ln_r_min) / -self.ln_r_min).clamp(0.0, 1.0) * (CURVE_NODES - 1) as f64;
        let i = (x.floor() as usize).min(CURVE_NODES - 2);
        let t = x - i as f64;
        let lerp = |a: f64, b: f64| a + (b - a) * t;
        let e_avg = lerp(self.e_avg[i], self.e_avg[i + 1]);
        let block = PARTS * self.slots;
        let (lo, hi) = (
            &self.values[i * block..(i + 1) * block],
            &self.values[(i + 1) * block..(i + 2) * block],
        );
        let weights = f0.map(|f| {
            let fms = Family::Metal { f0: f }.multiscatter(e_avg);
            [f, 1.0, f * fms, fms]
        });
        let out = (0..self.slots)
            .map(|k| {
                std::array::from_fn(|ch| {
                    (0..PARTS)
                        .map(|p| {
                            let at = p * self.slots + k;
                            weights[ch][p] * lerp(lo[at], hi[at])
                        })
                        .sum()
                })
            })
            .collect();
        (out, clamped)
    }
}

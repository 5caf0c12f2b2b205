//! The direction mixture a region draws its indirect directions from: cosine-weighted and
//! Blinn–Phong lobes, with weights that follow the bake-time material.
//!
//! One indirect direction serves every layer of the eye vertex (the correlated-noise
//! property of the stack), so the pdf cannot match every basis BRDF at once. The weights
//! favour the material the region has at bake time — the image the user sees first and the
//! one the preset table measures — and keep a defensive share for the rest of the range:
//!
//! - an editable region gives [`TUNED_SHARE`] to its bake-time material, split as a fixed
//!   region splits its whole (below: cosine, the lobe at the bake-time exponent and its tail
//!   lobe), and spreads [`RANGE_SHARE`] over lobes log-spaced across its ns range and
//!   [`RANGE_SHARE`] on cosine, so a layer of any basis keeps a pdf within a factor
//!   1/[`RANGE_SHARE`] = 10 of a lobe-only sampler's;
//! - a fixed region samples its own BRDF: cosine and its lobe by the same luminance split,
//!   of the specular part [`TUNED_SHARE`] at the lobe and [`RANGE_SHARE`] each at a lobe
//!   [`TAIL_WIDTH`] times wider and on cosine, for the tails of Cycles' microfacet lobes
//!   (the fixed region is evaluated exactly, sampled by its Blinn–Phong mapping).
//!
//! Why per material: the earlier ½ cosine + ½ four range lobes (whatever the material)
//! wasted half the directions of a diffuse region (editable, Ks = 0) on lobes, and did worse
//! there than uniform sampling (`tests/engine/sampling_comparison.rs`; the figure is in
//! docs/measurements.md, "Figures that were in code comments").
//!
//! Every weight is fixed before the bake, and [`DirectionMixture::pdf`] evaluates the whole
//! mixture for any direction, so the estimate is unbiased whatever the weights.

use glam::Vec3;
use std::f32::consts::PI;

use crate::brdf::BlinnPhong;
use crate::geometry::sampling::{
    blinn_phong_half_vector, blinn_phong_pdf, cosine_hemisphere, to_world,
};
use crate::{luminance, Rgb};

/// Share of an editable region's directions drawn for its bake-time material.
pub const TUNED_SHARE: f32 = 0.8;
/// Share spread over lobes across an editable region's ns range (and the same again on
/// cosine): the defensive floor for layers the bake-time material does not weigh.
pub const RANGE_SHARE: f32 = 0.1;
/// Lobes across an editable region's ns range, log-spaced from its ns_min to its ns_max.
pub const RANGE_LOBES: usize = 4;

/// How much wider than a region's bake-time lobe its tail lobe is (the exponent over this):
/// Cycles' microfacet lobes fall off polynomially where the Blinn–Phong lobe of their
/// mapping falls off like a Gaussian, so a sampler of the mapped lobe alone draws their
/// tails too rarely and weighs each tail direction very high.
pub const TAIL_WIDTH: f32 = 8.0;

/// Cosine weight and Blinn–Phong lobes (exponent, weight); the weights sum to 1.
#[derive(Clone, Debug, PartialEq)]
pub struct DirectionMixture {
    pub cosine: f32,
    pub lobes: Vec<(f32, f32)>,
}

/// Luminance share of the specular part of `material` (½ for a black material).
fn specular_share(material: &BlinnPhong) -> f32 {
    let lum = |c: [f32; 3]| luminance(Rgb::from(c)).max(0.0);
    let (d, s) = (lum(material.kd), lum(material.ks));
    if d + s > 0.0 && (d + s).is_finite() {
        s / (d + s)
    } else {
        0.5
    }
}

/// A material's own directions with specular share `s` and exponent `ns`: the cosine's
/// weight (of the whole) and the lobe and its tail lobe, their weights times `scale` (the
/// share of the mixture the material gets). Of the specular share [`TUNED_SHARE`] is the
/// lobe and [`RANGE_SHARE`] each the tail lobe and the cosine.
fn own_split(ns: f32, s: f32, scale: f32) -> (f32, [(f32, f32); 2]) {
    (
        (1.0 - s) + RANGE_SHARE * s,
        [
            (ns, scale * TUNED_SHARE * s),
            ((ns / TAIL_WIDTH).max(1.0), scale * RANGE_SHARE * s),
        ],
    )
}

impl DirectionMixture {
    /// Cosine only (a diffuse region).
    pub fn cosine() -> DirectionMixture {
        DirectionMixture {
            cosine: 1.0,
            lobes: Vec::new(),
        }
    }

    /// An editable region with bake-time `material` and exponents in [`ns_min`, `ns_max`].
    pub fn editable(material: &BlinnPhong, ns_min: f32, ns_max: f32) -> DirectionMixture {
        let s = specular_share(material);
        let ns = material.ns.clamp(ns_min, ns_max);
        let mut lobes: Vec<(f32, f32)> = (0..RANGE_LOBES)
            .map(|k| {
                let t = k as f32 / (RANGE_LOBES - 1) as f32;
                (
                    ns_min * (ns_max / ns_min).powf(t),
                    RANGE_SHARE / RANGE_LOBES as f32,
                )
            })
            .collect();
        // The bake-time material's share split as a fixed region's own (lobe, tail, cosine):
        // the Principled basis' lobes are Cycles' GGX, with the polynomial tails that the
        // tail lobe is there for.
        let (cosine, own) = own_split(ns, s, TUNED_SHARE);
        lobes.extend(own);
        DirectionMixture {
            cosine: RANGE_SHARE + TUNED_SHARE * cosine,
            lobes,
        }
    }

    /// A fixed region: its own BRDF's cosine and lobe by the luminance split.
    pub fn fixed(material: &BlinnPhong) -> DirectionMixture {
        if material.ks.iter().all(|k| *k <= 0.0) {
            return DirectionMixture::cosine();
        }
        let (cosine, lobes) = own_split(material.ns, specular_share(material), 1.0);
        DirectionMixture {
            cosine,
            lobes: lobes.to_vec(),
        }
    }

    /// Draws a direction around normal `n` for outgoing `wo` from (`u1`, `u2`) ∈ [0, 1)²:
    /// `u1` picks the component (cosine, then the lobes in order) and is rescaled to [0, 1)
    /// inside it, so a stratified 2-D point set stays stratified within each component (a
    /// separate "pick" number would hand each component a scattered subset of the points).
    /// May lie below the surface (a lobe's reflection); the caller checks.
    pub fn sample(&self, u1: f32, u2: f32, n: Vec3, wo: Vec3) -> Vec3 {
        let mut start = 0.0f32;
        let mut chosen = None;
        for (k, w) in std::iter::once(self.cosine)
            .chain(self.lobes.iter().map(|l| l.1))
            .enumerate()
        {
            if w > 0.0 && u1 < start + w {
                chosen = Some((k, (u1 - start) / w));
                break;
            }
            start += w;
        }
        // Rounding can leave u1 just past the last weight: take the last non-empty component.
        let (k, u) = chosen.unwrap_or_else(|| {
            let last = self
                .lobes
                .iter()
                .rposition(|l| l.1 > 0.0)
                .map_or(0, |i| i + 1);
            (last, 1.0 - f32::EPSILON)
        });
        let u = u.clamp(0.0, 1.0 - f32::EPSILON);
        if k == 0 {
            return to_world(n, cosine_hemisphere(u, u2));
        }
        let h = to_world(n, blinn_phong_half_vector(u, u2, self.lobes[k - 1].0));
        2.0 * wo.dot(h) * h - wo
    }

    /// Solid-angle pdf of [`DirectionMixture::sample`] for direction `wi` (0 below the surface).
    pub fn pdf(&self, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
        let cos = n.dot(wi);
        if cos <= 0.0 {
            return 0.0;
        }
        let mut pdf = self.cosine * cos / PI;
        let h = (wi + wo).normalize_or_zero();
        if h != Vec3::ZERO {
            for &(ns, w) in &self.lobes {
                if w > 0.0 {
                    pdf += w * blinn_phong_pdf(n.dot(h), wo.dot(h), ns);
                }
            }
        }
        pdf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn total(m: &DirectionMixture) -> f32 {
        m.cosine + m.lobes.iter().map(|l| l.1).sum::<f32>()
    }

    #[test]
    fn weights_sum_to_one_and_follow_the_material() {
        let diffuse = BlinnPhong {
            kd: [0.8; 3],
            ks: [0.0; 3],
            ns: 1.0,
        };
        let glossy = BlinnPhong {
            kd: [0.05; 3],
            ks: [0.9; 3],
            ns: 150.0,
        };
        let black = BlinnPhong {
            kd: [0.0; 3],
            ks: [0.0; 3],
            ns: 10.0,
        };
        for m in [&diffuse, &glossy, &black] {
            let mix = DirectionMixture::editable(m, 1.0, 200.0);
            assert!((total(&mix) - 1.0).abs() < 1e-6, "{mix:?}");
            assert!(mix
                .lobes
                .iter()
                .all(|l| l.1 >= 0.0 && l.0 >= 1.0 && l.0 <= 200.0));
            assert!((total(&DirectionMixture::fixed(m)) - 1.0).abs() < 1e-6);
        }
        let d = DirectionMixture::editable(&diffuse, 1.0, 200.0);
        assert!((d.cosine - (RANGE_SHARE + TUNED_SHARE)).abs() < 1e-6);
        let g = DirectionMixture::editable(&glossy, 1.0, 200.0);
        // The bake-time lobe, then its tail lobe.
        let (lobe, tail) = (g.lobes[RANGE_LOBES], g.lobes[RANGE_LOBES + 1]);
        assert!(lobe.1 > 0.6 && lobe.0 == 150.0, "{g:?}");
        assert!(tail.1 > 0.07 && tail.0 == 150.0 / TAIL_WIDTH, "{g:?}");
        // Every range lobe keeps its defensive share whatever the material.
        for mix in [&d, &g] {
            for l in &mix.lobes[..RANGE_LOBES] {
                assert!((l.1 - RANGE_SHARE / RANGE_LOBES as f32).abs() < 1e-7);
            }
        }
    }

    /// The pdf integrates to one over the directions it can produce (those above the
    /// surface; a lobe's reflections below it are lost mass, so ≤ 1), and matches the
    /// histogram of drawn directions.
    #[test]
    fn pdf_matches_the_sampler() {
        let glossy = BlinnPhong {
            kd: [0.3; 3],
            ks: [0.5; 3],
            ns: 40.0,
        };
        let mix = DirectionMixture::editable(&glossy, 1.0, 200.0);
        let n = Vec3::Z;
        let wo = Vec3::new(0.5, 0.0, 0.8).normalize();
        // Integral of the pdf over the hemisphere by a fine (φ, cos θ) grid.
        let (nz, nphi) = (400, 400);
        let mut integral = 0.0f64;
        for i in 0..nz {
            let z = (i as f32 + 0.5) / nz as f32;
            for j in 0..nphi {
                let phi = (j as f32 + 0.5) / nphi as f32 * 2.0 * PI;
                let r = (1.0 - z * z).sqrt();
                let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                integral += mix.pdf(n, wo, wi) as f64;
            }
        }
        integral *= 2.0 * PI as f64 / (nz * nphi) as f64;
        // Fraction of draws above the surface, by sampling.
        let draws = 200_000;
        let mut above = 0u32;
        let mut state = 0x1234_5678_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        };
        for _ in 0..draws {
            let wi = mix.sample(next(), next(), n, wo);
            if wi.z > 0.0 {
                above += 1;
            }
        }
        let frac = above as f64 / draws as f64;
        assert!(
            (integral - frac).abs() < 0.01,
            "∫pdf = {integral}, fraction above = {frac}"
        );
    }
}

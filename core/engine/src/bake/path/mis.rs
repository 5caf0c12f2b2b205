//! Multiple importance sampling of direct light: next-event estimation against the
//! directions a vertex's BSDF mixture draws.
//!
//! Light sampling alone gives a sharp lobe that meets a small bright light a weight
//! f·L·cos/p_light that the lobe's peak can make hundreds of times the pixel's value (the
//! fireflies of smooth metal); BSDF sampling alone misses small lights. Each vertex that
//! traces a BSDF-sampled ray therefore counts light both ways, weighted by the power
//! heuristic (β = 2, Veach 1997) on the two strategies' sample counts times their pdfs:
//! a light sample by w_l = (n_l p_l)² / ((n_l p_l)² + (n_b p_b)²), the light a BSDF ray
//! receives (an area light's front face, an emissive surface, the disk of a point or spot
//! light with a radius, a sun's cone, the world it escapes to) by w_b = 1 − w_l for that direction. The weights sum to one for every
//! direction, so the estimate stays unbiased for every layer.
//!
//! **Linearity.** A layer is linear in the coefficients of the editable materials only if
//! its weights do not depend on them. The BSDF pdf p_b used here is that of the vertex's
//! sampling strategy — its region's [`DirectionMixture`] (the bake-time material plus the
//! lobes spread across the region's ns range, fixed before the bake) and, at the eye, the
//! pixel's guide tree or uniform sampling when the settings say so — not the pdf of the
//! edited BRDF. The weights are thus fixed before the bake and the same in the bake and the
//! reference render, whatever the materials. They are close to optimal for the bake-time
//! material; for a relit material far from it they are still exact (unbiased), only less
//! effective.
//!
//! **The paper's uniform sampling.** With [`IndirectSampling::Uniform`] the eye's directions
//! follow no lobe: they would almost never find the light a sharp lobe reflects, so MIS
//! would gain nothing there and would cost the estimator its zero variance where light
//! sampling matches the BRDF (a diffuse surface under a constant world). The eye vertex then
//! keeps next-event estimation alone, as the paper has it, and its escaping rays carry
//! nothing; the vertices beyond it draw from their mixture and use MIS as below.
//!
//! **Where a vertex traces a BSDF ray.** The eye vertex with bounces ≥ 1 and every vertex a
//! path continues from have a BSDF ray anyway. The last vertex of a path (the eye with no
//! bounce, the first-bounce vertex with one bounce, the tail's last vertex) traces one only
//! for the light it brings, and only where its region's mixture has a specular lobe
//! ([`traces_bsdf_ray`]): a diffuse vertex keeps next-event estimation with full weight,
//! which is already the better strategy there, and costs no extra ray.

use glam::Vec3;
use std::f32::consts::PI;

use crate::bake::path::guide::GUIDE_WEIGHT;
use crate::bake::path::guide_tree::DirectionTree;
use crate::bake::path::mixture::DirectionMixture;
use crate::bake::prepare::context::BakeContext;
use crate::geometry::bvh::SurfaceHit;
use crate::geometry::lights::bsdf_hits::RayEnd;
use crate::options::IndirectSampling;
use crate::Rgb;

/// The BSDF-sampling strategy of a vertex: how its directions are drawn and how many.
#[derive(Clone, Copy)]
pub(crate) struct BsdfStrategy<'a> {
    pub sampling: IndirectSampling,
    pub mixture: &'a DirectionMixture,
    pub guide: Option<&'a DirectionTree>,
    /// Directions drawn per light sample set (the eye's indirect samples, else 1).
    pub count: u32,
}

impl<'a> BsdfStrategy<'a> {
    /// The strategy of a vertex beyond the eye: one draw from its region's mixture.
    pub fn mixture(ctx: &'a BakeContext, region: u32) -> BsdfStrategy<'a> {
        BsdfStrategy {
            sampling: IndirectSampling::Mixture,
            mixture: &ctx.regions[region as usize].mixture,
            guide: None,
            count: 1,
        }
    }

    /// Sample count times the pdf of drawing `wi` at a vertex with normal `n`, seen from `wo`.
    #[inline]
    pub fn density(&self, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
        self.count as f32 * indirect_pdf(self.sampling, self.mixture, self.guide, n, wo, wi)
    }
}

/// The solid-angle pdf with which [`crate::bake::path::integrator::sample_indirect`] draws `wi`
/// (what multiple importance sampling weighs light samples against, [`crate::bake::path::mis`]).
#[inline]
pub(crate) fn indirect_pdf(
    sampling: IndirectSampling,
    mixture: &DirectionMixture,
    guide: Option<&DirectionTree>,
    n: Vec3,
    wo: Vec3,
    wi: Vec3,
) -> f32 {
    if n.dot(wi) <= 0.0 {
        return 0.0;
    }
    if sampling == IndirectSampling::Uniform {
        return 1.0 / (2.0 * PI);
    }
    let guide = guide.filter(|_| sampling == IndirectSampling::Guided);
    let guide_weight = if guide.is_some() { GUIDE_WEIGHT } else { 0.0 };
    let mut pdf = (1.0 - guide_weight) * mixture.pdf(n, wo, wi);
    if let Some(g) = guide {
        pdf += guide_weight * g.pdf(wi);
    }
    pdf
}

/// Whether the last vertex of a path on a region with `mixture` traces a BSDF ray for the
/// light it meets: only where the mixture has a specular lobe (module docs).
#[inline]
pub(crate) fn traces_bsdf_ray(mixture: &DirectionMixture) -> bool {
    mixture.lobes.iter().any(|l| l.1 > 0.0)
}

/// The power heuristic's weight of the strategy with density `a` (count × pdf) against one
/// with density `b`: a²/(a² + b²), written as 1/(1 + (b/a)²) so that large pdfs do not
/// overflow; 1 when only `a` is infinite, 0 when `a` is 0 or not a number.
#[inline]
pub(crate) fn power_heuristic(a: f32, b: f32) -> f32 {
    if !(a > 0.0) {
        return 0.0;
    }
    if !(b > 0.0) {
        return 1.0;
    }
    if a.is_infinite() {
        return if b.is_infinite() { 0.5 } else { 1.0 };
    }
    let r = b / a;
    1.0 / (1.0 + r * r)
}

/// The light, per group, that a BSDF ray from `vertex` along `dir` receives from the
/// emitters it meets before or at `end` (its first hit, `None` when it escapes), each
/// weighted by its MIS weight against next-event estimation at `vertex`: `density` is the
/// BSDF strategy's count × pdf of `dir`; `eye` says whether `vertex` is the eye's, whose
/// light-sample count differs from the later vertices'. Adds into `out` (one entry per
/// group); returns whether anything arrived.
pub(crate) fn emission_along(
    ctx: &BakeContext,
    vertex: &SurfaceHit,
    dir: Vec3,
    density: f32,
    end: Option<&SurfaceHit>,
    eye: bool,
    out: &mut [Rgb],
) -> bool {
    let light_samples = ctx.settings.light_samples_at(eye) as f32;
    let origin = ctx
        .geometry
        .offset(vertex.position, vertex.geometric_normal);
    let end = end.map(|h| RayEnd {
        t: h.t,
        region: h.region,
        geometric_normal: h.geometric_normal,
    });
    let mut any = false;
    ctx.lights.emitted_along(
        vertex.position,
        vertex.shading_normal,
        origin,
        dir,
        end,
        |emitter, radiance, pdf| {
            if radiance == Rgb::ZERO {
                return;
            }
            let w = power_heuristic(density, light_samples * pdf);
            if w > 0.0 {
                out[ctx.lights.group_of(emitter)] += radiance * w;
                any = true;
            }
        },
    );
    any
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_two_weights_sum_to_one() {
        for (a, b) in [
            (1.0, 1.0),
            (3.0, 0.5),
            (1e-30, 1e30),
            (1e30, 2e30),
            (0.0, 4.0),
        ] {
            let s = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((s - 1.0).abs() < 1e-6, "{a} {b}: {s}");
        }
        assert_eq!(power_heuristic(f32::INFINITY, 3.0), 1.0);
        assert_eq!(power_heuristic(3.0, f32::INFINITY), 0.0);
        assert_eq!(power_heuristic(f32::NAN, 3.0), 0.0);
        assert_eq!(power_heuristic(2.0, 0.0), 1.0);
    }
}

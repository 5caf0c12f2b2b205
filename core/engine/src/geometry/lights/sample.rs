//! The light sampler: one sample of an emitter from a shading point ([`LightSet::sample`]),
//! as incident radiance over the solid-angle pdf and the pdf itself.

use glam::Vec3;
use std::f32::consts::PI;

use super::emitters::{AreaPlane, Emitter, WorldSampling};
use super::set::LightSet;
use crate::geometry::env_sampling::EnvSampler;
use crate::geometry::environment::Environment;
use crate::geometry::sampling::{
    concentric_disk, cosine_hemisphere, frame, to_world, uniform_cone,
};
use crate::geometry::spherical_rect::SphericalRect;
use crate::Rgb;

/// One light sample at a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Distance to the sampled point (infinite for the sun and the world).
    pub distance: f32,
    /// Incident radiance / solid-angle pdf.
    pub radiance_over_pdf: Rgb,
    /// The solid-angle pdf itself, for multiple importance sampling against BSDF-sampled
    /// directions ([`LightSet::emitted_along`] is the other side); `None` for a light no
    /// BSDF direction can meet (a point or spot without a radius, a sun without an angle).
    pub pdf: Option<f32>,
}

impl LightSet {
    /// Samples emitter `index` from point `p` with (shading) normal `n`; `None` when the
    /// sample carries no light (outside a spot cone, behind an area light, …).
    pub fn sample(&self, index: usize, p: Vec3, n: Vec3, u1: f32, u2: f32) -> Option<LightSample> {
        match &self.emitters[index] {
            Emitter::Point {
                position,
                intensity,
                radius,
                spot,
            } => {
                let mut target = *position;
                let mut axis = Vec3::ZERO;
                if *radius > 0.0 {
                    axis = (p - *position).normalize_or_zero();
                    if axis != Vec3::ZERO {
                        let (t, b) = frame(axis);
                        let (dx, dy) = concentric_disk(u1, u2);
                        target += (t * dx + b * dy) * *radius;
                    }
                }
                let d = target - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let dist = dist2.sqrt();
                let wi = d / dist;
                let mut li = *intensity / dist2;
                if let Some(s) = spot {
                    let mask = s.mask(wi);
                    if mask <= 0.0 {
                        return None;
                    }
                    li *= mask;
                }
                // The disk of a light with a radius, drawn uniformly by area: solid-angle pdf
                // d²/(π r² cos θ_l); a point without one is a single direction.
                let pdf = (axis != Vec3::ZERO)
                    .then(|| dist2 / (PI * radius * radius * wi.dot(axis).abs()));
                Some(LightSample {
                    wi,
                    distance: dist,
                    radiance_over_pdf: li,
                    pdf,
                })
            }
            Emitter::Sun {
                to_light,
                cos_half,
                radiance_over_pdf,
            } => {
                let wi = if *cos_half < 1.0 {
                    to_world(*to_light, uniform_cone(u1, u2, *cos_half))
                } else {
                    *to_light
                };
                Some(LightSample {
                    wi,
                    distance: f32::INFINITY,
                    radiance_over_pdf: *radiance_over_pdf,
                    pdf: sun_cone_pdf(*cos_half),
                })
            }
            Emitter::Area {
                shape,
                radiance_times_area,
                area,
            } => {
                let AreaPlane {
                    centre,
                    u,
                    v,
                    normal,
                    half_u,
                    half_v,
                    elliptic,
                } = shape;
                if shape.by_solid_angle(p, self.area_sampling) {
                    // One-sided: a point behind the light's plane (or in it) gets nothing.
                    if !((p - *centre).dot(*normal) > 0.0) || !(*area > 0.0) {
                        return None;
                    }
                    let ex = *u * (2.0 * half_u);
                    let ey = *v * (2.0 * half_v);
                    let corner = *centre - *u * *half_u - *v * *half_v;
                    let rect = SphericalRect::new(corner, ex, ey, p)?;
                    let d = rect.sample(u1, u2) - p;
                    let dist = d.length();
                    if !(dist > 0.0) {
                        return None;
                    }
                    return Some(LightSample {
                        wi: d / dist,
                        distance: dist,
                        radiance_over_pdf: *radiance_times_area
                            * ((rect.solid_angle / *area as f64) as f32),
                        pdf: Some((1.0 / rect.solid_angle) as f32),
                    });
                }
                let (a, b) = if *elliptic {
                    concentric_disk(u1, u2)
                } else {
                    (2.0 * u1 - 1.0, 2.0 * u2 - 1.0)
                };
                let q = *centre + *u * (a * half_u) + *v * (b * half_v);
                // One-sided emission.
                sampled_by_area(p, q, *radiance_times_area, *area, |wi| {
                    let cos_light = -wi.dot(*normal);
                    (!(cos_light <= 0.0)).then_some(cos_light)
                })
            }
            Emitter::Mesh {
                triangles,
                cdf,
                radiance_times_area,
                area,
                ..
            } => {
                // Pick a triangle by area with u1 (rescaled for reuse), a uniform point on it.
                let i = cdf.partition_point(|c| *c <= u1).min(cdf.len() - 1);
                let lo = if i == 0 { 0.0 } else { cdf[i - 1] };
                let w = cdf[i] - lo;
                let u1 = if w > 0.0 {
                    ((u1 - lo) / w).clamp(0.0, ONE_MINUS_EPS)
                } else {
                    0.5
                };
                let [v0, e1, e2, nl] = triangles[i];
                let su = u1.sqrt();
                let (b1, b2) = (su * (1.0 - u2), su * u2);
                let q = v0 + e1 * b1 + e2 * b2;
                // Two-sided emission.
                sampled_by_area(p, q, *radiance_times_area, *area, |wi| {
                    let cos_light = wi.dot(nl).abs();
                    (cos_light > 0.0).then_some(cos_light)
                })
            }
            Emitter::World => match (&self.world_sampler, self.world_sampling) {
                (Some(env), WorldSampling::Mixture) => {
                    sample_world_mixture(env, &self.environment, n, u1, u2)
                }
                _ => {
                    let local = cosine_hemisphere(u1, u2);
                    if local.z <= 1e-7 {
                        return None;
                    }
                    let wi = to_world(n, local);
                    let li = self.environment.radiance(wi);
                    Some(LightSample {
                        wi,
                        distance: f32::INFINITY,
                        radiance_over_pdf: li * (PI / local.z),
                        pdf: Some(local.z / PI),
                    })
                }
            },
        }
    }
}

/// One sample of the ½ image-warp + ½ cosine mixture from a point with normal `n`. The
/// branch is picked by `u1 < ½` and `u1` stretched back to [0, 1) (2·u1 or 2·u1 − 1): this
/// keeps the integrator's two uniforms per light sample and costs one of u1's 24 bits,
/// which is nothing next to the warp's own loss of a bit per pyramid level.
fn sample_world_mixture(
    env: &EnvSampler,
    environment: &Environment,
    n: Vec3,
    u1: f32,
    u2: f32,
) -> Option<LightSample> {
    let wi = if u1 < 0.5 {
        env.sample((2.0 * u1).min(ONE_MINUS_EPS), u2).0
    } else {
        to_world(
            n,
            cosine_hemisphere((2.0 * u1 - 1.0).min(ONE_MINUS_EPS), u2),
        )
    };
    let cos = n.dot(wi);
    if cos <= 1e-7 {
        return None;
    }
    // Both branches can produce any direction the other does, so the pdf is the full
    // mixture's whichever branch drew it.
    let pdf = world_mixture_pdf(env, cos, wi);
    if !(pdf > 0.0) {
        return None;
    }
    Some(LightSample {
        wi,
        distance: f32::INFINITY,
        radiance_over_pdf: environment.radiance(wi) / pdf,
        pdf: Some(pdf),
    })
}

/// The solid-angle pdf of [`sample_world_mixture`] for direction `wi` at cosine `cos` to the
/// normal.
#[inline]
pub(super) fn world_mixture_pdf(env: &EnvSampler, cos: f32, wi: Vec3) -> f32 {
    0.5 * env.pdf(wi) + 0.5 * cos / PI
}

/// The sample from shading point `p` towards point `q` of an emitter sampled uniformly by
/// area (an area light drawn on its surface, an emissive region): the area pdf 1/A turned
/// into solid angle gives the weight L·A·cos θ_l/d² and the pdf d²/(A·cos θ_l) (`area` is
/// A). `cos_light` says how the emitter faces the direction towards it: cos θ_l, or `None`
/// where it sends nothing that way.
#[inline]
fn sampled_by_area(
    p: Vec3,
    q: Vec3,
    radiance_times_area: Rgb,
    area: f32,
    cos_light: impl FnOnce(Vec3) -> Option<f32>,
) -> Option<LightSample> {
    let d = q - p;
    let dist2 = d.length_squared();
    if !(dist2 > 0.0) {
        return None;
    }
    let dist = dist2.sqrt();
    let wi = d / dist;
    let cos_light = cos_light(wi)?;
    Some(LightSample {
        wi,
        distance: dist,
        radiance_over_pdf: radiance_times_area * (cos_light / dist2),
        pdf: Some(dist2 / (area * cos_light)),
    })
}

/// The solid-angle pdf of a sun's uniform cone of half-angle cosine `cos_half`: 1/Ω with
/// Ω = 2π(1 − cos h); `None` for a sun without an angle (a single direction).
#[inline]
pub(super) fn sun_cone_pdf(cos_half: f32) -> Option<f32> {
    (cos_half < 1.0).then(|| 1.0 / (2.0 * PI * (1.0 - cos_half)))
}

/// The largest f32 below 1.
const ONE_MINUS_EPS: f32 = 1.0 - f32::EPSILON / 2.0;

//! The lights a BSDF-sampled ray meets: the second strategy of multiple importance sampling,
//! beside next-event estimation ([`LightSet::sample`]).
//!
//! A direction drawn from a surface's BSDF mixture can meet an emitter that next-event
//! estimation also samples: an area light's front face, an emissive region's surface, the
//! disk of a point or spot light with a radius, the cone of a sun with an angle, the world.
//! For each, [`LightSet::emitted_along`] gives the radiance the ray receives and the
//! solid-angle pdf with which [`LightSet::sample`] would have drawn that direction from the
//! same shading point, so the caller can weight both strategies (the bake's `mis` module). A point or spot light with a radius is, for both
//! strategies, the disk of that radius facing the shading point that light sampling draws
//! from, with the radiance I/(π r² cos θ_l) that makes a light sample's weight I/d² (an
//! approximation of Cycles' sphere light: the same light from a distance, a cone of
//! half-angle atan(r/d) instead of asin(r/d) up close). Points without a radius and suns
//! without an angle are single directions, left to light sampling alone: their
//! [`super::LightSample::pdf`] is `None`.

use glam::Vec3;
use std::f32::consts::PI;

use super::emitters::{AreaPlane, Emitter, WorldSampling};
use super::sample::{sun_cone_pdf, world_mixture_pdf};
use super::set::LightSet;
use crate::geometry::spherical_rect::SphericalRect;
use crate::Rgb;

/// What a traced ray hit first: its distance, the region, and the geometric normal.
#[derive(Clone, Copy, Debug)]
pub struct RayEnd {
    pub t: f32,
    pub region: u32,
    pub geometric_normal: Vec3,
}

impl AreaPlane {
    /// Distance from `p` along unit `dir` to the light's plane and the cosine at the light,
    /// for a direction that meets its front face.
    fn plane_hit(&self, p: Vec3, dir: Vec3) -> Option<(f32, f32)> {
        let cos_light = -dir.dot(self.normal);
        if !(cos_light > 0.0) {
            return None;
        }
        let t = (p - self.centre).dot(self.normal) / cos_light;
        (t > 0.0).then_some((t, cos_light))
    }
}

impl LightSet {
    /// Calls `add(emitter, radiance, pdf)` for every emitter that a ray from shading point `p`
    /// (shading normal `n`), leaving from `origin` along unit `dir`, receives light from
    /// before or at `end` (its first surface hit; `None` when it escapes). `pdf` is the
    /// solid-angle pdf with which [`LightSet::sample`] draws `dir` from `p` for that emitter
    /// (0 where it never does, infinite for a light seen exactly edge-on).
    pub fn emitted_along(
        &self,
        p: Vec3,
        n: Vec3,
        origin: Vec3,
        dir: Vec3,
        end: Option<RayEnd>,
        mut add: impl FnMut(usize, Rgb, f32),
    ) {
        let t_end = end.map_or(f32::INFINITY, |e| e.t);
        for (index, emitter) in self.emitters.iter().enumerate() {
            match emitter {
                Emitter::Point {
                    position,
                    intensity,
                    radius,
                    spot,
                } => {
                    // The disk facing `p` that light sampling draws from (module docs).
                    if !(*radius > 0.0) {
                        continue;
                    }
                    let axis = (p - *position).normalize_or_zero();
                    let cos_light = -dir.dot(axis);
                    if axis == Vec3::ZERO || !(cos_light > 0.0) {
                        continue;
                    }
                    let t = (p - *position).dot(axis) / cos_light;
                    let q = p + dir * t;
                    if !(t > 0.0 && t < t_end) || (q - *position).length() > *radius {
                        continue;
                    }
                    let mask = spot.map_or(1.0, |s| s.mask(dir));
                    if mask <= 0.0 {
                        continue;
                    }
                    let disk = PI * radius * radius * cos_light;
                    add(index, *intensity * (mask / disk), t * t / disk);
                }
                Emitter::Sun {
                    to_light,
                    cos_half,
                    radiance_over_pdf,
                } => {
                    let Some(pdf) = sun_cone_pdf(*cos_half) else {
                        continue;
                    };
                    if end.is_none() && dir.dot(*to_light) >= *cos_half {
                        add(index, *radiance_over_pdf * pdf, pdf);
                    }
                }
                Emitter::Area {
                    shape,
                    radiance_times_area,
                    area,
                } => {
                    if !(*area > 0.0) || !shape.front_face_hit(origin, dir, t_end) {
                        continue;
                    }
                    let pdf = if shape.by_solid_angle(p, self.area_sampling) {
                        let ex = shape.u * (2.0 * shape.half_u);
                        let ey = shape.v * (2.0 * shape.half_v);
                        let corner = shape.centre - shape.u * shape.half_u - shape.v * shape.half_v;
                        SphericalRect::new(corner, ex, ey, p)
                            .map_or(0.0, |r| (1.0 / r.solid_angle) as f32)
                    } else {
                        shape
                            .plane_hit(p, dir)
                            .map_or(0.0, |(t, cos_light)| t * t / (*area * cos_light))
                    };
                    add(index, *radiance_times_area / *area, pdf);
                }
                Emitter::Mesh {
                    region,
                    area,
                    radiance_times_area,
                    ..
                } => {
                    let Some(end) = end.filter(|e| e.region == *region) else {
                        continue;
                    };
                    if *radiance_times_area == Rgb::ZERO {
                        continue;
                    }
                    let cos_light = dir.dot(end.geometric_normal).abs();
                    let pdf = end.t * end.t / (*area * cos_light);
                    add(index, *radiance_times_area / *area, pdf);
                }
                Emitter::World => {
                    if end.is_some() {
                        continue;
                    }
                    let cos = n.dot(dir);
                    // Next-event estimation keeps only directions above 1e-7 (see `sample`).
                    let pdf = if cos <= 1e-7 {
                        0.0
                    } else {
                        match (&self.world_sampler, self.world_sampling) {
                            (Some(env), WorldSampling::Mixture) => world_mixture_pdf(env, cos, dir),
                            _ => cos / PI,
                        }
                    };
                    add(index, self.environment.radiance(dir), pdf);
                }
            }
        }
    }
}

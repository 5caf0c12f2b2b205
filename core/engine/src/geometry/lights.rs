//! Light sampling in Cycles' units.
//!
//! - Point: radiant intensity I = P/(4π) W/sr (× colour); a radius r > 0 samples a disk of
//!   radius r facing the shading point (a sphere light seen from outside, approximately).
//! - Spot: the point light of the same power, masked by Cycles' smoothstep cone
//!   (t = (cos θ − cos ½size)/((1 − cos ½size)·blend)).
//! - Sun: irradiance S W/m² on a surface facing it; an angular diameter α spreads it
//!   uniformly over a cone of half-angle α/2 (radiance S/(π sin²(α/2))).
//! - Area: one-sided Lambertian, radiance L = P/(π·A) along −(u × v). Squares and rectangles
//!   are sampled uniformly in the solid angle they subtend ([`SphericalRect`]: every sample
//!   weighs L·Ω); disks and ellipses uniformly on their surface (weight L·A·cos θ_l/d²) —
//!   their solid angle has no closed-form uniform parametrization, and a disk is ≈ 0.79 of
//!   its bounding square, so sampling the square and rejecting would lose a fifth of the
//!   samples and add the rejection's variance; [`AreaSampling::Area`] forces surface sampling
//!   for every shape (the reference the solid-angle sampling is measured against).
//! - World: radiance from every direction. A constant world is sampled cosine-weighted
//!   around the normal (zero variance on a diffuse surface). An image world is sampled from
//!   a defensive one-sample mixture, ½ luminance-warped ([`EnvSampler`]) + ½ cosine, with
//!   pdf ½·p_env + ½·p_cos; the cosine half bounds the weight at 2π/cos θ·L where the image
//!   pdf is small.
//!
//! Every sample returns incident radiance divided by the solid-angle pdf, so an estimator
//! is f·cos θ·`radiance_over_pdf` whatever the light, and the pdf itself, so that the bake
//! can weigh it against BSDF-sampled rays that meet the same light (multiple importance
//! sampling; [`LightSet::emitted_along`] gives what such a ray receives).

use glam::Vec3;
use std::f32::consts::PI;

use super::env_sampling::EnvSampler;
use super::environment::Environment;
use super::sampling::{concentric_disk, cosine_hemisphere, frame, to_world, uniform_cone};
use super::spherical_rect::SphericalRect;
use crate::options::LightGrouping;
use crate::scene::{AreaShape, Light, Scene, World};
use crate::Rgb;

pub mod bsdf_hits;

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

#[derive(Clone, Debug)]
enum Emitter {
    Point {
        position: Vec3,
        intensity: Rgb,
        radius: f32,
        spot: Option<Spot>,
    },
    Sun {
        to_light: Vec3,
        cos_half: f32,
        radiance_over_pdf: Rgb,
    },
    Area {
        shape: AreaPlane,
        radiance_times_area: Rgb,
        /// Surface area, m² (0 for a degenerate light, which then emits nothing).
        area: f32,
    },
    /// An emissive region's triangles, sampled uniformly by area (two-sided emission).
    Mesh {
        /// The scene region whose triangles these are (what a BSDF ray's hit names).
        region: u32,
        /// Total area, m².
        area: f32,
        /// Per triangle: v0, e1 = v1 − v0, e2 = v2 − v0, unit normal.
        triangles: Vec<[Vec3; 4]>,
        /// Cumulative area fraction per triangle (last = 1).
        cdf: Vec<f32>,
        /// Radiance times the total area (the area pdf is 1/A).
        radiance_times_area: Rgb,
    },
    World,
}

/// Where an area light lies: its centre, unit axes `u`, `v`, the normal it emits along (one
/// side only), half sizes along the axes, and whether it is a disk or an ellipse (else a
/// square or a rectangle). Shared by the light as sampled and the light as seen.
#[derive(Clone, Copy, Debug)]
struct AreaPlane {
    centre: Vec3,
    u: Vec3,
    v: Vec3,
    normal: Vec3,
    half_u: f32,
    half_v: f32,
    elliptic: bool,
}

/// A square or rectangle whose diagonal is below this fraction of its distance is sampled
/// by area even under [`AreaSampling::SolidAngle`]: its solid angle Ω ≈ A·cos θ/d² falls
/// below 10⁻⁶ sr, where the spherical-rectangle formula (four dihedral angles summing to
/// 2π + Ω, in f64) starts losing Ω's digits to rounding — seen from 1 m, a side of 10⁻⁷ m
/// came out 2 % too bright and one of 10⁻⁸ m (Ω ≈ 10⁻¹⁶, all rounding) black or up to
/// 10²⁹× too bright, depending on where it stood — while
/// the area sample's weight L·A·cos θ_l/d² varies by under 0.1 % across so small a light.
const SMALL_RECT_RATIO: f32 = 1e-3;

impl AreaPlane {
    /// Whether a light sampled under `sampling` is drawn uniformly in solid angle from `p`
    /// (a square or rectangle that is not small as seen from `p`), else uniformly by area.
    /// The light's sample and its pdf for a BSDF-sampled hit both ask this.
    fn by_solid_angle(&self, p: Vec3, sampling: AreaSampling) -> bool {
        if self.elliptic || sampling != AreaSampling::SolidAngle {
            return false;
        }
        let diagonal2 = 4.0 * (self.half_u * self.half_u + self.half_v * self.half_v);
        diagonal2 >= SMALL_RECT_RATIO * SMALL_RECT_RATIO * (p - self.centre).length_squared()
    }

    /// Whether a ray from `origin` along unit `dir` meets the light's front face before
    /// distance `t_hit` (the light emits along `normal`, so the ray meets it head-on).
    fn front_face_hit(&self, origin: Vec3, dir: Vec3, t_hit: f32) -> bool {
        let denom = dir.dot(self.normal);
        if !(denom < 0.0) {
            return false;
        }
        let t = (self.centre - origin).dot(self.normal) / denom;
        if !(t > 0.0 && t < t_hit) {
            return false;
        }
        let q = origin + dir * t - self.centre;
        let (a, b) = (q.dot(self.u) / self.half_u, q.dot(self.v) / self.half_v);
        if self.elliptic {
            a * a + b * b <= 1.0
        } else {
            a.abs() <= 1.0 && b.abs() <= 1.0
        }
    }
}

/// An emitter the camera sees directly ([`LightSet::seen_directly`]).
#[derive(Clone, Debug)]
enum Visible {
    /// A visible area light's front face.
    Area {
        shape: AreaPlane,
        radiance: Rgb,
        group: usize,
    },
    /// Every triangle of a region (the camera ray's own hit tells).
    Region {
        region: u32,
        radiance: Rgb,
        group: usize,
    },
}

/// How square and rectangular area lights are sampled (disks and ellipses always by area).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AreaSampling {
    /// Uniformly on the light's surface: weight L·A·cos θ_l/d², which varies across a
    /// close or large light.
    Area,
    /// Uniformly in the solid angle the light subtends (the default): weight L·Ω for every
    /// sample. See `cargo test --test area_sampling -- --nocapture` for the measured gain.
    #[default]
    SolidAngle,
}

#[derive(Clone, Copy, Debug)]
struct Spot {
    axis: Vec3,
    cos_half: f32,
    smooth: f32,
}

impl Spot {
    /// Cycles' smoothstep cone for the unit direction `wi` from a shading point towards the
    /// light: 1 inside, 0 outside, the blend between.
    fn mask(&self, wi: Vec3) -> f32 {
        let cos = (-wi).dot(self.axis);
        if self.smooth > 0.0 {
            let t = ((cos - self.cos_half) / self.smooth).clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        } else if cos > self.cos_half {
            1.0
        } else {
            0.0
        }
    }
}

/// How an image world is sampled (a constant world is always sampled by cosine).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WorldSampling {
    /// Cosine-weighted around the normal only (the reference for variance measurements).
    Cosine,
    /// ½ hierarchical warping of the image's luminance + ½ cosine (the default): far lower
    /// variance than cosine alone where a small bright sun sits in a dim sky
    /// (`tests/env_sampling.rs`; the figure is in docs/measurements.md, "Figures that were in
    /// code comments").
    #[default]
    Mixture,
}

/// The lights of a scene (and the world when it emits), ready for sampling.
#[derive(Clone, Debug)]
pub struct LightSet {
    emitters: Vec<Emitter>,
    /// The world's radiance (also for rays that escape).
    pub environment: Environment,
    /// The light groups; each group's emitters here are grey multiples of its tint when it
    /// has one (see [`common_tint`]).
    pub groups: Vec<LightGroup>,
    /// Group of every emitter.
    emitter_group: Vec<u16>,
    /// The image world's luminance pyramid (`None` for a constant or black world).
    world_sampler: Option<EnvSampler>,
    world_sampling: WorldSampling,
    area_sampling: AreaSampling,
    /// Emitters seen by camera rays, with the radiance they show (untinted, like the layers).
    visible: Vec<Visible>,
}

/// The colour shared by a set of emitter colours, if there is one: when all are
/// proportional to one colour c, the bake can use grey light and the relight multiply by c,
/// so paths that meet no other colour stay grey layers (one channel instead of three: a
/// third of the memory and of the relight's reads). Returns c scaled to a largest component
/// of 1, or white when the colours differ or `image_world` (an environment image is never
/// one colour). Proportional means equal after scaling within 1e-6 relative.
pub fn common_tint(colours: &[Rgb], image_world: bool) -> Rgb {
    if image_world {
        return Rgb::ONE;
    }
    let normalised: Vec<Rgb> = colours
        .iter()
        .filter(|c| c.max_element() > 0.0)
        .map(|c| *c / c.max_element())
        .collect();
    let Some(first) = normalised.first() else {
        return Rgb::ONE;
    };
    if normalised
        .iter()
        .all(|c| (*c - *first).abs().max_element() <= 1e-6)
    {
        *first
    } else {
        Rgb::ONE
    }
}

/// The emitted colour of a light (zero when it emits nothing).
fn light_colour(light: &Light) -> Rgb {
    match light {
        Light::Point { color, power, .. }
        | Light::Spot { color, power, .. }
        | Light::Area { color, power, .. } => Rgb::from(*color) * power.signum().max(0.0),
        Light::Sun {
            color, strength, ..
        }
        | Light::Emissive {
            color, strength, ..
        } => Rgb::from(*color) * strength.signum().max(0.0),
    }
}

/// A set of emitters whose layers are kept apart (a light group), and its common colour.
#[derive(Clone, Debug, PartialEq)]
pub struct LightGroup {
    pub name: String,
    pub tint: Rgb,
}

/// The name of the group holding the lights (and the world) that no scene light group lists.
pub const DEFAULT_LIGHT_GROUP: &str = "default";

/// Which group each light and the world fall in, with the groups' names.
fn group_membership(scene: &Scene, grouping: LightGrouping) -> (Vec<String>, Vec<usize>, usize) {
    match grouping {
        LightGrouping::All => (vec!["all".into()], vec![0; scene.lights.len()], 0),
        LightGrouping::PerLight => {
            let mut names: Vec<String> = (0..scene.lights.len())
                .map(|i| format!("light {i}"))
                .collect();
            let world_emits = match &scene.world {
                World::Color { color, strength } => {
                    *strength > 0.0 && color.iter().any(|c| *c > 0.0)
                }
                World::Equirect { strength, .. } => *strength > 0.0,
            };
            // The world gets a group of its own only when it emits.
            // (and when there is no light at all, so that there is always one group).
            let world = if world_emits || names.is_empty() {
                names.push("world".into());
                scene.lights.len()
            } else {
                0
            };
            (names, (0..scene.lights.len()).collect(), world)
        }
        LightGrouping::Scene => {
            let mut names: Vec<String> =
                scene.light_groups.iter().map(|g| g.name.clone()).collect();
            // A group the scene itself names "default" is that group (as the add-on maps
            // Blender's group of that name): a second one would make edits by name ambiguous.
            let default = match names.iter().position(|n| n == DEFAULT_LIGHT_GROUP) {
                Some(g) => g,
                None => {
                    names.push(DEFAULT_LIGHT_GROUP.into());
                    names.len() - 1
                }
            };
            let mut member = vec![default; scene.lights.len()];
            let mut world = default;
            for (g, spec) in scene.light_groups.iter().enumerate() {
                for &l in &spec.lights {
                    if let Some(m) = member.get_mut(l as usize) {
                        *m = g;
                    }
                }
                if spec.world {
                    world = g;
                }
            }
            (names, member, world)
        }
    }
}

/// `colour` with the tint factored out: a grey of the same largest component when the tint
/// is not white (so the bake's grey layers are bit-exact), the colour itself otherwise.
fn untinted(colour: Rgb, tint: Rgb) -> Rgb {
    if tint == Rgb::ONE {
        colour
    } else {
        Rgb::splat(colour.max_element())
    }
}

impl LightSet {
    /// Prepares the scene's lights, grouped by `grouping`; the world is one more emitter
    /// when it is not black. Each group's common colour is factored out of its emitters.
    pub fn new(scene: &Scene, grouping: LightGrouping) -> LightSet {
        let (names, member, world_group) = group_membership(scene, grouping);
        let image_world =
            matches!(&scene.world, World::Equirect { strength, .. } if *strength > 0.0);
        let world_colour = match &scene.world {
            World::Color { color, strength } => Rgb::from(*color) * *strength,
            World::Equirect { .. } => Rgb::ZERO,
        };
        let groups: Vec<LightGroup> = names
            .into_iter()
            .enumerate()
            .map(|(g, name)| {
                let mut colours: Vec<Rgb> = scene
                    .lights
                    .iter()
                    .zip(&member)
                    .filter(|(_, m)| **m == g)
                    .map(|(l, _)| light_colour(l))
                    .collect();
                if world_group == g {
                    colours.push(world_colour);
                }
                LightGroup {
                    name,
                    tint: common_tint(&colours, image_world && world_group == g),
                }
            })
            .collect();
        let mut emitters: Vec<Emitter> = scene
            .lights
            .iter()
            .zip(&member)
            .filter_map(|(l, m)| prepare(l, groups[*m].tint, scene))
            .collect();
        let mut emitter_group: Vec<u16> = member.iter().map(|m| *m as u16).collect();
        let visible = scene
            .lights
            .iter()
            .zip(&member)
            .filter_map(|(l, m)| visible_emitter(l, groups[*m].tint, *m, scene))
            .collect();
        let environment = match Environment::new(&scene.world) {
            Environment::Constant(c) => {
                Environment::Constant(untinted(c, groups[world_group].tint))
            }
            other => other,
        };
        if !environment.is_black() {
            emitters.push(Emitter::World);
            emitter_group.push(world_group as u16);
        }
        let world_sampler = match &environment {
            Environment::Equirect { image, strength } if *strength > 0.0 => EnvSampler::new(image),
            _ => None,
        };
        LightSet {
            emitters,
            environment,
            groups,
            emitter_group,
            world_sampler,
            world_sampling: WorldSampling::default(),
            area_sampling: AreaSampling::default(),
            visible,
        }
    }

    /// Emitters a camera ray from `origin` along unit `dir` sees before its first surface
    /// hit (at `t_hit`, in region `hit_region`; `None` for a ray that escapes): calls
    /// `add(group, radiance)` for each. Area lights are tested for the front face (one-sided,
    /// as Cycles renders them) and are not opaque: the surface behind is still shaded, as in
    /// Cycles, where lights are not geometry. An emissive region shows on both faces.
    pub fn seen_directly(
        &self,
        origin: Vec3,
        dir: Vec3,
        hit: Option<(f32, u32)>,
        mut add: impl FnMut(usize, Rgb),
    ) {
        let t_hit = hit.map_or(f32::INFINITY, |(t, _)| t);
        for vis in &self.visible {
            match vis {
                Visible::Area {
                    shape,
                    radiance,
                    group,
                } => {
                    if shape.front_face_hit(origin, dir, t_hit) {
                        add(*group, *radiance);
                    }
                }
                Visible::Region {
                    region,
                    radiance,
                    group,
                } => {
                    if hit.is_some_and(|(_, r)| r == *region) {
                        add(*group, *radiance);
                    }
                }
            }
        }
    }

    /// Chooses how an image world is sampled ([`WorldSampling::Mixture`] by default); both
    /// draw two uniforms per sample, so the bake's random-number order does not change.
    pub fn set_world_sampling(&mut self, sampling: WorldSampling) {
        self.world_sampling = sampling;
    }

    /// How an image world is sampled.
    pub fn world_sampling(&self) -> WorldSampling {
        self.world_sampling
    }

    /// Chooses how square and rectangular area lights are sampled
    /// ([`AreaSampling::SolidAngle`] by default); both draw two uniforms per sample.
    pub fn set_area_sampling(&mut self, sampling: AreaSampling) {
        self.area_sampling = sampling;
    }

    /// How square and rectangular area lights are sampled.
    pub fn area_sampling(&self) -> AreaSampling {
        self.area_sampling
    }

    /// The image world's importance sampler, when the world is an image that emits.
    pub fn world_sampler(&self) -> Option<&EnvSampler> {
        self.world_sampler.as_ref()
    }

    /// The group of emitter `index`.
    #[inline]
    pub fn group_of(&self, index: usize) -> usize {
        self.emitter_group[index] as usize
    }

    /// The group the world belongs to (for the world seen directly).
    pub fn world_group(&self) -> usize {
        self.emitter_group
            .last()
            .copied()
            .filter(|_| matches!(self.emitters.last(), Some(Emitter::World)))
            .unwrap_or(0) as usize
    }

    /// Number of emitters sampled at every shading point.
    pub fn len(&self) -> usize {
        self.emitters.len()
    }

    /// Whether nothing emits.
    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty()
    }

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
fn world_mixture_pdf(env: &EnvSampler, cos: f32, wi: Vec3) -> f32 {
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
fn sun_cone_pdf(cos_half: f32) -> Option<f32> {
    (cos_half < 1.0).then(|| 1.0 / (2.0 * PI * (1.0 - cos_half)))
}

/// The largest f32 below 1.
const ONE_MINUS_EPS: f32 = 1.0 - f32::EPSILON / 2.0;

/// The emitter the camera sees for `light`, when its `visible_camera` is on (group `group`).
fn visible_emitter(light: &Light, tint: Rgb, group: usize, scene: &Scene) -> Option<Visible> {
    match light {
        Light::Area {
            visible_camera: true,
            ..
        } => match prepare(light, tint, scene)? {
            Emitter::Area {
                shape,
                radiance_times_area,
                area,
            } if area > 0.0 => Some(Visible::Area {
                shape,
                radiance: radiance_times_area / area,
                group,
            }),
            _ => None,
        },
        Light::Emissive {
            region,
            strength,
            color,
            visible_camera: true,
        } => Some(Visible::Region {
            region: *region,
            radiance: untinted(Rgb::from(*color), tint) * strength.max(0.0),
            group,
        }),
        _ => None,
    }
}

fn prepare(light: &Light, tint: Rgb, scene: &Scene) -> Option<Emitter> {
    let colour = |c: &[f32; 3]| untinted(Rgb::from(*c), tint);
    match light {
        Light::Emissive {
            region,
            strength,
            color,
            ..
        } => {
            let mut triangles = Vec::new();
            let mut cdf = Vec::new();
            let mut total = 0.0f64;
            for mesh in &scene.meshes {
                for (t, idx) in mesh.indices.iter().enumerate() {
                    if mesh.region_of(t) != *region {
                        continue;
                    }
                    let get = |k: u32| mesh.positions.get(k as usize).map(|p| Vec3::from(*p));
                    let (Some(v0), Some(v1), Some(v2)) = (get(idx[0]), get(idx[1]), get(idx[2]))
                    else {
                        continue;
                    };
                    let (e1, e2) = (v1 - v0, v2 - v0);
                    let c = e1.cross(e2);
                    let a = 0.5 * c.length();
                    if !(a > 0.0) || !a.is_finite() {
                        continue;
                    }
                    total += a as f64;
                    triangles.push([v0, e1, e2, c.normalize()]);
                    cdf.push(total);
                }
            }
            if triangles.is_empty() || !(*strength > 0.0) {
                // Keep the emitter count equal to the light count (groups index by light).
                return Some(Emitter::Mesh {
                    region: *region,
                    area: 1.0,
                    triangles: vec![[Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]],
                    cdf: vec![1.0],
                    radiance_times_area: Rgb::ZERO,
                });
            }
            Some(Emitter::Mesh {
                region: *region,
                area: total as f32,
                triangles,
                cdf: cdf.iter().map(|c| (c / total) as f32).collect(),
                radiance_times_area: colour(color) * (*strength * total as f32),
            })
        }
        Light::Point {
            position,
            power,
            color,
            radius,
        } => Some(Emitter::Point {
            position: Vec3::from(*position),
            intensity: colour(color) * (*power / (4.0 * PI)),
            radius: *radius,
            spot: None,
        }),
        Light::Spot {
            position,
            direction,
            power,
            color,
            radius,
            spot_size,
            spot_blend,
        } => {
            let cos_half = (0.5 * spot_size).cos();
            Some(Emitter::Point {
                position: Vec3::from(*position),
                intensity: colour(color) * (*power / (4.0 * PI)),
                radius: *radius,
                spot: Some(Spot {
                    axis: Vec3::from(*direction).normalize(),
                    cos_half,
                    smooth: (1.0 - cos_half) * spot_blend,
                }),
            })
        }
        Light::Sun {
            direction,
            strength,
            color,
            angle,
        } => {
            let half = 0.5 * angle;
            let cos_half = half.cos();
            // Irradiance S from a uniform disk of half-angle h: L = S/(π sin²h); ∫ L dω over the
            // cone = L·2π(1 − cos h) = S·2/(1 + cos h) → S as h → 0.
            let factor = if half > 1e-6 {
                2.0 / (1.0 + cos_half)
            } else {
                1.0
            };
            Some(Emitter::Sun {
                to_light: -Vec3::from(*direction).normalize(),
                cos_half: if half > 1e-6 { cos_half } else { 1.0 },
                radiance_over_pdf: colour(color) * (*strength * factor),
            })
        }
        Light::Area {
            position,
            axis_u,
            axis_v,
            shape,
            size_x,
            size_y,
            power,
            color,
            ..
        } => {
            let u = Vec3::from(*axis_u).normalize();
            let v = Vec3::from(*axis_v).normalize();
            let (sx, sy) = match shape {
                AreaShape::Square | AreaShape::Disk => (*size_x, *size_x),
                AreaShape::Rectangle | AreaShape::Ellipse => (*size_x, size_y.unwrap_or(*size_x)),
            };
            let elliptic = matches!(shape, AreaShape::Disk | AreaShape::Ellipse);
            let area = if elliptic {
                PI * sx * sy / 4.0
            } else {
                sx * sy
            };
            // L = P/(π A); the area pdf is 1/A, so radiance/pdf (before cos/d²) is L·A = P/π.
            Some(Emitter::Area {
                shape: AreaPlane {
                    centre: Vec3::from(*position),
                    u,
                    v,
                    normal: -u.cross(v).normalize(),
                    half_u: 0.5 * sx,
                    half_v: 0.5 * sy,
                    elliptic,
                },
                radiance_times_area: colour(color)
                    * (*power / PI)
                    * if area > 0.0 { 1.0 } else { 0.0 },
                area,
            })
        }
    }
}

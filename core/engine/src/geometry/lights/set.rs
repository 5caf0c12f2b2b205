//! The light set: a scene's emitters and light groups, ready for sampling, what the camera
//! sees directly, and how square and rectangular lights and an image world are sampled.

use glam::Vec3;

use super::emitters::{prepare, visible_emitter, AreaSampling, Emitter, Visible, WorldSampling};
use super::groups::{common_tint, group_membership, light_colour, untinted, LightGroup};
use crate::geometry::env_sampling::EnvSampler;
use crate::geometry::environment::Environment;
use crate::options::LightGrouping;
use crate::scene::{Scene, World};
use crate::Rgb;

/// The lights of a scene (and the world when it emits), ready for sampling.
#[derive(Clone, Debug)]
pub struct LightSet {
    pub(super) emitters: Vec<Emitter>,
    /// The world's radiance (also for rays that escape).
    pub environment: Environment,
    /// The light groups; each group's emitters here are grey multiples of its tint when it
    /// has one (see [`common_tint`]).
    pub groups: Vec<LightGroup>,
    /// Group of every emitter.
    pub(super) emitter_group: Vec<u16>,
    /// The image world's luminance pyramid (`None` for a constant or black world).
    pub(super) world_sampler: Option<EnvSampler>,
    pub(super) world_sampling: WorldSampling,
    pub(super) area_sampling: AreaSampling,
    /// Emitters seen by camera rays, with the radiance they show (untinted, like the layers).
    pub(super) visible: Vec<Visible>,
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
}

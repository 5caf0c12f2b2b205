//! The world: constant or equirectangular radiance, with Blender's equirectangular mapping
//! (Cycles `direction_to_equirectangular`: u = 0.5 − atan2(y, x)/2π, v = 0.5 + asin(z)/π, so
//! the image centre faces +X and the top row is the zenith).

use glam::Vec3;

use super::texture::Texture;
use crate::scene::World;
use crate::Rgb;

/// The world ready for lookups.
#[derive(Clone, Debug)]
pub enum Environment {
    Constant(Rgb),
    Equirect { image: Texture, strength: f32 },
}

impl Environment {
    /// From the scene's world.
    pub fn new(world: &World) -> Environment {
        match world {
            World::Color { color, strength } => {
                Environment::Constant(Rgb::from(*color) * *strength)
            }
            World::Equirect { image, strength } => match Texture::from_ref(image) {
                Some(image) => Environment::Equirect {
                    image,
                    strength: *strength,
                },
                None => Environment::Constant(Rgb::ZERO),
            },
        }
    }

    /// Whether the world emits nothing (so it needs no sampling).
    pub fn is_black(&self) -> bool {
        match self {
            Environment::Constant(c) => c.max_element() <= 0.0,
            Environment::Equirect { strength, .. } => *strength <= 0.0,
        }
    }

    /// Radiance arriving from direction `dir` (unit, pointing away from the scene).
    pub fn radiance(&self, dir: Vec3) -> Rgb {
        match self {
            Environment::Constant(c) => *c,
            Environment::Equirect { image, strength } => {
                let u = 0.5 - dir.y.atan2(dir.x) / (2.0 * std::f32::consts::PI);
                let v = 0.5 + dir.z.clamp(-1.0, 1.0).asin() / std::f32::consts::PI;
                image.lookup(u, v) * *strength
            }
        }
    }
}

//! Ray tracing and sampling: BVH, camera rays, light and hemisphere sampling, textures.

pub mod bvh;
pub mod camera;
pub mod env_sampling;
pub mod environment;
pub mod lights;
pub mod sampling;
pub mod spherical_rect;
pub mod texture;

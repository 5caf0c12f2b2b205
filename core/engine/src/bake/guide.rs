//! Guided indirect sampling: a short first pass records where indirect light comes from,
//! per screen tile, and the bake then draws its indirect directions partly from that record.
//!
//! The record is a small equirectangular map per tile of [`GUIDE_TILE`]² pixels
//! ([`GUIDE_WIDTH`] × [`GUIDE_HEIGHT`] texels over the whole sphere, world space): for
//! [`GUIDE_SAMPLES`] cosine-distributed indirect rays per pixel, the radiance that comes back
//! (direct light reflected at the secondary hit by the bake-time materials, i.e. exactly what
//! the bake's indirect estimator carries) divided by the sampling pdf is added to the texel
//! of its direction; divided by the sample count and the texel's solid angle that is a
//! Monte Carlo estimate of the mean incoming radiance over the texel. Each map is then warped
//! the same way an HDR world is ([`EnvSampler`]: hierarchical sample warping over its mip
//! pyramid, exact pdf).
//!
//! In the bake ([`IndirectSampling::Guided`](super::settings::IndirectSampling)) the indirect
//! direction comes from a defensive one-sample mixture: [`GUIDE_WEIGHT`] of the tile's map,
//! the rest split between cosine and the basis lobes as in the plain mixture. The pdf of the
//! whole mixture is evaluated for every direction, so the estimate is unbiased whatever the
//! map holds (a tile whose map is black, or a map that points below a surface, only wastes
//! samples), and one sample set still serves all layers, so their noise stays correlated.
//! The map is built from the bake-time materials: editing a region's material afterwards
//! leaves the guide slightly off for the new material — still unbiased, a little noisier.
//!
//! The pass is deterministic (one task per tile, pixels in order, its own random stream), so
//! a reference render with the same settings builds the same guide and traces the same paths
//! as the bake.

use glam::Vec3;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

use crate::bake::context::BakeContext;
use crate::bake::integrator::{guide_sample, CountingTracer};
use crate::bake::vertex_brdf::MaterialBrdf;
use crate::brdf::BlinnPhong;
use crate::geometry::env_sampling::EnvSampler;
use crate::geometry::texture::Texture;
use crate::scene::ImageRef;
use crate::Result;

/// Side of a guide tile, pixels: a 512² image has 256 tiles, each fed by 2048 guide samples
/// spread over 128 texels.
pub const GUIDE_TILE: u32 = 32;
/// Texels of a tile's map around the sphere (φ).
pub const GUIDE_WIDTH: usize = 16;
/// Texels of a tile's map from pole to pole.
pub const GUIDE_HEIGHT: usize = 8;
/// Guide rays per pixel: the pass costs about 2/spp of the bake (≈ 12 % at 16 spp).
pub const GUIDE_SAMPLES: u32 = 2;
/// Share of the indirect mixture drawn from the guide map (the rest is cosine and lobes,
/// which bound the weight where the map is wrong).
pub const GUIDE_WEIGHT: f32 = 0.5;
/// Seed offset of the guide pass's random stream (the bake's own streams are untouched).
const GUIDE_SEED: u64 = 0x6775_6964_655f_7061;

/// The guide maps of every tile of an image, ready for sampling.
#[derive(Clone, Debug)]
pub struct GuideField {
    tiles_x: u32,
    tiles_y: u32,
    samplers: Vec<Option<EnvSampler>>,
    /// Rays the guide pass traced.
    pub rays: u64,
    /// Wall time of the guide pass, seconds.
    pub seconds: f64,
}

/// The texel (x from φ, y from the top) of direction `dir`, with the equirect convention
/// of the world ([`crate::geometry::environment`]): u = ½ − atan2(y, x)/2π, v = ½ + asin(z)/π.
fn texel_of(dir: Vec3) -> usize {
    let u = 0.5 - (dir.y as f64).atan2(dir.x as f64) / (2.0 * PI);
    let v = 0.5 + (dir.z as f64).clamp(-1.0, 1.0).asin() / PI;
    let x = ((u * GUIDE_WIDTH as f64) as usize).min(GUIDE_WIDTH - 1);
    let y = (((1.0 - v) * GUIDE_HEIGHT as f64) as usize).min(GUIDE_HEIGHT - 1);
    y * GUIDE_WIDTH + x
}

/// Solid angle of texel row `y` (from the top), each texel of it.
fn texel_solid_angle(y: usize) -> f64 {
    let z = |edge: usize| ((0.5 - edge as f64 / GUIDE_HEIGHT as f64) * PI).sin();
    (z(y) - z(y + 1)) * 2.0 * PI / GUIDE_WIDTH as f64
}

impl GuideField {
    /// Runs the guide pass over `ctx`'s image with the bake-time `materials` (editable
    /// regions, in editable order).
    pub fn build(ctx: &BakeContext, materials: Vec<BlinnPhong>) -> Result<GuideField> {
        let start = Instant::now();
        let brdf = MaterialBrdf::new(ctx, materials, false)?;
        let res = ctx.resolution;
        let tiles_x = res.width.div_ceil(GUIDE_TILE);
        let tiles_y = res.height.div_ceil(GUIDE_TILE);
        let built: Vec<(Option<EnvSampler>, u64)> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|t| {
                let (tx, ty) = (t % tiles_x, t / tiles_x);
                let mut sums = vec![0.0f64; GUIDE_WIDTH * GUIDE_HEIGHT];
                let mut tracer = CountingTracer::default();
                let mut count = 0u64;
                for py in ty * GUIDE_TILE..((ty + 1) * GUIDE_TILE).min(res.height) {
                    for px in tx * GUIDE_TILE..((tx + 1) * GUIDE_TILE).min(res.width) {
                        for s in 0..GUIDE_SAMPLES {
                            count += 1;
                            let seed = ctx.settings.seed ^ GUIDE_SEED;
                            if let Some((dir, value)) =
                                guide_sample(ctx, &brdf, &mut tracer, px, py, s, seed)
                            {
                                if value.is_finite() && value > 0.0 {
                                    sums[texel_of(dir)] += value as f64;
                                }
                            }
                        }
                    }
                }
                let rgb: Vec<f32> = sums
                    .iter()
                    .enumerate()
                    .flat_map(|(i, s)| {
                        let radiance = s / count.max(1) as f64 / texel_solid_angle(i / GUIDE_WIDTH);
                        [radiance as f32; 3]
                    })
                    .collect();
                let texture = Texture::from_ref(&ImageRef::Inline {
                    width: GUIDE_WIDTH as u32,
                    height: GUIDE_HEIGHT as u32,
                    rgb,
                });
                (texture.and_then(|t| EnvSampler::new(&t)), tracer.rays)
            })
            .collect();
        let rays = built.iter().map(|(_, r)| r).sum();
        Ok(GuideField {
            tiles_x,
            tiles_y,
            samplers: built.into_iter().map(|(s, _)| s).collect(),
            rays,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The map of the tile holding pixel (`px`, `py`); `None` where the pass saw no
    /// indirect light there.
    #[inline]
    pub fn sampler(&self, px: u32, py: u32) -> Option<&EnvSampler> {
        let (tx, ty) = (px / GUIDE_TILE, py / GUIDE_TILE);
        if tx >= self.tiles_x || ty >= self.tiles_y {
            return None;
        }
        self.samplers[(ty * self.tiles_x + tx) as usize].as_ref()
    }

    /// Tiles with a usable map, of all tiles.
    pub fn coverage(&self) -> (usize, usize) {
        (
            self.samplers.iter().filter(|s| s.is_some()).count(),
            self.samplers.len(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texels_cover_the_sphere_once() {
        let total: f64 = (0..GUIDE_HEIGHT).map(texel_solid_angle).sum::<f64>() * GUIDE_WIDTH as f64;
        assert!((total - 4.0 * PI).abs() < 1e-9, "{total}");
        assert_eq!(texel_of(Vec3::Z) / GUIDE_WIDTH, 0);
        assert_eq!(texel_of(-Vec3::Z) / GUIDE_WIDTH, GUIDE_HEIGHT - 1);
        assert_eq!(
            texel_of(Vec3::new(0.3, 0.1, 0.01)) / GUIDE_WIDTH,
            GUIDE_HEIGHT / 2 - 1
        );
    }
}

//! Guided indirect sampling: a short first pass records where indirect light comes from,
//! per screen tile, and the bake then draws its indirect directions partly from that record.
//!
//! For [`GUIDE_SAMPLES`] cosine-distributed indirect rays per pixel, the pass records the
//! direction and the luminance of the light that comes back along it (direct light reflected
//! at the secondary hit by the bake-time materials, i.e. exactly what the bake's indirect
//! estimator carries) times the cosine at the eye hit, over the cosine pdf: an estimate of
//! `L(ω)·cos θ`, the diffuse part of the integrand. The samples of a tile of [`GUIDE_TILE`]²
//! pixels build one [`DirectionTree`]: an adaptive quadtree over the sphere, fine where the
//! light is concentrated (a caustic, the bright patch under a lamp), sampled by hierarchical
//! sample warping with an exact pdf.
//!
//! In the bake ([`IndirectSampling::Guided`](super::settings::IndirectSampling)) the indirect
//! direction comes from a defensive one-sample mixture: [`GUIDE_WEIGHT`] of the tile's tree,
//! the rest the region's cosine-and-lobes [`super::mixture::DirectionMixture`]. The pdf of the
//! whole mixture is evaluated for every direction, so the estimate is unbiased whatever the
//! tree holds (a tile that saw no light, or a tree that points below a surface, only wastes
//! samples), and one sample set still serves all layers, so their noise stays correlated.
//! The tree is built from the bake-time materials: editing a region's material afterwards
//! leaves the guide slightly off for the new material — still unbiased, a little noisier.
//!
//! The pass is deterministic (one task per tile, pixels in order, its own random stream), so
//! a reference render with the same settings builds the same guide and traces the same paths
//! as the bake.

use rayon::prelude::*;
use std::time::Instant;

use crate::bake::context::BakeContext;
use crate::bake::guide_tree::DirectionTree;
use crate::bake::integrator::{guide_sample, CountingTracer};
use crate::bake::vertex_brdf::MaterialBrdf;
use crate::brdf::BlinnPhong;
use crate::Result;

/// Side of a guide tile, pixels: a 512² image has 1024 tiles, each fed by 1024 guide samples.
/// Locality is what pays: on the ring / Cornell scenes at 128², 8 spp, tiles of 32, 16 and
/// 8 pixels with 4 guide samples per pixel divided the variance of the paper's sampling by
/// 1.02 / 1.34, 1.43 / 1.47 and 1.06 / 1.58 (8-pixel tiles need more samples per pixel to
/// fill their trees: 1.40 / 1.76 with 8, at twice the pass's cost).
pub const GUIDE_TILE: u32 = 16;
/// Guide paths per pixel (3 rays each: eye, indirect, one shadow ray per light): 12 rays a
/// pixel, ≈ 3 % of a preview bake's 16 × (1 + 4 + 4 × (1 + 4)) = 400, ⅓ of an 8 × 1 × 1 bake's.
pub const GUIDE_SAMPLES: u32 = 4;
/// Share of the indirect mixture drawn from the guide (the rest is cosine and lobes, which
/// bound the weight where the guide is wrong).
pub const GUIDE_WEIGHT: f32 = 0.5;
/// Seed offset of the guide pass's random stream (the bake's own streams are untouched).
const GUIDE_SEED: u64 = 0x6775_6964_655f_7061;

/// The guide trees of every tile of an image, ready for sampling.
#[derive(Clone, Debug)]
pub struct GuideField {
    tiles_x: u32,
    tiles_y: u32,
    trees: Vec<Option<DirectionTree>>,
    /// Rays the guide pass traced.
    pub rays: u64,
    /// Wall time of the guide pass, seconds.
    pub seconds: f64,
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
        let built: Vec<(Option<DirectionTree>, u64)> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|t| {
                let (tx, ty) = (t % tiles_x, t / tiles_x);
                let mut samples = Vec::new();
                let mut tracer = CountingTracer::default();
                let seed = ctx.settings.seed ^ GUIDE_SEED;
                for py in ty * GUIDE_TILE..((ty + 1) * GUIDE_TILE).min(res.height) {
                    for px in tx * GUIDE_TILE..((tx + 1) * GUIDE_TILE).min(res.width) {
                        for s in 0..GUIDE_SAMPLES {
                            if let Some(sample) =
                                guide_sample(ctx, &brdf, &mut tracer, px, py, s, seed)
                            {
                                samples.push(sample);
                            }
                        }
                    }
                }
                (DirectionTree::build(&samples), tracer.rays)
            })
            .collect();
        let rays = built.iter().map(|(_, r)| r).sum();
        Ok(GuideField {
            tiles_x,
            tiles_y,
            trees: built.into_iter().map(|(s, _)| s).collect(),
            rays,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The tree of the tile holding pixel (`px`, `py`); `None` where the pass saw no
    /// indirect light there.
    #[inline]
    pub fn sampler(&self, px: u32, py: u32) -> Option<&DirectionTree> {
        let (tx, ty) = (px / GUIDE_TILE, py / GUIDE_TILE);
        if tx >= self.tiles_x || ty >= self.tiles_y {
            return None;
        }
        self.trees[(ty * self.tiles_x + tx) as usize].as_ref()
    }

    /// Tiles with a usable tree, of all tiles.
    pub fn coverage(&self) -> (usize, usize) {
        (
            self.trees.iter().filter(|s| s.is_some()).count(),
            self.trees.len(),
        )
    }
}

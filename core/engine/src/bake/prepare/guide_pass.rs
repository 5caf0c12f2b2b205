//! The guide pass: the short first trace that builds a guided bake's [`GuideField`] (see
//! [`crate::bake::path::guide`] for what it records and how the bake samples it). Apart from the
//! guide itself because it traces paths: the guide is data the bake context holds, the pass
//! calls the integrator, which reads the context.

use rayon::prelude::*;
use std::time::Instant;

use crate::bake::path::guide::{guide_samples, guide_tile, GuideField};
use crate::bake::path::guide_tree::DirectionTree;
use crate::bake::path::integrator::{guide_sample, CountingTracer};
use crate::bake::path::vertex_brdf::MaterialBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::brdf::BlinnPhong;
use crate::Result;

/// Seed offset of the guide pass's random stream (the bake's own streams are untouched).
const GUIDE_SEED: u64 = 0x6775_6964_655f_7061;

impl GuideField {
    /// Runs the guide pass over `ctx`'s image with the bake-time `materials` (editable
    /// regions, in editable order).
    /// Stops early with [`crate::RelumeError::Cancelled`] when `progress` is cancelled.
    pub fn build(
        ctx: &BakeContext,
        materials: Vec<BlinnPhong>,
        progress: &crate::progress::Progress,
    ) -> Result<GuideField> {
        let start = Instant::now();
        let brdf = MaterialBrdf::new(ctx, materials, false)?;
        let res = ctx.resolution;
        let samples_per_pixel = guide_samples(&ctx.settings);
        let side = guide_tile(samples_per_pixel);
        let tiles_x = res.width.div_ceil(side);
        let tiles_y = res.height.div_ceil(side);
        let built: Vec<(Option<DirectionTree>, u64)> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|t| {
                if progress.is_cancelled() {
                    return (None, 0);
                }
                let (tx, ty) = (t % tiles_x, t / tiles_x);
                let mut samples = Vec::new();
                let mut tracer = CountingTracer::default();
                let seed = ctx.settings.seed ^ GUIDE_SEED;
                for py in ty * side..((ty + 1) * side).min(res.height) {
                    for px in tx * side..((tx + 1) * side).min(res.width) {
                        for s in 0..samples_per_pixel {
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
        progress.check()?;
        let rays = built.iter().map(|(_, r)| r).sum();
        Ok(GuideField {
            side,
            tiles_x,
            tiles_y,
            trees: built.into_iter().map(|(s, _)| s).collect(),
            rays,
            seconds: start.elapsed().as_secs_f64(),
        })
    }
}

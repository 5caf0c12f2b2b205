//! A refinement's passes: one eye sample of every pixel traced twice along one path, the
//! difference summed (the module docs of [`super`] say why that difference is what the
//! relight misses past the second vertex).

use std::sync::Mutex;
use std::time::Instant;

use super::edited_tail::EditedTailBrdf;
use super::refinement::Refinement;
use super::refiner::TailRefiner;
use super::weighted_sink::WeightedSink;
use crate::bake::finish::denoise::{EyeFeatures, FEATURE_STRIDE};
use crate::bake::path::integrator::{trace_eye_sample, CountingTracer};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::schedule::tiles::{run_tiles, tiles};
use crate::memory::try_zeroed;
use crate::progress::Progress;
use crate::{RelumeError, Result, Rgb};

impl TailRefiner {
    /// Traces one pass (eye sample number `refinement.passes()` of every pixel) and adds it
    /// to `refinement`. A cancelled pass adds nothing and returns
    /// [`RelumeError::Cancelled`]; the passes before it stay.
    pub fn pass(&self, refinement: &mut Refinement, progress: &Progress) -> Result<()> {
        if !refinement.needed {
            return Ok(());
        }
        let ctx = &self.ctx;
        let res = ctx.resolution;
        let width = res.width as usize;
        let model = BasisBrdf { ctx };
        let edited = EditedTailBrdf::new(ctx, &refinement.materials, self.header.refine_bounces())?;
        let weights = &refinement.weights;
        let sample = refinement.passes;
        let n = refinement.sum.len();
        let image = Mutex::new(try_zeroed::<Rgb>(n, "a refinement pass")?);
        let eye_hits = Mutex::new(try_zeroed::<Option<(u32, glam::Vec3, glam::Vec3)>>(
            n,
            "a refinement pass's eye hits",
        )?);
        progress.start(tiles(res).len() as u64);
        run_tiles(res, ctx.settings.threads, progress, 1, |tile| {
            let mut tracer = CountingTracer::default();
            let mut out = vec![Rgb::ZERO; tile.pixels()];
            let mut eyes = vec![None; tile.pixels()];
            for ty in 0..tile.height {
                if progress.is_cancelled() {
                    return false;
                }
                for tx in 0..tile.width {
                    let (x, y) = (tile.x0 + tx, tile.y0 + ty);
                    let mut bake = WeightedSink::new(ctx, weights, true);
                    trace_eye_sample(ctx, &model, &mut bake, &mut tracer, x, y, sample);
                    let mut truth = WeightedSink::new(ctx, weights, false);
                    trace_eye_sample(ctx, &edited, &mut truth, &mut tracer, x, y, sample);
                    let d = truth.sum - bake.sum;
                    let i = (ty * tile.width + tx) as usize;
                    // Each trace keeps only finite light; their difference can still
                    // overflow, and a refinement must never spoil the relit image.
                    out[i] = if d.is_finite() { d } else { Rgb::ZERO };
                    eyes[i] = bake.eye;
                }
            }
            let mut img = image.lock().unwrap_or_else(|e| e.into_inner());
            for ty in 0..tile.height as usize {
                let row = (tile.y0 as usize + ty) * width + tile.x0 as usize;
                let w = tile.width as usize;
                img[row..row + w].copy_from_slice(&out[ty * w..(ty + 1) * w]);
            }
            drop(img);
            let mut hits = eye_hits.lock().unwrap_or_else(|e| e.into_inner());
            for ty in 0..tile.height as usize {
                let row = (tile.y0 as usize + ty) * width + tile.x0 as usize;
                let w = tile.width as usize;
                hits[row..row + w].copy_from_slice(&eyes[ty * w..(ty + 1) * w]);
            }
            true
        })?;
        let image = image.into_inner().unwrap_or_else(|e| e.into_inner());
        for (s, d) in refinement.sum.iter_mut().zip(&image) {
            *s += *d;
        }
        if sample % 2 == 1 {
            for (s, d) in refinement.sum_odd.iter_mut().zip(&image) {
                *s += *d;
            }
        }
        let hits = eye_hits.into_inner().unwrap_or_else(|e| e.into_inner());
        for (rec, hit) in refinement
            .features
            .chunks_exact_mut(FEATURE_STRIDE)
            .zip(hits)
        {
            if let Some((r, n, x)) = hit {
                EyeFeatures::add(rec, r, n, x);
            }
        }
        if sample == 0 && self.header.denoise.bounce_iterations > 0 {
            // The first pass's eye hits, whichever edit traced them: the same for all. Only
            // a stack baked with the denoiser smooths its corrections with it.
            self.reach.get_or_init(|| {
                let size = (width, res.height as usize);
                EyeFeatures::surfaces_from_window_sums(ctx, &refinement.features, 1, (0, 0), size)
                    .traced_reach(ctx)
            });
        }
        refinement.passes += 1;
        Ok(())
    }

    /// Passes until `seconds` have gone by (at least one pass, and at least two in all: one
    /// pass has no estimate of its noise, so nothing of it is shown), `max_passes` are
    /// done or `progress` is cancelled (then the passes done so far stay and this returns
    /// `Ok`).
    pub fn refine_for(
        &self,
        refinement: &mut Refinement,
        seconds: f64,
        max_passes: u32,
        progress: &Progress,
    ) -> Result<()> {
        let start = Instant::now();
        while refinement.needed && refinement.passes < max_passes {
            match self.pass(refinement, progress) {
                Ok(()) => {}
                Err(RelumeError::Cancelled) => return Ok(()),
                Err(e) => return Err(e),
            }
            if start.elapsed().as_secs_f64() >= seconds && refinement.passes >= 2 {
                break;
            }
        }
        Ok(())
    }
}

//! The reference renderer: the bake's sampler and seeds, with given materials instead of
//! basis functions, summed into one image. `relight(bake(S), M) − reference(S, M)` then
//! isolates what the stack adds: the basis error (true BRDF) or nothing but storage
//! rounding (projected BRDF).

use std::sync::Mutex;

use crate::bake::path::integrator::{trace_eye_sample, CountingTracer, PathSink};
use crate::bake::path::vertex_brdf::MaterialBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::bake::schedule::tiles::{run_tiles, tiles};
use crate::bake::settings::BakeSettings;
use crate::brdf::BlinnPhong;
use crate::progress::Progress;
use crate::scene::Scene;
use crate::{Result, Rgb};

/// Which BRDF the reference evaluates for editable regions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceBrdf {
    /// The true, un-projected Blinn–Phong.
    True,
    /// Its reconstruction in the stack's basis (what a relight can at best reproduce).
    Projected,
}

/// One pixel's sum; each light group's common colour (factored out of its emitters, as in
/// the bake) multiplies its contributions back.
struct PixelSink<'a> {
    sum: Rgb,
    tints: &'a [Rgb],
}

impl PathSink for PixelSink<'_> {
    fn world(&mut self, g: usize, v: Rgb) {
        self.sum += v * self.tints[g];
    }
    fn direct(&mut self, g: usize, _: u32, v: Rgb) {
        self.sum += v * self.tints[g];
    }
    fn bounce(&mut self, g: usize, _: u32, _: u32, v: Rgb) {
        self.sum += v * self.tints[g];
    }
}

/// A rendered image: RGBA f32, rows top to bottom.
#[derive(Clone, Debug)]
pub struct RgbaImage {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<f32>,
}

/// Renders `scene` with `materials` for its editable regions (in scene order of the
/// editable regions) using exactly the bake's paths for `settings`.
pub fn render_reference(
    scene: &Scene,
    settings: &BakeSettings,
    materials: &[BlinnPhong],
    brdf: ReferenceBrdf,
    progress: &Progress,
) -> Result<RgbaImage> {
    let (ctx, _) = BakeContext::new(scene, settings)?;
    render_with_context(&ctx, materials, brdf, progress)
}

/// As [`render_reference`], with a prepared context.
pub fn render_with_context(
    ctx: &BakeContext,
    materials: &[BlinnPhong],
    brdf: ReferenceBrdf,
    progress: &Progress,
) -> Result<RgbaImage> {
    let res = ctx.resolution;
    let width = res.width as usize;
    let vertex = MaterialBrdf::new(ctx, materials.to_vec(), brdf == ReferenceBrdf::Projected)?;
    let image = Mutex::new(vec![0.0f32; width * res.height as usize * 4]);
    let inv_spp = 1.0 / ctx.settings.spp as f32;
    let tints: Vec<Rgb> = ctx.lights.groups.iter().map(|g| g.tint).collect();
    progress.start(tiles(res).len() as u64);
    run_tiles(res, ctx.settings.threads, progress, 1, |tile| {
        let mut tracer = CountingTracer::default();
        let mut out = vec![0.0f32; tile.pixels() * 4];
        for ty in 0..tile.height {
            if progress.is_cancelled() {
                return false;
            }
            for tx in 0..tile.width {
                let mut sink = PixelSink {
                    sum: Rgb::ZERO,
                    tints: &tints,
                };
                for s in 0..ctx.settings.spp {
                    trace_eye_sample(
                        ctx,
                        &vertex,
                        &mut sink,
                        &mut tracer,
                        tile.x0 + tx,
                        tile.y0 + ty,
                        s,
                    );
                }
                let c = sink.sum * inv_spp;
                let i = (ty * tile.width + tx) as usize * 4;
                out[i..i + 4].copy_from_slice(&[c.x, c.y, c.z, 1.0]);
            }
        }
        let mut img = image.lock().unwrap_or_else(|e| e.into_inner());
        for ty in 0..tile.height as usize {
            let row = (tile.y0 as usize + ty) * width + tile.x0 as usize;
            let src = &out[ty * tile.width as usize * 4..(ty + 1) * tile.width as usize * 4];
            img[row * 4..row * 4 + src.len()].copy_from_slice(src);
        }
        true
    })?;
    Ok(RgbaImage {
        width: res.width,
        height: res.height,
        rgba: image.into_inner().unwrap_or_else(|e| e.into_inner()),
    })
}

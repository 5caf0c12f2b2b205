//! How many bounces a scene needs: a cheap pre-pass that measures the light each bounce adds.
//!
//! A bake whose settings carry a `bounce_budget` > 0 treats `bounces` as a cap. Before the
//! bake, [`estimate`] traces a few thousand paths (a grid of [`GRID`]² pixels, [`PATHS`]
//! each) with the bake-time materials at every vertex, next-event estimation at each vertex
//! and no roulette, up to the cap, and sums the luminance each bounce brings to the image
//! (bounce 0 is direct light at the eye). The count baked is the smallest n ≥ 1 whose
//! left-out bounces n+1..=cap hold at most `budget` of the measured light. The first bounce
//! is always kept: it is exact under edits and the one-bounce layers carry the tail.
//!
//! The pre-pass is an estimate from few paths (its noise is reported with it), and it
//! measures the bake-time materials: an edit that raises albedos makes later bounces count
//! for more than it says.

use rayon::prelude::*;

use crate::bake::path::bounce_kinds::{BounceKinds, KindLimits};
use crate::bake::path::frozen::{frozen_value, frozen_value_and_share};
use crate::bake::path::integrator::Tracer;
use crate::bake::path::integrator::{continuation, direct_light, group_light, CountingTracer};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::bounce_budget::{choose, BounceEstimate};
use crate::bake::prepare::context::BakeContext;
use crate::geometry::sampling::SampleStream;
use crate::options::MAX_BASES;
use crate::Rgb;

/// Pixels per side of the pre-pass grid (fewer when the image is smaller).
pub const GRID: u32 = 48;
/// Paths per grid pixel.
pub const PATHS: u32 = 4;

/// Runs the pre-pass for `ctx` (its own settings' seed, light samples and threads) and picks
/// the bounce count for `cap` and `budget`.
pub fn estimate(ctx: &BakeContext, cap: u32, budget: f32) -> BounceEstimate {
    let res = ctx.resolution;
    let (gx, gy) = (GRID.min(res.width), GRID.min(res.height));
    let rows: Vec<Vec<f64>> = match rayon::ThreadPoolBuilder::new()
        .num_threads(ctx.settings.threads)
        .build()
    {
        Ok(pool) => pool.install(|| {
            (0..gy)
                .into_par_iter()
                .map(|y| row(ctx, cap, gx, gy, y))
                .collect()
        }),
        Err(_) => (0..gy).map(|y| row(ctx, cap, gx, gy, y)).collect(),
    };
    let paths = gx as u64 * gy as u64 * PATHS as u64;
    let mut energy = vec![0.0f64; cap as usize + 1];
    for r in &rows {
        for (e, v) in energy.iter_mut().zip(r) {
            *e += v / paths as f64;
        }
    }
    let (chosen, left_out) = choose(&energy, budget);
    BounceEstimate {
        cap,
        budget,
        chosen,
        energy,
        left_out,
        paths,
    }
}

/// One grid row: per bounce, the summed luminance of its paths.
fn row(ctx: &BakeContext, cap: u32, gx: u32, gy: u32, y: u32) -> Vec<f64> {
    let res = ctx.resolution;
    let brdf = BasisBrdf { ctx };
    let mut tracer = CountingTracer::default();
    let mut energy = vec![0.0f64; cap as usize + 1];
    let mut values = [Rgb::ZERO; MAX_BASES];
    let mut light = group_light(ctx.lights.groups.len());
    let tints: Vec<Rgb> = ctx.lights.groups.iter().map(|g| g.tint).collect();
    let seed = ctx.settings.seed ^ 0xB0C7_CE5E_57A1_u64;
    let limits = KindLimits::of(&ctx.settings, cap);
    for x in 0..gx {
        let px = ((x as f32 + 0.5) * res.width as f32 / gx as f32) as u32;
        let py = ((y as f32 + 0.5) * res.height as f32 / gy as f32) as u32;
        let pixel = py as u64 * res.width as u64 + px as u64;
        for s in 0..PATHS {
            let mut stream = SampleStream::new(seed, pixel, s);
            let (jx, jy) = stream.next2();
            let (mut origin, mut dir) = ctx.camera.ray(px as f32 + jx, py as f32 + jy);
            let mut throughput = Rgb::ONE;
            let mut tmax = ctx.clip_end;
            // Cycles' per-kind limits, as the bake counts them.
            let mut kinds = limits.map(BounceKinds::new);
            #[allow(clippy::needless_range_loop)] // `bounce` also counts the path's length
            for bounce in 0..=cap as usize {
                let Some(hit) = tracer.intersect(ctx, origin, dir, 0.0, tmax) else {
                    break;
                };
                tmax = f32::INFINITY;
                let wo = -dir;
                // Bake-time materials at every vertex: the bake's tail BRDF.
                let tail = FrozenOnly(&brdf);
                let (_, c) = direct_light(
                    ctx,
                    &tail,
                    &mut tracer,
                    &hit,
                    wo,
                    None,
                    bounce > 0,
                    &mut stream,
                    &mut values,
                    &mut light,
                );
                let within = kinds.as_ref().map_or(1.0, BounceKinds::within);
                if within <= 0.0 {
                    break;
                }
                if c > 0 {
                    let mut sum = Rgb::ZERO;
                    for (g, t) in tints.iter().enumerate() {
                        sum += light[g * MAX_BASES] * *t;
                    }
                    energy[bounce] += (crate::luminance(throughput * sum) * within) as f64;
                }
                if bounce == cap as usize {
                    break;
                }
                let n = hit.shading_normal;
                let Some((wi, cos, pdf)) = continuation(ctx, &hit, wo, &mut stream) else {
                    break;
                };
                let (value, share) =
                    frozen_value_and_share(ctx, hit.region, hit.uv, n, wi, wo, kinds.is_some());
                if let Some(k) = kinds.as_mut() {
                    k.bounce(share);
                }
                throughput *= value * (cos / pdf);
                if throughput == Rgb::ZERO {
                    break;
                }
                origin = ctx.geometry.offset(hit.position, hit.geometric_normal);
                dir = wi;
            }
        }
    }
    energy
}

/// The bake-time BRDF as a one-slot vertex BRDF (for [`direct_light`]).
struct FrozenOnly<'a>(&'a BasisBrdf<'a>);

impl crate::bake::path::integrator::VertexBrdf for FrozenOnly<'_> {
    fn eval(
        &self,
        region: u32,
        uv: glam::Vec2,
        n: glam::Vec3,
        wi: glam::Vec3,
        wo: glam::Vec3,
        out: &mut [Rgb; MAX_BASES],
    ) -> (u32, usize) {
        out[0] = frozen_value(self.0.ctx, region, uv, n, wi, wo);
        (0, 1)
    }
    fn tail(
        &self,
        region: u32,
        uv: glam::Vec2,
        n: glam::Vec3,
        wi: glam::Vec3,
        wo: glam::Vec3,
    ) -> Rgb {
        frozen_value(self.0.ctx, region, uv, n, wi, wo)
    }
    fn tail_is_frozen(&self) -> bool {
        true
    }
    fn glossy_share(
        &self,
        region: u32,
        uv: glam::Vec2,
        n: glam::Vec3,
        wi: glam::Vec3,
        wo: glam::Vec3,
    ) -> f32 {
        crate::bake::path::frozen::frozen_glossy_share(self.0.ctx, region, uv, n, wi, wo)
    }
}

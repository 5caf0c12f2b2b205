//! `relume bench bake`: the bake's effective ray throughput against raw obvhs throughput on
//! the same scene and the same rays, measured in one run.
//!
//! The bake is timed whole (BVH build excluded, layer assembly included). Then the rays of
//! every 4th tile are recorded by re-running the integrator with a recording tracer, and
//! replayed through bare obvhs queries (closest hit or occlusion, as recorded) in parallel.
//! The ratio says how much of the bake is ray tracing.

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

use relume_engine::bake::path::integrator::{trace_eye_sample, PathSink, Tracer};
use relume_engine::bake::path::vertex_brdf::BasisBrdf;
use relume_engine::bake::prepare::context::BakeContext;
use relume_engine::bake::schedule::tiles::tiles;
use relume_engine::bake::settings::BakeSettings;
use relume_engine::geometry::bvh::SurfaceHit;
use relume_engine::progress::Progress;
use relume_engine::scene::Scene;
use relume_engine::{Result, Rgb};

/// Figures of one bench run.
#[derive(Clone, Debug, Serialize)]
pub struct BakeBench {
    pub triangles: usize,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub threads: usize,
    /// Tracing and layer assembly time of the bake (BVH build excluded).
    pub bake_seconds: f64,
    pub bake_rays: u64,
    pub effective_rays_per_second: f64,
    pub recorded_rays: usize,
    pub recorded_closest_fraction: f64,
    pub raw_seconds: f64,
    pub raw_rays_per_second: f64,
    /// effective / raw.
    pub ratio: f64,
    pub layers: usize,
}

#[derive(Clone, Copy)]
struct RecordedRay {
    origin: Vec3,
    dir: Vec3,
    tmin: f32,
    tmax: f32,
    closest: bool,
}

struct RecordingTracer {
    rays: Vec<RecordedRay>,
}

impl Tracer for RecordingTracer {
    fn intersect(
        &mut self,
        ctx: &BakeContext,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<SurfaceHit> {
        self.rays.push(RecordedRay {
            origin,
            dir,
            tmin,
            tmax,
            closest: true,
        });
        ctx.geometry.intersect(origin, dir, tmin, tmax)
    }
    fn occluded(&mut self, ctx: &BakeContext, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.rays.push(RecordedRay {
            origin,
            dir,
            tmin: 0.0,
            tmax,
            closest: false,
        });
        ctx.geometry.occluded(origin, dir, tmax)
    }
}

struct NullSink;
impl PathSink for NullSink {
    fn world(&mut self, _: usize, _: Rgb) {}
    fn direct(&mut self, _: usize, _: u32, _: Rgb) {}
    fn bounce(&mut self, _: usize, _: u32, _: u32, _: Rgb) {}
}

/// Runs the bench.
pub fn bench_bake(scene: &Scene, settings: &BakeSettings) -> Result<BakeBench> {
    let progress = Progress::new();
    let (stack, report) = relume_engine::bake::bake_tiled(scene, settings, &progress)?;
    let (ctx, _) = BakeContext::new(scene, settings)?;
    let brdf = BasisBrdf { ctx: &ctx };
    let mut tracer = RecordingTracer { rays: Vec::new() };
    for tile in tiles(ctx.resolution).iter().step_by(4) {
        for ty in 0..tile.height {
            for tx in 0..tile.width {
                for s in 0..settings.spp {
                    trace_eye_sample(
                        &ctx,
                        &brdf,
                        &mut NullSink,
                        &mut tracer,
                        tile.x0 + tx,
                        tile.y0 + ty,
                        s,
                    );
                }
            }
        }
    }
    let rays = tracer.rays;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| relume_engine::RelumeError::invalid("threads", e.to_string()))?;
    let threads = pool.current_num_threads();
    let geometry = &ctx.geometry;
    let t0 = Instant::now();
    let hits: usize = pool.install(|| {
        rays.par_chunks(4096)
            .map(|chunk| {
                let mut n = 0usize;
                for r in chunk {
                    let hit = if r.closest {
                        geometry
                            .intersect_raw(r.origin, r.dir, r.tmin, r.tmax)
                            .is_some()
                    } else {
                        geometry.occluded(r.origin, r.dir, r.tmax)
                    };
                    n += hit as usize;
                }
                n
            })
            .sum()
    });
    let raw_seconds = t0.elapsed().as_secs_f64();
    std::hint::black_box(hits);
    let raw = rays.len() as f64 / raw_seconds.max(1e-9);
    let closest = rays.iter().filter(|r| r.closest).count();
    Ok(BakeBench {
        triangles: report.triangles,
        width: report.width,
        height: report.height,
        spp: settings.spp,
        threads,
        bake_seconds: report.trace_seconds,
        bake_rays: report.rays,
        effective_rays_per_second: report.rays_per_second,
        recorded_rays: rays.len(),
        recorded_closest_fraction: closest as f64 / rays.len().max(1) as f64,
        raw_seconds,
        raw_rays_per_second: raw,
        ratio: report.rays_per_second / raw.max(1e-9),
        layers: stack.layers.len(),
    })
}

//! The bake: one path-tracing pass that fills every layer of the transfer stack.
//!
//! For each pixel and eye sample, the integrator ([`integrator`]) gives radiance per slot
//! (direct) and per slot pair (one bounce); a tile accumulates them densely, then hands every
//! layer that received anything to the whole-image layer store. At the end a layer whose
//! three channels are bit-identical everywhere (its paths met no colour: Table 1's grey
//! layers) is stored with one channel, an all-zero layer is dropped, and the rest are RGB.

pub mod bench;
pub mod context;
pub mod drop;
pub mod integrator;
pub mod progress;
pub mod reference;
pub mod settings;
pub mod signature;
pub mod tiles;
pub mod vertex_brdf;

use rayon::prelude::*;
use serde::Serialize;
use std::sync::Mutex;
use std::time::Instant;

use crate::scene::{hash::scene_hash, Scene};
use crate::stack::{Layer, RegionInfo, StackHeader, TransferStack, STACK_FORMAT_VERSION};
use crate::{Result, Rgb};
use context::BakeContext;
use drop::RawLayer;
use integrator::{trace_eye_sample, CountingTracer, PathSink};
use progress::Progress;
pub use settings::{BakeSettings, IndirectSampling};
use signature::LayerKey;
use vertex_brdf::BasisBrdf;

/// What a bake did, for the command line's JSON and the add-on's status.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    /// Whole bake, wall clock.
    pub seconds: f64,
    /// Validation, basis and BVH build.
    pub setup_seconds: f64,
    /// Path tracing and layer assembly.
    pub trace_seconds: f64,
    /// Part of `trace_seconds` spent turning the accumulated images into layers.
    pub assembly_seconds: f64,
    /// Rays per second of `trace_seconds`.
    pub rays: u64,
    pub rays_per_second: f64,
    pub width: u32,
    pub height: u32,
    pub triangles: usize,
    pub degenerate_triangles: usize,
    pub warnings: Vec<String>,
    /// Layers the slots allow (world + slots + slot pairs).
    pub layers_possible: usize,
    pub layers_grey: usize,
    pub layers_rgb: usize,
    /// Layers no path reached (e.g. a region never seen from another): not stored.
    pub layers_empty: usize,
    pub sample_bytes: usize,
    /// Layers kept and left out, per region, and what leaving them out costs.
    pub layers: drop::DropReport,
}

/// Accumulates one pixel of a tile densely: the tile buffer is pixel-major (all layers of
/// a pixel together, so a path's writes stay in a few cache lines), then layer, then RGB.
struct TileSink<'a> {
    /// The layers of the current pixel.
    buf: &'a mut [f32],
    slots: usize,
}

impl TileSink<'_> {
    #[inline]
    fn add(&mut self, layer: usize, v: Rgb) {
        let i = layer * 3;
        self.buf[i] += v.x;
        self.buf[i + 1] += v.y;
        self.buf[i + 2] += v.z;
    }
}

impl PathSink for TileSink<'_> {
    #[inline]
    fn world(&mut self, v: Rgb) {
        self.add(0, v);
    }
    #[inline]
    fn direct(&mut self, slot: u32, v: Rgb) {
        self.add(1 + slot as usize, v);
    }
    #[inline]
    fn bounce(&mut self, eye: u32, bounce: u32, v: Rgb) {
        let s = self.slots;
        self.add(1 + s + eye as usize * s + bounce as usize, v);
    }
}

/// The key of dense layer index `layer` for `ctx`'s slots.
pub fn layer_key(ctx: &BakeContext, layer: usize) -> LayerKey {
    let s = ctx.slot_count();
    if layer == 0 {
        LayerKey::new(vec![])
    } else if layer <= s {
        LayerKey::new(vec![ctx.slot_vertex[layer - 1]])
    } else {
        let pair = layer - 1 - s;
        LayerKey::new(vec![ctx.slot_vertex[pair / s], ctx.slot_vertex[pair % s]])
    }
}

/// Bakes `scene` into a transfer stack. `progress` reports and cancels from other threads.
pub fn bake(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
) -> Result<(TransferStack, BakeReport)> {
    let start = Instant::now();
    let (ctx, validation) = BakeContext::new(scene, settings)?;
    let setup_seconds = start.elapsed().as_secs_f64();
    let trace_start = Instant::now();
    let res = ctx.resolution;
    let (width, height) = (res.width as usize, res.height as usize);
    let layer_count = ctx.layer_count();
    let slots = ctx.slot_count();
    let store: Vec<Mutex<Vec<f32>>> = (0..layer_count).map(|_| Mutex::new(Vec::new())).collect();
    let rays = std::sync::atomic::AtomicU64::new(0);
    let brdf = BasisBrdf { ctx: &ctx };

    tiles::run_tiles(res, settings.threads, progress, |tile| {
        let tp = tile.pixels();
        let mut buf = vec![0.0f32; layer_count * tp * 3];
        let mut tracer = CountingTracer::default();
        for ty in 0..tile.height {
            if progress.is_cancelled() {
                return false;
            }
            for tx in 0..tile.width {
                let pixel = (ty * tile.width + tx) as usize;
                let mut sink = TileSink {
                    buf: &mut buf[pixel * layer_count * 3..(pixel + 1) * layer_count * 3],
                    slots,
                };
                for s in 0..settings.spp {
                    trace_eye_sample(
                        &ctx,
                        &brdf,
                        &mut sink,
                        &mut tracer,
                        tile.x0 + tx,
                        tile.y0 + ty,
                        s,
                    );
                }
            }
        }
        rays.fetch_add(tracer.rays, std::sync::atomic::Ordering::Relaxed);
        let stride = layer_count * 3;
        for (layer, slot) in store.iter().enumerate() {
            let texel = |p: usize| &buf[p * stride + layer * 3..p * stride + layer * 3 + 3];
            if (0..tp).all(|p| texel(p) == [0.0; 3]) {
                continue;
            }
            let mut image = slot.lock().unwrap_or_else(|e| e.into_inner());
            if image.is_empty() {
                *image = vec![0.0; width * height * 3];
            }
            for ty in 0..tile.height as usize {
                for tx in 0..tile.width as usize {
                    let dst = ((tile.y0 as usize + ty) * width + tile.x0 as usize + tx) * 3;
                    image[dst..dst + 3].copy_from_slice(texel(ty * tile.width as usize + tx));
                }
            }
        }
        true
    })?;

    let assembly_start = Instant::now();
    let inv_spp = 1.0 / settings.spp as f32;
    // Whole-image layers: averaged over the eye samples, grey when the three channels are
    // bit-identical everywhere (the path met no colour), `None` when nothing reached them.
    let assemble = |(index, slot): (usize, Mutex<Vec<f32>>)| -> Result<RawLayer, LayerKey> {
        let mut image = slot.into_inner().unwrap_or_else(|e| e.into_inner());
        let key = layer_key(&ctx, index);
        if image.is_empty() || image.iter().all(|v| *v == 0.0) {
            return Err(key);
        }
        image.iter_mut().for_each(|v| *v *= inv_spp);
        if image.chunks_exact(3).all(|c| c[0] == c[1] && c[1] == c[2]) {
            let y: Vec<f32> = image.chunks_exact(3).map(|c| c[0]).collect();
            Ok(RawLayer {
                key,
                channels: 1,
                data: y,
            })
        } else {
            Ok(RawLayer {
                key,
                channels: 3,
                data: image,
            })
        }
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| crate::RelumeError::invalid("threads", e.to_string()))?;
    let assembled: Vec<Result<RawLayer, LayerKey>> =
        pool.install(|| store.into_par_iter().enumerate().map(assemble).collect());
    let mut reached = Vec::new();
    let mut unreached = Vec::new();
    for a in assembled {
        match a {
            Ok(l) => reached.push(l),
            Err(k) => unreached.push(k),
        }
    }
    let empty = unreached.len();
    let (kept, drop_report) = drop::drop_negligible(
        &ctx,
        scene,
        reached,
        &unreached,
        settings.drop_budget as f64,
    );
    let mut layers: Vec<Layer> = pool.install(|| {
        kept.into_par_iter()
            .map(|l| Layer::from_f32(l.key, l.channels, &l.data, settings.precision))
            .collect()
    });
    let grey = layers.iter().filter(|l| l.channels == 1).count();
    let rgb = layers.len() - grey;
    if layers.is_empty() {
        // Nothing reached the eye (no light, black world: validation warned). Keep one black
        // layer so the stack is a valid file and relights to a black image.
        layers.push(Layer::from_f32(
            LayerKey::new(vec![]),
            1,
            &vec![0.0; width * height],
            settings.precision,
        ));
    }
    let header = StackHeader {
        format_version: STACK_FORMAT_VERSION,
        width: res.width,
        height: res.height,
        camera: scene.camera.clone(),
        spp: settings.spp,
        light_samples: settings.light_samples,
        bounces: settings.bounces,
        sampling: settings.sampling.name().into(),
        seed: settings.seed,
        regions: scene
            .regions
            .iter()
            .map(|r| {
                RegionInfo::from_region(
                    r,
                    r.editable
                        .then(|| context::basis_config_for(&settings.basis, r.ns_range)),
                )
            })
            .collect(),
        lights: scene.lights.clone(),
        scene_hash: scene_hash(scene),
        precision: settings.precision,
        light_tint: ctx.lights.tint.to_array(),
    };
    let stack = TransferStack { header, layers };
    let assembly_seconds = assembly_start.elapsed().as_secs_f64();
    let trace_seconds = trace_start.elapsed().as_secs_f64();
    let seconds = start.elapsed().as_secs_f64();
    let rays = rays.into_inner();
    let report = BakeReport {
        seconds,
        rays,
        setup_seconds,
        trace_seconds,
        assembly_seconds,
        rays_per_second: rays as f64 / trace_seconds.max(1e-9),
        width: res.width,
        height: res.height,
        triangles: validation.triangles,
        degenerate_triangles: validation.degenerate_triangles,
        warnings: validation.warnings,
        layers_possible: layer_count,
        layers_grey: grey,
        layers_rgb: rgb,
        layers_empty: empty,
        sample_bytes: stack.sample_bytes(),
        layers: drop_report,
    };
    Ok((stack, report))
}

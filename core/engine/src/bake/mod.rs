//! The bake: one path-tracing pass that fills every layer of the transfer stack.
//!
//! For each pixel and eye sample, the integrator ([`integrator`]) gives radiance per slot
//! (direct) and per slot pair (one bounce); a tile accumulates them densely, then hands every
//! layer that received anything to the whole-image layer store. At the end a layer whose
//! three channels are bit-identical everywhere (its paths met no colour: Table 1's grey
//! layers) is stored with one channel, an all-zero layer is dropped, and the rest are RGB.

pub mod bench;
pub mod blocks;
pub mod bounce_budget;
pub mod bounces;
pub mod context;
pub mod denoise;
pub mod drop;
pub mod estimate;
pub mod farm_file;
pub mod frozen;
pub mod guide;
pub mod guide_file;
pub mod guide_pass;
pub mod guide_tree;
pub mod integrator;
pub mod layout;
pub mod mixture;
pub mod partial;
pub mod partition;
pub mod presets;
pub mod progress;
pub mod reference;
pub mod settings;
pub mod setup;
pub mod signature;
pub mod subsurface;
pub mod subsurface_light;
pub mod tiles;
pub mod to_file;
pub mod vertex_brdf;

use rayon::prelude::*;
use serde::Serialize;
use std::sync::Mutex;
use std::time::Instant;

use crate::layer_key::LayerKey;
use crate::progress::{Progress, Stage};
use crate::scene::{hash::scene_hash, Scene};
use crate::stack::{
    Layer, LightGroupInfo, RegionInfo, StackHeader, TransferStack, STACK_FORMAT_VERSION,
};
use crate::{Result, Rgb};
use context::BakeContext;
use drop::RawLayer;
use integrator::{trace_eye_sample, CountingTracer, PathSink};
pub use layout::layer_key;
use layout::DenseLayout;
pub use settings::{BakeSettings, Denoise, IndirectSampling, LightGrouping};
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
    /// Part of `assembly_seconds` spent denoising ([`denoise`]; 0 when the settings ask for none).
    pub denoise_seconds: f64,
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
    /// The memory forecast made before tracing (compare with the measured peak).
    pub estimate: Option<estimate::BakeEstimate>,
    /// Bounces baked (the header's `bounces`) and, when the settings asked for what the
    /// scene needs, what the pre-pass measured ([`bounces`]).
    pub bounces: u32,
    pub bounce_estimate: Option<bounce_budget::BounceEstimate>,
}

/// Accumulates one pixel of a tile densely: the tile buffer is pixel-major (all layers of
/// a pixel together, so a path's writes stay in a few cache lines), then layer, then RGB.
struct TileSink<'a> {
    /// The layers of the current pixel.
    buf: &'a mut [f32],
    layout: DenseLayout,
    /// The pixel's eye-hit record for the denoiser ([`denoise::EyeFeatures`]).
    features: &'a mut [f32],
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
    fn world(&mut self, group: usize, v: Rgb) {
        self.add(self.layout.world(group), v);
    }
    #[inline]
    fn direct(&mut self, group: usize, slot: u32, v: Rgb) {
        self.add(self.layout.direct(group, slot), v);
    }
    #[inline]
    fn bounce(&mut self, group: usize, eye: u32, bounce: u32, v: Rgb) {
        self.add(self.layout.bounce(group, eye, bounce), v);
    }
    #[inline]
    fn eye_hit(&mut self, region: u32, normal: glam::Vec3, position: glam::Vec3) {
        denoise::EyeFeatures::add(self.features, region, normal, position);
    }
}

/// Bakes `scene` into a transfer stack. `progress` reports and cancels from other threads.
pub fn bake(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
) -> Result<(TransferStack, BakeReport)> {
    let (stack, report, _) =
        bake_progressive(scene, settings, &[settings.spp], progress, |_, _, _| Ok(()))?;
    Ok((stack, report))
}

/// One pass of a progressive bake.
#[derive(Clone, Debug, Serialize)]
pub struct PassReport {
    pub pass: usize,
    /// Eye samples per pixel so far.
    pub spp: u32,
    /// Seconds since the bake started, when this pass's stack was ready.
    pub seconds: f64,
    /// Estimated relative L2 noise of the image at the bake-time materials after this pass
    /// (from the change since the previous pass: for cumulative sample counts n₋ < n, the
    /// noise is ‖I − I₋‖·√(r/(1 − r)) with r = n₋/n); `None` for the first pass.
    pub estimated_rel_error: Option<f64>,
}

/// Sample counts of a progressive bake of `passes` passes ending at `spp`: doubling, so
/// each pass's estimate of the remaining noise is plain (see [`PassReport`]).
pub fn doubling_passes(spp: u32, passes: u32) -> Vec<u32> {
    let mut out: Vec<u32> = (0..passes.max(1))
        .rev()
        .map(|k| (spp >> k).max(1))
        .collect();
    out.dedup();
    out
}

/// A bake in passes: after pass k the stack holds `passes[k]` eye samples per pixel
/// (cumulative, increasing, the last one is the bake) and `on_pass` gets it — complete and
/// usable, e.g. to write it (atomically) and relight a first noisy image within seconds.
/// The paths are the same as one bake of `passes.last()` samples.
pub fn bake_progressive(
    scene: &Scene,
    settings: &BakeSettings,
    passes: &[u32],
    progress: &Progress,
    mut on_pass: impl FnMut(&TransferStack, &BakeReport, &PassReport) -> Result<()>,
) -> Result<(TransferStack, BakeReport, Vec<PassReport>)> {
    settings.validate()?;
    if passes.is_empty() || passes.windows(2).any(|w| w[0] >= w[1]) || passes[0] == 0 {
        return Err(crate::RelumeError::invalid(
            "bake passes",
            format!("{passes:?}: sample counts must increase from ≥ 1"),
        ));
    }
    let start = Instant::now();
    progress.set_stage(Stage::Setup);
    let mut settings = settings.clone();
    settings.spp = *passes.last().unwrap_or(&1);
    let (mut ctx, validation, prepared) = estimate::prepare_measured(scene, &settings, progress)?;
    // The forecast and the budget come before the guide pass and the trace, so a bake that
    // cannot fit is refused in a second, not after minutes of tracing.
    let forecast = estimate::estimate(&ctx, scene, passes.len(), prepared);
    crate::memory::check_budget(
        &format!(
            "this bake ({}×{}, {} of {} possible layers reached by a probe; stack ≈ {})",
            forecast.width,
            forecast.height,
            forecast.layers_reached,
            forecast.layers_possible,
            crate::memory::human_bytes(forecast.stack_bytes)
        ),
        forecast.peak_bytes,
        settings.memory_budget,
    )?;
    ctx.build_guide(scene, progress)?;
    let setup_seconds = start.elapsed().as_secs_f64();
    let res = ctx.resolution;
    let (width, height) = (res.width as usize, res.height as usize);
    let mut store = blocks::BlockStore::default();
    let rays = std::sync::atomic::AtomicU64::new(0);
    let tile_count = tiles::tiles(res).len() as u64;
    progress.set_stage(Stage::Tracing);
    progress.start(tile_count * settings.spp as u64);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| crate::RelumeError::invalid("threads", e.to_string()))?;
    let mut pass_reports = Vec::new();
    let mut previous_image: Option<Vec<f64>> = None;
    let mut done = 0u32;
    let mut result = None;
    for (pass, &upto) in passes.iter().enumerate() {
        let trace_start = Instant::now();
        let (from, to) = (done, upto);
        progress.set_stage(Stage::Tracing);
        let last_pass = pass + 1 == passes.len();
        // A one-pass bake keeps only its tree's root per pixel (one image per layer).
        trace_range(
            &ctx,
            &mut store,
            from,
            to,
            last_pass && from == 0,
            progress,
            &rays,
        )?;
        done = upto;
        let (sums, feature_sums) = if last_pass {
            std::mem::take(&mut store).fold()
        } else {
            store.fold_copy()?
        };
        let eye_features = denoise::EyeFeatures::from_sums(&ctx, &feature_sums, done);
        drop(feature_sums);
        let (stack, mut report, image) = assemble(
            &ctx,
            scene,
            &settings,
            &sums,
            &eye_features,
            done,
            &pool,
            width,
            height,
            progress,
            true,
        )?;
        drop(sums);
        let norm = image.iter().map(|v| v * v).sum::<f64>().sqrt();
        let estimated_rel_error = previous_image.as_ref().map(|prev| {
            let diff = prev
                .iter()
                .zip(&image)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            let r = from as f64 / to as f64;
            diff * (r / (1.0 - r)).sqrt() / norm.max(1e-300)
        });
        previous_image = Some(image);
        let trace_seconds = trace_start.elapsed().as_secs_f64();
        let total_rays = rays.load(std::sync::atomic::Ordering::Relaxed);
        report.seconds = start.elapsed().as_secs_f64();
        report.setup_seconds = setup_seconds;
        report.trace_seconds = report.seconds - setup_seconds;
        report.rays = total_rays;
        report.rays_per_second = total_rays as f64 / report.trace_seconds.max(1e-9);
        report.triangles = validation.triangles;
        report.degenerate_triangles = validation.degenerate_triangles;
        report.warnings = validation.warnings.clone();
        report.estimate = Some(forecast.clone());
        let _ = trace_seconds;
        let pass_report = PassReport {
            pass,
            spp: done,
            seconds: report.seconds,
            estimated_rel_error,
        };
        progress.check()?;
        on_pass(&stack, &report, &pass_report)?;
        pass_reports.push(pass_report);
        result = Some((stack, report));
    }
    progress.set_stage(Stage::Done);
    let (stack, report) = result.expect("at least one pass");
    Ok((stack, report, pass_reports))
}

/// Traces eye samples `samples` of every pixel of `tile` into the pass's `blocks` (the
/// [`blocks::dyadic_blocks`] of `samples`, or one block when `fold`: the range is a whole
/// bake `[0, spp)` and its tree's root is all that is kept). Every pixel adds its samples in
/// the canonical tree of [`blocks`], so any split of the samples gives the same bits.
#[allow(clippy::too_many_arguments)]
fn trace_tile(
    ctx: &BakeContext,
    brdf: &BasisBrdf,
    blocks: &[blocks::Block],
    fold: bool,
    tile: &tiles::Tile,
    samples: std::ops::Range<u32>,
    width: usize,
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<bool> {
    let layer_count = ctx.layer_count();
    let layout = DenseLayout::of(ctx);
    let height = ctx.resolution.height as usize;
    let tp = tile.pixels();
    let fs = denoise::FEATURE_STRIDE;
    let record = layer_count * 3 + fs;
    let mut buf: Vec<f32> =
        crate::memory::try_zeroed(blocks.len() * tp * record, "a tile's layer sums")?;
    let mut tree = blocks::PixelTree::new(layer_count)?;
    let mut tracer = CountingTracer::default();
    for ty in 0..tile.height {
        if progress.is_cancelled() {
            return Ok(false);
        }
        for tx in 0..tile.width {
            let pixel = (ty * tile.width + tx) as usize;
            tree.clear();
            for s in samples.clone() {
                let (layers, features) = tree.push_leaf(s);
                let mut sink = TileSink {
                    buf: layers,
                    layout,
                    features,
                };
                trace_eye_sample(
                    ctx,
                    brdf,
                    &mut sink,
                    &mut tracer,
                    tile.x0 + tx,
                    tile.y0 + ty,
                    s,
                );
                tree.close_leaf();
            }
            if fold {
                tree.fold();
            }
            debug_assert_eq!(tree.blocks().len(), blocks.len());
            for b in 0..blocks.len() {
                let dst = (b * tp + pixel) * record;
                buf[dst..dst + record].copy_from_slice(tree.record(b));
            }
        }
    }
    rays.fetch_add(tracer.rays, std::sync::atomic::Ordering::Relaxed);
    for (b, block) in blocks.iter().enumerate() {
        let records = &buf[b * tp * record..(b + 1) * tp * record];
        {
            let mut all = block.features.lock().unwrap_or_else(|e| e.into_inner());
            for ty in 0..tile.height as usize {
                for tx in 0..tile.width as usize {
                    let src = (ty * tile.width as usize + tx) * record + layer_count * 3;
                    let dst = ((tile.y0 as usize + ty) * width + tile.x0 as usize + tx) * fs;
                    all[dst..dst + fs].copy_from_slice(&records[src..src + fs]);
                }
            }
        }
        for (layer, slot) in block.layers.iter().enumerate() {
            let texel = |p: usize| &records[p * record + layer * 3..p * record + layer * 3 + 3];
            if (0..tp).all(|p| texel(p) == [0.0; 3]) {
                continue;
            }
            let mut image = slot.lock().unwrap_or_else(|e| e.into_inner());
            let image = match &mut *image {
                Some(image) => image,
                empty => empty.insert(crate::memory::try_zeroed(
                    width * height * 3,
                    "a layer's full-frame sums",
                )?),
            };
            for ty in 0..tile.height as usize {
                for tx in 0..tile.width as usize {
                    let dst = ((tile.y0 as usize + ty) * width + tile.x0 as usize + tx) * 3;
                    image[dst..dst + 3].copy_from_slice(texel(ty * tile.width as usize + tx));
                }
            }
        }
    }
    Ok(true)
}

/// Traces eye samples `from..to` of every pixel into `store` (see [`blocks`]); `fold` when
/// the range is a whole one-pass bake. Shared by the bake and a farm's partitions
/// ([`partition`]). Progress advances by `to − from` per tile.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_range(
    ctx: &BakeContext,
    store: &mut blocks::BlockStore,
    from: u32,
    to: u32,
    fold: bool,
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<()> {
    let res = ctx.resolution;
    let (width, height) = (res.width as usize, res.height as usize);
    let layer_count = ctx.layer_count();
    #[allow(clippy::single_range_in_vec_init)]
    let ranges = if fold {
        vec![from..to]
    } else {
        blocks::dyadic_blocks(from, to)
    };
    let pass_blocks = ranges
        .into_iter()
        .map(|r| blocks::Block::new(r, layer_count, width * height))
        .collect::<Result<Vec<_>>>()?;
    let alloc_failure: Mutex<Option<crate::RelumeError>> = Mutex::new(None);
    let brdf = BasisBrdf { ctx };
    tiles::run_tiles(
        res,
        ctx.settings.threads,
        progress,
        (to - from) as u64,
        |tile| {
            if alloc_failure.lock().map_or(true, |f| f.is_some()) {
                return false;
            }
            match trace_tile(
                ctx,
                &brdf,
                &pass_blocks,
                fold,
                tile,
                from..to,
                width,
                progress,
                rays,
            ) {
                Ok(done) => done,
                Err(e) => {
                    if let Ok(mut slot) = alloc_failure.lock() {
                        slot.get_or_insert(e);
                    }
                    false
                }
            }
        },
    )?;
    if let Some(e) = alloc_failure
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take()
    {
        return Err(e);
    }
    for b in pass_blocks {
        store.push(b);
    }
    Ok(())
}

/// Turns the store (sums over `spp` eye samples) into a stack, the report of its layers, and
/// the image at the bake-time materials (for the progressive error estimate).
#[allow(clippy::too_many_arguments)]
pub(crate) fn assemble(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    store: &[Mutex<Vec<f32>>],
    eye_features: &denoise::EyeFeatures,
    spp: u32,
    pool: &rayon::ThreadPool,
    width: usize,
    height: usize,
    progress: &Progress,
    last_pass: bool,
) -> Result<(TransferStack, BakeReport, Vec<f64>)> {
    let assembly_start = Instant::now();
    progress.set_stage(Stage::Assembly);
    let res = ctx.resolution;
    let layer_count = store.len();
    let inv_spp = 1.0 / spp as f32;
    // Whole-image layers: averaged over the eye samples, grey when the three channels are
    // bit-identical everywhere (the path met no colour), `None` when nothing reached them.
    // The last pass averages each accumulator in place (its sums are not needed again), so
    // assembly adds no second full copy of the layers to the bake's peak memory.
    enum Assembled {
        Layer(RawLayer),
        Empty(LayerKey),
        Skipped,
    }
    let assemble = |(index, slot): (usize, &Mutex<Vec<f32>>)| -> Result<Assembled> {
        if progress.is_cancelled() {
            return Ok(Assembled::Skipped);
        }
        let mut sums = slot.lock().unwrap_or_else(|e| e.into_inner());
        let key = layer_key(ctx, index);
        if sums.is_empty() || sums.iter().all(|v| *v == 0.0) {
            return Ok(Assembled::Empty(key));
        }
        let mut image: Vec<f32> = if last_pass {
            std::mem::take(&mut *sums)
        } else {
            let mut copy = crate::memory::try_with_capacity(sums.len(), "an averaged layer")?;
            copy.extend_from_slice(&sums);
            copy
        };
        drop(sums);
        for v in image.iter_mut() {
            *v *= inv_spp;
        }
        if image.chunks_exact(3).all(|c| c[0] == c[1] && c[1] == c[2]) {
            let mut y = crate::memory::try_with_capacity(image.len() / 3, "a grey layer")?;
            y.extend(image.chunks_exact(3).map(|c| c[0]));
            Ok(Assembled::Layer(RawLayer {
                key,
                channels: 1,
                data: y,
            }))
        } else {
            Ok(Assembled::Layer(RawLayer {
                key,
                channels: 3,
                data: image,
            }))
        }
    };
    let assembled: Vec<Result<Assembled>> =
        pool.install(|| store.par_iter().enumerate().map(assemble).collect());
    progress.check()?;
    let mut reached = Vec::new();
    let mut unreached = Vec::new();
    for a in assembled {
        match a? {
            Assembled::Layer(l) => reached.push(l),
            Assembled::Empty(k) => unreached.push(k),
            Assembled::Skipped => return Err(crate::RelumeError::Cancelled),
        }
    }
    let empty = unreached.len();
    let denoise_start = Instant::now();
    progress.set_stage(Stage::Denoising);
    pool.install(|| -> Result<()> {
        for (vertices, iterations) in [
            (1, settings.denoise.direct_iterations),
            (2, settings.denoise.bounce_iterations),
        ] {
            let mut chosen: Vec<&mut RawLayer> = reached
                .iter_mut()
                .filter(|l| l.key.path.len() == vertices)
                .collect();
            eye_features.filter_cancellable(&mut chosen, iterations, progress)?;
        }
        Ok(())
    })?;
    let denoise_seconds = denoise_start.elapsed().as_secs_f64();
    progress.set_stage(Stage::Finishing);
    let image = drop::bake_time_image(ctx, scene, &reached);
    progress.check()?;
    let (kept, drop_report) = drop::drop_negligible(
        ctx,
        scene,
        reached,
        &image,
        &unreached,
        settings.drop_budget as f64,
    );
    progress.check()?;
    let mut layers: Vec<Layer> = pool
        .install(|| {
            kept.into_par_iter()
                .map(|l| {
                    if progress.is_cancelled() {
                        None
                    } else {
                        Some(Layer::from_f32(
                            l.key,
                            l.channels,
                            &l.data,
                            settings.precision,
                        ))
                    }
                })
                .collect::<Option<Vec<Layer>>>()
        })
        .ok_or(crate::RelumeError::Cancelled)?;
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
        spp,
        light_samples: settings.light_samples,
        bounces: ctx.settings.bounces,
        sampling: settings.sampling.name().into(),
        seed: settings.seed,
        regions: scene
            .regions
            .iter()
            .zip(&ctx.translucent)
            .map(|(r, t)| RegionInfo {
                subsurface: t.as_ref().map(|t| t.info.clone()),
                ..RegionInfo::from_region(
                    r,
                    r.editable
                        .then(|| context::basis_config_for(&settings.basis, r.ns_range)),
                )
            })
            .collect(),
        lights: scene.lights.clone(),
        scene_hash: scene_hash(scene),
        precision: settings.precision,
        light_tint: ctx.lights.groups[0].tint.to_array(),
        light_groups: if ctx.settings.light_grouping == LightGrouping::All {
            Vec::new()
        } else {
            ctx.lights
                .groups
                .iter()
                .map(|g| LightGroupInfo {
                    name: g.name.clone(),
                    tint: g.tint.to_array(),
                })
                .collect()
        },
        denoise: settings.denoise,
    };
    let stack = TransferStack { header, layers };
    let assembly_seconds = assembly_start.elapsed().as_secs_f64();
    // Timing, ray and validation fields are filled in by the caller.
    let report = BakeReport {
        seconds: 0.0,
        rays: 0,
        setup_seconds: 0.0,
        trace_seconds: 0.0,
        assembly_seconds,
        denoise_seconds,
        rays_per_second: 0.0,
        width: res.width,
        height: res.height,
        triangles: 0,
        degenerate_triangles: 0,
        warnings: Vec::new(),
        layers_possible: layer_count,
        layers_grey: grey,
        layers_rgb: rgb,
        layers_empty: empty,
        sample_bytes: stack.sample_bytes(),
        layers: drop_report,
        estimate: None,
        bounces: ctx.settings.bounces,
        bounce_estimate: ctx.bounce_estimate.clone(),
    };
    Ok((stack, report, image))
}

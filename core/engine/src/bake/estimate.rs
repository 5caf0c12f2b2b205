//! What a bake will cost in memory, known before it traces: the number of layers its paths
//! will reach (found by a small probe trace), the bytes of its accumulators at their peak,
//! and the size of the stack it will write.
//!
//! A one-pass bake streams ([`super::stream`]): its memory is the tiled stack it builds
//! (per 16×16 tile only the layers non-zero there) plus the tile rows in flight, so the
//! forecast needs how many (tile, layer) pairs are non-zero: the probe counts them in the
//! tiles it visits, and since a few probe pixels per tile miss layers there, it also
//! counts per tile the layers its eye regions (and its neighbours') reached anywhere
//! ([`region_model_pairs`]) and keeps the larger count. Writing holds the stack, the entry
//! tables and the chunks in flight (the writer makes each chunk from the stack). A progressive bake (several passes) and a farm partition keep one
//! full-frame f32 RGB accumulator per layer any path reaches (see [`crate::bake`]), so
//! their memory is ≈ 12 bytes × reached layers × pixels. Which layers are reached depends
//! on what the camera sees: the layers *possible* (world + slots + slot
//! pairs per light group) can overstate it several times. The probe traces one eye sample
//! at a sparse grid of pixels with the bake's own integrator and counts the layers it
//! reaches (and which of them carry colour). Layers only a few pixels reach can be missed
//! by the probe; the estimate is a forecast, not a bound, and its accuracy is measured
//! (`tests/memory_estimate.rs`, docs/measurements.md).

use rayon::prelude::*;
use serde::Serialize;

use super::context::BakeContext;
use super::integrator::{trace_eye_sample, CountingTracer, PathSink};
use super::vertex_brdf::BasisBrdf;
use crate::options::Precision;
use crate::scene::{validate::ValidationReport, Scene};
use crate::Rgb;

/// Pixels the probe traces at most (on a regular grid).
pub const PROBE_PIXELS: u64 = 16_384;

/// Eye samples the probe traces per pixel: fewer missed layers that only a few strata of
/// the stratified numbers reach (on the assets scenes 8 saw every layer the bake reached,
/// 1 missed up to a fifth of them; docs/reliability.md).
const PROBE_SAMPLES: u32 = 8;

/// The probe's pixels spread their samples over this many first samples of the sequence.
const PROBE_SAMPLE_SPAN: u64 = 64;

/// A bake's forecast cost, printed before it starts (CLI `--json`, Python, the add-on).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BakeEstimate {
    pub width: u32,
    pub height: u32,
    /// Layers the slots and light groups allow.
    pub layers_possible: usize,
    /// Layers the probe's paths reached.
    pub layers_seen: usize,
    /// Layers the bake is expected to reach (its accumulators): those the probe saw. A layer
    /// that only rare paths reach can be missed (the bake then needs more than forecast);
    /// an extrapolation of unseen layers from the rarely seen ones (Chao's estimator) was
    /// tried and overshot, because layers come in correlated blocks (every basis pair of a
    /// region pair at once).
    pub layers_reached: usize,
    /// Of those, layers whose probe samples carried colour (stored RGB; the rest grey).
    pub layers_rgb: usize,
    /// Pixels the probe traced.
    pub probe_pixels: u64,
    /// Bytes of the per-layer f32 RGB accumulators (the bake's largest allocation).
    pub accumulator_bytes: u64,
    /// Bytes the prepared scene holds (geometry, BVH, textures, environment, subsurface).
    pub prepared_bytes: u64,
    /// Forecast peak of the bake's own allocations (accumulators, per-pixel features, tile
    /// buffers, geometry, assembly and write copies), in bytes.
    pub peak_bytes: u64,
    /// Forecast size of the stack in memory (layer samples at the stored precision: the
    /// tiled stack's entries for a streaming bake, full frames for the dense path); the
    /// file is smaller by its compression.
    pub stack_bytes: u64,
    /// Whether the forecast is of the streaming one-pass bake (else the dense path).
    pub streaming: bool,
    /// Forecast (tile, layer) entries of the tiled stack: the non-zero pairs the probe
    /// found per tile it visited, times the tiles.
    pub tile_entries: u64,
    /// Of those, forecast entries stored with three channels.
    pub tile_entries_rgb: u64,
    /// Bytes the same layers would take as full frames (what the dense path stores).
    pub dense_stack_bytes: u64,
    /// Each editable region's basis: its ns (and Principled roughness) range and the basis
    /// count the tolerance picked for it — the cost of a wide roughness range, shown before
    /// the bake (slots, hence layers, grow with the count).
    pub editable: Vec<RegionBasisCost>,
}

/// The basis an editable region is baked with ([`BakeEstimate::editable`]).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RegionBasisCost {
    pub region: String,
    pub ns_range: [f32; 2],
    /// `[roughness(ns_max), roughness(ns_min)]` under `ns = 2/α² − 2`, `α = r²`.
    pub roughness_range: [f32; 2],
    /// `N_b`, the diffuse basis included.
    pub bases: u32,
    /// Slots of the region (bases, plus the textured constant and subsurface slots).
    pub slots: u32,
    /// Worst relative L2 error of a lobe in the range.
    pub max_rel_l2: f64,
}

/// Records which layers a probe pixel's paths reach and whether their values carry colour.
struct ProbeSink<'a> {
    reached: &'a mut [bool],
    rgb: &'a mut [bool],
    layout: super::layout::DenseLayout,
    /// The eye regions the pixel's samples hit (the last entry: a sample that hit none).
    eye_regions: &'a mut [bool],
    /// Whether the current sample hit a region.
    hit: bool,
}

impl ProbeSink<'_> {
    fn add(&mut self, layer: usize, v: Rgb) {
        if v != Rgb::ZERO {
            self.reached[layer] = true;
            if v.x != v.y || v.y != v.z {
                self.rgb[layer] = true;
            }
        }
    }
}

impl PathSink for ProbeSink<'_> {
    fn world(&mut self, group: usize, v: Rgb) {
        self.add(self.layout.world(group), v);
    }
    fn direct(&mut self, group: usize, slot: u32, v: Rgb) {
        self.add(self.layout.direct(group, slot), v);
    }
    fn bounce(&mut self, group: usize, eye: u32, bounce: u32, v: Rgb) {
        self.add(self.layout.bounce(group, eye, bounce), v);
    }
    fn eye_hit(&mut self, region: u32, _normal: glam::Vec3, _position: glam::Vec3) {
        let last = self.eye_regions.len() - 1;
        self.eye_regions[(region as usize).min(last)] = true;
        self.hit = true;
    }
}

/// What one probe row found: per layer the probe pixels that reached it and whether it
/// carried colour, its pixel count, and per tile it crossed the layers reached there.
struct ProbeRow {
    counts: Vec<u32>,
    rgb: Vec<bool>,
    pixels: u64,
    tile_row: u32,
    tiles: std::collections::BTreeMap<u32, Vec<bool>>,
    /// Per tile it crossed, the eye regions its pixels hit.
    tile_regions: std::collections::BTreeMap<u32, Vec<bool>>,
    /// Per eye region, the layers reached by its pixels.
    region_layers: Vec<Vec<bool>>,
}

/// The inputs of [`streaming_peak`].
struct StreamingCosts {
    entries: u64,
    entries_rgb: u64,
    tiles: u64,
    threads: u64,
    geometry: u64,
    sample: u64,
    tile_buffers: u64,
}

/// The streaming bake's stack bytes and peak: the tiled stack, plus the tile rows in flight
/// (the band being traced and the denoiser's window, each tile its non-zero layers as f32,
/// one channel for a grey layer and three for a coloured one, and its pixels' features),
/// the row being stored, the per-thread tile buffers and denoiser windows, and the
/// geometry; writing holds the stack and the file's encoded copy.
fn streaming_peak(ctx: &BakeContext, c: &StreamingCosts) -> (u64, u64) {
    let res = ctx.resolution;
    let tile_px = (super::tiles::TILE * super::tiles::TILE) as u64;
    let grey = c.entries - c.entries_rgb.min(c.entries);
    let stack = tile_px * (grey + 3 * c.entries_rgb) * c.sample;
    let tiles_x = super::super::stack::tiled::tiles_along(res.width) as u64;
    let tiles_y = super::super::stack::tiled::tiles_along(res.height).max(1) as u64;
    let apron = super::band::apron_rows(&ctx.settings.denoise) as u64;
    let band = super::band::default_band_rows(res.width, c.threads as usize, apron as usize) as u64;
    let rows_held = (band + 2 * apron + 1).min(tiles_y);
    // f32 values per tile: a pixel's grey entry holds one, a coloured one three.
    let values_per_tile = (grey + 3 * c.entries_rgb).div_ceil(c.tiles.max(1)) * tile_px;
    let per_tile_traced = values_per_tile * 4 + tile_px * super::denoise::FEATURE_STRIDE as u64 * 4;
    let traced = rows_held * tiles_x * per_tile_traced;
    let window_px = res.width as u64 * ((2 * apron + band) * super::tiles::TILE as u64);
    let window = if apron > 0 {
        // Each worker's two scratch windows, the weights of every filter step, the
        // window's features (and their records while built).
        let steps = (ctx.settings.denoise.direct_iterations
            + ctx.settings.denoise.bounce_iterations) as u64;
        c.threads * window_px * 2 * 12 + window_px * (steps * 25 * 4 + 36 + 36)
    } else {
        0
    };
    // The rows being stored: their layers in f32 on their way to the builder.
    let row_out = band * tiles_x * values_per_tile * 4;
    let tracing = stack + traced + c.tile_buffers + window + row_out;
    // Writing: the stack, the entry tables as the file's columns (four u32 per entry) and
    // the chunks in flight (the writer makes each from the stack when it is compressed).
    let write = stack + 16 * c.entries + WRITE_CHUNK_ALLOWANCE * (c.threads + 2);
    // The bake's workers and the writer's compressor threads (one per core, whatever the
    // bake's thread count) each hold a stack and allocator state.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    let thread_overhead = THREAD_ALLOWANCE * (c.threads + cores);
    (stack, c.geometry + thread_overhead + tracing.max(write))
}

/// The (tile, layer) pairs of the visited tiles by the region model, and how many of them
/// carry colour: a tile holds every layer reached from each eye region seen in it or in
/// the tiles around it. At a few probe pixels per tile (1920×1080: about two) the probe's
/// own pairs miss the layers and regions its pixels did not land on; a pixel only holds
/// layers whose eye vertex is its own region, and those are what the probe found for the
/// region anywhere in the frame. An over-estimate by construction (a layer reached
/// somewhere on a region need not reach all of it, the neighbouring tiles' regions count
/// for the tile whose edge they cross, and a layer reached from two regions seen in a
/// tile counts twice), so the forecast errs towards refusing.
fn region_model_pairs(
    tile_regions: &std::collections::BTreeMap<(u32, u32), Vec<bool>>,
    region_layers: &[Vec<bool>],
    rgb: &[bool],
) -> (u64, u64) {
    let per_region: Vec<(u64, u64)> = region_layers
        .iter()
        .map(|set| {
            set.iter()
                .zip(rgb)
                .filter(|(r, _)| **r)
                .fold((0, 0), |(n, c), (_, rgb)| (n + 1, c + u64::from(*rgb)))
        })
        .collect();
    let (mut pairs, mut pairs_rgb) = (0u64, 0u64);
    let mut seen = vec![false; region_layers.len()];
    for &(ty, tx) in tile_regions.keys() {
        seen.fill(false);
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (y, x) = (ty as i64 + dy, tx as i64 + dx);
                if y < 0 || x < 0 {
                    continue;
                }
                if let Some(set) = tile_regions.get(&(y as u32, x as u32)) {
                    for (a, b) in seen.iter_mut().zip(set) {
                        *a |= *b;
                    }
                }
            }
        }
        for (region, (n, c)) in per_region.iter().enumerate() {
            if seen[region] {
                pairs += n;
                pairs_rgb += c;
            }
        }
    }
    (pairs, pairs_rgb)
}

/// Resident bytes allowed per thread for its stack and allocator state: an approximation
/// (a thread's default stack size), set when the forecast without it fell a few per cent
/// short of the measured peak of a small bake on many threads (docs/scale.md).
const THREAD_ALLOWANCE: u64 = 2 << 20;

/// Bytes one chunk in flight takes while written: a 16-line block of the widest part
/// (4 096 pixels × 4 channels × 4 bytes) uncompressed, in the compressor's working copies
/// and compressed.
const WRITE_CHUNK_ALLOWANCE: u64 = 4 * 16 * 4096 * 16;

/// Bytes the scene's geometry and BVH take once prepared (positions, normals, UVs,
/// triangles and the BVH's nodes): a per-triangle allowance.
const BYTES_PER_TRIANGLE: u64 = 160;

/// Traces the probe over `ctx` and forecasts the bake's memory for `passes` progressive
/// passes: one pass streams, several keep dense sums while they hand each pass's stack
/// out. `prepared_bytes`: what preparing `ctx` took (geometry, BVH, textures,
/// environment, subsurface samples), measured by the caller where the OS tells
/// ([`prepare_measured`]); `None` falls back to a per-triangle allowance.
pub fn estimate(
    ctx: &BakeContext,
    scene: &Scene,
    passes: usize,
    prepared_bytes: Option<u64>,
) -> BakeEstimate {
    estimate_path(ctx, scene, passes, passes <= 1, prepared_bytes)
}

/// [`estimate`] of the dense path whatever the passes (a farm partition: full-frame sums).
pub fn estimate_dense(
    ctx: &BakeContext,
    scene: &Scene,
    passes: usize,
    prepared_bytes: Option<u64>,
) -> BakeEstimate {
    estimate_path(ctx, scene, passes, false, prepared_bytes)
}

fn estimate_path(
    ctx: &BakeContext,
    scene: &Scene,
    passes: usize,
    streaming: bool,
    prepared_bytes: Option<u64>,
) -> BakeEstimate {
    let res = ctx.resolution;
    let pixels = res.width as u64 * res.height as u64;
    let layers = ctx.layer_count();
    let mut counts = vec![0u32; layers];
    let mut rgb = vec![false; layers];
    let stride = ((pixels as f64 / PROBE_PIXELS as f64).sqrt().ceil() as u32).max(1);
    let brdf = BasisBrdf { ctx };
    // Offset by half a stride so the grid samples the frame's inside, not its edge.
    let rows: Vec<u32> = (stride / 2..res.height).step_by(stride as usize).collect();
    let tile = super::tiles::TILE;
    // Eye regions, and one more for samples that hit none (the world).
    let regions = ctx.regions.len() + 1;
    let per_row: Vec<ProbeRow> = rows
        .par_iter()
        .map(|&y| {
            let mut counts = vec![0u32; layers];
            let mut reached = vec![false; layers];
            let mut rgb = vec![false; layers];
            let mut tiles: std::collections::BTreeMap<u32, Vec<bool>> = Default::default();
            let mut tile_regions: std::collections::BTreeMap<u32, Vec<bool>> = Default::default();
            let mut region_layers = vec![vec![false; layers]; regions];
            let mut eye_regions = vec![false; regions];
            let mut tracer = CountingTracer::default();
            let mut n = 0;
            for x in (stride / 2..res.width).step_by(stride as usize) {
                reached.fill(false);
                eye_regions.fill(false);
                let mut sink = ProbeSink {
                    reached: &mut reached,
                    rgb: &mut rgb,
                    layout: super::layout::DenseLayout::of(ctx),
                    eye_regions: &mut eye_regions,
                    hit: false,
                };
                // Pixels take turns through the first samples of the sequence: a layer that
                // only some strata of the stratified numbers reach is still seen.
                let cell = (x / stride) as u64 + 7919 * (y / stride) as u64;
                for k in 0..PROBE_SAMPLES {
                    let sample =
                        ((cell * PROBE_SAMPLES as u64 + k as u64) % PROBE_SAMPLE_SPAN) as u32;
                    sink.hit = false;
                    trace_eye_sample(ctx, &brdf, &mut sink, &mut tracer, x, y, sample);
                    if !sink.hit {
                        sink.eye_regions[regions - 1] = true;
                    }
                }
                for (c, r) in counts.iter_mut().zip(&reached) {
                    *c += u32::from(*r);
                }
                let in_tile = tiles.entry(x / tile).or_insert_with(|| vec![false; layers]);
                for (t, r) in in_tile.iter_mut().zip(&reached) {
                    *t |= *r;
                }
                let seen = tile_regions
                    .entry(x / tile)
                    .or_insert_with(|| vec![false; regions]);
                for (region, hit) in eye_regions.iter().enumerate() {
                    if *hit {
                        seen[region] = true;
                        for (a, r) in region_layers[region].iter_mut().zip(&reached) {
                            *a |= *r;
                        }
                    }
                }
                n += 1;
            }
            ProbeRow {
                counts,
                rgb,
                pixels: n,
                tile_row: y / tile,
                tiles,
                tile_regions,
                region_layers,
            }
        })
        .collect();
    let mut probe_pixels = 0u64;
    // The (tile, layer) pairs reached in each tile the probe visited.
    let mut tile_sets: std::collections::BTreeMap<(u32, u32), Vec<bool>> = Default::default();
    let mut tile_regions: std::collections::BTreeMap<(u32, u32), Vec<bool>> = Default::default();
    let mut region_layers = vec![vec![false; layers]; regions];
    for row in per_row {
        for (tx, seen) in row.tile_regions {
            let all = tile_regions
                .entry((row.tile_row, tx))
                .or_insert_with(|| vec![false; regions]);
            for (a, b) in all.iter_mut().zip(seen) {
                *a |= b;
            }
        }
        for (all, got) in region_layers.iter_mut().zip(row.region_layers) {
            for (a, b) in all.iter_mut().zip(got) {
                *a |= b;
            }
        }
        probe_pixels += row.pixels;
        for (a, b) in counts.iter_mut().zip(row.counts) {
            *a += b;
        }
        for (a, b) in rgb.iter_mut().zip(row.rgb) {
            *a |= b;
        }
        for (tx, set) in row.tiles {
            let all = tile_sets
                .entry((row.tile_row, tx))
                .or_insert_with(|| vec![false; layers]);
            for (a, b) in all.iter_mut().zip(set) {
                *a |= b;
            }
        }
    }
    let (mut pairs, mut pairs_rgb) = (0u64, 0u64);
    for set in tile_sets.values() {
        for (l, r) in set.iter().enumerate() {
            if *r {
                pairs += 1;
                pairs_rgb += u64::from(rgb[l]);
            }
        }
    }
    let (region_pairs, region_pairs_rgb) = region_model_pairs(&tile_regions, &region_layers, &rgb);
    let (pairs, pairs_rgb) = (pairs.max(region_pairs), pairs_rgb.max(region_pairs_rgb));
    let all_tiles = super::tiles::tiles(res).len() as u64;
    let visited = tile_sets.len().max(1) as u64;
    let tile_entries = (pairs * all_tiles).div_ceil(visited);
    let tile_entries_rgb = (pairs_rgb * all_tiles).div_ceil(visited);
    let layers_seen = counts.iter().filter(|c| **c > 0).count().max(1);
    let layers_reached = layers_seen;
    // Layers the probe did not see take the seen layers' share of colour.
    let rgb_seen = rgb.iter().filter(|r| **r).count();
    let layers_rgb =
        ((rgb_seen as f64 / layers_seen as f64) * layers_reached as f64).round() as usize;
    let layers_grey = layers_reached - layers_rgb.min(layers_reached);
    let threads = if ctx.settings.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        ctx.settings.threads
    } as u64;

    let px = pixels;
    let reached_u = layers_reached as u64;
    let accumulator_bytes = px.saturating_mul(reached_u).saturating_mul(12);
    let features = px * super::denoise::FEATURE_STRIDE as u64 * 4;
    let tile_px = (super::tiles::TILE * super::tiles::TILE) as u64;
    let tile_buffers = threads * layers as u64 * tile_px * 12;
    let geometry =
        (scene.triangle_count() as u64 * BYTES_PER_TRIANGLE).max(prepared_bytes.unwrap_or(0));
    // Averaged layers: grey ones one channel, the rest three, f32.
    let raw = px * (layers_grey as u64 * 4 + layers_rgb as u64 * 12);
    let sample = match ctx.settings.precision {
        Precision::F16 => 2,
        Precision::F32 => 4,
    };
    let dense_stack_bytes = px * (layers_grey as u64 + 3 * layers_rgb as u64) * sample;
    let stack_bytes = dense_stack_bytes;
    let denoising =
        ctx.settings.denoise.direct_iterations + ctx.settings.denoise.bounce_iterations > 0;
    // The denoiser's 25 weights per pixel and one output copy per worker.
    let denoise = if denoising {
        px * 25 * 4 + threads * px * 12
    } else {
        0
    };
    // Tracing: accumulators, features, tile buffers.
    let tracing = accumulator_bytes + features + tile_buffers;
    // Assembly and finishing: the last pass averages each accumulator in place (a
    // progressive bake's earlier passes copy them), then the stored-precision layers are made
    // while the averaged ones still hold their memory: the allocator keeps layer-sized blocks
    // it has freed for reuse rather than giving them back, so the resident peak is close to
    // their sum.
    let averaged = if passes > 1 {
        accumulator_bytes + raw
    } else {
        accumulator_bytes.max(raw + stack_bytes)
    };
    let assembly = averaged + features + denoise;
    // Writing: the stack and the file's de-interleaved channels (reusing freed blocks when
    // the averaged layers were larger).
    let write = stack_bytes * 2 + if passes > 1 { accumulator_bytes } else { 0 };
    let peak_bytes = geometry + tracing.max(assembly).max(write);
    let (stack_bytes, peak_bytes) = if streaming {
        streaming_peak(
            ctx,
            &StreamingCosts {
                entries: tile_entries,
                entries_rgb: tile_entries_rgb,
                tiles: all_tiles,
                threads,
                geometry,
                sample,
                tile_buffers,
            },
        )
    } else {
        (stack_bytes, peak_bytes)
    };
    BakeEstimate {
        width: res.width,
        height: res.height,
        layers_possible: layers,
        layers_seen,
        layers_reached,
        layers_rgb,
        probe_pixels,
        accumulator_bytes,
        prepared_bytes: geometry,
        peak_bytes,
        stack_bytes,
        streaming,
        tile_entries,
        tile_entries_rgb,
        dense_stack_bytes,
        editable: ctx
            .regions
            .iter()
            .filter_map(|r| match &r.model {
                super::context::RegionModel::Editable {
                    basis: crate::brdf::RegionBasis::BlinnPhong(basis),
                    ..
                } => {
                    let cfg = basis.config();
                    let rep = basis.error_report();
                    Some(RegionBasisCost {
                        region: r.name.clone(),
                        ns_range: [cfg.ns_min, cfg.ns_max],
                        roughness_range: [
                            crate::stack::bases::ns_to_roughness(cfg.ns_max),
                            crate::stack::bases::ns_to_roughness(cfg.ns_min),
                        ],
                        bases: basis.count() as u32,
                        slots: r.slot_count,
                        max_rel_l2: rep.max_rel_l2,
                    })
                }
                super::context::RegionModel::Editable {
                    basis: crate::brdf::RegionBasis::Principled(basis),
                    ..
                } => {
                    let r_min = basis.config().roughness_min;
                    let (lo, hi) = basis.config().fitted_ns_range();
                    Some(RegionBasisCost {
                        region: r.name.clone(),
                        ns_range: [lo, hi],
                        roughness_range: [r_min as f32, 1.0],
                        bases: basis.count() as u32,
                        slots: r.slot_count,
                        max_rel_l2: basis.report().lobe_worst,
                    })
                }
                _ => None,
            })
            .collect(),
    }
}

/// The forecast of a bake of `scene` with `settings` in `passes` passes, without baking:
/// validation, bases, BVH, subsurface samples and the probe (a second or so), for a
/// front end to show before the user commits to a bake. The budget is not applied here;
/// compare `peak_bytes` with [`crate::memory::budget_bytes`].
pub fn estimate_bake(
    scene: &Scene,
    settings: &crate::bake::BakeSettings,
    passes: usize,
    progress: &crate::progress::Progress,
) -> crate::Result<BakeEstimate> {
    settings.validate()?;
    let (ctx, _, prepared) = prepare_measured(scene, settings, progress)?;
    Ok(estimate(&ctx, scene, passes.max(1), prepared))
}

/// [`BakeContext::prepare`], and the growth of this process's resident memory while it ran
/// (`None` where the OS does not tell, or when other threads freed more than it took).
pub fn prepare_measured(
    scene: &Scene,
    settings: &crate::bake::BakeSettings,
    progress: &crate::progress::Progress,
) -> crate::Result<(BakeContext, ValidationReport, Option<u64>)> {
    let before = crate::memory::current_rss_bytes();
    let (ctx, report) = BakeContext::prepare(scene, settings, progress)?;
    let after = crate::memory::current_rss_bytes();
    let grown = match (before, after) {
        (Some(b), Some(a)) if a > b => Some(a - b),
        _ => None,
    };
    Ok((ctx, report, grown))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three tiles in a row: region 0 seen in the first two, region 1 in the last two.
    /// Region 0's pixels reached layers 0 and 1 (1 in colour), region 1's layer 2. Every
    /// tile then counts both regions (its own and its neighbours'), and the count is at
    /// least what the probe's own per-tile sets hold.
    #[test]
    fn the_region_model_counts_each_seen_region_s_layers_around_every_tile() {
        let mut tiles = std::collections::BTreeMap::new();
        tiles.insert((0, 0), vec![true, false]);
        tiles.insert((0, 1), vec![true, true]);
        tiles.insert((0, 2), vec![false, true]);
        let region_layers = vec![vec![true, true, false], vec![false, false, true]];
        let rgb = [false, true, false];
        let (pairs, pairs_rgb) = region_model_pairs(&tiles, &region_layers, &rgb);
        let per_tile = region_layers
            .iter()
            .map(|set| set.iter().filter(|r| **r).count() as u64)
            .sum::<u64>();
        assert_eq!(pairs, 3 * per_tile);
        assert_eq!(pairs_rgb, 3);
        // The probe's own sets: each tile holds only its own regions' layers.
        let own: u64 = tiles
            .values()
            .map(|seen| {
                seen.iter()
                    .zip(&region_layers)
                    .filter(|(s, _)| **s)
                    .map(|(_, set)| set.iter().filter(|r| **r).count() as u64)
                    .sum::<u64>()
            })
            .sum();
        assert!(pairs >= own);
    }
}

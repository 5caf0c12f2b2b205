//! What a bake will cost in memory, known before it traces: the number of layers its paths
//! will reach (found by a small probe trace), the bytes it holds at its peak, and the size
//! of the stack it will write.
//!
//! Every bake finishes by streaming ([`crate::bake::schedule::stream`]): its memory is the
//! tiled stack it builds (per 16×16 tile only the layers non-zero there) plus the tile rows
//! in flight, so the forecast needs how many (tile, layer) pairs are non-zero: the probe
//! counts them in the tiles it visits, and since a few probe pixels per tile miss layers
//! there, it also counts per tile the layers its eye regions (and its neighbours') reached
//! anywhere ([`region_model_pairs`]) and keeps the larger count. Writing holds the stack,
//! the entry tables and the chunks in flight (the writer makes each chunk from the stack).
//! A progressive bake (several passes) also keeps, between its passes, each tile's sample
//! sums for the same (tile, layer) pairs ([`kept_sums`]). Which layers are reached depends
//! on what the camera sees: the layers *possible* (world + slots + slot
//! pairs per light group) can overstate it several times. The probe traces one eye sample
//! at a sparse grid of pixels with the bake's own integrator and counts the layers it
//! reaches (and which of them carry colour). Layers only a few pixels reach can be missed
//! by the probe; the estimate is a forecast, not a bound, and its accuracy is measured
//! (`tests/memory_estimate.rs`, docs/measurements.md).
//!
//! The probe is bounded whatever the scene and settings: it traces with at most
//! [`PROBE_MAX_LIGHT_SAMPLES`] light samples and [`PROBE_MAX_INDIRECT_SAMPLES`] indirect
//! directions per vertex, measures what an eye sample costs in rays and thins its grid so
//! that it traces about [`PROBE_RAYS`] rays (a scene of many lights is probed at fewer
//! pixels), checks the cancel before every eye sample, and keeps only the layers its paths
//! reach (never a flag per possible layer: 300 editable regions make 3.3 million). The
//! forecast is then arithmetic on what it found (`tests/engine/forecast_bounds.rs`).

use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;
use serde::Serialize;

use super::context::BakeContext;
use crate::bake::path::integrator::{trace_eye_sample, CountingTracer, PathSink};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::options::Precision;
use crate::progress::Progress;
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

/// Rays the probe plans to trace at most (about a second on the project's 2-core machine
/// for a small scene; the assets scenes' full 16 384-pixel grid stays within it). A scene
/// whose eye samples cost more rays (many lights, many bounces) is probed at fewer pixels,
/// so the forecast's time does not grow with the light count or the sample counts; its
/// layer counts then come from a sparser grid.
const PROBE_RAYS: u64 = 1 << 22;

/// Fewest pixels the probe plans to trace, however costly a sample (it stops at 1.5 ×
/// [`PROBE_RAYS`] all the same).
const PROBE_MIN_PIXELS: u64 = 64;

/// Pixels the pilot traces (one sample each) to measure the rays an eye sample costs.
const PROBE_PILOT_PIXELS: u64 = 64;

/// Light samples and indirect directions the probe traces per path vertex at most: which
/// layers a path reaches does not depend on how many samples share a vertex, and the
/// presets use at most 4 (a larger count, up to [`crate::bake::settings`]' limits, would
/// only make the probe slower).
const PROBE_MAX_LIGHT_SAMPLES: u32 = 4;
const PROBE_MAX_INDIRECT_SAMPLES: u32 = 4;

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
    /// Bytes a progressive bake keeps between its passes: per tile, per block of the
    /// canonical summation tree, the f32 RGB sums of the layers reached there and the
    /// pixels' features, plus the bake-time images its error estimate compares (0 for a
    /// one-pass bake).
    pub kept_sums_bytes: u64,
    /// Bytes the prepared scene holds (geometry, BVH, textures, environment, subsurface).
    pub prepared_bytes: u64,
    /// Forecast peak of the bake's own allocations (the stack, the tile rows in flight and
    /// the denoiser's windows, tile buffers, a progressive bake's kept sums, geometry and
    /// its BVH build, the write's copies) plus the scene it reads ([`scene_bytes`]), in
    /// bytes.
    pub peak_bytes: u64,
    /// Forecast size of the stack in memory (the tiled stack's entries at the stored
    /// precision); the file is smaller by its compression.
    pub stack_bytes: u64,
    /// Forecast (tile, layer) entries of the tiled stack: the non-zero pairs the probe
    /// found per tile it visited, times the tiles.
    pub tile_entries: u64,
    /// Of those, forecast entries stored with three channels.
    pub tile_entries_rgb: u64,
    /// Bytes the same layers would take as full frames (for comparison: no bake holds them).
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

/// Records which layers a probe pixel's paths reach and whether their values carry colour,
/// sparsely (a layer index per contribution): a scene of many editable regions has millions
/// of possible layers, of which one pixel reaches a few hundred at most, so nothing here is
/// proportional to the layers possible.
struct ProbeSink<'a> {
    /// Layers reached by the pixel's samples (with repeats; sorted and deduplicated after).
    reached: &'a mut Vec<u32>,
    rgb: &'a mut HashSet<u32>,
    layout: crate::bake::layout::DenseLayout,
    /// The eye regions the pixel's samples hit (the last entry: a sample that hit none).
    eye_regions: &'a mut Vec<u32>,
    /// Whether the current sample hit a region.
    hit: bool,
    /// The region index that stands for "no region" (the world).
    no_region: u32,
}

impl ProbeSink<'_> {
    fn add(&mut self, layer: usize, v: Rgb) {
        if v != Rgb::ZERO {
            self.reached.push(layer as u32);
            if v.x != v.y || v.y != v.z {
                self.rgb.insert(layer as u32);
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
        self.eye_regions.push(region.min(self.no_region));
        self.hit = true;
    }
    fn tail_edits(&self) -> bool {
        true
    }
    fn tail_edit(&mut self, group: usize, eye: usize, region: usize, bin: usize, v: Rgb) {
        self.add(self.layout.tail_edit(group, eye, region, bin), v);
    }
}

/// A set of layer (or region) indices, sorted, without repeats.
type IndexSet = Vec<u32>;

/// `a ∪ b` into `a` (both sorted, without repeats).
fn union_into(a: &mut IndexSet, b: &[u32]) {
    if b.is_empty() {
        return;
    }
    a.extend_from_slice(b);
    a.sort_unstable();
    a.dedup();
}

/// What one probe row found: the layers its pixels reached and those that carried colour,
/// its pixel count, and per tile it crossed the layers reached there.
struct ProbeRow {
    reached: HashSet<u32>,
    rgb: HashSet<u32>,
    pixels: u64,
    tile_row: u32,
    tiles: BTreeMap<u32, IndexSet>,
    /// Per tile it crossed, the eye regions its pixels hit.
    tile_regions: BTreeMap<u32, IndexSet>,
    /// Per eye region its pixels hit, the layers they reached.
    region_layers: HashMap<u32, HashSet<u32>>,
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
    let tile_px = (crate::bake::schedule::tiles::TILE * crate::bake::schedule::tiles::TILE) as u64;
    let grey = c.entries - c.entries_rgb.min(c.entries);
    let stack = tile_px * (grey + 3 * c.entries_rgb) * c.sample;
    let tiles_x = crate::stack::tiled::tiles_along(res.width) as u64;
    let tiles_y = crate::stack::tiled::tiles_along(res.height).max(1) as u64;
    let apron = crate::bake::schedule::band::apron_rows(&ctx.settings.denoise) as u64;
    let band = crate::bake::schedule::band::default_band_rows(
        res.width,
        c.threads as usize,
        apron as usize,
    ) as u64;
    let rows_held = (band + 2 * apron + 1).min(tiles_y);
    // f32 values per tile: a pixel's grey entry holds one, a coloured one three.
    let values_per_tile = (grey + 3 * c.entries_rgb).div_ceil(c.tiles.max(1)) * tile_px;
    let per_tile_traced =
        values_per_tile * 4 + tile_px * crate::bake::finish::denoise::FEATURE_STRIDE as u64 * 4;
    let traced = rows_held * tiles_x * per_tile_traced;
    let window_px =
        res.width as u64 * ((2 * apron + band) * crate::bake::schedule::tiles::TILE as u64);
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

/// What a progressive bake keeps between its passes ([`kept_sums`]).
struct KeptSums {
    bytes: u64,
    /// The most blocks of the summation tree one pass traces per pixel (at least 1).
    blocks_traced: u64,
}

/// A progressive bake of `passes` doubling passes ([`crate::bake::schedule::doubling`]) keeps,
/// after each pass, popcount(samples so far) blocks per tile, each holding the f32 RGB sums
/// of the layers reached on the tile (forecast as the stack's `entries`, all three
/// channels: the sums are not split into grey and coloured) and the pixels' features; its
/// error estimate holds two bake-time images (f64 RGB). A one-pass bake keeps none.
fn kept_sums(ctx: &BakeContext, passes: usize, entries: u64, tiles: u64, pixels: u64) -> KeptSums {
    if passes <= 1 {
        return KeptSums {
            bytes: 0,
            blocks_traced: 1,
        };
    }
    let counts = crate::bake::schedule::doubling::doubling_passes(ctx.settings.spp, passes as u32);
    let kept_blocks = counts.iter().map(|c| c.count_ones()).max().unwrap_or(1) as u64;
    let blocks_traced = std::iter::once(0)
        .chain(counts.iter().copied())
        .zip(counts.iter().copied())
        .map(|(from, to)| crate::bake::schedule::blocks::dyadic_blocks(from, to).len())
        .max()
        .unwrap_or(1)
        .max(1) as u64;
    let tile_px = (crate::bake::schedule::tiles::TILE * crate::bake::schedule::tiles::TILE) as u64;
    let features = crate::bake::finish::denoise::FEATURE_STRIDE as u64 * 4;
    let per_block = entries
        .saturating_mul(tile_px * 12)
        .saturating_add(tiles.saturating_mul(tile_px * features));
    KeptSums {
        bytes: per_block
            .saturating_mul(kept_blocks)
            .saturating_add(pixels * 3 * 8 * 2),
        blocks_traced,
    }
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
    tile_regions: &BTreeMap<(u32, u32), IndexSet>,
    region_layers: &HashMap<u32, HashSet<u32>>,
    rgb: &HashSet<u32>,
) -> (u64, u64) {
    let per_region: HashMap<u32, (u64, u64)> = region_layers
        .iter()
        .map(|(region, set)| {
            let coloured = set.iter().filter(|l| rgb.contains(l)).count() as u64;
            (*region, (set.len() as u64, coloured))
        })
        .collect();
    let (mut pairs, mut pairs_rgb) = (0u64, 0u64);
    let mut seen: IndexSet = Vec::new();
    for &(ty, tx) in tile_regions.keys() {
        seen.clear();
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (y, x) = (ty as i64 + dy, tx as i64 + dx);
                if y < 0 || x < 0 {
                    continue;
                }
                if let Some(set) = tile_regions.get(&(y as u32, x as u32)) {
                    seen.extend_from_slice(set);
                }
            }
        }
        seen.sort_unstable();
        seen.dedup();
        for region in &seen {
            if let Some((n, c)) = per_region.get(region) {
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
pub(crate) const BYTES_PER_TRIANGLE: u64 = 160;

/// Bytes a BVH build holds per triangle beyond the prepared geometry, at its peak: the
/// unordered triangles and shading records next to their BVH-ordered copies, and the
/// builder's bounding boxes, Morton codes and binary tree (obvhs' PLOC). Set from the
/// measured peak of building grids of 0.3–2.9 M triangles (`tests/engine/forecast_bounds.rs`); a
/// 2.9 M-triangle scene was forecast at 464 MiB without it and peaked at 1.5 GiB.
pub(crate) const BVH_BUILD_BYTES_PER_TRIANGLE: u64 = 256;

/// Bytes `scene` holds in memory (its meshes' arrays and inline images): resident for the
/// whole bake, so part of its peak, and counted from the lengths without copying anything.
pub fn scene_bytes(scene: &Scene) -> u64 {
    let image = |img: &crate::scene::ImageRef| match img {
        crate::scene::ImageRef::Inline { rgb, .. } => rgb.len() as u64 * 4,
        _ => 0,
    };
    let meshes: u64 = scene
        .meshes
        .iter()
        .map(|m| {
            m.positions.len() as u64 * 12
                + m.normals.as_ref().map_or(0, |n| n.len() as u64 * 12)
                + m.uvs.as_ref().map_or(0, |u| u.len() as u64 * 8)
                + m.indices.len() as u64 * 12
                + m.triangle_regions
                    .as_ref()
                    .map_or(0, |r| r.len() as u64 * 4)
        })
        .sum();
    let textures: u64 = scene
        .regions
        .iter()
        .filter_map(|r| r.albedo_texture.as_ref())
        .map(image)
        .sum();
    let world = match &scene.world {
        crate::scene::World::Equirect { image: img, .. } => image(img),
        _ => 0,
    };
    meshes + textures + world
}

/// Traces the probe over `ctx` and forecasts the bake's memory for `passes` progressive
/// passes: every pass finishes by streaming, and several keep per-tile sparse sums between
/// them ([`kept_sums`]). `prepared_bytes`: what preparing `ctx` took (geometry, BVH, textures,
/// environment, subsurface samples), measured by the caller where the OS tells
/// ([`prepare_measured`]); `None` falls back to a per-triangle allowance. `ctx` is borrowed
/// mutably only while the probe traces with its capped sample counts, and is left as it
/// was. Stops with [`crate::RelumeError::Cancelled`] within an eye sample of a cancel.
pub fn estimate(
    ctx: &mut BakeContext,
    scene: &Scene,
    passes: usize,
    prepared_bytes: Option<u64>,
    progress: &Progress,
) -> crate::Result<BakeEstimate> {
    // The probe traces with its per-vertex sample counts capped (the layers a path reaches
    // do not depend on how many samples share a vertex), then the settings are restored.
    let settings = ctx.settings.clone();
    ctx.settings.light_samples = settings.light_samples.min(PROBE_MAX_LIGHT_SAMPLES);
    ctx.settings.bounce_light_samples = settings
        .bounce_light_samples
        .map(|n| n.min(PROBE_MAX_LIGHT_SAMPLES));
    ctx.settings.indirect_samples = settings.indirect_samples.min(PROBE_MAX_INDIRECT_SAMPLES);
    let probe = probe(ctx, progress);
    ctx.settings = settings;
    forecast(ctx, scene, passes, prepared_bytes, probe?)
}

/// What the probe found, merged over its rows.
struct ProbeFindings {
    probe_pixels: u64,
    /// Layers any probe path reached.
    reached: HashSet<u32>,
    /// Of those, the layers whose samples carried colour.
    rgb: HashSet<u32>,
    /// The (tile, layer) pairs reached in each tile the probe visited.
    tile_sets: BTreeMap<(u32, u32), IndexSet>,
    /// Per visited tile, the eye regions its probe pixels hit.
    tile_regions: BTreeMap<(u32, u32), IndexSet>,
    /// Per eye region, the layers its probe pixels reached.
    region_layers: HashMap<u32, HashSet<u32>>,
}

/// The probe pixels' grid stride for a frame of `pixels` when one eye sample costs
/// `rays_per_sample` rays: the densest grid of at most [`PROBE_PIXELS`] pixels whose
/// [`PROBE_SAMPLES`] samples each fit in [`PROBE_RAYS`] (at least [`PROBE_MIN_PIXELS`]).
fn probe_stride(pixels: u64, rays_per_sample: f64) -> u32 {
    let per_pixel = rays_per_sample.max(1.0) * PROBE_SAMPLES as f64;
    let affordable =
        (PROBE_RAYS as f64 / per_pixel).clamp(PROBE_MIN_PIXELS as f64, PROBE_PIXELS as f64);
    ((pixels as f64 / affordable).sqrt().ceil() as u32).max(1)
}

/// Traces the probe: a pilot of one eye sample at a few pixels measures what one sample
/// costs, then [`PROBE_SAMPLES`] samples at each pixel of the grid [`probe_stride`] picks.
/// The probe stops tracing once it has spent 1.5 × [`PROBE_RAYS`] (the pilot's measure
/// was too low), and checks `progress`'s cancel before every eye sample.
fn probe(ctx: &BakeContext, progress: &Progress) -> crate::Result<ProbeFindings> {
    let res = ctx.resolution;
    let pixels = res.width as u64 * res.height as u64;
    let brdf = BasisBrdf { ctx };
    let layout = crate::bake::layout::DenseLayout::of(ctx);
    let no_region = ctx.regions.len() as u32;
    let spent = AtomicU64::new(0);
    let rays_per_sample = {
        let pilot_stride =
            ((pixels as f64 / PROBE_PILOT_PIXELS as f64).sqrt().ceil() as u32).max(1);
        let mut tracer = CountingTracer::default();
        let (mut reached, mut rgb, mut regions) = (Vec::new(), HashSet::new(), Vec::new());
        let mut samples = 0u64;
        'pilot: for y in (pilot_stride / 2..res.height).step_by(pilot_stride as usize) {
            for x in (pilot_stride / 2..res.width).step_by(pilot_stride as usize) {
                progress.check()?;
                if tracer.rays > PROBE_RAYS / 8 {
                    break 'pilot;
                }
                let mut sink = ProbeSink {
                    reached: &mut reached,
                    rgb: &mut rgb,
                    layout,
                    eye_regions: &mut regions,
                    hit: false,
                    no_region,
                };
                trace_eye_sample(ctx, &brdf, &mut sink, &mut tracer, x, y, 0);
                reached.clear();
                regions.clear();
                samples += 1;
            }
        }
        spent.fetch_add(tracer.rays, Ordering::Relaxed);
        tracer.rays as f64 / samples.max(1) as f64
    };
    let stride = probe_stride(pixels, rays_per_sample);
    // Offset by half a stride so the grid samples the frame's inside, not its edge.
    let rows: Vec<u32> = (stride / 2..res.height).step_by(stride as usize).collect();
    let tile = crate::bake::schedule::tiles::TILE;
    let per_row: Vec<crate::Result<ProbeRow>> = rows
        .par_iter()
        .map(|&y| {
            let mut row = ProbeRow {
                reached: HashSet::new(),
                rgb: HashSet::new(),
                pixels: 0,
                tile_row: y / tile,
                tiles: BTreeMap::new(),
                tile_regions: BTreeMap::new(),
                region_layers: HashMap::new(),
            };
            let (mut reached, mut eye_regions) = (Vec::new(), Vec::new());
            for x in (stride / 2..res.width).step_by(stride as usize) {
                if spent.load(Ordering::Relaxed) > PROBE_RAYS + PROBE_RAYS / 2 {
                    break;
                }
                reached.clear();
                eye_regions.clear();
                let mut tracer = CountingTracer::default();
                let mut sink = ProbeSink {
                    reached: &mut reached,
                    rgb: &mut row.rgb,
                    layout,
                    eye_regions: &mut eye_regions,
                    hit: false,
                    no_region,
                };
                // Pixels take turns through the first samples of the sequence: a layer that
                // only some strata of the stratified numbers reach is still seen.
                let cell = (x / stride) as u64 + 7919 * (y / stride) as u64;
                for k in 0..PROBE_SAMPLES {
                    progress.check()?;
                    let sample =
                        ((cell * PROBE_SAMPLES as u64 + k as u64) % PROBE_SAMPLE_SPAN) as u32;
                    sink.hit = false;
                    trace_eye_sample(ctx, &brdf, &mut sink, &mut tracer, x, y, sample);
                    if !sink.hit {
                        sink.eye_regions.push(no_region);
                    }
                }
                spent.fetch_add(tracer.rays, Ordering::Relaxed);
                reached.sort_unstable();
                reached.dedup();
                eye_regions.sort_unstable();
                eye_regions.dedup();
                row.reached.extend(reached.iter().copied());
                union_into(row.tiles.entry(x / tile).or_default(), &reached);
                union_into(row.tile_regions.entry(x / tile).or_default(), &eye_regions);
                for region in &eye_regions {
                    row.region_layers
                        .entry(*region)
                        .or_default()
                        .extend(reached.iter().copied());
                }
                row.pixels += 1;
            }
            Ok(row)
        })
        .collect();
    let mut found = ProbeFindings {
        probe_pixels: 0,
        reached: HashSet::new(),
        rgb: HashSet::new(),
        tile_sets: BTreeMap::new(),
        tile_regions: BTreeMap::new(),
        region_layers: HashMap::new(),
    };
    for row in per_row {
        let row = row?;
        for (tx, seen) in row.tile_regions {
            union_into(
                found.tile_regions.entry((row.tile_row, tx)).or_default(),
                &seen,
            );
        }
        for (region, got) in row.region_layers {
            found.region_layers.entry(region).or_default().extend(got);
        }
        found.probe_pixels += row.pixels;
        found.reached.extend(row.reached);
        found.rgb.extend(row.rgb);
        for (tx, set) in row.tiles {
            union_into(found.tile_sets.entry((row.tile_row, tx)).or_default(), &set);
        }
    }
    Ok(found)
}

/// The forecast from what the probe found: arithmetic on its counts, allocating nothing
/// proportional to the layers or the pixels.
fn forecast(
    ctx: &BakeContext,
    scene: &Scene,
    passes: usize,
    prepared_bytes: Option<u64>,
    found: ProbeFindings,
) -> crate::Result<BakeEstimate> {
    let res = ctx.resolution;
    let pixels = res.width as u64 * res.height as u64;
    let layers = ctx.layer_count();
    let ProbeFindings {
        probe_pixels,
        reached,
        rgb,
        tile_sets,
        tile_regions,
        region_layers,
    } = found;
    let mut pairs = 0u64;
    let mut pairs_rgb = 0u64;
    for set in tile_sets.values() {
        pairs += set.len() as u64;
        pairs_rgb += set.iter().filter(|l| rgb.contains(l)).count() as u64;
    }
    let (region_pairs, region_pairs_rgb) = region_model_pairs(&tile_regions, &region_layers, &rgb);
    let (pairs, pairs_rgb) = (pairs.max(region_pairs), pairs_rgb.max(region_pairs_rgb));
    let tile = crate::bake::schedule::tiles::TILE;
    let all_tiles = res.width.div_ceil(tile) as u64 * res.height.div_ceil(tile) as u64;
    let visited = tile_sets.len().max(1) as u64;
    let tile_entries = (pairs * all_tiles).div_ceil(visited);
    let tile_entries_rgb = (pairs_rgb * all_tiles).div_ceil(visited);
    let layers_seen = reached.len().max(1);
    let layers_reached = layers_seen;
    // Layers the probe did not see take the seen layers' share of colour.
    let rgb_seen = reached.iter().filter(|l| rgb.contains(l)).count();
    let layers_rgb =
        ((rgb_seen as f64 / layers_seen as f64) * layers_reached as f64).round() as usize;
    let layers_grey = layers_reached - layers_rgb.min(layers_reached);
    let threads = if ctx.settings.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        ctx.settings.threads
    } as u64;

    let tile_px = (crate::bake::schedule::tiles::TILE * crate::bake::schedule::tiles::TILE) as u64;
    let tile_buffers = threads * layers as u64 * tile_px * 12;
    let geometry =
        (scene.triangle_count() as u64 * BYTES_PER_TRIANGLE).max(prepared_bytes.unwrap_or(0));
    let sample = match ctx.settings.precision {
        Precision::F16 => 2,
        Precision::F32 => 4,
    };
    let dense_stack_bytes = pixels * (layers_grey as u64 + 3 * layers_rgb as u64) * sample;
    let kept = kept_sums(ctx, passes, tile_entries, all_tiles, pixels);
    let (stack_bytes, streaming_peak_bytes) = streaming_peak(
        ctx,
        &StreamingCosts {
            entries: tile_entries,
            entries_rgb: tile_entries_rgb,
            tiles: all_tiles,
            threads,
            geometry,
            sample,
            // A pass traces every block of its sample range at once.
            tile_buffers: tile_buffers * kept.blocks_traced,
        },
    );
    let peak_bytes = streaming_peak_bytes + kept.bytes;
    // Building the BVH holds the unordered triangles and the builder's own arrays beside
    // the prepared geometry; the scene itself stays resident throughout.
    let build = scene.triangle_count() as u64 * BVH_BUILD_BYTES_PER_TRIANGLE;
    let peak_bytes = peak_bytes.max(geometry + build) + scene_bytes(scene);
    Ok(BakeEstimate {
        width: res.width,
        height: res.height,
        layers_possible: layers,
        layers_seen,
        layers_reached,
        layers_rgb,
        probe_pixels,
        kept_sums_bytes: kept.bytes,
        prepared_bytes: geometry,
        peak_bytes,
        stack_bytes,
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
                    basis:
                        crate::brdf::RegionBasis::Principled(basis)
                        | crate::brdf::RegionBasis::PrincipledWithBakeLobe(basis, _),
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
    })
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
    // The estimate reports whether the bake fits rather than refusing it.
    let (mut ctx, _, prepared) = prepare_and_measure(scene, settings, progress)?;
    estimate(&mut ctx, scene, passes.max(1), prepared, progress)
}

/// [`BakeContext::prepare`], and the growth of this process's resident memory while it ran
/// (`None` where the OS does not tell, or when other threads freed more than it took).
/// Refuses first, before anything is built, a scene whose geometry alone cannot fit the
/// settings' budget ([`check_geometry_budget`]).
pub fn prepare_measured(
    scene: &Scene,
    settings: &crate::bake::BakeSettings,
    progress: &crate::progress::Progress,
) -> crate::Result<(BakeContext, ValidationReport, Option<u64>)> {
    check_geometry_budget(scene, settings.memory_budget)?;
    prepare_and_measure(scene, settings, progress)
}

/// The part of the forecast known before anything is built: the scene's arrays, its
/// prepared geometry and the BVH build's transient, per triangle. Over `budget` (`None`: the
/// default budget) it is refused as [`crate::RelumeError::OutOfMemory`] naming the
/// triangles, before the BVH build would take that memory.
pub fn check_geometry_budget(scene: &Scene, budget: Option<u64>) -> crate::Result<()> {
    let triangles = scene.triangle_count() as u64;
    crate::memory::check_budget(
        &format!(
            "this scene's geometry ({triangles} triangles, their BVH build and the scene itself)"
        ),
        scene_bytes(scene)
            .saturating_add(triangles * (BYTES_PER_TRIANGLE + BVH_BUILD_BYTES_PER_TRIANGLE)),
        budget,
    )
}

fn prepare_and_measure(
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
        let mut tiles = BTreeMap::new();
        tiles.insert((0, 0), vec![0]);
        tiles.insert((0, 1), vec![0, 1]);
        tiles.insert((0, 2), vec![1]);
        let region_layers: HashMap<u32, HashSet<u32>> = [
            (0, [0u32, 1].into_iter().collect()),
            (1, [2u32].into_iter().collect()),
        ]
        .into_iter()
        .collect();
        let rgb: HashSet<u32> = [1u32].into_iter().collect();
        let (pairs, pairs_rgb) = region_model_pairs(&tiles, &region_layers, &rgb);
        let per_tile = region_layers.values().map(|s| s.len() as u64).sum::<u64>();
        assert_eq!(pairs, 3 * per_tile);
        assert_eq!(pairs_rgb, 3);
        // The probe's own sets: each tile holds only its own regions' layers.
        let own: u64 = tiles
            .values()
            .map(|seen| {
                seen.iter()
                    .map(|r| region_layers[r].len() as u64)
                    .sum::<u64>()
            })
            .sum();
        assert!(pairs >= own);
    }

    /// The probe's grid thins as an eye sample costs more rays, so its work stays within
    /// its ray budget, down to its floor of pixels.
    #[test]
    fn the_probe_grid_thins_with_the_cost_of_a_sample() {
        let pixels = 1920 * 1080;
        let grid = |rays: f64| {
            let s = probe_stride(pixels, rays) as u64;
            (1920u64.div_ceil(s)) * (1080u64.div_ceil(s))
        };
        assert!(grid(1.0) <= PROBE_PIXELS * 11 / 10);
        for rays in [10.0, 1e3, 1e5] {
            let n = grid(rays);
            assert!(
                (n as f64) * rays * PROBE_SAMPLES as f64 <= 1.2 * PROBE_RAYS as f64
                    || n <= 2 * PROBE_MIN_PIXELS,
                "{rays} rays a sample: {n} pixels"
            );
            assert!(n >= PROBE_MIN_PIXELS / 2, "{rays}: {n}");
        }
    }
}

//! The last step of every bake, one tile at a time: a tile's denoised f32 layers become
//! entries of the tiled stack ([`TiledStackBuilder`]), and the statistics the layer
//! dropping needs (per-layer norms, the image at the bake-time materials) are gathered on
//! the way, so no step after it needs the layers as full frames.
//!
//! Every bake ends here through the streaming finish ([`crate::bake::schedule::stream`]), which
//! hands over each tile row as soon as its denoiser window is ready — traced on the way (a
//! one-pass bake) or summed from kept sample sums (a progressive bake's passes, a farm's
//! merge). A tile's entries, the order its statistics are added in (layer id within a
//! tile, raster order across tiles) and the dropping depend only on the tiles' values.
//!
//! Where the settings ask for it ([`BounceCompression`]), a tile's bounce layers become
//! lattice entries ([`crate::stack::tiled::lattice`]) here, segmented by the tile's eye
//! features, each kept only within its tolerance. That is an approximation: its error at
//! the bake-time materials is measured over the whole image (`compression_error`). The
//! statistics above — the drop decisions' norms and the bake-time image — are taken from
//! the uncompressed values, so dropping does not depend on the compression.

use crate::bake::finish::denoise::EyeFeatures;
use crate::bake::finish::drop::{self, DropReport, LayerNorm};
use crate::bake::non_finite::{zero_non_finite, NonFiniteReport};
use crate::bake::prepare::context::BakeContext;
use crate::bake::settings::BounceCompression;
use crate::layer_key::LayerKey;
use crate::layer_key::PathVertex;
use crate::scene::Scene;
use crate::stack::tiled::lattice::{segment_map, LatticeFitter, PixelSurface};
use crate::stack::tiled::lattice_sign::{self, SignedFit};
use crate::stack::tiled::{
    StackTile, TileCoefficients, TileLattice, TileLayer, TileRadiance, TileRect, TileValues,
    TiledLayerInfo, TiledStack, TiledStackBuilder,
};
use crate::{Result, Rgb};

/// One layer's f32 radiance over one tile (the tile's pixels row-major, `channels`
/// interleaved), denoised and averaged: what [`finalise_tile`] takes.
pub(crate) struct TileInput {
    pub layer: u32,
    pub channels: u8,
    pub data: Vec<f32>,
}

/// What one finalised tile adds to the stack's statistics.
pub(crate) struct TileTally {
    /// Per entry stored: layer id, whether stored grey, Σ value² over its stored channels.
    entries: Vec<(u32, bool, f64)>,
    /// Σ over the tile's pixels and channels of the bake-time image².
    image_sumsq: f64,
    /// The tile's bake-time image (RGB, f64), when the caller keeps the whole image.
    image: Option<Vec<f64>>,
    /// Values handed to the builder.
    values: usize,
    /// Σ over the tile's pixels and channels of (bake-time image − its compressed form)².
    error_sumsq: f64,
    /// Per-pixel values the tile's lattice entries stand in for, and the coefficients they
    /// hold instead.
    lattice_replaced: usize,
    lattice_values: usize,
    /// Layer values that came in NaN or infinite (stored as 0) and lattice fits given up
    /// for a non-finite coefficient ([`crate::bake::non_finite`]).
    non_finite_values: u64,
    non_finite_fits: u64,
}

/// What a bake compresses as lattice entries: the settings' step and tolerance and, per
/// layer id, whether the layer may be compressed (two or more vertices, none subsurface:
/// the bounce layers; the world, direct and subsurface layers stay per pixel).
pub(crate) struct LatticePlan {
    step: u32,
    tolerance: f64,
    eligible: Vec<bool>,
    /// Least weight magnitude an entry's error is weighed with: [`WEIGHT_FLOOR`] × the
    /// largest bake-time weight of any layer.
    weight_floor: f64,
}

/// Share of the largest layer weight below which a layer's bake-time weight is not
/// trusted to stay small under edits (see [`compress_tile`]).
const WEIGHT_FLOOR: f64 = 0.1;

impl LatticePlan {
    /// The plan of `compression` for `ctx`'s layers, whose bake-time `weights` these are;
    /// `None` when it is off.
    pub(crate) fn new(
        ctx: &BakeContext,
        compression: BounceCompression,
        weights: &[Rgb],
    ) -> Option<LatticePlan> {
        if compression.step == 0 {
            return None;
        }
        let eligible = (0..ctx.layer_count())
            .map(|i| {
                let key = crate::bake::layout::layer_key(ctx, i);
                key.path.len() >= 2
                    && !key
                        .path
                        .iter()
                        .any(|v| matches!(v, PathVertex::Subsurface { .. }))
            })
            .collect();
        let largest = weights
            .iter()
            .map(|w| w.abs().max_element() as f64)
            .fold(0.0, f64::max);
        Some(LatticePlan {
            step: compression.step,
            tolerance: compression.tolerance as f64,
            eligible,
            weight_floor: WEIGHT_FLOOR * largest,
        })
    }
}

/// The surfaces of `rect`'s pixels from `features` whose pixel (0, 0) is the frame's
/// `origin` (a window's features, or the whole frame's with origin (0, 0)).
pub(crate) fn tile_surfaces(
    features: &EyeFeatures,
    origin: (u32, u32),
    rect: TileRect,
) -> Vec<PixelSurface> {
    let mut out = Vec::with_capacity(rect.pixels());
    for y in rect.y0..rect.y0 + rect.height {
        for x in rect.x0..rect.x0 + rect.width {
            out.push(features.surface((x - origin.0) as usize, (y - origin.1) as usize));
        }
    }
    out
}

/// Stores tile `tile` (covering `rect`) of `inputs` into `builder`: an all-zero layer is
/// left out, one whose three channels have the same bits throughout the tile is stored grey
/// (one channel), and the builder quantises each entry with its own scale. `weights` are
/// the layers' weights at the bake-time materials (by layer id); `keep_image` keeps the
/// tile's bake-time image in the tally (a progressive bake's error estimate needs it).
/// With a `lattice` plan and the tile's pixel `surfaces`, the plan's layers are stored as
/// lattice entries where that stays within its tolerance (see the module doc).
#[allow(clippy::too_many_arguments)]
pub(crate) fn finalise_tile(
    builder: &TiledStackBuilder,
    tile: usize,
    rect: TileRect,
    mut inputs: Vec<TileInput>,
    weights: &[Rgb],
    keep_image: bool,
    lattice: Option<&LatticePlan>,
    surfaces: &[PixelSurface],
) -> Result<TileTally> {
    inputs.sort_by_key(|i| i.layer);
    let mut image = vec![0.0f64; rect.pixels() * 3];
    let mut kept: Vec<TileInput> = Vec::with_capacity(inputs.len());
    let mut entries = Vec::with_capacity(inputs.len());
    let mut non_finite_values = 0;
    for mut input in inputs {
        non_finite_values += zero_non_finite(&mut input.data);
        if input.data.iter().all(|v| *v == 0.0) {
            continue;
        }
        if input.channels == 3
            && input
                .data
                .chunks_exact(3)
                .all(|p| p[0] == p[1] && p[1] == p[2])
        {
            input.data = input.data.chunks_exact(3).map(|p| p[0]).collect();
            input.channels = 1;
        }
        let sumsq: f64 = input.data.iter().map(|v| (*v as f64) * (*v as f64)).sum();
        let w = weights[input.layer as usize];
        let w = [w.x as f64, w.y as f64, w.z as f64];
        if input.channels == 1 {
            for (px, v) in image.chunks_exact_mut(3).zip(&input.data) {
                for c in 0..3 {
                    px[c] += w[c] * *v as f64;
                }
            }
        } else {
            for (i, v) in input.data.iter().enumerate() {
                image[i] += w[i % 3] * *v as f64;
            }
        }
        entries.push((input.layer, input.channels == 1, sumsq));
        kept.push(input);
    }
    let image_sumsq: f64 = image.iter().map(|v| v * v).sum();
    let compressed = match lattice {
        Some(plan) if surfaces.len() == rect.pixels() => {
            compress_tile(plan, rect, surfaces, &kept, &image, image_sumsq, weights)
        }
        _ => None,
    };
    let (lattice, fits, non_finite_fits) = match compressed {
        Some((lattice, fits, refused)) => (Some(lattice), fits, refused),
        None => (None, Vec::new(), 0),
    };
    let radiance: Vec<TileRadiance> = kept
        .iter()
        .enumerate()
        .filter(|(k, _)| !fits.iter().any(|f| f.input == *k))
        .map(|(_, i)| TileRadiance {
            layer: i.layer,
            channels: i.channels,
            radiance: &i.data,
        })
        .collect();
    let coefficients: Vec<TileCoefficients> = fits
        .iter()
        .map(|f| TileCoefficients {
            layer: kept[f.input].layer,
            channels: kept[f.input].channels,
            segments: f.mask,
            coefficients: &f.coefficients,
        })
        .collect();
    builder.insert_with_lattice(tile, &radiance, lattice, &coefficients)?;
    let lattice_replaced: usize = fits.iter().map(|f| kept[f.input].data.len()).sum();
    let lattice_values: usize = fits.iter().map(|f| f.coefficients.len()).sum();
    let mut error = vec![
        0.0f64;
        if fits.is_empty() {
            0
        } else {
            rect.pixels() * 3
        }
    ];
    for f in &fits {
        let input = &kept[f.input];
        let w = weights[input.layer as usize];
        let w = [w.x as f64, w.y as f64, w.z as f64];
        let c = input.channels as usize;
        for (p, px) in error.chunks_exact_mut(3).enumerate() {
            for (ch, e) in px.iter_mut().enumerate() {
                let i = p * c + ch.min(c - 1);
                *e += w[ch] * (input.data[i] as f64 - f.reconstructed[i] as f64);
            }
        }
    }
    Ok(TileTally {
        entries,
        image_sumsq,
        image: keep_image.then_some(image),
        values: kept.iter().map(|i| i.data.len()).sum::<usize>() + lattice_values
            - lattice_replaced,
        error_sumsq: error.iter().map(|v| v * v).sum(),
        lattice_replaced,
        lattice_values,
        non_finite_values,
        non_finite_fits,
    })
}

/// A layer of the tile kept as a lattice entry.
struct KeptFit {
    /// Position in the tile's inputs.
    input: usize,
    mask: u32,
    coefficients: Vec<f32>,
    reconstructed: Vec<f32>,
}

/// The tile's lattice, the plan's layers it keeps as lattice entries and how many fits were
/// given up for a non-finite coefficient or reconstruction (those layers stay exact, per
/// pixel); `None` when it keeps none (or the tile needs more segments than a lattice has).
///
/// Which: each candidate is fitted, and its error weighs `‖w̄ ⊙ (L − L̃)‖` over the tile,
/// `w̄` its bake-time weight per channel in magnitude, raised to at least the plan's weight
/// floor (so a layer the bake-time materials happen to leave dark still counts when an edit
/// lights it). The smallest errors are kept while their squares add up to at most
/// `(tolerance · ‖tile image‖)²`: layers' fitting errors are mostly independent noise, so
/// the image's error at the bake-time materials stays near `tolerance`; the bake measures
/// what it actually is.
///
/// Sign: each fit keeps a layer that is ≥ 0 on a segment ≥ 0 there, and of the kept fits
/// those that would take the tile's bake-time `image` below zero where it is not are given
/// up ([`lattice_sign`]).
#[allow(clippy::too_many_arguments)]
fn compress_tile(
    plan: &LatticePlan,
    rect: TileRect,
    surfaces: &[PixelSurface],
    kept: &[TileInput],
    image: &[f64],
    image_sumsq: f64,
    weights: &[Rgb],
) -> Option<(TileLattice, Vec<KeptFit>, u64)> {
    let candidates: Vec<usize> = (0..kept.len())
        .filter(|&k| plan.eligible[kept[k].layer as usize])
        .filter(|&k| weights.get(kept[k].layer as usize).is_some())
        .collect();
    if candidates.is_empty() || image_sumsq <= 0.0 {
        return None;
    }
    let map = segment_map(surfaces)?;
    let lattice = TileLattice::new(plan.step, rect.width, rect.height, map).ok()?;
    let fitter = LatticeFitter::new(&lattice);
    let mut fitted: Vec<(f64, KeptFit)> = Vec::new();
    let mut non_finite_fits = 0;
    for k in candidates {
        let input = &kept[k];
        let Some(fit) = fitter.fit(&input.data, input.channels) else {
            continue;
        };
        if !(fit.coefficients.iter().all(|v| v.is_finite())
            && fit.reconstructed.iter().all(|v| v.is_finite()))
        {
            non_finite_fits += 1;
            continue;
        }
        if fit.coefficients.len() >= input.data.len() {
            continue;
        }
        let w = weights[input.layer as usize].to_array();
        let w = w.map(|v| (v.abs() as f64).max(plan.weight_floor));
        let c = input.channels as usize;
        let mut err = 0.0f64;
        for (a, b) in input
            .data
            .chunks_exact(c)
            .zip(fit.reconstructed.chunks_exact(c))
        {
            for (ch, wc) in w.iter().enumerate() {
                let d = a[ch.min(c - 1)] as f64 - b[ch.min(c - 1)] as f64;
                err += (wc * d).powi(2);
            }
        }
        fitted.push((
            err,
            KeptFit {
                input: k,
                mask: fit.mask,
                coefficients: fit.coefficients,
                reconstructed: fit.reconstructed,
            },
        ));
    }
    fitted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.input.cmp(&b.1.input)));
    let budget = plan.tolerance * plan.tolerance * image_sumsq;
    let mut spent = 0.0;
    let mut fits: Vec<KeptFit> = Vec::new();
    for (err, fit) in fitted {
        if spent + err > budget {
            break;
        }
        spent += err;
        fits.push(fit);
    }
    let signed: Vec<SignedFit> = fits
        .iter()
        .map(|f| {
            let input = &kept[f.input];
            let w = weights[input.layer as usize];
            SignedFit {
                weight: [w.x as f64, w.y as f64, w.z as f64],
                channels: input.channels,
                data: &input.data,
                fitted: &f.reconstructed,
            }
        })
        .collect();
    let keep = lattice_sign::repair_negative_pixels(image, &signed);
    drop(signed);
    let mut keep = keep.into_iter();
    fits.retain(|_| keep.next().unwrap_or(false));
    fits.sort_by_key(|f| f.input);
    // A tile with no fit kept still reports the fits it gave up (the builder keeps no
    // lattice without a lattice entry).
    (!fits.is_empty() || non_finite_fits > 0).then_some((lattice, fits, non_finite_fits))
}

/// The statistics of the tiles finalised so far, added in raster order.
pub(crate) struct StackTally {
    /// Per layer id, Σ value² over its grey entries (one channel each).
    grey_sumsq: Vec<f64>,
    /// Per layer id, Σ value² over its RGB entries.
    rgb_sumsq: Vec<f64>,
    image_sumsq: f64,
    /// The whole bake-time image (RGB, f64), when kept.
    image: Option<Vec<f64>>,
    width: usize,
    values: usize,
    value_bytes: usize,
    error_sumsq: f64,
    lattice_replaced: usize,
    lattice_values: usize,
    non_finite_values: u64,
    non_finite_fits: u64,
}

impl StackTally {
    /// No tile yet, for `layers` layer ids; `keep_image` keeps the whole bake-time image
    /// (`pixels` of a `width`-wide frame).
    pub(crate) fn new(
        layers: usize,
        width: usize,
        pixels: usize,
        precision: crate::options::Precision,
        keep_image: bool,
    ) -> Self {
        StackTally {
            values: 0,
            value_bytes: value_bytes(precision),
            grey_sumsq: vec![0.0; layers],
            rgb_sumsq: vec![0.0; layers],
            image_sumsq: 0.0,
            image: keep_image.then(|| vec![0.0; pixels * 3]),
            width,
            error_sumsq: 0.0,
            lattice_replaced: 0,
            lattice_values: 0,
            non_finite_values: 0,
            non_finite_fits: 0,
        }
    }

    /// Adds a tile's tally; tiles must come in raster order (the sums' order is the
    /// bits of the drop decisions).
    pub(crate) fn add(&mut self, rect: TileRect, tally: TileTally) {
        for (layer, grey, sumsq) in tally.entries {
            let slot = if grey {
                &mut self.grey_sumsq
            } else {
                &mut self.rgb_sumsq
            };
            slot[layer as usize] += sumsq;
        }
        self.image_sumsq += tally.image_sumsq;
        self.values += tally.values;
        self.error_sumsq += tally.error_sumsq;
        self.lattice_replaced += tally.lattice_replaced;
        self.lattice_values += tally.lattice_values;
        self.non_finite_values += tally.non_finite_values;
        self.non_finite_fits += tally.non_finite_fits;
        if let (Some(all), Some(tile)) = (&mut self.image, tally.image) {
            for ty in 0..rect.height as usize {
                let row = (rect.y0 as usize + ty) * self.width + rect.x0 as usize;
                let w = rect.width as usize;
                all[row * 3..(row + w) * 3].copy_from_slice(&tile[ty * w * 3..(ty + 1) * w * 3]);
            }
        }
    }
}

impl StackTally {
    /// Bytes of the values stored so far.
    pub(crate) fn stored_bytes(&self) -> usize {
        self.values * self.value_bytes
    }
}

/// Bytes of one stored value.
pub(crate) fn value_bytes(precision: crate::options::Precision) -> usize {
    match precision {
        crate::options::Precision::F16 => 2,
        crate::options::Precision::F32 => 4,
    }
}

/// A finished bake's stack and what its layers became.
pub(crate) struct Finished {
    pub stack: TiledStack,
    pub drop: DropReport,
    pub possible: usize,
    pub grey: usize,
    pub rgb: usize,
    pub empty: usize,
    /// Bytes the kept layers would hold as full frames (the dense layout).
    pub dense_bytes: usize,
    /// The bake-time image, when the tally kept it.
    pub image: Option<Vec<f64>>,
    /// ‖bake-time image − its compressed form‖ / ‖bake-time image‖ over the whole frame,
    /// before layers are dropped (0 without lattice entries).
    pub compression_error: f64,
    /// Bytes the lattice entries saved against storing the same entries per pixel, before
    /// layers are dropped.
    pub compression_saved_bytes: usize,
    /// What each stage kept finite ([`crate::bake::non_finite`]).
    pub non_finite: NonFiniteReport,
}

/// Per layer id what the whole bake saw: whether any sample reached it, and whether its
/// averaged radiance carried colour anywhere (before denoising: the stored layer's
/// channels, as the dense stack had them).
pub(crate) struct LayerFacts {
    pub reached: Vec<bool>,
    pub coloured: Vec<bool>,
}

/// Finishes the stack once every tile is in: leaves out the layers no path reached and,
/// under `budget`, the negligible ones ([`drop`]), renumbers the rest in id order, and
/// keeps one black layer when nothing is left (the stack stays a valid file that relights
/// to black).
pub(crate) fn finish_stack(
    ctx: &BakeContext,
    builder: TiledStackBuilder,
    tally: StackTally,
    facts: &LayerFacts,
    weights: &[Rgb],
    budget: f64,
) -> Result<Finished> {
    let non_finite = NonFiniteReport {
        path_contributions: ctx.non_finite.path_contributions(),
        layer_values: tally.non_finite_values,
        lattice_fits: tally.non_finite_fits,
        stored_values: builder.non_finite_zeroed(),
    };
    let stack = builder.finish()?;
    let compression_error = if tally.image_sumsq > 0.0 {
        (tally.error_sumsq / tally.image_sumsq).sqrt()
    } else {
        0.0
    };
    let compression_saved_bytes =
        tally.lattice_replaced.saturating_sub(tally.lattice_values) * tally.value_bytes;
    let count = stack.layers.len();
    let keys: Vec<LayerKey> = stack.layers.iter().map(|l| l.key.clone()).collect();
    let reached: Vec<usize> = (0..count).filter(|&i| facts.reached[i]).collect();
    let unreached: Vec<LayerKey> = (0..count)
        .filter(|&i| !facts.reached[i])
        .map(|i| keys[i].clone())
        .collect();
    let norms: Vec<LayerNorm> = reached
        .iter()
        .map(|&i| {
            let (channels, sumsq) = if facts.coloured[i] {
                (3, 3.0 * tally.grey_sumsq[i] + tally.rgb_sumsq[i])
            } else {
                (1, tally.grey_sumsq[i] + tally.rgb_sumsq[i])
            };
            LayerNorm {
                key: keys[i].clone(),
                channels,
                norm: sumsq.sqrt(),
            }
        })
        .collect();
    let reference = tally.image_sumsq.sqrt();
    let (leave, bound) = drop::choose_negligible(ctx, &norms, reference, budget);
    let mut keep = vec![false; count];
    let mut dropped_ids = vec![false; count];
    for (k, &i) in reached.iter().enumerate() {
        keep[i] = !leave[k];
        dropped_ids[i] = leave[k];
    }
    let cost = if reference > 0.0 && dropped_ids.iter().any(|d| *d) {
        lost_image_norm(&stack, &dropped_ids, weights) / reference
    } else {
        0.0
    };
    let kept_keys: Vec<LayerKey> = (0..count)
        .filter(|&i| keep[i])
        .map(|i| keys[i].clone())
        .collect();
    let dropped_keys: Vec<LayerKey> = (0..count)
        .filter(|&i| dropped_ids[i])
        .map(|i| keys[i].clone())
        .collect();
    let report = drop::drop_report(
        ctx,
        &kept_keys,
        &dropped_keys,
        &unreached,
        budget,
        bound,
        cost,
    );
    let mut stack = keep_layers(stack, &keep, &facts.coloured);
    let grey = stack.layers.iter().filter(|l| l.channels == 1).count();
    let rgb = stack.layers.len() - grey;
    let pixels = stack.header.width as usize * stack.header.height as usize;
    let dense_bytes = (grey + 3 * rgb) * pixels * value_bytes(stack.header.precision);
    if stack.layers.is_empty() {
        stack.layers.push(TiledLayerInfo {
            key: LayerKey::new(vec![]),
            channels: 1,
            scale: 1.0,
        });
    }
    Ok(Finished {
        stack,
        drop: report,
        possible: count,
        grey,
        rgb,
        empty: unreached.len(),
        dense_bytes,
        image: tally.image,
        compression_error,
        compression_saved_bytes,
        non_finite,
    })
}

/// ‖Σ w_l L_l‖ over the layers marked in `dropped`, from their stored entries.
fn lost_image_norm(stack: &TiledStack, dropped: &[bool], weights: &[Rgb]) -> f64 {
    let mut sumsq = 0.0f64;
    for (t, tile) in stack.tiles.iter().enumerate() {
        let pixels = stack.tile_rect(t).pixels();
        let mut image = vec![0.0f64; pixels * 3];
        let mut any = false;
        for (e, entry) in tile.entries.iter().enumerate() {
            if !dropped[entry.layer as usize] {
                continue;
            }
            any = true;
            let w = weights[entry.layer as usize].to_array();
            for p in 0..pixels {
                for c in 0..3 {
                    image[p * 3 + c] += w[c] as f64 * stack.value(t, e, p, c) as f64;
                }
            }
        }
        if any {
            sumsq += image.iter().map(|v| v * v).sum::<f64>();
        }
    }
    sumsq.sqrt()
}

/// The stack with only the layers marked in `keep`, renumbered in id order; a kept layer
/// has 3 channels where `coloured`, else 1.
fn keep_layers(stack: TiledStack, keep: &[bool], coloured: &[bool]) -> TiledStack {
    let mut new_id = vec![u32::MAX; keep.len()];
    let mut layers = Vec::new();
    for (i, info) in stack.layers.into_iter().enumerate() {
        if keep[i] {
            new_id[i] = layers.len() as u32;
            layers.push(TiledLayerInfo {
                channels: if coloured[i] { 3 } else { 1 },
                ..info
            });
        }
    }
    let tiles = stack
        .tiles
        .into_iter()
        .enumerate()
        .map(|(t, tile)| {
            let pixels =
                crate::stack::tiled::tile_rect(stack.header.width, stack.header.height, t).pixels();
            if tile.entries.iter().all(|e| keep[e.layer as usize]) {
                let entries = tile
                    .entries
                    .into_iter()
                    .map(|e| TileLayer {
                        layer: new_id[e.layer as usize],
                        ..e
                    })
                    .collect();
                return StackTile {
                    entries,
                    values: tile.values,
                    lattice: tile.lattice,
                };
            }
            let mut values = TileValues::empty(tile.values.precision());
            let mut entries = Vec::new();
            for e in &tile.entries {
                if !keep[e.layer as usize] {
                    continue;
                }
                let range = e.offset as usize..e.offset as usize + tile.value_count(e, pixels);
                let offset = values.len() as u32;
                match (&mut values, &tile.values) {
                    (TileValues::F16(out), TileValues::F16(src)) => {
                        out.extend_from_slice(&src[range])
                    }
                    (TileValues::F32(out), TileValues::F32(src)) => {
                        out.extend_from_slice(&src[range])
                    }
                    _ => unreachable!("one precision per tile"),
                }
                entries.push(TileLayer {
                    layer: new_id[e.layer as usize],
                    offset,
                    ..*e
                });
            }
            let lattice = tile
                .lattice
                .filter(|_| entries.iter().any(|e: &TileLayer| e.segments != 0));
            // The finished stack holds no room its growth over-allocated.
            values.shrink_to_fit();
            entries.shrink_to_fit();
            StackTile {
                entries,
                values,
                lattice,
            }
        })
        .collect();
    TiledStack {
        header: stack.header,
        layers,
        tiles,
    }
}

/// The header's scene-dependent parts come from [`super::describe::stack_header`]; a builder takes every possible
/// layer id (key and 3 channels: a tile's grey entries are found per tile).
pub(crate) fn builder_for(
    ctx: &BakeContext,
    header: crate::stack::StackHeader,
) -> Result<TiledStackBuilder> {
    let layers = (0..ctx.layer_count())
        .map(|i| (crate::bake::layout::layer_key(ctx, i), 3u8))
        .collect();
    TiledStackBuilder::new(header, layers)
}

/// Per layer id, its weight at the scene's bake-time materials.
pub(crate) fn layer_weights(ctx: &BakeContext, scene: &Scene) -> Result<Vec<Rgb>> {
    let keys: Vec<LayerKey> = (0..ctx.layer_count())
        .map(|i| crate::bake::layout::layer_key(ctx, i))
        .collect();
    drop::bake_time_weights(ctx, scene, &keys)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stack::StackHeader;

    fn header(size: u32) -> StackHeader {
        serde_json::from_value(serde_json::json!({
            "format_version": 2, "width": size, "height": size,
            "camera": {"projection": "perspective",
                       "matrix_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
            "spp": 1, "light_samples": 1, "bounces": 0, "sampling": "uniform", "seed": 0,
            "regions": [], "lights": [], "scene_hash": "", "precision": "f16",
            "light_tint": [1.0, 1.0, 1.0], "light_groups": [],
            "denoise": {"direct_iterations": 0, "bounce_iterations": 0},
        }))
        .unwrap()
    }

    /// The denoiser's output stage: a NaN, an infinity and a subnormal among a tile's layer
    /// values. The first two are stored as 0 and counted, the subnormal is kept; the builder
    /// (the last guard) has nothing left to do.
    #[test]
    fn non_finite_layer_values_are_stored_as_zero_and_counted() {
        let builder =
            TiledStackBuilder::new(header(4), vec![(LayerKey::new(vec![]), 3u8)]).unwrap();
        let mut data = vec![0.25f32; 16 * 3];
        data[0] = f32::NAN;
        data[4] = f32::INFINITY;
        data[8] = 1e-40;
        let rect = crate::stack::tiled::tile_rect(4, 4, 0);
        let input = TileInput {
            layer: 0,
            channels: 3,
            data,
        };
        let tally = finalise_tile(
            &builder,
            0,
            rect,
            vec![input],
            &[Rgb::ONE],
            false,
            None,
            &[],
        )
        .unwrap();
        assert_eq!(tally.non_finite_values, 2);
        assert!(tally.image_sumsq.is_finite() && tally.image_sumsq > 0.0);
        assert_eq!(builder.non_finite_zeroed(), 0);
        let stack = builder.finish().unwrap();
        let TileValues::F16(v) = &stack.tiles[0].values else {
            panic!("f16 expected");
        };
        let scale = stack.tiles[0].entries[0].scale;
        assert_eq!(v[0].to_f32(), 0.0);
        assert_eq!(v[4].to_f32(), 0.0);
        assert_eq!(v[1].to_f32() * scale, 0.25);
    }

    /// The lattice fit stage: a layer whose least-squares fit overflows f32 (values at
    /// f32's limit, rising steeply towards the tile's edge, which the bilinear lattice
    /// overshoots) is not stored as lattice
    /// coefficients; it is counted and stays exact, per pixel.
    #[test]
    fn a_lattice_fit_that_overflows_keeps_the_layer_exact() {
        let rect = crate::stack::tiled::tile_rect(16, 16, 0);
        let plan = LatticePlan {
            step: 4,
            tolerance: 1.0,
            eligible: vec![true],
            weight_floor: 0.0,
        };
        let surfaces = vec![Some((0u32, [0.0f32, 0.0, 1.0])); 256];
        let data: Vec<f32> = (0..256)
            .map(|p| f32::MAX * ((p % 16) as f32 / 15.0).powi(3))
            .collect();
        let image: Vec<f64> = data.iter().flat_map(|v| [*v as f64; 3]).collect();
        let image_sumsq = image.iter().map(|v| v * v).sum();
        let kept = [TileInput {
            layer: 0,
            channels: 1,
            data,
        }];
        let (_, fits, refused) = compress_tile(
            &plan,
            rect,
            &surfaces,
            &kept,
            &image,
            image_sumsq,
            &[Rgb::ONE],
        )
        .expect("the refused fit is reported");
        assert!(fits.is_empty());
        assert_eq!(refused, 1);
    }
}

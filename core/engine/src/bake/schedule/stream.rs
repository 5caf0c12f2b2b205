//! The one-pass bake whose memory follows the data: tile rows are traced in bands, each
//! traced tile is kept only as its sparse averages (the layers non-zero there, a grey one
//! on one channel: [`super::traced_tile`]) and its pixels' eye features, and a tile row is
//! finalised into the tiled stack as soon as the rows its denoiser reads are traced. Peak
//! memory is the stack built so far plus the rows in flight, not layers × frame; the
//! allocator's free pages are handed back after each window
//! ([`crate::memory::release_free_memory`]), so what is resident follows what is held.
//!
//! The denoiser ([`crate::bake::finish::denoise`]) is a fixed linear operator whose weights depend
//! only on the eye features, with a footprint of [`crate::bake::finish::denoise::footprint_radius`]
//! pixels. A tile row is filtered on a window of `apron` tile rows above and below it
//! ([`super::band`]; `apron · 16` ≥ that radius), whose cut edges are treated like the image's: the row's output is then exactly what the
//! whole-frame filter gives (errors from a cut edge travel at most the radius inwards), so
//! the stack is, bit for bit, what filtering full frames would give (the unit tests of
//! [`crate::bake::finish::denoise`] and [`super::denoise_sparse`] hold the two side by side).
//! A farm's merge and each pass of a progressive bake run this same walk on tiles summed
//! from kept sample sums ([`finish_streaming`], `super::summed_finish`). Each layer is
//! filtered only on the tiles it is
//! present on plus the footprint, and only on the rows the finalised tiles need, so the
//! filter's work follows the tile entries rather than layers × window.

use rayon::prelude::*;
use std::time::Instant;

use super::band::apron_rows;
use super::denoise_sparse::{SparseScratch, SparseTiles};
use super::tiles::{self, TILE};
use super::traced_tile::{trace_sparse, TracedLayer, TracedTile};
use crate::bake::finish::denoise::{footprint_radius, EyeFeatures, FEATURE_STRIDE};
use crate::bake::finish::describe::stack_header;
use crate::bake::finish::finalise::{
    builder_for, finalise_tile, finish_stack, layer_weights, tile_surfaces, Finished, LatticePlan,
    LayerFacts, StackTally, TileInput, TileTally,
};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::bake::settings::BakeSettings;
use crate::progress::{Progress, Stage};
use crate::scene::Scene;
use crate::stack::tiled::{tiles_along, TileRect, TiledStackBuilder};
use crate::Result;

/// What the streaming bake made.
pub(crate) struct Streamed {
    pub finished: Finished,
    /// Seconds filtering the windows (features, weights, layers).
    pub denoise_seconds: f64,
    /// Seconds of per-layer work: the filtering, finalising tiles into the stack and
    /// finishing it.
    pub assembly_seconds: f64,
    /// The most bytes held at once in stored tiles, traced rows and denoiser windows.
    pub peak_accounted_bytes: usize,
    /// Eye samples per pixel of every tile, in raster order (the bake's `spp` everywhere
    /// unless adaptive sampling stopped tiles early; empty for a farm's merge).
    pub tile_samples: Vec<u32>,
}

/// Bakes `settings.spp` samples per pixel in one pass, streaming tile rows into the tiled
/// stack; `band_rows` tile rows are traced at once (rayon over their tiles).
#[allow(clippy::too_many_arguments)]
pub(crate) fn bake_streaming(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    band_rows: usize,
    pool: &rayon::ThreadPool,
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<Streamed> {
    let brdf = BasisBrdf { ctx };
    let spp = settings.spp;
    // Adaptive sampling's rule reads the bake-time image: the layers' weights at the
    // scene's materials, the ones the finish computes too.
    let weights = match settings.adaptive.is_off() {
        true => None,
        false => Some(layer_weights(ctx, scene)?),
    };
    let adaptive = weights.as_deref().map(|w| (settings.adaptive, w));
    let mut tile_samples = vec![spp; tiles::tiles(ctx.resolution).len()];
    let mut streamed = finish_streaming(
        ctx,
        scene,
        settings,
        band_rows,
        pool,
        progress,
        false,
        |band_tiles| {
            let done: Vec<Result<TracedTile>> = pool.install(|| {
                band_tiles
                    .par_iter()
                    .map(|tile| {
                        progress.check()?;
                        let t = trace_sparse(ctx, &brdf, tile, spp, adaptive, progress, rays)?;
                        progress.advance(spp as u64);
                        Ok(t)
                    })
                    .collect()
            });
            let done: Vec<TracedTile> = done.into_iter().collect::<Result<_>>()?;
            for (tile, t) in band_tiles.iter().zip(&done) {
                tile_samples[tile.index] = t.samples;
            }
            Ok(done)
        },
    )?;
    streamed.tile_samples = tile_samples;
    Ok(streamed)
}

/// The streaming bake's walk over the frame with its tiles from `source`: given the next
/// band's tiles (raster order), it returns them as [`TracedTile`]s in the same order — traced
/// here ([`bake_streaming`]), or summed samples (`super::summed_finish`: a farm merge's
/// parts, a progressive bake's kept tiles). Everything after (the windows, the denoiser,
/// finalising, the stack's finish) is the one code path. `keep_image`: the finished stack
/// carries its image at the bake-time materials ([`Finished::image`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn finish_streaming(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    band_rows: usize,
    pool: &rayon::ThreadPool,
    progress: &Progress,
    keep_image: bool,
    mut source: impl FnMut(&[tiles::Tile]) -> Result<Vec<TracedTile>>,
) -> Result<Streamed> {
    let res = ctx.resolution;
    let (width, height) = (res.width as usize, res.height as usize);
    let spp = settings.spp;
    let all = tiles::tiles(res);
    let tx = tiles_along(res.width) as usize;
    let ty = tiles_along(res.height) as usize;
    let apron = apron_rows(&settings.denoise);
    let band = band_rows.max(1);
    let builder = builder_for(ctx, stack_header(ctx, scene, settings, spp))?;
    let weights = layer_weights(ctx, scene)?;
    let layer_count = ctx.layer_count();
    let mut tally = StackTally::new(
        layer_count,
        width,
        width * height,
        settings.precision,
        keep_image,
    );
    let mut facts = LayerFacts {
        reached: vec![false; layer_count],
        coloured: vec![false; layer_count],
    };
    let path_len: Vec<usize> = (0..layer_count)
        .map(|i| crate::bake::layout::layer_key(ctx, i).path.len())
        .collect();
    let plan = LatticePlan::new(ctx, settings.compression, &weights);
    let mut rows: Vec<Option<Vec<TracedTile>>> = (0..ty).map(|_| None).collect();
    let (mut traced, mut next, mut freed) = (0usize, 0usize, 0usize);
    let mut held_rows = 0usize;
    let mut peak = 0usize;
    let mut denoise_seconds = 0.0;
    let mut assembly_seconds = 0.0;
    while next < ty {
        progress.check()?;
        let needed = (next + apron + 1).min(ty);
        if traced < needed {
            progress.set_stage(Stage::Tracing);
            let upto = (traced + band).max(needed).min(ty);
            let band_tiles = &all[traced * tx..upto * tx];
            let mut done = source(band_tiles)?;
            if apron > 0 {
                // The denoiser's reach, traced once per tile for every window it is in.
                let start = Instant::now();
                pool.install(|| {
                    done.par_iter_mut().for_each(|t| {
                        let (x0, y0) = (t.rect.x0 as usize, t.rect.y0 as usize);
                        let size = (t.rect.width as usize, t.rect.height as usize);
                        t.reach = EyeFeatures::surfaces_from_window_sums(
                            ctx,
                            &t.features,
                            spp,
                            (x0, y0),
                            size,
                        )
                        .traced_reach(ctx);
                    })
                });
                let reach_seconds = start.elapsed().as_secs_f64();
                denoise_seconds += reach_seconds;
                assembly_seconds += reach_seconds;
            }
            for t in &done {
                held_rows += t.bytes();
                for l in &t.layers {
                    facts.reached[l.id as usize] = true;
                    facts.coloured[l.id as usize] |= l.channels == 3;
                }
            }
            for r in (traced..upto).rev() {
                rows[r] = Some(done.split_off((r - traced) * tx));
            }
            traced = upto;
            peak = peak.max(tally.stored_bytes() + held_rows);
            continue;
        }
        // Every row whose window is traced is finalised on one window, each layer filtered
        // only where it can be non-zero and on the rows these need
        // ([`EyeFeatures::filter_sparse`]).
        let last = if traced == ty {
            ty - 1
        } else {
            traced - 1 - apron
        };
        let window = Window {
            ctx,
            settings,
            rows: &rows,
            lo: next.saturating_sub(apron),
            hi: (last + apron).min(ty - 1),
            centre: (next, last),
            width,
            height,
            path_len: &path_len,
            finishing: traced == ty,
            lattice: plan.as_ref(),
            keep_image,
        };
        let WindowDone {
            tallies,
            transient,
            filter_seconds,
            finalise_seconds,
        } = window.finalise(&builder, &weights, pool, progress)?;
        denoise_seconds += filter_seconds;
        assembly_seconds += filter_seconds + finalise_seconds;
        for (rect, t) in tallies {
            tally.add(rect, t);
        }
        peak = peak.max(tally.stored_bytes() + held_rows + transient);
        // Row r serves the rows up to r + apron: those up to `last` are done.
        while freed + apron <= last {
            if let Some(row) = rows[freed].take() {
                held_rows -= row.iter().map(TracedTile::bytes).sum::<usize>();
            }
            freed += 1;
        }
        // The rows and the window's buffers just freed lie between the stack's tiles: give
        // their pages back before the next band is traced, so resident memory follows what
        // is held rather than the largest window so far.
        crate::memory::release_free_memory();
        next = last + 1;
    }
    drop(rows);
    progress.check()?;
    progress.set_stage(Stage::Finishing);
    let finish_start = Instant::now();
    let finished = finish_stack(
        ctx,
        builder,
        tally,
        &facts,
        &weights,
        settings.drop_budget as f64,
    )?;
    assembly_seconds += finish_start.elapsed().as_secs_f64();
    // What follows (writing the stack) holds the stack and its own buffers only.
    crate::memory::release_free_memory();
    Ok(Streamed {
        finished,
        denoise_seconds,
        assembly_seconds,
        peak_accounted_bytes: peak,
        tile_samples: Vec::new(),
    })
}

/// The traced rows `lo..=hi` around the tile rows `centre` (first, last) being finalised.
struct Window<'a> {
    ctx: &'a BakeContext,
    settings: &'a BakeSettings,
    rows: &'a [Option<Vec<TracedTile>>],
    lo: usize,
    hi: usize,
    centre: (usize, usize),
    width: usize,
    height: usize,
    path_len: &'a [usize],
    /// Every row is traced: what is left is the bake's finish, reported as
    /// [`Stage::Finishing`] rather than row by row.
    finishing: bool,
    /// The bounce layers' lattice compression, when the settings ask for it.
    lattice: Option<&'a LatticePlan>,
    /// Whether the tiles' bake-time images are kept (the stack's whole image at the
    /// bake-time materials: one image, not one per layer).
    keep_image: bool,
}

impl Window<'_> {
    /// Reports `stage` unless the bake is finishing.
    fn stage(&self, progress: &Progress, stage: Stage) {
        progress.set_stage(if self.finishing {
            Stage::Finishing
        } else {
            stage
        });
    }

    fn row(&self, r: usize) -> &[TracedTile] {
        self.rows[r].as_deref().unwrap_or(&[])
    }

    /// First pixel row and height of the window.
    fn span(&self) -> (usize, usize) {
        let y0 = self.lo * TILE as usize;
        let y1 = ((self.hi + 1) * TILE as usize).min(self.height);
        (y0, y1 - y0)
    }

    fn iterations(&self, layer: u32) -> u32 {
        match self.path_len[layer as usize] {
            1 => self.settings.denoise.direct_iterations,
            2 => self.settings.denoise.bounce_iterations,
            _ => 0,
        }
    }

    /// The window's eye features (only built when some layer is filtered).
    fn features(&self) -> EyeFeatures {
        let (y0, h) = self.span();
        let mut sums = Vec::with_capacity(self.width * h * FEATURE_STRIDE);
        for _ in 0..self.width * h {
            sums.extend_from_slice(&EyeFeatures::EMPTY);
        }
        let mut reach = vec![f32::INFINITY; self.width * h];
        for r in self.lo..=self.hi {
            for t in self.row(r) {
                for py in 0..t.rect.height as usize {
                    for px in 0..t.rect.width as usize {
                        let src = (py * t.rect.width as usize + px) * FEATURE_STRIDE;
                        let dst =
                            ((t.rect.y0 as usize + py - y0) * self.width + t.rect.x0 as usize + px)
                                * FEATURE_STRIDE;
                        sums[dst..dst + FEATURE_STRIDE]
                            .copy_from_slice(&t.features[src..src + FEATURE_STRIDE]);
                        reach[dst / FEATURE_STRIDE] = t.reach[src / FEATURE_STRIDE];
                    }
                }
            }
        }
        EyeFeatures::surfaces_from_window_sums(
            self.ctx,
            &sums,
            self.settings.spp,
            (0, y0),
            (self.width, h),
        )
        .with_reach(reach)
    }

    /// Filters what the centre row needs and finalises its tiles: their tallies in raster
    /// order, and the bytes the windows held at once.
    fn finalise(
        &self,
        builder: &TiledStackBuilder,
        weights: &[crate::Rgb],
        pool: &rayon::ThreadPool,
        progress: &Progress,
    ) -> Result<WindowDone> {
        self.stage(progress, Stage::Assembly);
        let centre: Vec<&TracedTile> = (self.centre.0..=self.centre.1)
            .flat_map(|r| self.row(r).iter())
            .collect();
        // Every layer present in the window may reach the centre row once filtered.
        let mut ids: Vec<u32> = (self.lo..=self.hi)
            .flat_map(|r| self.row(r).iter())
            .flat_map(|t| t.layers.iter().map(|l| l.id))
            .collect();
        ids.sort_unstable();
        ids.dedup();
        let filtered = ids.iter().any(|&l| self.iterations(l) > 0);
        let (y0, h) = self.span();
        // The centre's pixel rows within the window: what the sparse filter must get exact.
        let wanted = self.centre.0 * TILE as usize - y0
            ..((self.centre.1 + 1) * TILE as usize).min(self.height) - y0;
        let filter_start = Instant::now();
        let (features, direct, bounce) = if filtered {
            let f = pool.install(|| self.features());
            let weights =
                |iterations| pool.install(|| f.weights_for_rows(iterations, wanted.clone()));
            let d = weights(self.settings.denoise.direct_iterations);
            let b = weights(self.settings.denoise.bounce_iterations);
            (Some(f), Some(d), Some(b))
        } else {
            (None, None, None)
        };
        let window_bytes = self.width * h * 3 * 4;
        // The window's tiles each layer is present on, built once for all layers.
        let tx = tiles_along(self.width as u32) as usize;
        let mut present: Vec<Vec<(usize, &TracedLayer)>> = ids.iter().map(|_| Vec::new()).collect();
        for r in self.lo..=self.hi {
            for t in self.row(r) {
                let at = (r - self.lo) * tx + (t.rect.x0 / TILE) as usize;
                for l in &t.layers {
                    if let Ok(i) = ids.binary_search(&l.id) {
                        present[i].push((at, l));
                    }
                }
            }
        }
        let window_tiles = (self.hi + 1 - self.lo) * tx;
        let centre_tiles = (self.centre.0 - self.lo) * tx..(self.centre.1 + 1 - self.lo) * tx;
        // Stages interleave row by row: the row's filtering, then its tiles' storing.
        self.stage(progress, Stage::Denoising);
        // Per layer: the centre tiles it is present on (position in `centre`) and its values
        // there. Each worker keeps its scratch window from layer to layer.
        let per_layer: Vec<Result<Vec<(usize, TileInput)>>> = pool.install(|| {
            ids.par_iter()
                .zip(present.par_iter())
                .map_init(
                    || None,
                    |scratch: &mut Option<SparseScratch>, (&layer, tiles)| {
                        progress.check()?;
                        let iterations = self.iterations(layer);
                        let (Some(f), true) = (&features, iterations > 0) else {
                            return Ok(centre
                                .iter()
                                .enumerate()
                                .filter_map(|(i, t)| {
                                    t.layer(layer).map(|l| {
                                        (
                                            i,
                                            TileInput {
                                                layer,
                                                channels: l.channels,
                                                data: l.data.clone(),
                                            },
                                        )
                                    })
                                })
                                .collect());
                        };
                        // A filtered layer reaches the footprint around its tiles.
                        let grow = footprint_radius(iterations).div_ceil(TILE as usize);
                        let rows = self.hi + 1 - self.lo;
                        let mut reach = vec![false; window_tiles];
                        let mut on = vec![false; window_tiles];
                        for &(at, _) in tiles.iter() {
                            on[at] = true;
                            let (cx, cy) = (at % tx, at / tx);
                            for y in cy.saturating_sub(grow)..(cy + grow + 1).min(rows) {
                                for x in cx.saturating_sub(grow)..(cx + grow + 1).min(tx) {
                                    reach[y * tx + x] = true;
                                }
                            }
                        }
                        if !reach[centre_tiles.clone()].iter().any(|r| *r) {
                            return Ok(Vec::new());
                        }
                        let w = if self.path_len[layer as usize] == 1 {
                            direct.as_ref()
                        } else {
                            bounce.as_ref()
                        }
                        .expect("weights built when filtering");
                        if scratch.is_none() {
                            *scratch = Some(SparseScratch::new(self.width * h)?);
                        }
                        let scratch = scratch.as_mut().expect("made above");
                        // Grey on every tile it is present on: filtered on one channel (the
                        // same values as each of the three; see `denoise_sparse`).
                        let c = if tiles.iter().all(|(_, l)| l.channels == 1) {
                            1
                        } else {
                            3
                        };
                        let input = scratch.input(c);
                        for &(at, l) in tiles.iter() {
                            let rect = tile_in_window(at, tx, self.width, h);
                            put_tile(input, c, self.width, rect, l);
                        }
                        let region = SparseTiles {
                            present: &on,
                            reach: &reach,
                            tiles_x: tx,
                            tile: TILE as usize,
                            rows: wanted.clone(),
                        };
                        f.filter_sparse(w, scratch, &region);
                        let filtered = scratch.output();
                        let out = centre
                            .iter()
                            .enumerate()
                            .filter_map(|(i, t)| {
                                let at = (t.rect.y0 as usize / TILE as usize - self.lo) * tx
                                    + (t.rect.x0 / TILE) as usize;
                                if !reach[at] {
                                    return None;
                                }
                                let tw = t.rect.width as usize;
                                let rows = (0..t.rect.height as usize).map(|py| {
                                    let at = ((t.rect.y0 as usize + py - y0) * self.width
                                        + t.rect.x0 as usize)
                                        * c;
                                    &filtered[at..at + tw * c]
                                });
                                // A tile the filtered layer does not reach stays out.
                                if rows.clone().all(|r| r.iter().all(|v| *v == 0.0)) {
                                    return None;
                                }
                                let mut out = Vec::with_capacity(t.rect.pixels() * c);
                                rows.for_each(|r| out.extend_from_slice(r));
                                Some((
                                    i,
                                    TileInput {
                                        layer,
                                        channels: c as u8,
                                        data: out,
                                    },
                                ))
                            })
                            .collect();
                        scratch.clear(&region, self.width, h);
                        Ok(out)
                    },
                )
                .collect()
        });
        let filter_seconds = if filtered {
            filter_start.elapsed().as_secs_f64()
        } else {
            0.0
        };
        let mut inputs: Vec<Vec<TileInput>> = centre.iter().map(|_| Vec::new()).collect();
        let mut row_values = 0usize;
        for per_tile in per_layer {
            for (col, input) in per_tile? {
                row_values += input.data.len();
                inputs[col].push(input);
            }
        }
        progress.check()?;
        self.stage(progress, Stage::Assembly);
        let finalise_start = Instant::now();
        let tallies: Vec<Result<(TileRect, TileTally)>> = pool.install(|| {
            centre
                .par_iter()
                .zip(inputs.into_par_iter())
                .map(|(t, inputs)| {
                    progress.check()?;
                    let index = (t.rect.y0 / TILE) as usize * tx + (t.rect.x0 / TILE) as usize;
                    // The tile's own features: per pixel the same as the whole frame's.
                    let surfaces = match self.lattice {
                        Some(_) => tile_surfaces(
                            &EyeFeatures::surfaces_from_window_sums(
                                self.ctx,
                                &t.features,
                                self.settings.spp,
                                (t.rect.x0 as usize, t.rect.y0 as usize),
                                (t.rect.width as usize, t.rect.height as usize),
                            ),
                            (t.rect.x0, t.rect.y0),
                            t.rect,
                        ),
                        None => Vec::new(),
                    };
                    let tally = finalise_tile(
                        builder,
                        index,
                        t.rect,
                        inputs,
                        weights,
                        self.keep_image,
                        self.lattice,
                        &surfaces,
                    )?;
                    Ok((t.rect, tally))
                })
                .collect()
        });
        let tallies = tallies.into_iter().collect::<Result<Vec<_>>>()?;
        let threads = pool.current_num_threads().max(1);
        let steps = (self.settings.denoise.direct_iterations
            + self.settings.denoise.bounce_iterations) as usize;
        // The row's f32 layers on their way to the builder, and while filtering each
        // worker's two scratch windows, the filters' weights and the features.
        let transient = row_values * 4
            + if filtered {
                2 * window_bytes * threads.min(ids.len())
                    + self.width * h * (FEATURE_STRIDE * 4 + WINDOW_FEATURE_BYTES + steps * 25 * 4)
            } else {
                0
            };
        Ok(WindowDone {
            tallies,
            transient,
            filter_seconds,
            finalise_seconds: finalise_start.elapsed().as_secs_f64(),
        })
    }
}

/// Bytes per pixel of a window's [`EyeFeatures`] (region, normal, position, footprint).
const WINDOW_FEATURE_BYTES: usize = 36;

/// What finalising a window's centre rows gave.
struct WindowDone {
    /// The centre tiles' tallies in raster order.
    tallies: Vec<(TileRect, TileTally)>,
    /// Bytes held at once beyond the traced rows and the stack.
    transient: usize,
    /// Seconds filtering (features, weights, layers).
    filter_seconds: f64,
    /// Seconds finalising the centre tiles into the stack.
    finalise_seconds: f64,
}

/// Writes `layer`'s values on the window-local tile `rect` into a window `width` pixels
/// wide of `channels` (1 or 3) per pixel; a grey tile of a layer filtered as RGB is
/// widened to three equal channels (exactly the values the RGB form would hold).
fn put_tile(
    window: &mut [f32],
    channels: usize,
    width: usize,
    rect: TileRect,
    layer: &TracedLayer,
) {
    let n = rect.width as usize;
    let from = layer.channels as usize;
    for py in 0..rect.height as usize {
        let dst = ((rect.y0 as usize + py) * width + rect.x0 as usize) * channels;
        let src = &layer.data[py * n * from..(py + 1) * n * from];
        let dst = &mut window[dst..dst + n * channels];
        if from == channels {
            dst.copy_from_slice(src);
        } else {
            for (px, v) in dst.chunks_exact_mut(channels).zip(src.chunks_exact(from)) {
                for (c, out) in px.iter_mut().enumerate() {
                    *out = v[c.min(from - 1)];
                }
            }
        }
    }
}

/// The window-local rectangle of the window's tile `at` (row-major, `tx` per row) in a
/// window of `width` × `height` pixels.
fn tile_in_window(at: usize, tx: usize, width: usize, height: usize) -> TileRect {
    let (x0, y0) = ((at % tx) * TILE as usize, (at / tx) * TILE as usize);
    TileRect {
        x0: x0 as u32,
        y0: y0 as u32,
        width: (TILE as usize).min(width - x0) as u32,
        height: (TILE as usize).min(height - y0) as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn traced(channels: u8, data: Vec<f32>) -> TracedLayer {
        TracedLayer {
            id: 0,
            channels,
            data,
        }
    }

    /// A grey tile put into an RGB window holds what its RGB form would; a tile of the
    /// window's own channels is copied; nothing outside the tile is written.
    #[test]
    fn a_grey_tile_in_an_rgb_window_is_its_rgb_form() {
        let (width, height) = (40usize, 20usize);
        let rect = tile_in_window(2, 3, width, height);
        assert_eq!((rect.x0, rect.width, rect.height), (32, 8, 16));
        let grey: Vec<f32> = (0..rect.pixels()).map(|i| i as f32 * 0.5 - 3.0).collect();
        let rgb: Vec<f32> = grey.iter().flat_map(|v| [*v; 3]).collect();
        let mut from_grey = vec![0.0f32; width * height * 3];
        put_tile(&mut from_grey, 3, width, rect, &traced(1, grey.clone()));
        let mut from_rgb = vec![0.0f32; width * height * 3];
        put_tile(&mut from_rgb, 3, width, rect, &traced(3, rgb));
        assert_eq!(from_grey, from_rgb);
        let mut one = vec![0.0f32; width * height];
        put_tile(&mut one, 1, width, rect, &traced(1, grey));
        for y in 0..height {
            for x in 0..width {
                let inside = x >= 32 && y < 16;
                let v = one[y * width + x];
                assert_eq!(v != 0.0 || (x == 38 && y == 0), inside, "({x}, {y})");
                for c in 0..3 {
                    assert_eq!(from_grey[(y * width + x) * 3 + c].to_bits(), v.to_bits());
                }
            }
        }
    }
}

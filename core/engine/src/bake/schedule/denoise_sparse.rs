//! The denoiser on one layer of a streaming bake's window, computing only where the layer
//! can be non-zero and only the rows the finalised tiles need ([`EyeFeatures::filter_sparse`]).
//!
//! A layer is filtered with the channels it has: one where every tile it is present on
//! holds it grey (equal R, G and B), else three. Each channel runs the same taps in the
//! same order on the same weights, so a grey layer filtered on one channel gives, bit for
//! bit, the first channel of the same layer filtered as RGB (and R, G and B of that are
//! equal), at a third of the work and of the memory. Grey layers are filtered eight pixels
//! of a row at a time where the CPU has AVX2 (`grey_run`), with the same arithmetic per
//! pixel, so the same bits.

use std::ops::Range;

mod grey_run;

use crate::bake::finish::denoise::{footprint_radius, step_rows, EyeFeatures, FilterWeights};
use grey_run::{GreyRun, Taps, LANES};

impl EyeFeatures {
    /// [`Self::filter_one`] of a layer of `scratch.channels()` channels that is zero outside
    /// the tiles `region.reach` marks, computing only what the rows `region.rows` need: at
    /// step k the pixels of the reached tiles on [`step_rows`] (the wanted rows widened by
    /// the taps of the steps after k). The layer comes in [`SparseScratch::input`] (zero
    /// outside its tiles) and its filtered rows are in [`SparseScratch::output`] afterwards.
    ///
    /// Why the wanted rows come out bit for bit as [`Self::filter_one`] gives them: each
    /// computed pixel runs the same taps in the same order on the same weights and the same
    /// values. A pixel it reads that lies outside the reached tiles is zero in both (the
    /// filter is linear with weights from the features only: a pixel farther than the
    /// footprint from every non-zero one stays zero), and a pixel it reads inside them was
    /// computed at the step before, since the rows of step k − 1 cover step k's taps.
    /// Skipping a tap on a zero value changes no sum: adding +0 leaves any sum but −0 as it
    /// was, and a sum starting at +0 never becomes −0.
    pub fn filter_sparse(
        &self,
        weights: &FilterWeights,
        scratch: &mut SparseScratch,
        region: &SparseTiles,
    ) {
        match scratch.channels {
            1 => self.filter_sparse_channels::<1>(weights, scratch, region),
            _ => self.filter_sparse_channels::<3>(weights, scratch, region),
        }
    }

    fn filter_sparse_channels<const C: usize>(
        &self,
        weights: &FilterWeights,
        scratch: &mut SparseScratch,
        region: &SparseTiles,
    ) {
        let iterations = weights.steps.len() as u32;
        scratch.result_in_b = false;
        for (k, w) in weights.steps.iter().enumerate() {
            let step = 1usize << k;
            let rows = step_rows(&region.rows, k as u32, iterations, self.height);
            let read = rows.start.saturating_sub(2 * step)..(rows.end + 2 * step).min(self.height);
            // Where the layer can be non-zero after this step: within the reach of the
            // steps so far (2·step each) of the tiles it is present on.
            let rects =
                region.reached_rects(footprint_radius(k as u32 + 1), self.width, self.height);
            let (src, out) = if scratch.result_in_b {
                (&scratch.b, &mut scratch.a)
            } else {
                (&scratch.a, &mut scratch.b)
            };
            // Regions the layer is non-zero on among the pixels this step reads (weights
            // never cross regions, so the others' pixels keep their value).
            let mut live = vec![false; self.region_count];
            for_each_pixel(&rects, self.width, &read, |p| {
                if let Some(r) = self.region[p] {
                    if !live[r as usize] && src[p * C..p * C + C].iter().any(|v| *v != 0.0) {
                        live[r as usize] = true;
                    }
                }
            });
            let taps = Taps::new(self.width, step);
            let computed =
                |p: usize| w[p][12] != 0.0 && self.region[p].is_some_and(|r| live[r as usize]);
            // Grey layers (most) eight pixels of a row at a time where the CPU can.
            let runs = if C == 1 { GreyRun::detect() } else { None };
            for_each_run(&rects, self.width, &rows, |start, end| {
                let mut p = start;
                if let Some(run) = runs {
                    while p + LANES <= end {
                        let lanes: [bool; LANES] = std::array::from_fn(|i| computed(p + i));
                        if !lanes.iter().any(|c| *c) {
                            out[p..p + LANES].copy_from_slice(&src[p..p + LANES]);
                        } else if !run.filter8(w, src, out, &taps, p, lanes) {
                            for q in p..p + LANES {
                                filter_pixel::<C>(w, src, out, &taps, q, computed(q));
                            }
                        }
                        p += LANES;
                    }
                }
                for q in p..end {
                    filter_pixel::<C>(w, src, out, &taps, q, computed(q));
                }
            });
            scratch.result_in_b = !scratch.result_in_b;
        }
    }
}

/// A rectangle of pixels: columns `x0..x1`, rows `y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

/// One pixel of one step of the filter (`computed`: the filter changes it; else it keeps
/// its value): from +0, `acc += weight · value` over the taps whose weight is not 0, in
/// order.
#[inline(always)]
fn filter_pixel<const C: usize>(
    w: &[[f32; 25]],
    src: &[f32],
    out: &mut [f32],
    taps: &Taps,
    p: usize,
    computed: bool,
) {
    if !computed {
        out[p * C..p * C + C].copy_from_slice(&src[p * C..p * C + C]);
        return;
    }
    let mut acc = [0.0f32; C];
    for (&wt, &offset) in w[p].iter().zip(&taps.offsets) {
        if wt == 0.0 {
            continue;
        }
        // A tap with a weight lies inside the window.
        let q = (p as isize + offset) as usize * C;
        for (a, v) in acc.iter_mut().zip(&src[q..q + C]) {
            *a += wt * v;
        }
    }
    out[p * C..p * C + C].copy_from_slice(&acc);
}

/// Calls `f(start, end)` with the pixel indices `start..end` of each row of the `rects` on
/// the pixel rows `rows`.
fn for_each_run(
    rects: &[PixelRect],
    width: usize,
    rows: &Range<usize>,
    mut f: impl FnMut(usize, usize),
) {
    for r in rects {
        for y in r.y0.max(rows.start)..r.y1.min(rows.end) {
            f(y * width + r.x0, y * width + r.x1);
        }
    }
}

/// Calls `f` with every pixel index of the `rects` on the pixel rows `rows`.
fn for_each_pixel(
    rects: &[PixelRect],
    width: usize,
    rows: &Range<usize>,
    mut f: impl FnMut(usize),
) {
    for r in rects {
        for y in r.y0.max(rows.start)..r.y1.min(rows.end) {
            for x in r.x0..r.x1 {
                f(y * width + x);
            }
        }
    }
}

/// Where one layer may be non-zero on a window once filtered, and which rows are wanted
/// ([`EyeFeatures::filter_sparse`]).
pub struct SparseTiles<'a> {
    /// Per tile of the window, row-major: whether the layer is non-zero there (it is zero
    /// on every other tile).
    pub present: &'a [bool],
    /// Per tile of the window, row-major: whether the layer may be non-zero there once
    /// filtered (the present tiles and those within the filter's footprint of them).
    pub reach: &'a [bool],
    pub tiles_x: usize,
    /// Tile side in pixels (the last column and row cut by the window's edges).
    pub tile: usize,
    /// The window's pixel rows whose filtered values are wanted.
    pub rows: Range<usize>,
}

impl SparseTiles<'_> {
    /// Per reached tile, the pixels within `radius` of a present tile (the bounding box of
    /// that part of the tile): a superset of where the layer can be non-zero once filtered
    /// with a footprint of `radius`, growing with it.
    fn reached_rects(&self, radius: usize, width: usize, height: usize) -> Vec<PixelRect> {
        let t = self.tile;
        let tiles_y = self.reach.len() / self.tiles_x.max(1);
        let grow = radius.div_ceil(t);
        let mut rects = Vec::new();
        for (i, _) in self.reach.iter().enumerate().filter(|(_, r)| **r) {
            let (cx, cy) = (i % self.tiles_x, i / self.tiles_x);
            let tile = PixelRect {
                x0: cx * t,
                x1: ((cx + 1) * t).min(width),
                y0: cy * t,
                y1: ((cy + 1) * t).min(height),
            };
            let mut bbox: Option<PixelRect> = None;
            for py in cy.saturating_sub(grow)..(cy + grow + 1).min(tiles_y) {
                for px in cx.saturating_sub(grow)..(cx + grow + 1).min(self.tiles_x) {
                    if !self.present[py * self.tiles_x + px] {
                        continue;
                    }
                    let near = PixelRect {
                        x0: (px * t).saturating_sub(radius).max(tile.x0),
                        x1: ((px + 1) * t + radius).min(tile.x1),
                        y0: (py * t).saturating_sub(radius).max(tile.y0),
                        y1: ((py + 1) * t + radius).min(tile.y1),
                    };
                    if near.x0 >= near.x1 || near.y0 >= near.y1 {
                        continue;
                    }
                    bbox = Some(match bbox {
                        None => near,
                        Some(b) => PixelRect {
                            x0: b.x0.min(near.x0),
                            x1: b.x1.max(near.x1),
                            y0: b.y0.min(near.y0),
                            y1: b.y1.max(near.y1),
                        },
                    });
                }
            }
            rects.extend(bbox);
        }
        rects
    }
}

/// Two window-sized buffers of up to three channels that [`EyeFeatures::filter_sparse`]
/// steps between, reused from layer to layer: a layer only writes the tiles it reaches,
/// and [`Self::clear`] zeroes those again, so a reused buffer costs what the layer covers,
/// not the window. A one-channel layer uses the first third of each.
pub struct SparseScratch {
    a: Vec<f32>,
    b: Vec<f32>,
    pixels: usize,
    /// Channels of the layer in the buffers: 1 or 3.
    channels: usize,
    result_in_b: bool,
}

impl SparseScratch {
    /// Zeroed buffers for a window of `pixels` pixels.
    pub fn new(pixels: usize) -> crate::Result<SparseScratch> {
        Ok(SparseScratch {
            a: crate::memory::try_zeroed(pixels * 3, "a denoiser window's layer")?,
            b: crate::memory::try_zeroed(pixels * 3, "a denoiser window's layer")?,
            pixels,
            channels: 3,
            result_in_b: false,
        })
    }

    /// Where the next layer to filter is put, with `channels` (1 or 3) interleaved per
    /// pixel (zero outside the tiles it reaches).
    pub fn input(&mut self, channels: usize) -> &mut [f32] {
        self.channels = if channels == 1 { 1 } else { 3 };
        self.result_in_b = false;
        &mut self.a[..self.pixels * self.channels]
    }

    /// Channels of the layer in the buffers.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The filtered layer after [`EyeFeatures::filter_sparse`] (the input if it had no
    /// step), [`Self::channels`] per pixel.
    pub fn output(&self) -> &[f32] {
        let n = self.pixels * self.channels;
        if self.result_in_b {
            &self.b[..n]
        } else {
            &self.a[..n]
        }
    }

    /// Zeroes the `tiles` of both buffers (the tiles a layer reached) for the next layer.
    pub fn clear(&mut self, region: &SparseTiles, width: usize, height: usize) {
        let t = region.tile;
        let c = self.channels;
        let tiles: Vec<PixelRect> = region
            .reach
            .iter()
            .enumerate()
            .filter(|(_, r)| **r)
            .map(|(i, _)| {
                let (cx, cy) = (i % region.tiles_x, i / region.tiles_x);
                PixelRect {
                    x0: cx * t,
                    x1: ((cx + 1) * t).min(width),
                    y0: cy * t,
                    y1: ((cy + 1) * t).min(height),
                }
            })
            .collect();
        for buf in [&mut self.a, &mut self.b] {
            for r in &tiles {
                for y in r.y0..r.y1 {
                    buf[(y * width + r.x0) * c..(y * width + r.x1) * c].fill(0.0);
                }
            }
        }
        self.result_in_b = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::finish::denoise::tests::{layer, noise, two_walls};

    /// The tiles of a `w`×`h` window (`tile` pixels a side) a layer present on `present`
    /// reaches once filtered with `iterations` steps, and the present ones.
    fn reach_of(
        present: &[(usize, usize)],
        (w, h, tile): (usize, usize, usize),
        iterations: u32,
    ) -> (Vec<bool>, Vec<bool>) {
        let (tx, ty) = (w.div_ceil(tile), h.div_ceil(tile));
        let grow = footprint_radius(iterations).div_ceil(tile);
        let mut reach = vec![false; tx * ty];
        let mut present_mask = vec![false; tx * ty];
        for &(cx, cy) in present {
            present_mask[cy * tx + cx] = true;
            for y in cy.saturating_sub(grow)..(cy + grow + 1).min(ty) {
                for x in cx.saturating_sub(grow)..(cx + grow + 1).min(tx) {
                    reach[y * tx + x] = true;
                }
            }
        }
        (present_mask, reach)
    }

    /// A layer of `channels` channels non-zero (noise) on the `present` tiles.
    fn tiles_of_noise(
        present: &[(usize, usize)],
        (w, h, tile): (usize, usize, usize),
        channels: usize,
    ) -> Vec<f32> {
        let mut data = vec![0.0f32; w * h * channels];
        for &(cx, cy) in present {
            for y in cy * tile..((cy + 1) * tile).min(h) {
                for x in cx * tile..((cx + 1) * tile).min(w) {
                    for c in 0..channels {
                        let i = (y * w + x) * channels + c;
                        data[i] = noise(i) + c as f32;
                    }
                }
            }
        }
        data
    }

    /// A layer non-zero on a few 8-px tiles of a 40×30 window, filtered sparsely for some
    /// wanted rows, equals the whole-window filter on those rows bit for bit, with one
    /// channel or three.
    #[test]
    fn the_sparse_filter_gives_the_whole_filter_on_the_wanted_rows() {
        let (w, h, tile) = (40, 30, 8);
        let f = two_walls(w, h);
        let tx = w.div_ceil(tile);
        let present = [(0, 1), (2, 2), (4, 0), (3, 3)];
        let mut scratch = SparseScratch::new(w * h).unwrap();
        for channels in [3usize, 1] {
            let data = tiles_of_noise(&present, (w, h, tile), channels);
            for iterations in 1..=3u32 {
                let (present_mask, reach) = reach_of(&present, (w, h, tile), iterations);
                let mut whole = layer(data.clone(), channels as u32);
                f.filter_one(&f.weights_for(iterations), &mut whole);
                for wanted in [6..14, 0..30, 22..30] {
                    let region = SparseTiles {
                        present: &present_mask,
                        reach: &reach,
                        tiles_x: tx,
                        tile,
                        rows: wanted.clone(),
                    };
                    scratch.input(channels).copy_from_slice(&data);
                    f.filter_sparse(
                        &f.weights_for_rows(iterations, wanted.clone()),
                        &mut scratch,
                        &region,
                    );
                    let span = wanted.start * w * channels..wanted.end * w * channels;
                    let got = &scratch.output()[span.clone()];
                    let want = &whole.data[span];
                    assert!(want.iter().any(|v| *v != 0.0));
                    for (i, (a, b)) in got.iter().zip(want).enumerate() {
                        assert_eq!(
                            a.to_bits(),
                            b.to_bits(),
                            "{channels} channels, {iterations} steps, rows {wanted:?}, value {i}"
                        );
                    }
                    // Clearing leaves the scratch zero for the next layer, whatever its
                    // channels.
                    scratch.clear(&region, w, h);
                    assert!(scratch.a.iter().all(|v| *v == 0.0));
                    assert!(scratch.b.iter().all(|v| *v == 0.0));
                }
            }
        }
    }

    /// A grey layer filtered on one channel is, bit for bit, each channel of the same
    /// layer filtered as RGB: the filter treats channels alike and apart.
    #[test]
    fn a_grey_layer_on_one_channel_is_each_channel_of_it_as_rgb() {
        let (w, h, tile) = (40, 30, 8);
        let f = two_walls(w, h);
        let tx = w.div_ceil(tile);
        let present = [(1, 1), (2, 1), (4, 3)];
        let grey = tiles_of_noise(&present, (w, h, tile), 1);
        let rgb: Vec<f32> = grey.iter().flat_map(|v| [*v; 3]).collect();
        let (present_mask, reach) = reach_of(&present, (w, h, tile), 3);
        let region = SparseTiles {
            present: &present_mask,
            reach: &reach,
            tiles_x: tx,
            tile,
            rows: 8..24,
        };
        let weights = f.weights_for_rows(3, 8..24);
        let mut one = SparseScratch::new(w * h).unwrap();
        one.input(1).copy_from_slice(&grey);
        f.filter_sparse(&weights, &mut one, &region);
        let mut three = SparseScratch::new(w * h).unwrap();
        three.input(3).copy_from_slice(&rgb);
        f.filter_sparse(&weights, &mut three, &region);
        assert_eq!((one.channels(), three.channels()), (1, 3));
        let mut changed = false;
        let wanted = 8 * w..24 * w;
        let rgb_out = three.output()[wanted.start * 3..wanted.end * 3].chunks_exact(3);
        for ((v, before), rgb) in one.output()[wanted.clone()]
            .iter()
            .zip(&grey[wanted.clone()])
            .zip(rgb_out)
        {
            changed |= v != before;
            for c in rgb {
                assert_eq!(v.to_bits(), c.to_bits());
            }
        }
        assert!(changed, "the filter changed nothing");
    }
}

//! The non-zero samples of every layer repacked row by row for the sum.
//!
//! A stack keeps each layer as its own image; summing them row by row jumps between ~180
//! separate arrays per image row (one per layer with pixels there), which defeats the
//! hardware prefetcher and left the sum several times above the memory-bandwidth bound
//! (`docs/measurements.md`). Repacked, the non-zero span of every (row, layer) lies back to
//! back in row order, so a full relight reads one array front to back while one image row
//! (16 bytes a pixel, 8 KiB at 512 pixels) stays in L1. Building it costs one pass over the stack at load.

use half::f16;

use super::kernels::Kernels;
use super::spans::LayerPlan;
use crate::stack::{LayerSamples, TransferStack};
use crate::Rgb;

/// One (row, layer) span.
#[derive(Clone, Copy, Debug)]
struct Span {
    layer: u32,
    x0: u32,
    len: u32,
    grey: bool,
    /// Offset of the span's first value in `halves` (f16 layers) or `floats` (f32 layers).
    offset: usize,
    half: bool,
}

/// Layer samples in row order.
pub(crate) struct PackedRows {
    halves: Vec<f16>,
    floats: Vec<f32>,
    spans: Vec<Span>,
    /// Spans of row y are `spans[row_start[y]..row_start[y + 1]]`.
    row_start: Vec<usize>,
    width: usize,
    layer_bytes: Vec<usize>,
}

impl PackedRows {
    /// Bytes of samples stored for layer `l` (what a sum that includes it reads).
    pub(crate) fn layer_bytes(&self, l: usize) -> usize {
        self.layer_bytes[l]
    }

    /// Repacks the non-zero spans described by `plans`.
    pub(crate) fn build(
        stack: &TransferStack,
        plans: &[LayerPlan],
        width: usize,
        height: usize,
    ) -> PackedRows {
        let mut halves = Vec::new();
        let mut floats = Vec::new();
        let mut spans = Vec::new();
        let mut row_start = Vec::with_capacity(height + 1);
        let mut layer_bytes = vec![0usize; stack.layers.len()];
        for y in 0..height {
            row_start.push(spans.len());
            for (l, layer) in stack.layers.iter().enumerate() {
                let [x0, x1] = plans[l].spans[y];
                if x0 >= x1 {
                    continue;
                }
                // Widen to whole groups of 8 pixels (the zeros added cost a few bytes and
                // spare the kernels a scalar tail on every span).
                let x0 = x0 / 8 * 8;
                let x1 = (x1.div_ceil(8) * 8).min(width as u32);
                let ch = layer.channels as usize;
                let range = (y * width + x0 as usize) * ch..(y * width + x1 as usize) * ch;
                let (offset, half) = match &layer.samples {
                    LayerSamples::F16(v) => {
                        halves.extend_from_slice(&v[range]);
                        (halves.len() - (x1 - x0) as usize * ch, true)
                    }
                    LayerSamples::F32(v) => {
                        floats.extend_from_slice(&v[range]);
                        (floats.len() - (x1 - x0) as usize * ch, false)
                    }
                };
                layer_bytes[l] += (x1 - x0) as usize * ch * if half { 2 } else { 4 };
                spans.push(Span {
                    layer: l as u32,
                    x0,
                    len: x1 - x0,
                    grey: ch == 1,
                    offset,
                    half,
                });
            }
        }
        row_start.push(spans.len());
        PackedRows {
            halves,
            floats,
            spans,
            row_start,
            width,
            layer_bytes,
        }
    }

    /// Adds `weights[layer] · samples` into `out`, the RGBA rows starting at row `y0`, for
    /// every span whose weight is non-zero and whose layer passes `include` (all when `None`).
    ///
    /// Per row, grey spans accumulate into planar R, G, B rows and RGB spans into an
    /// interleaved RGB row (no shuffles in the inner loops), merged into RGBA at the end.
    pub(crate) fn add_rows(
        &self,
        out: &mut [f32],
        y0: usize,
        weights: &[Rgb],
        include: Option<&[bool]>,
        kernels: Kernels,
    ) {
        let width = self.width;
        let rows = out.len() / (4 * width).max(1);
        let mut scratch = vec![0.0f32; 6 * width];
        for dy in 0..rows {
            let y = y0 + dy;
            scratch.fill(0.0);
            let (planar, rgb) = scratch.split_at_mut(3 * width);
            let (r, gb) = planar.split_at_mut(width);
            let (g, b) = gb.split_at_mut(width);
            for s in &self.spans[self.row_start[y]..self.row_start[y + 1]] {
                let l = s.layer as usize;
                if include.is_some_and(|inc| !inc[l]) {
                    continue;
                }
                let w = weights[l];
                if w == Rgb::ZERO {
                    continue;
                }
                let w = w.to_array();
                let (x0, x1) = (s.x0 as usize, (s.x0 + s.len) as usize);
                if s.grey {
                    let (r, g, b) = (&mut r[x0..x1], &mut g[x0..x1], &mut b[x0..x1]);
                    if s.half {
                        kernels.add_grey_planar(
                            r,
                            g,
                            b,
                            &self.halves[s.offset..s.offset + s.len as usize],
                            w,
                        );
                    } else {
                        kernels.add_grey_planar(
                            r,
                            g,
                            b,
                            &self.floats[s.offset..s.offset + s.len as usize],
                            w,
                        );
                    }
                } else {
                    let acc = &mut rgb[3 * x0..3 * x1];
                    let n = 3 * s.len as usize;
                    if s.half {
                        kernels.add_rgb_interleaved(acc, &self.halves[s.offset..s.offset + n], w);
                    } else {
                        kernels.add_rgb_interleaved(acc, &self.floats[s.offset..s.offset + n], w);
                    }
                }
            }
            let row = &mut out[dy * width * 4..(dy + 1) * width * 4];
            for ((px, c), ((rr, gg), bb)) in row
                .chunks_exact_mut(4)
                .zip(rgb.chunks_exact(3))
                .zip(r.iter().zip(g.iter()).zip(b.iter()))
            {
                px[0] += rr + c[0];
                px[1] += gg + c[1];
                px[2] += bb + c[2];
            }
        }
    }
}

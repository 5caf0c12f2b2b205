//! The non-zero span of every row of a layer, found once when a CPU relighter is built so
//! the sums read only those spans; the same scan checks that every sample is finite.

use crate::stack::{Layer, LayerSamples};
use crate::{RelumeError, Result};

/// Per-layer preparation.
pub(crate) struct LayerPlan {
    /// Per row, the span `[x0, x1)` of pixels with a non-zero sample; `x0 == x1` if none.
    pub(crate) spans: Vec<[u32; 2]>,
}

/// Scans a layer: non-zero span of every row, and finiteness of every sample.
pub(crate) fn plan_layer(layer: &Layer, width: usize, height: usize) -> Result<LayerPlan> {
    let ch = layer.channels as usize;
    let row_len = width * ch;
    let mut spans = Vec::with_capacity(height);
    for y in 0..height {
        let row = y * row_len..(y + 1) * row_len;
        // (first, last) non-zero sample index in the row, or the first non-finite one.
        let scan = match &layer.samples {
            LayerSamples::F16(v) => scan_row(&v[row], |h| {
                let b = h.to_bits();
                (b & 0x7fff != 0, b & 0x7c00 != 0x7c00)
            }),
            LayerSamples::F32(v) => scan_row(&v[row], |&x| (x != 0.0, x.is_finite())),
        };
        let (first, last) = match scan {
            Ok(s) => s,
            Err(i) => {
                return Err(RelumeError::NonFinite {
                    what: format!(
                        "layer {}, pixel ({}, {y}) channel {}",
                        layer.key.layer_name(),
                        i / ch,
                        i % ch
                    ),
                })
            }
        };
        let span = match (first, last) {
            (Some(f), Some(l)) => [(f / ch) as u32, (l / ch + 1) as u32],
            _ => [0, 0],
        };
        spans.push(span);
    }
    Ok(LayerPlan { spans })
}

/// `Ok((first non-zero, last non-zero))` sample positions of a row, or `Err(position)` of
/// its first non-finite sample. `test` gives (non-zero, finite).
#[allow(clippy::type_complexity)]
fn scan_row<T>(
    row: &[T],
    test: impl Fn(&T) -> (bool, bool),
) -> Result<(Option<usize>, Option<usize>), usize> {
    let mut first = None;
    let mut last = None;
    for (i, s) in row.iter().enumerate() {
        let (nz, finite) = test(s);
        if !finite {
            return Err(i);
        }
        if nz {
            first.get_or_insert(i);
            last = Some(i);
        }
    }
    Ok((first, last))
}

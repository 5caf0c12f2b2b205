//! The CPU's [`LayerSum`]: the packed non-zero spans of every layer, summed in row bands in
//! parallel.
//!
//! The sum is memory-bound, so the work is arranged to read each needed sample once and
//! nothing else:
//! - **Row bands in parallel.** The image is cut in bands of [`BAND_ROWS`] rows, one rayon
//!   task each; inside a band every layer touching it is added row by row into the band's
//!   RGBA output (16 rows × 512 px × 16 B = 128 KiB, which stays in L2 while 16 KiB–48 KiB
//!   of each layer streams through).
//! - **Zero spans skipped.** When the relighter is built, each layer row gets the span
//!   `[x0, x1)` of its non-zero pixels (`spans.rs`); rows that are all zero are skipped,
//!   and so are the zero ends of the others. A layer whose path starts at a region that
//!   covers a quarter of the frame costs about a quarter of its bytes.
//! - **Zero weights skipped.** A layer whose weight is 0 (say every specular basis of a
//!   region with `Ks = 0`) is not read at all.
//! - **Fast inner loops** (`kernels.rs`): AVX2 + FMA + F16C where the CPU has them
//!   (detected at run time), converting f16 in registers.
//!
//! In the test profile (debug assertions on) the intrinsics carry UB checks and the sum is
//! several times slower: time release builds only. Measured figures are in
//! `docs/measurements.md`.

use rayon::prelude::*;

use crate::stack::TransferStack;
use crate::{RelumeError, Result, Rgb};

use super::kernels::Kernels;
use super::layer_sum::{LayerSum, RelightStats};
use super::packed::PackedRows;
use super::spans::plan_layer;

/// Rows per parallel task. 512 rows give 32 tasks: enough for rayon to balance two to
/// sixteen threads when the layers cover the frame unevenly, while each task still reads
/// 16 rows (16–48 KiB) of a layer in one contiguous stretch.
pub const BAND_ROWS: usize = 16;

/// The layers of one stack packed for the CPU sum, and the image they sum to.
pub(crate) struct BandSum {
    width: usize,
    /// The non-zero samples in row order (what the sums read).
    packed: PackedRows,
    kernels: Kernels,
    /// RGBA f32, alpha 1.
    image: Vec<f32>,
    /// Scratch of an incremental sum: whether each layer is among those to add.
    member: Vec<bool>,
}

impl BandSum {
    /// Scans every layer (non-zero spans, finite samples) and packs the non-zero spans.
    /// The stack's shape must have been checked ([`super::StackShape::new`]).
    pub(crate) fn new(
        stack: &TransferStack,
        width: usize,
        height: usize,
        kernels: Kernels,
    ) -> Result<BandSum> {
        let plans = stack
            .layers
            .par_iter()
            .map(|l| plan_layer(l, width, height))
            .collect::<Result<Vec<_>>>()?;
        let packed = PackedRows::build(stack, &plans, width, height);
        let mut image = vec![0.0f32; width * height * 4];
        image.chunks_exact_mut(4).for_each(|p| p[3] = 1.0);
        Ok(BandSum {
            width,
            packed,
            kernels,
            image,
            member: vec![false; stack.layers.len()],
        })
    }

    /// Layers with a non-zero weight and samples, and their bytes.
    fn stats(&self, layers: impl Iterator<Item = usize>, effective: &[Rgb]) -> RelightStats {
        let mut stats = RelightStats::default();
        for l in layers {
            if effective[l] != Rgb::ZERO && self.packed.layer_bytes(l) > 0 {
                stats.layers_summed += 1;
                stats.bytes_read += self.packed.layer_bytes(l);
            }
        }
        stats
    }
}

impl LayerSum for BandSum {
    type Error = RelumeError;

    fn full(&mut self, effective: &[Rgb]) -> Result<RelightStats> {
        let stats = self.stats(0..effective.len(), effective);
        sum_bands(
            &mut self.image,
            self.width,
            &self.packed,
            effective,
            None,
            true,
            self.kernels,
        );
        Ok(stats)
    }

    fn incremental(&mut self, layers: &[u32], effective: &[Rgb]) -> Result<RelightStats> {
        let stats = self.stats(layers.iter().map(|&l| l as usize), effective);
        layers.iter().for_each(|&l| self.member[l as usize] = true);
        sum_bands(
            &mut self.image,
            self.width,
            &self.packed,
            effective,
            Some(&self.member),
            false,
            self.kernels,
        );
        layers.iter().for_each(|&l| self.member[l as usize] = false);
        Ok(stats)
    }

    fn image(&self) -> &[f32] {
        &self.image
    }
}

/// Adds `weights[l] · layer l` for the layers listed per band into `image` (RGBA).
/// With `reset`, each band is first set to (0, 0, 0, 1).
#[allow(clippy::too_many_arguments)]
fn sum_bands(
    image: &mut [f32],
    width: usize,
    packed: &PackedRows,
    weights: &[Rgb],
    include: Option<&[bool]>,
    reset: bool,
    kernels: Kernels,
) {
    let band_len = (BAND_ROWS * width * 4).max(4);
    image
        .par_chunks_mut(band_len)
        .enumerate()
        .for_each(|(b, out)| {
            if reset {
                out.chunks_exact_mut(4)
                    .for_each(|p| p.copy_from_slice(&[0.0, 0.0, 0.0, 1.0]));
            }
            packed.add_rows(out, b * BAND_ROWS, weights, include, kernels);
        });
}

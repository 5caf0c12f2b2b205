//! [`CpuRelighter`]: the relight bookkeeping paired with the CPU's tiled sum.

use std::sync::Arc;

use crate::stack::tiled::TiledStack;
use crate::stack::{LayerSamples, Precision, TransferStack};
use crate::{RelumeError, Result, Rgb};

use super::bookkeeping::RelightBookkeeping;
use super::cpu_sum::TiledLayerSum;
use super::kernels::Kernels;
use super::layer_sum::{LayerSum, RelightStats};

/// The CPU relighter of one stack, summing the tiled layout ([`TiledStack`]) it shares with
/// the loader through an `Arc`: it keeps no copy of the samples. Build it once per loaded
/// stack, then call [`relight`](Self::relight) and [`relight_region`](Self::relight_region)
/// per edit.
pub struct CpuRelighter {
    book: RelightBookkeeping,
    sum: TiledLayerSum,
}

impl CpuRelighter {
    /// The relighter of a dense stack, for callers that hold one (tests, older code): the
    /// stack is checked, then converted once to the tiled layout
    /// ([`TiledStack::from_dense`]), which the relighter keeps instead. The dense stack is
    /// not retained; while the caller keeps its `Arc` both layouts are in memory, so
    /// loaders should read the tiled layout directly and use [`from_tiled`](Self::from_tiled).
    ///
    /// Errors: a layer whose sample count is not width·height·channels, whose channel
    /// count is not 1 or 3, whose key names an editable region or a light group the header
    /// does not have, or which holds a non-finite sample or scale.
    pub fn new(stack: Arc<TransferStack>) -> Result<Self> {
        Self::with_kernels(stack, Kernels::detect())
    }

    /// The relighter of a tiled stack (as [`crate::stack::tiled::file::read_tiled`] or a
    /// bake gives it), shared, not copied.
    ///
    /// Errors: a layer whose channel count is not 1 or 3, whose key names an editable
    /// region or a light group the header does not have, a non-finite layer scale, a tile
    /// table that does not match the header's size.
    pub fn from_tiled(stack: Arc<TiledStack>) -> Result<Self> {
        Self::tiled_with_kernels(stack, Kernels::detect())
    }

    pub(crate) fn with_kernels(stack: Arc<TransferStack>, kernels: Kernels) -> Result<Self> {
        // The shape and finiteness first, so a bad dense stack is refused in the words of
        // the dense layout (layer, pixel) rather than of its tiles.
        RelightBookkeeping::new(&stack)?;
        check_finite_samples(&stack)?;
        let tiled = match uniform_precision(&stack) {
            None => TiledStack::from_dense(&stack)?,
            Some(f32_copy) => TiledStack::from_dense(&f32_copy)?,
        };
        Self::tiled_with_kernels(Arc::new(tiled), kernels)
    }

    fn tiled_with_kernels(stack: Arc<TiledStack>, kernels: Kernels) -> Result<Self> {
        let book = RelightBookkeeping::from_tiled(&stack)?;
        if stack.tiles.len() != stack.tile_count() {
            return Err(RelumeError::invalid(
                "tiled stack",
                format!(
                    "{} tiles; its size needs {}",
                    stack.tiles.len(),
                    stack.tile_count()
                ),
            ));
        }
        let sum = TiledLayerSum::new(stack, kernels)?;
        Ok(CpuRelighter { book, sum })
    }

    /// Bytes the relighter holds besides the stack it shares: the image, the layer weights
    /// and lists. A relight's memory is this plus [`TiledStack::memory_bytes`].
    pub fn own_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.book.heap_bytes() + self.sum.heap_bytes()
    }

    /// Number of editable regions (those of `stack.header.regions` with `editable`).
    pub fn editable_count(&self) -> usize {
        self.book.shape().editable_count()
    }

    /// Number of bases the layers of editable region `region` use: the largest basis index
    /// in any key plus one (0 for a region no layer mentions or an index out of range).
    /// A relight accepts more coefficients than this, since a basis whose layers were all
    /// dropped as negligible leaves no key behind.
    pub fn basis_count(&self, region: usize) -> usize {
        self.book.shape().basis_count(region)
    }

    /// Image width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        self.book.shape().size()
    }

    /// The stack being relit (tiled; a dense stack given to [`new`](Self::new) was
    /// converted).
    pub fn stack(&self) -> &Arc<TiledStack> {
        self.sum.stack()
    }

    /// The current image: RGBA f32, rows top-down, alpha 1 (black before the first relight).
    pub fn image(&self) -> &[f32] {
        self.sum.image()
    }

    /// What the last relight did.
    pub fn last_stats(&self) -> RelightStats {
        self.book.last_stats()
    }

    /// Full relight: `coefs[region][basis]` RGB for every editable region. Returns the RGBA
    /// f32 image (alpha 1).
    ///
    /// Errors: not one coefficient list per editable region, fewer coefficients than the
    /// region's [`basis_count`](Self::basis_count), a non-finite coefficient.
    pub fn relight(&mut self, coefs: &[Vec<Rgb>]) -> Result<&[f32]> {
        self.book.relight(&mut self.sum, coefs)?;
        Ok(self.sum.image())
    }

    /// Light groups' live strength × colour (one RGB gain per group of the stack's
    /// `light_groups`, 1 leaves the group as baked), then a full re-sum: see
    /// [`RelightBookkeeping::set_light_group_gains`].
    pub fn set_light_group_gains(&mut self, gains: &[Rgb]) -> Result<&[f32]> {
        self.book.set_light_group_gains(&mut self.sum, gains)?;
        Ok(self.sum.image())
    }

    /// Incremental relight: only editable region `region` changed, to `coefs` (its basis
    /// coefficients). Adds `(w_new − w_old) · layer` for the layers whose key contains the
    /// region and whose weight changed; every [`super::FULL_RESUM_EVERY`]-th call re-sums
    /// all layers instead to bound float drift. Needs a full [`relight`](Self::relight)
    /// first.
    pub fn relight_region(&mut self, region: usize, coefs: &[Rgb]) -> Result<&[f32]> {
        self.book.relight_region(&mut self.sum, region, coefs)?;
        Ok(self.sum.image())
    }
}

/// Every sample of a dense stack is finite; the error names the layer, pixel and channel.
fn check_finite_samples(stack: &TransferStack) -> Result<()> {
    let width = stack.header.width as usize;
    for layer in &stack.layers {
        let bad = match &layer.samples {
            LayerSamples::F16(v) => v.iter().position(|x| !x.is_finite()),
            LayerSamples::F32(v) => v.iter().position(|x| !x.is_finite()),
        };
        if let Some(i) = bad {
            let ch = layer.channels.max(1) as usize;
            let pixel = i / ch;
            return Err(RelumeError::NonFinite {
                what: format!(
                    "layer {}, pixel ({}, {}) channel {}",
                    layer.key.layer_name(),
                    pixel % width.max(1),
                    pixel / width.max(1),
                    i % ch
                ),
            });
        }
    }
    Ok(())
}

/// A dense stack may mix f16 and f32 layers (or disagree with its header's precision) where
/// the tiled layout holds one precision: such a stack is copied with every layer in f32
/// (f16 → f32 is exact, so the relight is unchanged). `None` when it already agrees.
fn uniform_precision(stack: &TransferStack) -> Option<TransferStack> {
    let agrees = |l: &crate::stack::Layer| {
        matches!(
            (&l.samples, stack.header.precision),
            (LayerSamples::F16(_), Precision::F16) | (LayerSamples::F32(_), Precision::F32)
        )
    };
    if stack.layers.iter().all(agrees) {
        return None;
    }
    let mut copy = stack.clone();
    copy.header.precision = Precision::F32;
    for layer in &mut copy.layers {
        if let LayerSamples::F16(v) = &layer.samples {
            layer.samples = LayerSamples::F32(v.iter().map(|x| x.to_f32()).collect());
        }
    }
    Some(copy)
}

//! [`CpuRelighter`]: the relight bookkeeping paired with the CPU's band sum.

use std::sync::Arc;

use crate::stack::TransferStack;
use crate::{Result, Rgb};

use super::band_sum::BandSum;
use super::bookkeeping::RelightBookkeeping;
use super::kernels::Kernels;
use super::layer_sum::{LayerSum, RelightStats};

/// The CPU relighter of one stack. Build it once per loaded stack (the build scans every
/// sample, ≈ the cost of one relight), then call [`relight`](Self::relight) and
/// [`relight_region`](Self::relight_region) per edit.
pub struct CpuRelighter {
    book: RelightBookkeeping,
    sum: BandSum,
}

impl CpuRelighter {
    /// Checks the stack, prepares the per-editable-region layer lists, and packs the
    /// non-zero row spans of every layer.
    ///
    /// Errors: a layer whose sample count is not width·height·channels, whose channel
    /// count is not 1 or 3, whose key names an editable region or a light group the header
    /// does not have, or which holds a non-finite sample or scale.
    pub fn new(stack: Arc<TransferStack>) -> Result<Self> {
        Self::with_kernels(stack, Kernels::detect())
    }

    pub(crate) fn with_kernels(stack: Arc<TransferStack>, kernels: Kernels) -> Result<Self> {
        let book = RelightBookkeeping::new(stack)?;
        let (width, height) = book.shape().size();
        let sum = BandSum::new(book.stack(), width, height, kernels)?;
        Ok(CpuRelighter { book, sum })
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

    /// The stack being relit.
    pub fn stack(&self) -> &Arc<TransferStack> {
        self.book.stack()
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

//! The one thing a relighter's device does: sum weighted layers into an image. The
//! bookkeeping ([`super::RelightBookkeeping`]) decides which layers and which weights; a
//! [`LayerSum`] (the CPU's row bands, the GPU's kernel) only adds them up, so the two
//! relights share every rule and differ only in where the arithmetic runs.

use crate::{RelumeError, Rgb};

/// What the last relight did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RelightStats {
    /// Layers actually added (zero-weight and zero-delta layers are not).
    pub layers_summed: usize,
    /// Bytes of layer samples read (non-zero spans only).
    pub bytes_read: usize,
    /// Whether it was an incremental (delta) update.
    pub incremental: bool,
}

/// A device that sums the layers of one stack into an RGBA f32 image (rows top-down,
/// alpha 1). `effective[l]` is layer `l`'s weight times its scale; a zero one is skipped
/// unread. Each call returns what it read (`incremental` is left for the caller to set).
pub trait LayerSum {
    /// Errors of the device; the bookkeeping's own refusals convert into it.
    type Error: From<RelumeError>;

    /// Sets the image to `Σ_l effective[l] · layer l` over every layer.
    fn full(&mut self, effective: &[Rgb]) -> Result<RelightStats, Self::Error>;

    /// Adds `effective[l] · layer l` to the image for each `l` of `layers` (ascending);
    /// the other entries of `effective` are to be ignored.
    fn incremental(
        &mut self,
        layers: &[u32],
        effective: &[Rgb],
    ) -> Result<RelightStats, Self::Error>;

    /// [`incremental`](Self::incremental) for an edit of editable region `region`, whose
    /// layers `layers` are (the same list at every edit of the region): a sum may keep, per
    /// region, where those layers are. By default it does not.
    fn incremental_region(
        &mut self,
        region: usize,
        layers: &[u32],
        effective: &[Rgb],
    ) -> Result<RelightStats, Self::Error> {
        let _ = region;
        self.incremental(layers, effective)
    }

    /// The current image.
    fn image(&self) -> &[f32];
}

//! The CPU's [`LayerSum`]: [`super::tiled_sum`] over the shared [`TiledStack`], with the
//! image it sums into. It keeps no copy of the samples: the relighter's memory is the stack
//! (shared through its `Arc`), this image and a few per-layer numbers.
//!
//! The sum is memory-bound: a full relight reads every entry of a non-zero weight once (a
//! tile row per rayon task, the tile's accumulators in L1), an incremental one only the
//! changed layers' entries: for an edit of one region, from the list of that region's
//! entries per tile kept since its first edit ([`RegionEntries`]), asking the memory for the
//! next tile's listed values and pixels while it sums a tile; otherwise found per tile by
//! binary search in the tile's sorted table, or, when many layers changed, by walking the
//! table against a per-layer table of deltas.
//! In the test profile (debug assertions on) the SIMD intrinsics carry UB checks and the
//! sum is several times slower: time release builds only. Measured figures are in
//! `docs/measurements.md`.

use std::sync::Arc;

use crate::stack::tiled::TiledStack;
use crate::{Result, Rgb};

use super::kernels::Kernels;
use super::layer_sum::{LayerSum, RelightStats};
use super::region_entries::RegionEntries;
use super::tiled_sum;

/// The tiled stack, the image and the scratch of an incremental sum.
pub(crate) struct TiledLayerSum {
    stack: Arc<TiledStack>,
    kernels: Kernels,
    /// Bytes of stored values per layer id (what adding the layer reads).
    layer_bytes: Vec<usize>,
    /// RGBA f32, alpha 1.
    image: Vec<f32>,
    /// Scratch: `(layer, delta)` of an incremental sum.
    changed: Vec<(u32, Rgb)>,
    /// Per editable region, where its layers' entries are: `None` until its first edit, then
    /// `Some(None)` when the stack's tables are too large to list (its edits walk them).
    regions: Vec<Option<Option<RegionEntries>>>,
}

impl TiledLayerSum {
    /// The sum of `stack` (already validated: every constructor and the reader do), with a
    /// black image.
    /// Errors when the image cannot be allocated.
    pub(crate) fn new(stack: Arc<TiledStack>, kernels: Kernels) -> Result<TiledLayerSum> {
        let pixels = stack.header.width as usize * stack.header.height as usize;
        let mut image: Vec<f32> = crate::memory::try_zeroed(pixels * 4, "relight image")?;
        image.chunks_exact_mut(4).for_each(|px| px[3] = 1.0);
        Ok(TiledLayerSum {
            layer_bytes: stack.layer_bytes(),
            stack,
            kernels,
            image,
            changed: Vec::new(),
            regions: Vec::new(),
        })
    }

    /// The stack summed.
    pub(crate) fn stack(&self) -> &Arc<TiledStack> {
        &self.stack
    }

    /// Heap bytes besides the stack: the image, the per-layer byte counts, the scratch.
    pub(crate) fn heap_bytes(&self) -> usize {
        self.image.capacity() * 4
            + self.layer_bytes.capacity() * std::mem::size_of::<usize>()
            + self.changed.capacity() * std::mem::size_of::<(u32, Rgb)>()
            + self
                .regions
                .iter()
                .flatten()
                .flatten()
                .map(RegionEntries::heap_bytes)
                .sum::<usize>()
    }

    fn stats(&self, layers: impl Iterator<Item = usize>, effective: &[Rgb]) -> RelightStats {
        let mut stats = RelightStats::default();
        // A layer no tile holds (zero everywhere) is not added.
        for l in layers.filter(|&l| effective[l] != Rgb::ZERO && self.layer_bytes[l] > 0) {
            stats.layers_summed += 1;
            stats.bytes_read += self.layer_bytes[l];
        }
        stats
    }
}

impl LayerSum for TiledLayerSum {
    type Error = crate::RelumeError;

    fn full(&mut self, effective: &[Rgb]) -> Result<RelightStats> {
        tiled_sum::full_with(&self.stack, effective, &mut self.image, self.kernels)?;
        Ok(self.stats(0..effective.len(), effective))
    }

    fn incremental(&mut self, layers: &[u32], effective: &[Rgb]) -> Result<RelightStats> {
        self.changed.clear();
        self.changed.extend(
            layers
                .iter()
                .map(|&l| (l, effective.get(l as usize).copied().unwrap_or(Rgb::ZERO))),
        );
        tiled_sum::incremental_with(&self.stack, &self.changed, &mut self.image, self.kernels)?;
        Ok(self.stats(layers.iter().map(|&l| l as usize), effective))
    }

    fn incremental_region(
        &mut self,
        region: usize,
        layers: &[u32],
        effective: &[Rgb],
    ) -> Result<RelightStats> {
        if self.regions.len() <= region {
            self.regions.resize_with(region + 1, || None);
        }
        if self.regions[region].is_none() {
            // Built once, or found unlistable once: not tried again at every edit.
            self.regions[region] = Some(RegionEntries::build(&self.stack, layers)?);
        }
        let Some(Some(entries)) = &self.regions[region] else {
            return self.incremental(layers, effective);
        };
        tiled_sum::incremental_listed(
            &self.stack,
            entries,
            effective,
            &mut self.image,
            self.kernels,
        )?;
        Ok(self.stats(layers.iter().map(|&l| l as usize), effective))
    }

    fn image(&self) -> &[f32] {
        &self.image
    }
}

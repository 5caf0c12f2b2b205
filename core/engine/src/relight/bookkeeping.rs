//! [`RelightBookkeeping`]: everything a relighter keeps between edits apart from the image —
//! the coefficients of the current image, the weight of every layer for them, which layers
//! an edit of one region touches, and when drift calls for a full re-sum. The CPU and the GPU
//! relighters each pair one of these with their [`LayerSum`].
//!
//! **Incremental relight.** When one region's material changes, only layers whose key
//! contains that region change weight: [`RelightBookkeeping::relight_region`] hands the sum
//! `(w_new − w_old) · scale` for those layers to add to the current image. Each such update
//! rounds once more per pixel (relative ≈ 2⁻²⁴ of the largest term summed), so error grows
//! with the number of edits; every [`FULL_RESUM_EVERY`]-th edit is a full re-sum instead,
//! which keeps the drift below ≈ 64 · 6·10⁻⁸ ≈ 4·10⁻⁶ of the pixel's terms — a hundred times
//! under the f16 quantisation of the layers themselves (2⁻¹¹ ≈ 4.9·10⁻⁴).

use crate::layer_key::LayerKey;
use crate::stack::tiled::TiledStack;
use crate::stack::{StackHeader, TransferStack};
use crate::{RelumeError, Result, Rgb};

use super::layer_sum::{LayerSum, RelightStats};
use super::part_scales::{has_tail_edits, PartScales};
use super::shape::StackShape;
use super::weight::{group_factors_of, layer_weight};

/// Every this many incremental edits, [`RelightBookkeeping::relight_region`] re-sums
/// everything to bound float drift (see the module notes: ≈ 4·10⁻⁶ relative at most).
pub const FULL_RESUM_EVERY: usize = 64;

/// The weights of one stack's layers for the current materials and light gains.
pub struct RelightBookkeeping {
    /// The stack's header (its light tints and groups).
    header: StackHeader,
    /// Per layer id, its key.
    keys: Vec<LayerKey>,
    /// Per layer id, the scale the sum's samples need (the dense layer's scale; 1 for a
    /// tiled stack, whose entries carry their own scales and the sum applies them).
    scales: Vec<f32>,
    shape: StackShape,
    /// Coefficients of the current image.
    coefs: Vec<Vec<Rgb>>,
    /// The part scales of `coefs` when the stack has tail-edit layers
    /// ([`super::part_scales`]); `None` otherwise (no layer needs them).
    part_scales: Option<PartScales>,
    /// Weight × group factor of every layer for `coefs` (without the layer's scale).
    weights: Vec<Rgb>,
    /// Scratch handed to the sum: per layer, weight (or weight change) × scale.
    effective: Vec<Rgb>,
    /// Per layer-key light group (0: all lights; g + 1: group g), the colour factored out
    /// of its layers at bake time times the group's live gain.
    group_factors: Vec<Rgb>,
    /// Whether the sum's image is that of `coefs` (an incremental edit needs one).
    has_image: bool,
    edits_since_full: usize,
    stats: RelightStats,
}

impl RelightBookkeeping {
    /// Checks a dense stack ([`StackShape::new`]) and starts with no image. The weights
    /// handed to the sum include each layer's scale.
    pub fn new(stack: &TransferStack) -> Result<Self> {
        let shape = StackShape::new(stack)?;
        Self::with_layers(
            stack.header.clone(),
            stack
                .layers
                .iter()
                .map(|l| (l.key.clone(), l.scale))
                .collect(),
            shape,
        )
    }

    /// Checks a tiled stack ([`StackShape::from_tiled`]) and starts with no image. The
    /// weights handed to the sum leave out the scales: each tile entry has its own.
    pub fn from_tiled(stack: &TiledStack) -> Result<Self> {
        let shape = StackShape::from_tiled(stack)?;
        Self::with_layers(
            stack.header.clone(),
            stack.layers.iter().map(|l| (l.key.clone(), 1.0)).collect(),
            shape,
        )
    }

    fn with_layers(
        header: StackHeader,
        layers: Vec<(LayerKey, f32)>,
        shape: StackShape,
    ) -> Result<Self> {
        let (keys, scales): (Vec<LayerKey>, Vec<f32>) = layers.into_iter().unzip();
        let group_factors = group_factors_of(&header, keys.iter(), None)?;
        let part_scales = if has_tail_edits(keys.iter()) {
            Some(PartScales::for_header(&header)?)
        } else {
            None
        };
        let n_layers = keys.len();
        Ok(RelightBookkeeping {
            header,
            keys,
            scales,
            shape,
            coefs: Vec::new(),
            part_scales,
            weights: vec![Rgb::ZERO; n_layers],
            effective: vec![Rgb::ZERO; n_layers],
            group_factors,
            has_image: false,
            edits_since_full: 0,
            stats: RelightStats::default(),
        })
    }

    /// The header of the stack being relit.
    pub fn header(&self) -> &StackHeader {
        &self.header
    }

    /// Number of layers (ids `0..layer_count`).
    pub fn layer_count(&self) -> usize {
        self.keys.len()
    }

    /// Bytes this bookkeeping holds on the heap beyond the header (keys, weights, layer
    /// lists): part of a relighter's memory besides the stack and the image.
    pub fn heap_bytes(&self) -> usize {
        let rgb = std::mem::size_of::<Rgb>();
        let keys: usize = self
            .keys
            .iter()
            .map(|k| std::mem::size_of::<LayerKey>() + std::mem::size_of_val(&k.path[..]))
            .sum();
        let lists: usize = self.shape.region_layers.iter().map(|l| l.len() * 4).sum();
        keys + self.scales.len() * 4 + (self.weights.len() + self.effective.len()) * rgb + lists
    }

    /// Its size, editable regions and their layers.
    pub fn shape(&self) -> &StackShape {
        &self.shape
    }

    /// What the last relight did.
    pub fn last_stats(&self) -> RelightStats {
        self.stats
    }

    /// Full relight: `coefs[region][basis]` RGB for every editable region.
    ///
    /// Errors: not one coefficient list per editable region, fewer coefficients than the
    /// region's basis count, a non-finite coefficient; the sum's own.
    pub fn relight<S: LayerSum>(
        &mut self,
        sum: &mut S,
        coefs: &[Vec<Rgb>],
    ) -> std::result::Result<(), S::Error> {
        self.shape.check_coefs(coefs)?;
        self.coefs = coefs.to_vec();
        if let Some(p) = &mut self.part_scales {
            p.set(coefs);
        }
        self.full_sum(sum)
    }

    /// Light groups' live strength × colour (one RGB gain per group of the stack's
    /// `light_groups`, 1 leaves the group as baked), then a full re-sum: every layer of a
    /// group scales by its gain, since radiance is linear in each light's emission.
    pub fn set_light_group_gains<S: LayerSum>(
        &mut self,
        sum: &mut S,
        gains: &[Rgb],
    ) -> std::result::Result<(), S::Error> {
        self.group_factors = group_factors_of(&self.header, self.keys.iter(), Some(gains))?;
        if !self.has_image {
            return Err(RelumeError::invalid(
                "light group gains",
                "there is no image yet: call relight with every region's coefficients first",
            )
            .into());
        }
        self.full_sum(sum)
    }

    /// Incremental relight: only editable region `region` changed, to `coefs` (its basis
    /// coefficients). The sum adds `(w_new − w_old) · scale · layer` for the layers whose
    /// key contains the region; every [`FULL_RESUM_EVERY`]-th call re-sums all layers
    /// instead. Needs a full [`relight`](Self::relight) first. If the sum fails, the image is
    /// unknown and only a full relight may follow.
    pub fn relight_region<S: LayerSum>(
        &mut self,
        sum: &mut S,
        region: usize,
        coefs: &[Rgb],
    ) -> std::result::Result<(), S::Error> {
        self.shape.check_region(region, coefs)?;
        if !self.has_image {
            return Err(RelumeError::invalid(
                "incremental relight",
                "there is no image to update yet: call relight with every region's coefficients first",
            )
            .into());
        }
        self.coefs[region] = coefs.to_vec();
        if let Some(p) = &mut self.part_scales {
            p.set_region(region, coefs);
        }
        self.edits_since_full += 1;
        if self.edits_since_full >= FULL_RESUM_EVERY {
            return self.full_sum(sum);
        }
        let layers = &self.shape.region_layers[region];
        let part_scales = scales_of(&self.part_scales);
        for &l in layers {
            let key = &self.keys[l as usize];
            let new = layer_weight(key, &self.coefs, part_scales)
                * self.group_factors[key.light_group as usize];
            let delta = new - self.weights[l as usize];
            self.weights[l as usize] = new;
            self.effective[l as usize] = delta * self.scales[l as usize];
        }
        match sum.incremental_region(region, layers, &self.effective) {
            Ok(stats) => {
                self.stats = RelightStats {
                    incremental: true,
                    ..stats
                };
                Ok(())
            }
            Err(e) => {
                self.has_image = false;
                Err(e)
            }
        }
    }

    /// Recomputes every weight from `self.coefs` and re-sums every layer.
    fn full_sum<S: LayerSum>(&mut self, sum: &mut S) -> std::result::Result<(), S::Error> {
        let part_scales = scales_of(&self.part_scales);
        for (l, key) in self.keys.iter().enumerate() {
            let w = layer_weight(key, &self.coefs, part_scales)
                * self.group_factors[key.light_group as usize];
            self.weights[l] = w;
            self.effective[l] = w * self.scales[l];
        }
        self.has_image = false;
        let stats = sum.full(&self.effective)?;
        self.has_image = true;
        self.edits_since_full = 0;
        self.stats = RelightStats {
            incremental: false,
            ..stats
        };
        Ok(())
    }
}

/// The current part scales (empty when the stack has no tail-edit layers).
fn scales_of(p: &Option<PartScales>) -> &[[Rgb; 2]] {
    p.as_ref().map_or(&[], |p| p.scales())
}

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

use std::sync::Arc;

use crate::stack::TransferStack;
use crate::{RelumeError, Result, Rgb};

use super::layer_sum::{LayerSum, RelightStats};
use super::shape::StackShape;
use super::weight::{group_factors, layer_weight};

/// Every this many incremental edits, [`RelightBookkeeping::relight_region`] re-sums
/// everything to bound float drift (see the module notes: ≈ 4·10⁻⁶ relative at most).
pub const FULL_RESUM_EVERY: usize = 64;

/// The weights of one stack's layers for the current materials and light gains.
pub struct RelightBookkeeping {
    stack: Arc<TransferStack>,
    shape: StackShape,
    /// Coefficients of the current image.
    coefs: Vec<Vec<Rgb>>,
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
    /// Checks the stack ([`StackShape::new`]) and starts with no image.
    pub fn new(stack: Arc<TransferStack>) -> Result<Self> {
        let shape = StackShape::new(&stack)?;
        let group_factors = group_factors(&stack, None)?;
        let n_layers = stack.layers.len();
        Ok(RelightBookkeeping {
            stack,
            shape,
            coefs: Vec::new(),
            weights: vec![Rgb::ZERO; n_layers],
            effective: vec![Rgb::ZERO; n_layers],
            group_factors,
            has_image: false,
            edits_since_full: 0,
            stats: RelightStats::default(),
        })
    }

    /// The stack being relit.
    pub fn stack(&self) -> &Arc<TransferStack> {
        &self.stack
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
        self.group_factors = group_factors(&self.stack, Some(gains))?;
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
        self.edits_since_full += 1;
        if self.edits_since_full >= FULL_RESUM_EVERY {
            return self.full_sum(sum);
        }
        let layers = &self.shape.region_layers[region];
        for &l in layers {
            let layer = &self.stack.layers[l as usize];
            let new = layer_weight(&layer.key, &self.coefs)
                * self.group_factors[layer.key.light_group as usize];
            let delta = new - self.weights[l as usize];
            self.weights[l as usize] = new;
            self.effective[l as usize] = delta * layer.scale;
        }
        match sum.incremental(layers, &self.effective) {
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
        for (l, layer) in self.stack.layers.iter().enumerate() {
            let w = layer_weight(&layer.key, &self.coefs)
                * self.group_factors[layer.key.light_group as usize];
            self.weights[l] = w;
            self.effective[l] = w * layer.scale;
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

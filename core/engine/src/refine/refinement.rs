//! One edit's refinement: what its passes have summed so far.

use crate::brdf::MaterialSpec;
use crate::Rgb;

/// One edit's refinement: its layer weights and materials, and the per-pixel sum of the
/// passes traced so far.
pub struct Refinement {
    pub(super) weights: Vec<Rgb>,
    pub(super) materials: Vec<MaterialSpec>,
    /// Whether anything is missing: a tail (two bounces or more) and an edited material.
    pub(super) needed: bool,
    pub(super) sum: Vec<Rgb>,
    /// The same sum over the odd-numbered passes only: the even and odd halves are
    /// independent estimates, whose difference says how noisy the mean is
    /// ([`super::shrinkage`]).
    pub(super) sum_odd: Vec<Rgb>,
    /// Per pixel, the eye hits of the passes ([`FEATURE_STRIDE`] floats: what the bake's
    /// linear denoiser weighs by).
    pub(super) features: Vec<f32>,
    pub(super) passes: u32,
    pub(super) width: u32,
    pub(super) height: u32,
}

impl Refinement {
    /// Passes traced so far.
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// Whether the edit leaves anything to refine (a tail and an edited material).
    pub fn is_needed(&self) -> bool {
        self.needed
    }
}

//! A refinement's correction: the mean of its passes, smoothed as the bake smooths its
//! bounce layers, and added to a relit image.

use super::refinement::Refinement;
use super::refiner::TailRefiner;
use crate::bake::finish::denoise::EyeFeatures;
use crate::bake::finish::drop::RawLayer;
use crate::layer_key::LayerKey;
use crate::{RelumeError, Result, Rgb};

impl TailRefiner {
    /// The correction of `refinement` so far, per pixel (rows top to bottom): the mean
    /// difference over its passes, smoothed by the bake's linear denoiser at the stack's
    /// bounce-layer iterations (the tail is indirect light, as smooth as the bounce
    /// layers; the filter's weights come from the passes' eye hits only, as the bake's do).
    /// Zero before the first pass and where nothing is needed.
    pub fn correction(&self, refinement: &Refinement) -> Vec<Rgb> {
        if refinement.passes == 0 || !refinement.needed {
            return vec![Rgb::ZERO; refinement.sum.len()];
        }
        let inv = 1.0 / refinement.passes as f32;
        let mean: Vec<Rgb> = refinement.sum.iter().map(|d| *d * inv).collect();
        let iterations = self.header.denoise.bounce_iterations;
        if iterations == 0 {
            return mean;
        }
        let (w, h) = (refinement.width as usize, refinement.height as usize);
        let features = EyeFeatures::from_window_sums(
            &self.ctx,
            &refinement.features,
            refinement.passes,
            (0, 0),
            (w, h),
        );
        let mut layer = RawLayer {
            key: LayerKey::new(vec![]),
            channels: 3,
            data: mean.iter().flat_map(|d| [d.x, d.y, d.z]).collect(),
        };
        features.filter_one(&features.weights_for(iterations), &mut layer);
        layer
            .data
            .chunks_exact(3)
            .map(|c| Rgb::new(c[0], c[1], c[2]))
            .collect()
    }

    /// [`Self::correction`] as RGBA f32 (alpha 0).
    pub fn correction_rgba(&self, refinement: &Refinement) -> Vec<f32> {
        self.correction(refinement)
            .iter()
            .flat_map(|d| [d.x, d.y, d.z, 0.0])
            .collect()
    }

    /// Adds [`Self::correction`] to a relit RGBA image of the same size (rows top first).
    pub fn add_to(&self, refinement: &Refinement, rgba: &mut [f32]) -> Result<()> {
        let n = (refinement.width * refinement.height) as usize;
        if rgba.len() != n * 4 {
            return Err(RelumeError::invalid(
                "image",
                format!(
                    "{} values for a {}×{} refinement",
                    rgba.len(),
                    refinement.width,
                    refinement.height
                ),
            ));
        }
        if refinement.passes == 0 || !refinement.needed {
            return Ok(());
        }
        for (p, d) in rgba.chunks_exact_mut(4).zip(self.correction(refinement)) {
            p[0] += d.x;
            p[1] += d.y;
            p[2] += d.z;
        }
        Ok(())
    }
}

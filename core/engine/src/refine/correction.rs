//! A refinement's correction: the mean of its passes, smoothed as the bake smooths its
//! bounce layers, shrunk where it is within its noise, and added to a relit image.

use super::refinement::Refinement;
use super::refiner::TailRefiner;
use super::shrinkage;
use crate::bake::finish::denoise::EyeFeatures;
use crate::bake::finish::drop::RawLayer;
use crate::layer_key::LayerKey;
use crate::{RelumeError, Result, Rgb};

impl TailRefiner {
    /// The correction shown: [`Self::mean_correction`] shrunk towards zero where it is
    /// within its own noise ([`shrinkage`]), so that early passes do not make the image
    /// noisier than the relight. Zero before the second pass (one pass has no estimate of
    /// its noise) and where nothing is needed.
    pub fn correction(&self, refinement: &Refinement) -> Vec<Rgb> {
        let n = refinement.sum.len();
        if refinement.passes < 2 || !refinement.needed {
            return vec![Rgb::ZERO; n];
        }
        let k = refinement.passes;
        let (k_odd, k_even) = (k / 2, k - k / 2);
        let even: Vec<Rgb> = (refinement.sum.iter().zip(&refinement.sum_odd))
            .map(|(s, o)| (*s - *o) / k_even as f32)
            .collect();
        let odd: Vec<Rgb> = refinement
            .sum_odd
            .iter()
            .map(|o| *o / k_odd as f32)
            .collect();
        let smooth = self.smoother(refinement);
        let (mean, even, odd) = (smooth(self.mean(refinement)), smooth(even), smooth(odd));
        let noise = shrinkage::variance_of_mean(&even, &odd, k_even, k_odd);
        let weights = shrinkage::weights(
            &mean,
            &noise,
            refinement.width as usize,
            refinement.height as usize,
        );
        mean.iter().zip(weights).map(|(d, w)| *d * w).collect()
    }

    /// The mean difference over the refinement's passes, per pixel (rows top to bottom),
    /// smoothed by the bake's linear denoiser at the stack's bounce-layer iterations (the
    /// tail is indirect light, as smooth as the bounce layers; the filter's weights come
    /// from the passes' eye hits only, as the bake's do). After as many passes as the bake
    /// had samples, with a stack baked without the denoiser, the relit image plus this is
    /// the bake's own paths with the edited tail. Zero before the first pass and where
    /// nothing is needed.
    pub fn mean_correction(&self, refinement: &Refinement) -> Vec<Rgb> {
        if refinement.passes == 0 || !refinement.needed {
            return vec![Rgb::ZERO; refinement.sum.len()];
        }
        self.smoother(refinement)(self.mean(refinement))
    }

    fn mean(&self, refinement: &Refinement) -> Vec<Rgb> {
        let inv = 1.0 / refinement.passes as f32;
        refinement.sum.iter().map(|d| *d * inv).collect()
    }

    /// The bake's linear denoiser for this refinement's pixels (weights built once, the
    /// reach the refiner's), or nothing where the stack was baked without it.
    fn smoother(&self, refinement: &Refinement) -> impl Fn(Vec<Rgb>) -> Vec<Rgb> {
        let iterations = self.header.denoise.bounce_iterations;
        let filter = (iterations > 0).then(|| {
            let (w, h) = (refinement.width as usize, refinement.height as usize);
            let surfaces = EyeFeatures::surfaces_from_window_sums(
                &self.ctx,
                &refinement.features,
                refinement.passes,
                (0, 0),
                (w, h),
            );
            // The first pass of any refinement sets it, and a refinement is smoothed only
            // after a pass; tracing it here is the fallback should that ever not hold.
            let reach =
                (self.reach.get().cloned()).unwrap_or_else(|| surfaces.traced_reach(&self.ctx));
            let features = surfaces.with_reach(reach);
            let weights = features.weights_for(iterations);
            (features, weights)
        });
        move |image: Vec<Rgb>| {
            let Some((features, weights)) = &filter else {
                return image;
            };
            let mut layer = RawLayer {
                key: LayerKey::new(vec![]),
                channels: 3,
                data: image.iter().flat_map(|d| [d.x, d.y, d.z]).collect(),
            };
            features.filter_one(weights, &mut layer);
            layer
                .data
                .chunks_exact(3)
                .map(|c| Rgb::new(c[0], c[1], c[2]))
                .collect()
        }
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
        if refinement.passes < 2 || !refinement.needed {
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

//! The set-up steps of a bake that trace rays, in the order the bake runs them, after
//! [`BakeContext::lay_out`] (validation, bases, slots, geometry):
//! 1. the light entering every translucent region ([`super::subsurface_light`]);
//! 2. the bounce pre-pass, when the settings ask for the bounce count the scene needs
//!    ([`super::bounces`]);
//! 3. the guide pass of a guided bake ([`super::guide_pass`]).
//!
//! The bake runs 1 and 2 ([`BakeContext::prepare`]), then its memory forecast and budget
//! check, then 3 ([`BakeContext::build_guide`]), so a bake that cannot fit is refused before
//! the guide pass. [`BakeContext::new`] runs them all, for callers that trace with the
//! context directly (the reference render, the benches).

use crate::bake::path::guide::GuideField;
use crate::bake::prepare::context::BakeContext;
use crate::bake::settings::BakeSettings;
use crate::options::IndirectSampling;
use crate::progress::Progress;
use crate::scene::{validate::ValidationReport, Scene};
use crate::{RelumeError, Result};

impl BakeContext {
    /// A context ready to trace `scene` with `settings`: every set-up step, the guide pass
    /// of a guided bake included.
    pub fn new(scene: &Scene, settings: &BakeSettings) -> Result<(BakeContext, ValidationReport)> {
        let progress = Progress::new();
        let (mut ctx, report) = Self::prepare(scene, settings, &progress)?;
        ctx.build_guide(scene, &progress)?;
        Ok((ctx, report))
    }

    /// [`Self::new`] without the guide pass ([`Self::build_guide`]): the laid-out context
    /// with its translucent regions' light and the bounce count, stopping with
    /// [`RelumeError::Cancelled`] soon after `progress` is cancelled (the subsurface samples
    /// take seconds).
    pub fn prepare(
        scene: &Scene,
        settings: &BakeSettings,
        progress: &Progress,
    ) -> Result<(BakeContext, ValidationReport)> {
        let (mut ctx, report) = Self::lay_out(scene, settings, progress)?;
        ctx.prepare_subsurface_light(scene, progress)?;
        progress.check()?;
        ctx.choose_bounces();
        Ok((ctx, report))
    }

    /// Traces the light entering every translucent region (step 1).
    fn prepare_subsurface_light(&mut self, scene: &Scene, progress: &Progress) -> Result<()> {
        if self.translucent.iter().all(|t| t.is_none()) {
            return Ok(());
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(self.settings.threads)
            .build()
            .map_err(|e| RelumeError::invalid("threads", e.to_string()))?;
        // The light is traced through the context while the regions are filled in: they
        // stand apart meanwhile (the tracing reads no translucent region).
        let mut translucent = std::mem::take(&mut self.translucent);
        let traced = translucent
            .iter_mut()
            .enumerate()
            .try_for_each(|(i, t)| match t {
                Some(t) => pool.install(|| {
                    super::subsurface_light::prepare_light(self, scene, i, t, progress)
                }),
                None => Ok(()),
            });
        self.translucent = translucent;
        traced
    }

    /// Runs the bounce pre-pass when the settings give a bounce budget and more than one
    /// bounce, and bakes the count it chooses (step 2).
    fn choose_bounces(&mut self) {
        let settings = &self.settings;
        if settings.bounce_budget > 0.0 && settings.bounces > 1 {
            let estimate = super::bounces::estimate(self, settings.bounces, settings.bounce_budget);
            self.settings.bounces = estimate.chosen;
            self.bounce_estimate = Some(estimate);
        }
    }

    /// Runs the guide pass when the settings ask for guided sampling (step 3: a first trace
    /// over the image); stops with [`RelumeError::Cancelled`] when `progress` is cancelled.
    pub fn build_guide(&mut self, scene: &Scene, progress: &Progress) -> Result<()> {
        // `self.settings.bounces` is the count the bounce pre-pass chose.
        if self.settings.sampling == IndirectSampling::Guided && self.settings.bounces >= 1 {
            let materials = scene
                .regions
                .iter()
                .filter(|r| r.editable)
                .map(|r| r.material.to_blinn_phong())
                .collect();
            progress.check()?;
            self.guide = Some(GuideField::build(self, materials, progress)?);
        }
        Ok(())
    }
}

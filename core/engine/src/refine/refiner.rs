//! What refines the edits of one stack: the scene prepared for tracing as the bake traced
//! it, checked against the stack's header, and a new refinement per edit.

use std::sync::OnceLock;

use super::edited_tail::EditedTailBrdf;
use super::refinement::Refinement;
use super::weighted_sink::dense_weights;
use crate::bake::finish::denoise::{EyeFeatures, FEATURE_STRIDE};
use crate::bake::finish::describe::stack_header;
use crate::bake::prepare::context::BakeContext;
use crate::bake::settings::BakeSettings;
use crate::brdf::MaterialSpec;
use crate::geometry::lights::LightSet;
use crate::memory::{try_with_capacity, try_zeroed};
use crate::options::{IndirectSampling, LightGrouping};
use crate::relight::part_scales::PartScales;
use crate::scene::hash::scene_hash;
use crate::scene::{Resolution, Scene};
use crate::stack::bases::StackBases;
use crate::stack::{RegionInfo, StackHeader};
use crate::{RelumeError, Result, Rgb};

/// What refines edits of one stack: the scene traced as the bake traced it (its slots, its
/// tail-edit layers, its bounces), built once per stack, and the stack's bases, which turn
/// an edit's materials into layer weights as the relight does.
pub struct TailRefiner {
    pub(super) ctx: BakeContext,
    pub(super) header: StackHeader,
    bases: StackBases,
    part_scales: PartScales,
    /// Each pixel's [reach](crate::bake::finish::reach::harmonic_distance) for the
    /// correction's denoiser, traced once per stack from the eye hits of the first pass
    /// any refinement traces. Eye hits do not depend on the materials, so that pass is the
    /// same for every edit and the reach is the same whichever edit refined first; tracing
    /// it at every correction would cost rays of the whole frame each time an image is
    /// shown.
    pub(super) reach: OnceLock<Vec<f32>>,
}

impl TailRefiner {
    /// `scene`: the scene the stack whose header is `header` was baked from (its editable
    /// regions' materials may be edited ones: the bake-time ones are taken from the header);
    /// `settings`: the bake's settings (its sampling, light grouping, threads; the samples
    /// per pixel, seed, bounces and resolution are taken from the header).
    ///
    /// Errors: [`RelumeError::StackStale`] for another scene; a region the header does not
    /// have; whatever preparing the scene for tracing meets.
    pub fn new(scene: &Scene, settings: &BakeSettings, header: &StackHeader) -> Result<Self> {
        let hash = scene_hash(scene);
        if hash != header.scene_hash {
            return Err(RelumeError::StackStale {
                stack_hash: header.scene_hash.clone(),
                scene_hash: hash,
            });
        }
        let mut scene = scene.clone();
        if scene.regions.len() != header.regions.len() {
            return Err(RelumeError::invalid(
                "scene",
                format!(
                    "{} regions where the stack has {}",
                    scene.regions.len(),
                    header.regions.len()
                ),
            ));
        }
        for (r, info) in scene.regions.iter_mut().zip(&header.regions) {
            if r.editable {
                r.material = info.material.clone();
            }
        }
        let mut settings = settings.clone();
        settings.spp = header.spp;
        settings.seed = header.seed;
        settings.bounces = header.bounces;
        settings.bounce_budget = 0.0;
        settings.resolution = Some(Resolution {
            width: header.width,
            height: header.height,
        });
        let (ctx, _) = BakeContext::new(&scene, &settings)?;
        same_bases(&ctx, &scene, &settings, header)?;
        Ok(TailRefiner {
            ctx,
            header: header.clone(),
            bases: StackBases::from_header(header)?,
            part_scales: PartScales::for_header(header)?,
            reach: OnceLock::new(),
        })
    }

    /// [`Self::new`] with the settings the stack's header records: its sampling, light
    /// samples and light grouping (the one whose groups the header names); what it does not
    /// record (indirect samples per eye sample) is the default, so the passes' paths are
    /// then not the bake's own, only as likely — the difference each pass adds has the same
    /// mean either way. `threads`: 0 for every core.
    pub fn for_stack(scene: &Scene, header: &StackHeader, threads: usize) -> Result<Self> {
        let sampling = match header.sampling.as_str() {
            "uniform" => IndirectSampling::Uniform,
            "guided" => IndirectSampling::Guided,
            _ => IndirectSampling::Mixture,
        };
        let names: Vec<&str> = header
            .light_groups
            .iter()
            .map(|g| g.name.as_str())
            .collect();
        let light_grouping = if names.is_empty() {
            LightGrouping::All
        } else {
            [LightGrouping::Scene, LightGrouping::PerLight]
                .into_iter()
                .find(|g| {
                    let set = LightSet::new(scene, *g);
                    set.groups
                        .iter()
                        .map(|g| g.name.as_str())
                        .eq(names.iter().copied())
                })
                .ok_or_else(|| {
                    RelumeError::invalid(
                        "scene",
                        format!(
                            "its lights group neither as the stack's light groups ({}) nor one \
                             per light",
                            names.join(", ")
                        ),
                    )
                })?
        };
        // The bases as the header records them: the Principled basis of the regions baked
        // in it, the Blinn–Phong one of the others (from a region that declares no ns range
        // of its own, whose range is then the bake's default), the subsurface samples.
        let editable: Vec<_> = scene
            .regions
            .iter()
            .zip(&header.regions)
            .filter(|(r, _)| r.editable)
            .collect();
        let defaults = BakeSettings::default();
        let principled_basis = editable.iter().find_map(|(_, i)| {
            i.principled_basis_with_bake_lobe
                .clone()
                .or_else(|| i.principled_basis.clone())
        });
        let basis = editable
            .iter()
            .filter(|(_, i)| i.basis.is_some())
            .min_by_key(|(r, _)| r.ns_range.is_some())
            .and_then(|(_, i)| i.basis.clone())
            .unwrap_or(defaults.basis.clone());
        let subsurface_samples = editable
            .iter()
            .filter(|(r, _)| r.subsurface.as_ref().is_none_or(|s| s.samples.is_none()))
            .find_map(|(_, i)| i.subsurface.as_ref().map(|s| s.samples))
            .unwrap_or(defaults.subsurface_samples);
        let settings = BakeSettings {
            light_samples: header.light_samples,
            bounce_light_samples: header.bounce_light_samples,
            diffuse_bounces: header.diffuse_bounces,
            glossy_bounces: header.glossy_bounces,
            sampling,
            light_grouping,
            threads,
            precision: header.precision,
            basis,
            principled_basis,
            subsurface_samples,
            ..defaults
        };
        Self::new(scene, &settings, header)
    }

    /// A new refinement for the editable regions' `materials` (editable order) and the
    /// light groups' `gains` (as the relight takes them); nothing traced yet.
    pub fn start(&self, materials: &[MaterialSpec], gains: Option<&[Rgb]>) -> Result<Refinement> {
        let coefs = self.bases.coefficients(materials)?;
        let mut scales = self.part_scales.clone();
        scales.set(&coefs);
        let weights = dense_weights(&self.ctx, &self.header, &coefs, scales.scales(), gains)?;
        let bake_time: Vec<&MaterialSpec> = self
            .header
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| &r.material)
            .collect();
        let edited = materials.iter().zip(&bake_time).any(|(m, b)| m != *b);
        let res = self.ctx.resolution;
        let pixels = (res.width * res.height) as usize;
        let mut features = try_with_capacity(pixels * FEATURE_STRIDE, "the refinement's eye hits")?;
        for _ in 0..pixels {
            features.extend_from_slice(&EyeFeatures::EMPTY);
        }
        // Checks the materials against the regions once, here.
        EditedTailBrdf::new(&self.ctx, materials, self.header.refine_bounces())?;
        Ok(Refinement {
            weights,
            materials: materials.to_vec(),
            needed: edited && self.header.refine_bounces() >= 2,
            sum: try_zeroed(pixels, "the refinement's sums")?,
            sum_odd: try_zeroed(pixels, "the refinement's sums of odd passes")?,
            features,
            passes: 0,
            width: res.width,
            height: res.height,
        })
    }

    /// The samples per pixel the bake traced: after as many passes the refinement has
    /// covered the bake's own paths.
    pub fn bake_samples(&self) -> u32 {
        self.header.spp
    }
}

/// Errors unless `ctx` lays out every editable region's slots as the stack did (the same
/// basis, texture slot and subsurface slots): the layer weights of an edit would otherwise
/// land on other layers. Names the first region that differs.
fn same_bases(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    header: &StackHeader,
) -> Result<()> {
    let ours = stack_header(ctx, scene, settings, header.spp);
    let layout = |r: &RegionInfo| {
        serde_json::json!({
            "basis": r.basis,
            "principled_basis": r.principled_basis,
            "principled_basis_with_bake_lobe": r.principled_basis_with_bake_lobe,
            "textured": r.textured,
            "subsurface": r.subsurface.as_ref().map(|s| (&s.basis, s.eye_diffuse_slot, s.first_slot)),
        })
    };
    for (a, b) in ours.regions.iter().zip(&header.regions) {
        if a.editable && layout(a) != layout(b) {
            return Err(RelumeError::invalid(
                "refine",
                format!(
                    "region \"{}\" would be traced in another basis than the stack's \
                     ({} against {}): give the bake's settings",
                    a.name,
                    layout(a),
                    layout(b)
                ),
            ));
        }
    }
    Ok(())
}

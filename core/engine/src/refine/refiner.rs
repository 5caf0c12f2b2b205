//! The refinement of one edit: passes of eye samples traced twice, their difference summed
//! per pixel (the module docs of [`super`] say why that difference is what the relight
//! misses past the second vertex).

use std::sync::Mutex;
use std::time::Instant;

use super::edited_tail::EditedTailBrdf;
use super::weighted_sink::{dense_weights, WeightedSink};
use crate::bake::finish::denoise::{EyeFeatures, FEATURE_STRIDE};
use crate::bake::finish::describe::stack_header;
use crate::bake::finish::drop::RawLayer;
use crate::bake::path::integrator::{trace_eye_sample, CountingTracer};
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::bake::schedule::tiles::{run_tiles, tiles};
use crate::bake::settings::BakeSettings;
use crate::brdf::MaterialSpec;
use crate::geometry::lights::LightSet;
use crate::layer_key::LayerKey;
use crate::options::{IndirectSampling, LightGrouping};
use crate::progress::Progress;
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
    ctx: BakeContext,
    header: StackHeader,
    bases: StackBases,
    part_scales: PartScales,
}

/// One edit's refinement: its layer weights and materials, and the per-pixel sum of the
/// passes traced so far.
pub struct Refinement {
    weights: Vec<Rgb>,
    materials: Vec<MaterialSpec>,
    /// Whether anything is missing: a tail (two bounces or more) and an edited material.
    needed: bool,
    sum: Vec<Rgb>,
    /// Per pixel, the eye hits of the passes ([`FEATURE_STRIDE`] floats: what the bake's
    /// linear denoiser weighs by).
    features: Vec<f32>,
    passes: u32,
    width: u32,
    height: u32,
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
        // Checks the materials against the regions once, here.
        EditedTailBrdf::new(&self.ctx, materials)?;
        Ok(Refinement {
            weights,
            materials: materials.to_vec(),
            needed: edited && self.ctx.settings.bounces >= 2,
            sum: vec![Rgb::ZERO; (res.width * res.height) as usize],
            features: EyeFeatures::EMPTY
                .iter()
                .copied()
                .cycle()
                .take((res.width * res.height) as usize * FEATURE_STRIDE)
                .collect(),
            passes: 0,
            width: res.width,
            height: res.height,
        })
    }

    /// Traces one pass (eye sample number `refinement.passes()` of every pixel) and adds it
    /// to `refinement`. A cancelled pass adds nothing and returns
    /// [`RelumeError::Cancelled`]; the passes before it stay.
    pub fn pass(&self, refinement: &mut Refinement, progress: &Progress) -> Result<()> {
        if !refinement.needed {
            return Ok(());
        }
        let ctx = &self.ctx;
        let res = ctx.resolution;
        let width = res.width as usize;
        let model = BasisBrdf { ctx };
        let edited = EditedTailBrdf::new(ctx, &refinement.materials)?;
        let weights = &refinement.weights;
        let sample = refinement.passes;
        let image = Mutex::new(vec![Rgb::ZERO; refinement.sum.len()]);
        let eye_hits = Mutex::new(vec![None; refinement.sum.len()]);
        progress.start(tiles(res).len() as u64);
        run_tiles(res, ctx.settings.threads, progress, 1, |tile| {
            let mut tracer = CountingTracer::default();
            let mut out = vec![Rgb::ZERO; tile.pixels()];
            let mut eyes = vec![None; tile.pixels()];
            for ty in 0..tile.height {
                if progress.is_cancelled() {
                    return false;
                }
                for tx in 0..tile.width {
                    let (x, y) = (tile.x0 + tx, tile.y0 + ty);
                    let mut bake = WeightedSink::new(ctx, weights, true);
                    trace_eye_sample(ctx, &model, &mut bake, &mut tracer, x, y, sample);
                    let mut truth = WeightedSink::new(ctx, weights, false);
                    trace_eye_sample(ctx, &edited, &mut truth, &mut tracer, x, y, sample);
                    let d = truth.sum - bake.sum;
                    let i = (ty * tile.width + tx) as usize;
                    // Each trace keeps only finite light; their difference can still
                    // overflow, and a refinement must never spoil the relit image.
                    out[i] = if d.is_finite() { d } else { Rgb::ZERO };
                    eyes[i] = bake.eye;
                }
            }
            let mut img = image.lock().unwrap_or_else(|e| e.into_inner());
            for ty in 0..tile.height as usize {
                let row = (tile.y0 as usize + ty) * width + tile.x0 as usize;
                let w = tile.width as usize;
                img[row..row + w].copy_from_slice(&out[ty * w..(ty + 1) * w]);
            }
            drop(img);
            let mut hits = eye_hits.lock().unwrap_or_else(|e| e.into_inner());
            for ty in 0..tile.height as usize {
                let row = (tile.y0 as usize + ty) * width + tile.x0 as usize;
                let w = tile.width as usize;
                hits[row..row + w].copy_from_slice(&eyes[ty * w..(ty + 1) * w]);
            }
            true
        })?;
        let image = image.into_inner().unwrap_or_else(|e| e.into_inner());
        for (s, d) in refinement.sum.iter_mut().zip(image) {
            *s += d;
        }
        let hits = eye_hits.into_inner().unwrap_or_else(|e| e.into_inner());
        for (rec, hit) in refinement
            .features
            .chunks_exact_mut(FEATURE_STRIDE)
            .zip(hits)
        {
            if let Some((r, n, x)) = hit {
                EyeFeatures::add(rec, r, n, x);
            }
        }
        refinement.passes += 1;
        Ok(())
    }

    /// Passes until `seconds` have gone by (at least one pass), `max_passes` are done or
    /// `progress` is cancelled (then the passes done so far stay and this returns `Ok`).
    pub fn refine_for(
        &self,
        refinement: &mut Refinement,
        seconds: f64,
        max_passes: u32,
        progress: &Progress,
    ) -> Result<()> {
        let start = Instant::now();
        while refinement.needed && refinement.passes < max_passes {
            match self.pass(refinement, progress) {
                Ok(()) => {}
                Err(RelumeError::Cancelled) => return Ok(()),
                Err(e) => return Err(e),
            }
            if start.elapsed().as_secs_f64() >= seconds {
                break;
            }
        }
        Ok(())
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

//! Bake settings.

use serde::{Deserialize, Serialize};

use crate::brdf::principled_fit::fitted_ns;
use crate::brdf::BasisConfig;
pub use crate::options::{Denoise, IndirectSampling, LightGrouping, Precision};
use crate::scene::Resolution;

/// Everything that controls a bake (and the reference render that mirrors it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BakeSettings {
    /// Eye samples per pixel (anti-aliasing; the eye region is in the layer key).
    pub spp: u32,
    /// Samples per light (and for the world) at the eye's shading point, and at every
    /// vertex past it unless `bounce_light_samples` says otherwise.
    pub light_samples: u32,
    /// Samples per light at the vertices past the eye (the bounces); `None`: as many as
    /// `light_samples`. A bounce vertex's direct light reaches the image through a BRDF and
    /// an indirect sample's weight, so one sample there costs a shadow ray and the basis'
    /// values per light for light that the indirect samples average anyway — Cycles takes one
    /// per vertex too. Draft and preview set 1, final as many as the eye.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bounce_light_samples: Option<u32>,
    /// Indirect directions per eye hit.
    pub indirect_samples: u32,
    /// Indirect bounces, as Cycles' Max Bounces counts them: 0 direct light only, 1 one
    /// indirect bounce (the paper, exact under edits), n > 1 adds bounces 2..n as a "frozen
    /// tail" traced with the bake-time materials and folded into the one-bounce layers
    /// ([`crate::bake::path::integrator`]). With `bounce_budget > 0` this is the cap, and the bake
    /// measures how many the scene needs ([`crate::bake::prepare::bounces`]). At most
    /// [`MAX_BOUNCES`].
    pub bounces: u32,
    /// Most diffuse bounces a path takes, as Cycles' Diffuse light path limit counts them
    /// (Blender's default 4); `None`: only `bounces` limits them. With a glossy limit this
    /// lets a path that alternates glossy and diffuse surfaces go on past either limit alone,
    /// up to `bounces` in all ([`crate::bake::path::bounce_kinds`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diffuse_bounces: Option<u32>,
    /// Most glossy bounces a path takes, as Cycles' Glossy light path limit counts them
    /// (Blender's default 4); `None`: only `bounces` limits them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub glossy_bounces: Option<u32>,
    /// Relative share of the image's light that bounces beyond the chosen count may leave
    /// out (e.g. 0.005); 0 bakes exactly `bounces`. The presets set it.
    #[serde(default)]
    pub bounce_budget: f32,
    pub sampling: IndirectSampling,
    pub seed: u64,
    /// Overrides the scene's resolution.
    pub resolution: Option<Resolution>,
    pub precision: Precision,
    /// Basis of editable regions that declare no ns range of their own.
    pub basis: BasisConfig,
    /// When set, editable regions with an opaque, untextured Principled material are baked
    /// in a basis of Cycles' Principled lobes with their bake-time lobe as one more slot
    /// ([`crate::brdf::principled_basis`]). The presets set it; the engine's default (the
    /// paper's) leaves it unset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub principled_basis: Option<crate::brdf::principled_basis::PrincipledBasisConfig>,
    /// Worker threads (0: all cores). The result does not depend on it.
    pub threads: usize,
    /// Relative L2 error a relit image may lose to leaving out negligible layers (see
    /// [`crate::bake::finish::drop`]); 0 keeps every layer a path reached.
    #[serde(default)]
    pub drop_budget: f32,
    #[serde(default)]
    pub light_grouping: LightGrouping,
    /// Surface samples per translucent region (spread uniformly by area) unless the region's
    /// `subsurface.samples` says otherwise. 65 536 by default, as in the translucency paper
    /// (its models use 64k sample points).
    #[serde(default = "default_subsurface_samples")]
    pub subsurface_samples: u32,
    /// Opening criterion θ of the subsurface octree: a cluster of samples is summed as one
    /// point when its radius is ≤ θ × its distance (error ≈ θ²/2 of the far field). The
    /// default keeps octree + PCA + f16 close to the brute-force sum (`tests/engine/subsurface.rs`)
    /// while the gather stays most of a translucent bake's cost rather than all of it
    /// (docs/measurements.md, "Figures that were in code comments").
    #[serde(default = "default_subsurface_theta")]
    pub subsurface_theta: f32,
    /// The stack's denoiser; off by default (the presets turn it on).
    #[serde(default)]
    pub denoise: Denoise,
    /// Bytes the bake may plan to use at its peak; `None`: a share of the machine's
    /// available memory ([`crate::memory::budget_bytes`]). A bake whose estimate
    /// ([`crate::bake::prepare::estimate`]) exceeds it is refused before tracing.
    #[serde(default)]
    pub memory_budget: Option<u64>,
    /// How the bounce layers are stored: per pixel, or where it stays within its tolerance
    /// as lattice entries ([`crate::stack::tiled::lattice`]). Off by default (the presets
    /// turn it on): an approximation, measured by the bake ([`super::report::BakeReport`]'s
    /// `compression_error`).
    #[serde(default)]
    pub compression: BounceCompression,
    /// Per-tile adaptive sampling ([`crate::bake::schedule::adaptive`]): a tile stops
    /// taking eye samples once its estimated error reaches a threshold. Off by default
    /// (threshold 0: the bake is bit for bit the one without it), and then not written
    /// (stacks and farm files keep their bytes).
    #[serde(default, skip_serializing_if = "AdaptiveSampling::is_off")]
    pub adaptive: AdaptiveSampling,
}

/// Per-tile adaptive sampling: after `min_spp` eye samples, and after every doubling of
/// them, a tile whose estimated error ([`crate::bake::schedule::adaptive::tile_error`])
/// is at most `threshold` takes no more samples; the others go on up to the bake's `spp`.
/// Cycles' adaptive sampling is the model (its noise threshold, its minimum samples, its
/// error from the full and a half-sample image), on 16 × 16 tiles instead of pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveSampling {
    /// Noise threshold on Cycles' scale (its per-pixel error: the noise estimate over the
    /// square root of the pixel's intensity), in [0, 1); 0: off.
    pub threshold: f32,
    /// Eye samples every tile takes before its first check; 0: automatic
    /// ([`AdaptiveSampling::first_check`]).
    pub min_spp: u32,
}

impl AdaptiveSampling {
    /// Whether adaptive sampling is off (the bake takes `spp` samples everywhere).
    pub fn is_off(&self) -> bool {
        self.threshold == 0.0
    }

    /// The sample count of a tile's first check in a bake of `spp`: `min_spp`, or when 0
    /// an eighth of `spp` and at least 4 (fewer samples make the half-image estimate too
    /// noisy to stop on), at most `spp`.
    pub fn first_check(&self, spp: u32) -> u32 {
        let n = if self.min_spp == 0 {
            (spp / 8).max(4)
        } else {
            self.min_spp
        };
        n.clamp(1, spp.max(1))
    }
}

/// Lattice compression of the bounce layers (paths of two or more vertices, none of them
/// subsurface): per tile, the bake fits bilinear hats every `step` pixels on each segment
/// of the tile to each bounce layer, and keeps the fits with the smallest errors (weighed
/// by the layers' bake-time weights, with a floor) while their squared errors add up to at
/// most `(tolerance × ‖the tile's bake-time image‖)²` — so the image's relative error at the
/// bake-time materials stays near `tolerance` (measured and reported), and edits that
/// reweigh the layers move it by about as much as they reweigh them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BounceCompression {
    /// Pixels between lattice nodes (1 to 16); 0 stores every layer per pixel.
    pub step: u32,
    /// Relative L2 error of each tile's image the compression may spend (see the type's
    /// doc).
    pub tolerance: f32,
}

impl BounceCompression {
    /// Every layer per pixel.
    pub const OFF: BounceCompression = BounceCompression {
        step: 0,
        tolerance: 0.0,
    };

    /// The tolerance of the draft and preview presets, and of a compression turned on by
    /// its step alone; chosen by measurement (docs/scale.md).
    pub const DEFAULT_TOLERANCE: f32 = 0.02;

    /// This compression with lattice step `step` (0: off). Turning it on from off also
    /// gives it [`Self::DEFAULT_TOLERANCE`], so a step alone compresses; the command line
    /// and the Python settings both set the step through here.
    pub fn with_step(self, step: u32) -> BounceCompression {
        let tolerance = if step > 0 && self.tolerance == 0.0 {
            Self::DEFAULT_TOLERANCE
        } else {
            self.tolerance
        };
        BounceCompression { step, tolerance }
    }
}

impl Default for BounceCompression {
    fn default() -> Self {
        BounceCompression::OFF
    }
}

/// The Principled roughness range an editable region is baked for when neither the region
/// nor the settings name one: the add-on's default (its material panel's Min and Max), so
/// that the command line, Python and the add-on bake the same range and a smooth material
/// (down to roughness 0.1) is not silently rendered rough.
pub const DEFAULT_ROUGHNESS_RANGE: [f32; 2] = [0.1, 1.0];

/// [`DEFAULT_ROUGHNESS_RANGE`] as the Blinn–Phong exponent range `[ns_min, ns_max]` of the
/// core's mapping ([`crate::brdf::principled_to_blinn_phong`], whose exponent depends on
/// roughness alone), so the add-on, which asks the mapping for its ranges, and the CLI bake
/// the same bases.
pub fn default_ns_range() -> [f32; 2] {
    [
        fitted_ns(DEFAULT_ROUGHNESS_RANGE[1]),
        fitted_ns(DEFAULT_ROUGHNESS_RANGE[0]),
    ]
}

fn default_subsurface_samples() -> u32 {
    65_536
}
fn default_subsurface_theta() -> f32 {
    0.15
}

impl Default for BakeSettings {
    fn default() -> Self {
        BakeSettings {
            spp: 16,
            light_samples: 4,
            bounce_light_samples: None,
            indirect_samples: 1,
            bounces: 1,
            diffuse_bounces: None,
            glossy_bounces: None,
            bounce_budget: 0.0,
            sampling: IndirectSampling::Uniform,
            seed: 0,
            resolution: None,
            precision: Precision::F16,
            basis: {
                let [ns_min, ns_max] = default_ns_range();
                BasisConfig {
                    ns_min,
                    ns_max,
                    ..BasisConfig::default()
                }
            },
            principled_basis: None,
            threads: 0,
            drop_budget: 0.0,
            light_grouping: LightGrouping::All,
            subsurface_samples: default_subsurface_samples(),
            subsurface_theta: default_subsurface_theta(),
            denoise: Denoise::OFF,
            memory_budget: None,
            compression: BounceCompression::OFF,
            adaptive: AdaptiveSampling::default(),
        }
    }
}

/// Most worker threads a bake starts: far above any core count the bake scales to, far
/// below the thousands that would exhaust the OS's thread limits.
pub const MAX_THREADS: usize = 1024;

/// Most À-trous iterations of the denoiser (a 2⁸ × 4-pixel reach already spans any frame).
pub const MAX_DENOISE_ITERATIONS: u32 = 8;

impl BakeSettings {
    /// Light samples per light at a path vertex: the eye's (`eye`) or one past it.
    #[inline]
    pub fn light_samples_at(&self, eye: bool) -> u32 {
        match (eye, self.bounce_light_samples) {
            (false, Some(n)) => n,
            _ => self.light_samples,
        }
    }

    /// The one set of rules every front end (command line, Python, add-on) applies, with
    /// the same words, each error naming the setting by its key in [`super::fields`]:
    /// sample counts ≥ 1 (light and indirect samples at most
    /// [`MAX_VERTEX_SAMPLES`]), bounces within [`MAX_BOUNCES`], threads within
    /// [`MAX_THREADS`], a resolution override within [`Resolution::MAX_SIDE`], finite
    /// budgets, a compression tolerance only with a compression step, a consistent basis
    /// ([`crate::brdf::basis::check_config`]). Scene-dependent checks (regions, lights) happen when the bake prepares.
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |what: &str, message: String| Err(crate::RelumeError::invalid(what, message));
        for (what, v) in [
            ("spp", self.spp),
            ("light_samples", self.light_samples),
            ("bounce_light_samples", self.light_samples_at(false)),
            ("indirect_samples", self.indirect_samples),
            ("subsurface_samples", self.subsurface_samples),
        ] {
            if v == 0 {
                return bad(what, "must be ≥ 1, got 0".into());
            }
        }
        for (what, v) in [
            ("light_samples", self.light_samples),
            ("bounce_light_samples", self.light_samples_at(false)),
            ("indirect_samples", self.indirect_samples),
        ] {
            if v > MAX_VERTEX_SAMPLES {
                return bad(
                    what,
                    format!(
                        "{v} asked; at most {MAX_VERTEX_SAMPLES} per path vertex (one eye sample's work grows with it, and a bake checks its cancel between eye samples)"
                    ),
                );
            }
        }
        if self.bounces > MAX_BOUNCES {
            return bad(
                "bounces",
                format!(
                    "{} asked; this build bakes 0 to {MAX_BOUNCES}",
                    self.bounces
                ),
            );
        }
        for (what, v) in [
            ("diffuse_bounces", self.diffuse_bounces),
            ("glossy_bounces", self.glossy_bounces),
        ] {
            if let Some(v) = v.filter(|v| *v > MAX_BOUNCES) {
                return bad(
                    what,
                    format!("{v} asked; this build bakes 0 to {MAX_BOUNCES}"),
                );
            }
        }
        if self.threads > MAX_THREADS {
            return bad(
                "threads",
                format!(
                    "{} asked; at most {MAX_THREADS} (0 uses every core)",
                    self.threads
                ),
            );
        }
        if let Some(r) = self.resolution {
            r.validate("resolution")?;
        }
        if let Some(cfg) = &self.principled_basis {
            // A region's slots are the basis' and its bake-time lobe's.
            let most = crate::options::MAX_BASES - 1;
            if !(2..=most).contains(&cfg.bases) {
                return bad(
                    "principled_bases",
                    format!(
                        "{} asked; 2 (the constant and one lobe) to {most}, the bake-time lobe's slot coming on top",
                        cfg.bases
                    ),
                );
            }
        }
        if !(self.drop_budget.is_finite() && (0.0..1.0).contains(&self.drop_budget)) {
            return bad(
                "drop_budget",
                format!("must be in [0, 1), got {}", self.drop_budget),
            );
        }
        if !(self.bounce_budget.is_finite() && (0.0..1.0).contains(&self.bounce_budget)) {
            return bad(
                "bounce_budget",
                format!("must be in [0, 1), got {}", self.bounce_budget),
            );
        }
        if !(self.subsurface_theta.is_finite() && self.subsurface_theta > 0.0) {
            return bad(
                "subsurface_theta",
                format!("must be finite and > 0, got {}", self.subsurface_theta),
            );
        }
        for (what, n) in [
            ("denoise_direct", self.denoise.direct_iterations),
            ("denoise_bounce", self.denoise.bounce_iterations),
        ] {
            if n > MAX_DENOISE_ITERATIONS {
                return bad(what, format!("{n} asked; at most {MAX_DENOISE_ITERATIONS}"));
            }
        }
        let c = self.compression;
        if c.step > crate::stack::tiled::lattice::MAX_LATTICE_STEP {
            return bad(
                "compression_step",
                format!(
                    "{} pixels asked; at most {}",
                    c.step,
                    crate::stack::tiled::lattice::MAX_LATTICE_STEP
                ),
            );
        }
        if !(c.tolerance.is_finite() && (0.0..1.0).contains(&c.tolerance)) {
            return bad(
                "compression_tolerance",
                format!("must be in [0, 1), got {}", c.tolerance),
            );
        }
        if c.step == 0 && c.tolerance != 0.0 {
            return bad(
                "compression_tolerance",
                format!(
                    "{} given, but the bounce layers are not compressed: give a compression step (or a preset)",
                    c.tolerance
                ),
            );
        }
        let a = self.adaptive;
        if !(a.threshold.is_finite() && (0.0..1.0).contains(&a.threshold)) {
            return bad(
                "adaptive_threshold",
                format!("must be in [0, 1), got {}", a.threshold),
            );
        }
        if a.is_off() && a.min_spp != 0 {
            return bad(
                "adaptive_min_spp",
                format!(
                    "{} given, but adaptive sampling is off: give an adaptive threshold",
                    a.min_spp
                ),
            );
        }
        if self.memory_budget == Some(0) {
            return bad("memory_budget_mb", "must be > 0 (MiB)".into());
        }
        crate::brdf::basis::check_config(&self.basis).map_err(|e| match e {
            crate::RelumeError::Basis(message) => crate::RelumeError::invalid("basis", message),
            other => other,
        })?;
        Ok(())
    }
}

/// Most light samples or indirect directions a path vertex may take: 256 times the final
/// preset's 4, and the add-on's properties' maximum. One eye sample's work grows with their product (and the light count), and the
/// bake and its forecast check the cancel between eye samples, so a count near `u32::MAX`
/// is refused as no real bake rather than run for days without a way to stop it.
pub const MAX_VERTEX_SAMPLES: u32 = 1024;

/// Highest bounce count this build bakes (bounces beyond the first are the frozen tail, so
/// the layer keys do not grow with it).
pub const MAX_BOUNCES: u32 = 128;

/// Blender's default Max Bounces (Cycles, `scene.cycles.max_bounces`): the cap the presets
/// use when the caller gives none.
pub const DEFAULT_BOUNCES: u32 = 12;

/// The settings as a farm compares them: threads and the memory budget cleared (they change
/// no result), everything else as given.
pub fn normalized(settings: &BakeSettings) -> BakeSettings {
    BakeSettings {
        threads: 0,
        memory_budget: None,
        ..settings.clone()
    }
}

/// Hash (hex) of [`normalized`] settings and the engine version: parts, guide and merge
/// must agree on it.
pub fn settings_fingerprint(settings: &BakeSettings) -> String {
    let mut bytes = serde_json::to_vec(&normalized(settings)).unwrap_or_default();
    bytes.extend_from_slice(env!("CARGO_PKG_VERSION").as_bytes());
    format!("{:016x}", crate::scene::hash::fnv1a(&bytes))
}

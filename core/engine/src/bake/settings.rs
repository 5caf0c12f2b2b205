//! Bake settings.

use serde::{Deserialize, Serialize};

use crate::brdf::BasisConfig;
use crate::scene::Resolution;
use crate::stack::Precision;

/// How indirect directions are drawn at the eye hit. Both are unbiased and share one sample
/// set across all layers, so the layers' noise stays correlated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IndirectSampling {
    /// Uniform over the hemisphere, as in the paper (pdf 1/2π).
    Uniform,
    /// A mixture: ½ cosine-weighted + ½ spread over Blinn–Phong lobes covering the region's
    /// ns range (4 exponents, log-spaced), its pdf evaluated exactly.
    Mixture,
    /// The mixture plus a guide: a first pass records incoming indirect radiance per screen
    /// tile ([`crate::bake::guide`]); half of the directions are drawn from that map, the
    /// other half from the cosine + lobes mixture; pdf exact.
    Guided,
}

impl IndirectSampling {
    /// The name written in stack headers.
    pub fn name(self) -> &'static str {
        match self {
            IndirectSampling::Uniform => "uniform",
            IndirectSampling::Mixture => "mixture",
            IndirectSampling::Guided => "guided",
        }
    }
}

/// Which lights share layers. Light groups make each group's strength and colour live at
/// relight time; storage and relight cost grow with the number of groups.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum LightGrouping {
    /// All lights (and the world) in one set of layers.
    #[default]
    All,
    /// One group per light, and one for the world.
    PerLight,
    /// The scene file's `light_groups` (Blender's light groups); lights in none share a
    /// "default" group.
    Scene,
}

/// How much of the bake's noise the stack's linear denoiser ([`crate::bake::denoise`]) takes
/// out: À-trous iterations per kind of layer, 0 for none. Each iteration doubles the
/// kernel's reach (5 iterations: 125 pixels across); the filter's weights come from the
/// geometry only, so relighting stays exact with respect to the filtered stack, at the cost
/// of bias where light changes faster than geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct Denoise {
    /// Iterations on the layers lit directly at the eye vertex (shadows live here: keep small).
    pub direct_iterations: u32,
    /// Iterations on the one-bounce layers (smooth indirect light, most of the noise).
    pub bounce_iterations: u32,
}

impl Denoise {
    /// No filtering: the stack is the unbiased Monte Carlo estimate.
    pub const OFF: Denoise = Denoise {
        direct_iterations: 0,
        bounce_iterations: 0,
    };
}

/// Everything that controls a bake (and the reference render that mirrors it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BakeSettings {
    /// Eye samples per pixel (anti-aliasing; the eye region is in the layer key).
    pub spp: u32,
    /// Samples per light (and for the world) at every shading point.
    pub light_samples: u32,
    /// Indirect directions per eye hit.
    pub indirect_samples: u32,
    /// Indirect bounces, as Cycles' Max Bounces counts them: 0 direct light only, 1 one
    /// indirect bounce (the paper, exact under edits), n > 1 adds bounces 2..n as a "frozen
    /// tail" traced with the bake-time materials and folded into the one-bounce layers
    /// ([`crate::bake::integrator`]). With `bounce_budget > 0` this is the cap, and the bake
    /// measures how many the scene needs ([`crate::bake::bounces`]). At most [`MAX_BOUNCES`].
    pub bounces: u32,
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
    /// Worker threads (0: all cores). The result does not depend on it.
    pub threads: usize,
    /// Relative L2 error a relit image may lose to leaving out negligible layers (see
    /// [`crate::bake::drop`]); 0 keeps every layer a path reached.
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
    /// point when its radius is ≤ θ × its distance (error ≈ θ²/2 of the far field; 0.15
    /// keeps octree + PCA + f16 within 0.3 % of the brute-force sum in `tests/subsurface.rs`;
    /// the gather costs ≈ 90 µs per eye hit there, most of a translucent bake).
    #[serde(default = "default_subsurface_theta")]
    pub subsurface_theta: f32,
    /// The stack's denoiser; off by default (the presets turn it on).
    #[serde(default)]
    pub denoise: Denoise,
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
            indirect_samples: 1,
            bounces: 1,
            bounce_budget: 0.0,
            sampling: IndirectSampling::Uniform,
            seed: 0,
            resolution: None,
            precision: Precision::F16,
            basis: BasisConfig::default(),
            threads: 0,
            drop_budget: 0.0,
            light_grouping: LightGrouping::All,
            subsurface_samples: default_subsurface_samples(),
            subsurface_theta: default_subsurface_theta(),
            denoise: Denoise::OFF,
        }
    }
}

/// Highest bounce count this build bakes (bounces beyond the first are the frozen tail, so
/// the layer keys do not grow with it).
pub const MAX_BOUNCES: u32 = 128;

/// Blender's default Max Bounces (Cycles, `scene.cycles.max_bounces`): the cap the presets
/// use when the caller gives none.
pub const DEFAULT_BOUNCES: u32 = 12;

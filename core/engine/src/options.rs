//! The bake's options that the stack records and the rest of the engine reads: storage
//! precision, indirect sampling, light grouping, the denoiser, and the limits that size the
//! integrator's per-vertex arrays. A leaf of the engine: the bake, the stack, the geometry
//! and the relight all use it, and it imports none of them.

use serde::{Deserialize, Serialize};

/// Most bases one region may use: bounds the per-vertex scratch arrays of the integrator.
pub const MAX_BASES: usize = 32;

/// Most light groups a bake keeps apart: bounds the per-vertex arrays that hold light per
/// group (a scene with more groups is refused while the bake prepares).
pub const MAX_GROUPS: usize = 16;

/// Storage precision of layer samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Half floats with a per-layer scale (see [`crate::stack::Layer::scale`]): half the memory and
    /// bandwidth; relative rounding error ≤ 2⁻¹¹ per sample.
    F16,
    F32,
}

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
    /// tile (the guide pass of the bake); half of the directions are drawn from that map, the
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
    /// All lights (and the world) in one set of layers (the command line also calls it
    /// `none`: no groups).
    #[default]
    #[serde(alias = "none")]
    All,
    /// One group per light, and one for the world.
    PerLight,
    /// The scene file's `light_groups` (Blender's light groups); lights in none share a
    /// "default" group.
    Scene,
}

/// How much of the bake's noise the stack's linear denoiser (the bake's `denoise` step) takes
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

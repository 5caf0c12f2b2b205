//! The transfer stack: every layer of a bake, in memory, and its OpenEXR file ([`exr_file`]).

pub mod bases;
pub mod exr_file;
#[doc(hidden)]
pub mod hostile;
pub mod staleness;
pub mod tiled;

use serde::{Deserialize, Serialize};

use crate::brdf::BasisConfig;
use crate::layer_key::LayerKey;
pub use crate::options::Precision;
use crate::scene::{Camera, Light};

/// Version of the stack file layout; a file with another version is refused.
pub const STACK_FORMAT_VERSION: u32 = 1;

/// What a stack was baked from and how; stored in the file header and checked on load.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StackHeader {
    pub format_version: u32,
    pub width: u32,
    pub height: u32,
    pub camera: Camera,
    pub spp: u32,
    pub light_samples: u32,
    /// Light samples at the vertices past the eye; `None` (and stacks written before it was
    /// recorded): `light_samples`. A refinement traces its tails with it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bounce_light_samples: Option<u32>,
    pub bounces: u32,
    /// Cycles' per-kind light path limits the bake counted ([`crate::bake::path::bounce_kinds`]);
    /// `None` (and stacks written before they were recorded): only `bounces`. A refinement
    /// traces its tails with them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diffuse_bounces: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub glossy_bounces: Option<u32>,
    /// Indirect sampling: "uniform" (the paper), "mixture" or "guided".
    pub sampling: String,
    pub seed: u64,
    pub regions: Vec<RegionInfo>,
    pub lights: Vec<Light>,
    /// Hash of everything in the scene that the bake depends on ([`crate::scene::hash`]).
    pub scene_hash: String,
    pub precision: Precision,
    /// The colour shared by every emitter, factored out of the layers (see
    /// [`crate::geometry::lights::common_tint`]): layers are baked with grey light and every
    /// layer weight is multiplied by this at relight. [1, 1, 1] when the lights differ in colour.
    #[serde(default = "white_tint")]
    pub light_tint: [f32; 3],
    /// Light groups kept apart (layer keys `G<g+1>_…`), each with its own tint in place of
    /// `light_tint`; empty when all lights share the layers (keys with light group 0).
    #[serde(default)]
    pub light_groups: Vec<LightGroupInfo>,
    /// The linear denoiser the bake applied (the bake's `denoise` step); off in stacks
    /// written before it existed.
    #[serde(default)]
    pub denoise: crate::options::Denoise,
    /// The bounces the bake was allowed: its settings' cap where a bounce budget chose
    /// fewer (`bounces`). A refinement traces an edit up to it, so the bounces the budget
    /// left out at the bake-time materials come back where an edit makes them matter; 0 in
    /// stacks written before it was recorded ([`Self::refine_bounces`]).
    #[serde(default)]
    pub bounce_cap: u32,
}

/// A light group of a stack: its name and the colour factored out of its layers.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LightGroupInfo {
    pub name: String,
    pub tint: [f32; 3],
}

impl StackHeader {
    /// The bounces a refinement traces an edit's paths to: the bake's cap, at least the
    /// bounces baked.
    pub fn refine_bounces(&self) -> u32 {
        self.bounce_cap.max(self.bounces)
    }

    /// The colour factored out of the layers of light group `key_group` (a layer key's
    /// `light_group`: 0 for all lights together, g + 1 for group g).
    pub fn group_tint(&self, key_group: u16) -> Option<[f32; 3]> {
        if key_group == 0 {
            Some(self.light_tint)
        } else {
            self.light_groups
                .get(key_group as usize - 1)
                .map(|g| g.tint)
        }
    }
}

fn white_tint() -> [f32; 3] {
    [1.0; 3]
}

/// One region as the stack knows it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RegionInfo {
    pub name: String,
    pub editable: bool,
    /// The material at bake time: baked in for a fixed region, the default of an editable one.
    pub material: crate::brdf::MaterialSpec,
    /// The basis of an editable region (rebuilt deterministically from this on load).
    pub basis: Option<BasisConfig>,
    /// Whether an albedo texture scales the diffuse basis of this (editable) region. With the
    /// diffuse basis in the specular fit, such a region stores one more layer per position:
    /// the untextured constant, so the texture never tints the specular part.
    #[serde(default)]
    pub textured: bool,
    /// A translucent region's subsurface basis and slot layout (absent for opaque regions
    /// and in stacks from before translucency).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subsurface: Option<crate::bssrdf::SubsurfaceInfo>,
    /// The Principled basis of an editable region baked in one (then `basis` is `None`, so
    /// a build that does not know this field refuses the region rather than misreading it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub principled_basis: Option<crate::brdf::principled_basis::PrincipledBasisConfig>,
    /// The Principled basis of an editable region baked in it with its bake-time lobe as
    /// one more slot ([`crate::brdf::RegionBasis::PrincipledWithBakeLobe`]; then `basis` and
    /// `principled_basis` are `None`, so a build that does not know this slot refuses the
    /// region rather than relighting without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub principled_basis_with_bake_lobe:
        Option<crate::brdf::principled_basis::PrincipledBasisConfig>,
}

impl RegionInfo {
    /// This record with the Principled basis it was baked in (`None`: none).
    pub fn with_principled_basis(
        mut self,
        cfg: Option<crate::brdf::principled_basis::PrincipledBasisConfig>,
    ) -> RegionInfo {
        self.principled_basis = cfg;
        self
    }

    /// This record with the Principled basis it was baked in (`None`: none), that basis
    /// with the bake-time slot when `with_bake_lobe`.
    pub fn with_principled(
        mut self,
        cfg: Option<crate::brdf::principled_basis::PrincipledBasisConfig>,
        with_bake_lobe: bool,
    ) -> RegionInfo {
        if with_bake_lobe {
            self.principled_basis = None;
            self.principled_basis_with_bake_lobe = cfg;
        } else {
            self.principled_basis = cfg;
            self.principled_basis_with_bake_lobe = None;
        }
        self
    }

    /// What a stack records of scene region `region` baked with basis `basis` (editable
    /// regions; `None` for fixed ones).
    pub fn from_region(region: &crate::scene::Region, basis: Option<BasisConfig>) -> RegionInfo {
        RegionInfo {
            name: region.name.clone(),
            editable: region.editable,
            material: region.material.clone(),
            basis,
            textured: region.editable && region.albedo_texture.is_some(),
            subsurface: None,
            principled_basis: None,
            principled_basis_with_bake_lobe: None,
        }
    }
}

/// Samples of one layer: interleaved per pixel (1 channel for grey layers, 3 for RGB),
/// rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerSamples {
    F16(Vec<half::f16>),
    F32(Vec<f32>),
}

impl LayerSamples {
    /// Number of stored values.
    pub fn len(&self) -> usize {
        match self {
            LayerSamples::F16(v) => v.len(),
            LayerSamples::F32(v) => v.len(),
        }
    }
    /// Whether there is no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Value `i` as f32 (before the layer's scale).
    #[inline]
    pub fn get(&self, i: usize) -> f32 {
        match self {
            LayerSamples::F16(v) => v[i].to_f32(),
            LayerSamples::F32(v) => v[i],
        }
    }
    /// Bytes of sample storage.
    pub fn bytes(&self) -> usize {
        match self {
            LayerSamples::F16(v) => v.len() * 2,
            LayerSamples::F32(v) => v.len() * 4,
        }
    }
}

/// One layer: radiance of all paths with one signature, for unit coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    pub key: LayerKey,
    /// 1 (grey: the path met no colour) or 3 (RGB).
    pub channels: u32,
    /// Stored value × scale = radiance. Chosen per layer so that half floats neither
    /// overflow (65504) for very bright lights nor lose precision for very dim ones.
    pub scale: f32,
    pub samples: LayerSamples,
}

/// A whole transfer stack.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferStack {
    pub header: StackHeader,
    pub layers: Vec<Layer>,
}

impl Layer {
    /// Builds a layer from f32 radiance (`channels` interleaved), choosing the scale and,
    /// for f16, quantising. The scale maps the largest magnitude to 2¹⁴ (f16 max is 65504).
    pub fn from_f32(key: LayerKey, channels: u32, values: &[f32], precision: Precision) -> Layer {
        let max_abs = values.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        match precision {
            Precision::F32 => Layer {
                key,
                channels,
                scale: 1.0,
                samples: LayerSamples::F32(values.to_vec()),
            },
            Precision::F16 => {
                let scale = if max_abs > 0.0 && max_abs.is_finite() {
                    max_abs / 16384.0
                } else {
                    1.0
                };
                let inv = 1.0 / scale;
                Layer {
                    key,
                    channels,
                    scale,
                    samples: LayerSamples::F16(
                        values
                            .iter()
                            .map(|v| half::f16::from_f32(v * inv))
                            .collect(),
                    ),
                }
            }
        }
    }

    /// Radiance of value `i` (scale applied).
    #[inline]
    pub fn value(&self, i: usize) -> f32 {
        self.samples.get(i) * self.scale
    }
}

impl TransferStack {
    /// Total bytes of layer samples (what a full relight reads).
    pub fn sample_bytes(&self) -> usize {
        self.layers.iter().map(|l| l.samples.bytes()).sum()
    }
    /// Positions of the editable regions among `header.regions`.
    pub fn editable_regions(&self) -> Vec<usize> {
        (0..self.header.regions.len())
            .filter(|&r| self.header.regions[r].editable)
            .collect()
    }
}

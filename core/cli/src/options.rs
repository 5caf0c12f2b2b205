//! Options shared by the commands that trace paths (bake, reference, bench bake).

use clap::{Args, ValueEnum};
use relume_engine::bake::{BakeSettings, IndirectSampling, LightGrouping};
use relume_engine::brdf::{BasisConfig, BasisCount};
use relume_engine::scene::Resolution;
use relume_engine::stack::Precision;
use relume_engine::RelumeError;

#[derive(Clone, Copy, ValueEnum)]
pub enum SamplingArg {
    Uniform,
    Mixture,
    /// The mixture plus a per-tile guide map from a short first pass.
    Guided,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum LightGroupsArg {
    /// All lights share the layers.
    None,
    /// One group per light (and one for the world): every light's strength and colour live.
    PerLight,
    /// The scene file's light groups (Blender's light groups).
    Scene,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum PrecisionArg {
    F16,
    F32,
}

/// Bake options; `reference` takes the same so it traces the same paths.
#[derive(Args, Clone)]
pub struct BakeOptions {
    /// Eye samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Samples per light (and for the world) at every shading point.
    #[arg(long, default_value_t = 4)]
    pub light_samples: u32,
    /// Indirect directions per eye hit.
    #[arg(long, default_value_t = 1)]
    pub indirect_samples: u32,
    /// 0: direct light only; 1: one indirect bounce (the paper).
    #[arg(long, default_value_t = 1)]
    pub bounces: u32,
    /// Indirect sampling: uniform hemisphere (the paper), cosine + lobes mixture, or guided.
    #[arg(long, value_enum, default_value = "uniform")]
    pub sampling: SamplingArg,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Override the scene's resolution, e.g. 256x256.
    #[arg(long)]
    pub resolution: Option<String>,
    /// Layer storage precision.
    #[arg(long, value_enum, default_value = "f16")]
    pub precision: PrecisionArg,
    /// Basis count N_b (including the diffuse basis).
    #[arg(long, default_value_t = 6)]
    pub bases: u32,
    /// Instead of --bases: the smallest basis whose worst lobe error is at most this (e.g. 0.03).
    #[arg(long)]
    pub tolerance: Option<f32>,
    /// Blinn–Phong exponent range of editable regions without a range of their own.
    #[arg(long, default_value_t = 1.0)]
    pub ns_min: f32,
    #[arg(long, default_value_t = 200.0)]
    pub ns_max: f32,
    /// Worker threads (0: all cores); the result does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Leave out layers whose worst-case contribution to any relit image stays within this
    /// relative L2 error (e.g. 0.001); 0 keeps every layer a path reached.
    #[arg(long, default_value_t = 0.0)]
    pub drop_budget: f32,
    /// Keep light groups apart so their strength and colour can be edited at relight time
    /// (storage and relight cost grow with the number of groups).
    #[arg(long, value_enum, default_value = "none")]
    pub light_groups: LightGroupsArg,
    /// Surface samples per translucent region (uniform by area), unless the scene's region
    /// sets `subsurface.samples`.
    #[arg(long, default_value_t = 65536)]
    pub subsurface_samples: u32,
}

impl BakeOptions {
    /// The engine's settings.
    pub fn settings(&self) -> Result<BakeSettings, RelumeError> {
        let resolution = match &self.resolution {
            None => None,
            Some(s) => Some(parse_resolution(s)?),
        };
        Ok(BakeSettings {
            spp: self.spp,
            light_samples: self.light_samples,
            indirect_samples: self.indirect_samples,
            bounces: self.bounces,
            sampling: match self.sampling {
                SamplingArg::Uniform => IndirectSampling::Uniform,
                SamplingArg::Mixture => IndirectSampling::Mixture,
                SamplingArg::Guided => IndirectSampling::Guided,
            },
            seed: self.seed,
            resolution,
            precision: match self.precision {
                PrecisionArg::F16 => Precision::F16,
                PrecisionArg::F32 => Precision::F32,
            },
            basis: BasisConfig {
                ns_min: self.ns_min,
                ns_max: self.ns_max,
                count: match self.tolerance {
                    Some(t) => BasisCount::Tolerance(t),
                    None => BasisCount::Fixed(self.bases),
                },
                ..BasisConfig::default()
            },
            threads: self.threads,
            drop_budget: self.drop_budget,
            light_grouping: match self.light_groups {
                LightGroupsArg::None => LightGrouping::All,
                LightGroupsArg::PerLight => LightGrouping::PerLight,
                LightGroupsArg::Scene => LightGrouping::Scene,
            },
            subsurface_samples: self.subsurface_samples,
            ..BakeSettings::default()
        })
    }
}

/// Parses `WxH`.
pub fn parse_resolution(s: &str) -> Result<Resolution, RelumeError> {
    let bad = || {
        RelumeError::invalid(
            "--resolution",
            format!("\"{s}\" (expected WIDTHxHEIGHT, e.g. 512x512)"),
        )
    };
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let width: u32 = w.trim().parse().map_err(|_| bad())?;
    let height: u32 = h.trim().parse().map_err(|_| bad())?;
    if width == 0 || height == 0 {
        return Err(bad());
    }
    Ok(Resolution { width, height })
}

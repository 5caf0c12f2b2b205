//! Options shared by the commands that trace paths (bake, reference, bench bake).

use clap::{Args, ValueEnum};
use relume_engine::bake::presets::Preset;
use relume_engine::bake::settings::{default_ns_range, DEFAULT_BOUNCES};
use relume_engine::bake::{BakeSettings, IndirectSampling, LightGrouping};
use relume_engine::brdf::principled_basis::PrincipledBasisConfig;
use relume_engine::brdf::{BasisConfig, BasisCount};
use relume_engine::scene::Resolution;
use relume_engine::stack::Precision;
use relume_engine::RelumeError;

#[derive(Clone, Copy, Debug, ValueEnum)]
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

/// `--lobe`: the basis editable regions are baked in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LobeArg {
    BlinnPhong,
    Principled,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum PrecisionArg {
    F16,
    F32,
}

/// The quality presets of [`Preset`], as the command line spells them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PresetArg {
    /// Seconds at half resolution: for checking the set-up.
    Draft,
    /// A usable image at full resolution in seconds to a minute.
    Preview,
    /// Many samples and a tight basis, for final frames.
    Final,
}

impl PresetArg {
    pub fn preset(self) -> Preset {
        match self {
            PresetArg::Draft => Preset::Draft,
            PresetArg::Preview => Preset::Preview,
            PresetArg::Final => Preset::Final,
        }
    }
}

/// The values the options fall back to when neither a flag nor a preset sets them (the
/// paper's configuration, as before presets existed).
pub const DEFAULT_SPP: u32 = 16;
pub const DEFAULT_LIGHT_SAMPLES: u32 = 4;
pub const DEFAULT_INDIRECT_SAMPLES: u32 = 1;
pub const DEFAULT_BASES: u32 = 6;

/// Bake options; `reference` takes the same so it traces the same paths.
///
/// Precedence: an explicit flag, then the preset's value (`--preset`), then the default.
#[derive(Args, Clone)]
pub struct BakeOptions {
    /// Quality preset: sets --spp, --light-samples, --indirect-samples, --sampling,
    /// --tolerance and a resolution scale (draft: ½ of the scene's resolution); explicit
    /// flags override the preset's values. docs/measurements.md#presets-measured says what each costs.
    #[arg(long, value_enum)]
    pub preset: Option<PresetArg>,
    /// Eye samples per pixel [default: 16, or the preset's].
    #[arg(long)]
    pub spp: Option<u32>,
    /// Samples per light (and for the world) at every shading point [default: 4, or the
    /// preset's].
    #[arg(long)]
    pub light_samples: Option<u32>,
    /// Indirect directions per eye hit [default: 1, or the preset's].
    #[arg(long)]
    pub indirect_samples: Option<u32>,
    /// Indirect bounces as Cycles counts them (0: direct light only; 1: one bounce, the
    /// paper; more: bounces 2.. traced with the bake-time materials, the "frozen tail").
    /// With a preset this is the cap and the bake measures how many the scene needs
    /// [default: 1, or 12 (Blender's default) with a preset].
    #[arg(long)]
    pub bounces: Option<u32>,
    /// Share of the image's light the bounces past the baked count may leave out (0: bake
    /// exactly --bounces) [default: 0, or the preset's].
    #[arg(long)]
    pub bounce_budget: Option<f32>,
    /// Indirect sampling: uniform hemisphere (the paper), cosine + lobes mixture, or guided
    /// [default: uniform, or the preset's (mixture)].
    #[arg(long, value_enum)]
    pub sampling: Option<SamplingArg>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Override the scene's resolution, e.g. 256x256 (a preset's resolution scale then
    /// does not apply; --resolution-scale does).
    #[arg(long)]
    pub resolution: Option<String>,
    /// Scale each side of the resolution (the scene's, or --resolution's) by this factor,
    /// e.g. 0.5 [default: the preset's when --resolution is not given, else 1].
    #[arg(long)]
    pub resolution_scale: Option<f64>,
    /// Layer storage precision.
    #[arg(long, value_enum, default_value = "f16")]
    pub precision: PrecisionArg,
    /// Basis count N_b (including the diffuse basis) [default: 6, or the preset's
    /// tolerance].
    #[arg(long)]
    pub bases: Option<u32>,
    /// Instead of --bases: the smallest basis whose worst lobe error is at most this (e.g. 0.03).
    #[arg(long)]
    pub tolerance: Option<f32>,
    /// Blinn–Phong exponent range of editable regions without a range of their own
    /// [default: Principled roughness 0.1–1, the add-on's: ns ≈ 0.0015–35 000 under the fitted
    /// Principled mapping].
    #[arg(long)]
    pub ns_min: Option<f32>,
    /// Upper end of that range [default: ns ≈ 35 000, the fitted exponent at roughness 0.1].
    #[arg(long)]
    pub ns_max: Option<f32>,
    /// The lobes editable regions are baked in: the paper's Blinn–Phong basis, or
    /// (experimental) a basis of Cycles' Principled lobes for editable regions with an
    /// opaque, untextured Principled material (21 slots, roughness 0.1–1; others keep
    /// Blinn–Phong, with a warning).
    #[arg(long, value_enum, default_value = "blinn-phong")]
    pub lobe: LobeArg,
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
    /// À-trous iterations of the stack's linear denoiser on the direct layers [default: 0,
    /// or the preset's]; each doubles the kernel's reach.
    #[arg(long)]
    pub denoise_direct: Option<u32>,
    /// À-trous iterations on the one-bounce layers [default: 0, or the preset's].
    #[arg(long)]
    pub denoise_bounce: Option<u32>,
    /// Memory the bake may plan to use at its peak, in MiB; a bake whose estimate exceeds
    /// it is refused before tracing [default: 80 % of the available memory].
    #[arg(long)]
    pub memory_budget_mb: Option<f64>,
    /// Bounce-layer compression: pixels between lattice nodes (1 to 16), 0 to store every
    /// layer per pixel [default: off, or the preset's].
    #[arg(long)]
    pub compression_step: Option<u32>,
    /// Relative L2 error of each tile's bake-time image the bounce-layer compression may
    /// spend, in [0, 1) [default: the preset's, or the draft and preview presets' when only
    /// --compression-step is given].
    #[arg(long)]
    pub compression_tolerance: Option<f32>,
}

impl BakeOptions {
    /// The engine's settings for a scene whose own resolution is `scene_resolution`: the
    /// preset's values first, then every flag given explicitly, then the resolution (an
    /// explicit `--resolution`, else the scene's) scaled by `--resolution-scale` or, without
    /// an explicit resolution, by the preset's scale.
    pub fn settings(&self, scene_resolution: Resolution) -> Result<BakeSettings, RelumeError> {
        let mut s = BakeSettings {
            spp: DEFAULT_SPP,
            light_samples: DEFAULT_LIGHT_SAMPLES,
            indirect_samples: DEFAULT_INDIRECT_SAMPLES,
            bounces: match (self.bounces, self.preset) {
                (Some(n), _) => n,
                (None, Some(_)) => DEFAULT_BOUNCES,
                (None, None) => 1,
            },
            sampling: IndirectSampling::Uniform,
            seed: self.seed,
            resolution: None,
            precision: match self.precision {
                PrecisionArg::F16 => Precision::F16,
                PrecisionArg::F32 => Precision::F32,
            },
            basis: BasisConfig {
                ns_min: self.ns_min.unwrap_or(default_ns_range()[0]),
                ns_max: self.ns_max.unwrap_or(default_ns_range()[1]),
                count: BasisCount::Fixed(DEFAULT_BASES),
                ..BasisConfig::default()
            },
            principled_basis: match self.lobe {
                LobeArg::BlinnPhong => None,
                LobeArg::Principled => Some(PrincipledBasisConfig::default()),
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
        };
        let preset_scale = match self.preset {
            Some(p) => p.preset().apply(&mut s),
            None => 1.0,
        };
        if let Some(v) = self.spp {
            s.spp = v;
        }
        if let Some(v) = self.bounce_budget {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return Err(RelumeError::invalid(
                    "--bounce-budget",
                    format!("{v} (a share of the light in [0, 1))"),
                ));
            }
            s.bounce_budget = v;
        }
        if let Some(v) = self.light_samples {
            s.light_samples = v;
        }
        if let Some(v) = self.indirect_samples {
            s.indirect_samples = v;
        }
        if let Some(v) = self.denoise_direct {
            s.denoise.direct_iterations = v;
        }
        if let Some(v) = self.denoise_bounce {
            s.denoise.bounce_iterations = v;
        }
        if self.memory_budget_mb.is_some() {
            s.memory_budget = budget_from_mib(self.memory_budget_mb)?;
        }
        if let Some(v) = self.sampling {
            s.sampling = match v {
                SamplingArg::Uniform => IndirectSampling::Uniform,
                SamplingArg::Mixture => IndirectSampling::Mixture,
                SamplingArg::Guided => IndirectSampling::Guided,
            };
        }
        if let Some(step) = self.compression_step {
            s.compression = s.compression.with_step(step);
        }
        if let Some(t) = self.compression_tolerance {
            if s.compression.step == 0 {
                return Err(RelumeError::invalid(
                    "--compression-tolerance",
                    "the bounce layers are not compressed: give --compression-step or a preset",
                ));
            }
            s.compression.tolerance = t;
        }
        match (self.tolerance, self.bases) {
            (Some(t), _) => s.basis.count = BasisCount::Tolerance(t),
            (None, Some(n)) => s.basis.count = BasisCount::Fixed(n),
            (None, None) => {}
        }
        let explicit = match &self.resolution {
            None => None,
            Some(text) => Some(parse_resolution(text)?),
        };
        let scale = match (self.resolution_scale, explicit) {
            (Some(f), _) => {
                // Checked even at 1, so "--resolution-scale nan" never passes silently.
                scale_resolution(
                    Resolution {
                        width: 1,
                        height: 1,
                    },
                    f,
                )?;
                f
            }
            (None, Some(_)) => 1.0,
            (None, None) => preset_scale,
        };
        s.resolution = match (explicit, scale == 1.0) {
            (None, true) => None,
            (Some(r), true) => Some(r),
            (base, false) => Some(scale_resolution(base.unwrap_or(scene_resolution), scale)?),
        };
        s.validate()?;
        Ok(s)
    }
}

/// `r` with each side multiplied by `scale` (the engine's [`Resolution::scaled`], as the
/// Python bindings' `resolution_scale`): errors name `--resolution-scale`.
pub fn scale_resolution(r: Resolution, scale: f64) -> Result<Resolution, RelumeError> {
    r.scaled(scale).map_err(|e| match e {
        RelumeError::InvalidValue { message, .. } => {
            RelumeError::invalid("--resolution-scale", message)
        }
        other => other,
    })
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
    let r = Resolution { width, height };
    r.validate("--resolution")?;
    Ok(r)
}

/// `--memory-budget-mb` in bytes (`None`: the default budget), refused unless finite and > 0;
/// one reading for every command that takes it.
pub fn budget_from_mib(mib: Option<f64>) -> Result<Option<u64>, RelumeError> {
    match mib {
        None => Ok(None),
        Some(mb) if mb.is_finite() && mb > 0.0 => Ok(Some((mb * 1024.0 * 1024.0) as u64)),
        Some(mb) => Err(RelumeError::invalid(
            "--memory-budget-mb",
            format!("{mb} (MiB, must be > 0)"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use relume_engine::bake::settings::BounceCompression;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        options: BakeOptions,
    }

    const SCENE: Resolution = Resolution {
        width: 512,
        height: 384,
    };

    fn settings(args: &[&str]) -> Result<BakeSettings, RelumeError> {
        let cli = Cli::try_parse_from(std::iter::once("relume").chain(args.iter().copied()))
            .map_err(|e| RelumeError::invalid("arguments", e.to_string()))?;
        cli.options.settings(SCENE)
    }

    #[test]
    fn without_a_preset_the_defaults_are_the_papers() {
        let s = settings(&[]).unwrap();
        assert_eq!((s.spp, s.light_samples, s.indirect_samples), (16, 4, 1));
        assert_eq!(s.sampling, IndirectSampling::Uniform);
        assert!(matches!(s.basis.count, BasisCount::Fixed(6)));
        assert_eq!(s.resolution, None);
        assert_eq!((s.bounces, s.bounce_budget), (1, 0.0));
    }

    #[test]
    fn compression_flags_override_the_preset_and_bad_values_are_refused_by_the_engine() {
        assert_eq!(settings(&[]).unwrap().compression, BounceCompression::OFF);
        let preview = Preset::Preview.values().compression;
        assert_eq!(
            settings(&["--preset", "preview"]).unwrap().compression,
            preview
        );
        let off = settings(&["--preset", "final", "--compression-step", "0"]).unwrap();
        assert_eq!(off.compression.step, 0);
        let c = settings(&["--compression-step", "8"]).unwrap().compression;
        assert_eq!(
            (c.step, c.tolerance),
            (8, BounceCompression::DEFAULT_TOLERANCE)
        );
        let c = settings(&["--preset", "preview", "--compression-tolerance", "0.005"])
            .unwrap()
            .compression;
        assert_eq!((c.step, c.tolerance), (preview.step, 0.005));
        // Without compression a tolerance means nothing: said, not ignored.
        let e = settings(&["--compression-tolerance", "0.01"]).unwrap_err();
        assert!(e.to_string().contains("--compression-step"), "{e}");
        // The engine's rules (BakeSettings::validate) judge the values.
        for bad in [
            &["--compression-step", "17"][..],
            &["--preset", "draft", "--compression-tolerance", "1.5"][..],
            &["--preset", "draft", "--compression-tolerance", "NaN"][..],
        ] {
            let e = settings(bad).unwrap_err();
            assert!(e.to_string().contains("compression"), "{bad:?}: {e}");
        }
    }

    #[test]
    fn a_preset_caps_bounces_at_blenders_default_and_measures_what_the_scene_needs() {
        let s = settings(&["--preset", "final"]).unwrap();
        assert_eq!(s.bounces, DEFAULT_BOUNCES);
        assert_eq!(s.bounce_budget, Preset::Final.values().bounce_budget);
        let s = settings(&[
            "--preset",
            "final",
            "--bounces",
            "3",
            "--bounce-budget",
            "0",
        ])
        .unwrap();
        assert_eq!((s.bounces, s.bounce_budget), (3, 0.0));
        assert!(settings(&["--bounce-budget", "2"]).is_err());
    }

    #[test]
    fn a_preset_sets_its_values_and_scales_the_scene_resolution() {
        for preset in Preset::ALL {
            let s = settings(&["--preset", preset.name()]).unwrap();
            let v = preset.values();
            assert_eq!(
                (s.spp, s.light_samples, s.indirect_samples, s.sampling),
                (v.spp, v.light_samples, v.indirect_samples, v.sampling),
                "{}",
                preset.name()
            );
            assert!(
                matches!(s.basis.count, BasisCount::Tolerance(t) if t == v.basis_tolerance),
                "{}",
                preset.name()
            );
            let expected = (v.resolution_scale != 1.0)
                .then(|| scale_resolution(SCENE, v.resolution_scale).unwrap());
            assert_eq!(s.resolution, expected, "{}", preset.name());
        }
        assert_eq!(
            settings(&["--preset", "draft"]).unwrap().resolution,
            Some(Resolution {
                width: 256,
                height: 192
            })
        );
    }

    #[test]
    fn explicit_flags_override_the_preset() {
        let s = settings(&[
            "--preset",
            "final",
            "--spp",
            "3",
            "--light-samples",
            "2",
            "--sampling",
            "uniform",
            "--bases",
            "7",
            "--seed",
            "9",
        ])
        .unwrap();
        let f = Preset::Final.values();
        assert_eq!((s.spp, s.light_samples, s.seed), (3, 2, 9));
        assert_eq!(
            s.indirect_samples, f.indirect_samples,
            "not given: the preset's"
        );
        assert_eq!(s.sampling, IndirectSampling::Uniform);
        assert!(matches!(s.basis.count, BasisCount::Fixed(7)));
        let s = settings(&["--preset", "final", "--tolerance", "0.2", "--bases", "7"]).unwrap();
        assert!(matches!(s.basis.count, BasisCount::Tolerance(t) if t == 0.2));
    }

    #[test]
    fn an_explicit_resolution_wins_over_the_preset_scale() {
        let s = settings(&["--preset", "draft", "--resolution", "100x50"]).unwrap();
        assert_eq!(
            s.resolution,
            Some(Resolution {
                width: 100,
                height: 50
            })
        );
        let s = settings(&["--preset", "draft", "--resolution-scale", "0.25"]).unwrap();
        assert_eq!(
            s.resolution,
            Some(Resolution {
                width: 128,
                height: 96
            })
        );
        let s = settings(&["--resolution", "100x50", "--resolution-scale", "0.5"]).unwrap();
        assert_eq!(
            s.resolution,
            Some(Resolution {
                width: 50,
                height: 25
            })
        );
        let s = settings(&["--preset", "draft", "--resolution-scale", "1"]).unwrap();
        assert_eq!(s.resolution, None);
        assert!(settings(&["--resolution-scale", "0"]).is_err());
        assert!(settings(&["--resolution-scale", "nan"]).is_err());
        let e = settings(&["--preset", "ultra"]).unwrap_err().to_string();
        assert!(
            e.contains("draft") && e.contains("preview") && e.contains("final"),
            "{e}"
        );
    }
}

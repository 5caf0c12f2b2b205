//! Options shared by the commands that trace paths (bake, reference, bench bake): a preset
//! and one flag per bake setting, made from the engine's [`FIELDS`] (a flag is its key with
//! dashes, its help the key's documentation), so a setting added to the engine is a flag
//! with no code here. A value is read as JSON when it parses (numbers, `null`) and as text
//! otherwise (`uniform`, `256x256`), then converted by serde; the engine's rules judge it.

use clap::{Arg, ArgMatches, Args, FromArgMatches, ValueEnum};
use relume_engine::bake::fields::{BakeFields, FIELDS};
use relume_engine::bake::presets::Preset;
use relume_engine::bake::BakeSettings;
use relume_engine::scene::Resolution;
use relume_engine::RelumeError;
use serde_json::{Map, Value};

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

/// Older spellings of two flags, kept for the scripts and farm templates that use them.
pub const FLAG_ALIASES: [(&str, &str); 2] = [
    ("basis_tolerance", "tolerance"),
    ("light_grouping", "light-groups"),
];

/// Bake options; `reference` takes the same so it traces the same paths.
///
/// Precedence: an explicit flag, then the preset's value (`--preset`), then the default.
#[derive(Args, Clone)]
pub struct BakeOptions {
    /// Quality preset: sets samples, sampling, the basis tolerance, the denoiser, the
    /// compression, a bounce budget (with 12 bounces as the cap) and a resolution scale
    /// (draft: ½); explicit flags override its values. docs/measurements.md#presets-measured
    /// says what each costs.
    #[arg(long, value_enum)]
    pub preset: Option<PresetArg>,
    #[command(flatten)]
    pub fields: FieldFlags,
}

/// The bake-setting flags given, as key → JSON value.
#[derive(Clone, Debug, Default)]
pub struct FieldFlags(pub Map<String, Value>);

impl FromArgMatches for FieldFlags {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut given = FieldFlags::default();
        given.update_from_arg_matches(m)?;
        Ok(given)
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        for field in FIELDS {
            if let Some(text) = m.get_one::<String>(field.key) {
                self.0.insert(field.key.into(), value_of(text));
            }
        }
        Ok(())
    }
}

impl Args for FieldFlags {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        let defaults = BakeFields::default().to_map();
        FIELDS.iter().fold(cmd, |cmd, field| {
            let default = defaults
                .get(field.key)
                .map_or("null".into(), Value::to_string);
            let key = field.key;
            let mut arg = Arg::new(field.key)
                .long(field.flag())
                .value_parser(move |text: &str| of_its_type(key, text).map(|()| text.to_string()))
                .value_name(field.key.to_uppercase())
                .help(format!(
                    "{} [default: {default}, or the preset's]",
                    field.doc()
                ));
            for (key, alias) in FLAG_ALIASES {
                if key == field.key {
                    arg = arg.visible_alias(alias);
                }
            }
            cmd.arg(arg)
        })
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

/// A flag's text as JSON: parsed when it is JSON (numbers, `null`), else the text itself.
fn value_of(text: &str) -> Value {
    serde_json::from_str(text).unwrap_or_else(|_| Value::from(text))
}

/// Whether `text` converts to the type of the field `key` (not whether the engine's rules
/// accept the value): a value of the wrong type is a usage error, as clap's typed flags
/// make it, with serde's words.
fn of_its_type(key: &str, text: &str) -> Result<(), String> {
    let mut map = BakeFields::default().to_map();
    map.insert(key.into(), value_of(text));
    serde_json::from_value::<BakeFields>(Value::Object(map))
        .map(drop)
        .map_err(|e| e.to_string())
}

impl BakeOptions {
    /// The engine's settings for a scene whose own resolution is `scene_resolution`: the
    /// preset's fields (or the defaults), then the flags given. An error names the flag.
    pub fn settings(&self, scene_resolution: Resolution) -> Result<BakeSettings, RelumeError> {
        let mut fields = match self.preset {
            Some(p) => BakeFields::preset(p.preset()),
            None => BakeFields::default(),
        };
        fields
            .apply(&self.fields.0)
            .and_then(|()| fields.settings(scene_resolution))
            .map_err(name_the_flag)
    }
}

/// An error naming a setting by its key names it by its flag.
fn name_the_flag(e: RelumeError) -> RelumeError {
    match e {
        RelumeError::InvalidValue { what, message } if FIELDS.iter().any(|f| f.key == what) => {
            RelumeError::invalid(format!("--{}", what.replace('_', "-")), message)
        }
        other => other,
    }
}

/// `r` with each side multiplied by `scale` (the engine's [`Resolution::scaled`]): errors
/// name `--resolution-scale`.
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
/// for `merge`, which takes the budget without the bake's other settings.
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
    use relume_engine::bake::settings::{BounceCompression, DEFAULT_BOUNCES};
    use relume_engine::bake::{IndirectSampling, LightGrouping};
    use relume_engine::brdf::BasisCount;

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
        assert!(e.to_string().contains("give a compression step"), "{e}");
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
        let s = settings(&["--preset", "final", "--tolerance", "0.2"]).unwrap();
        assert!(matches!(s.basis.count, BasisCount::Tolerance(t) if t == 0.2));
        // Both name the basis count: refused rather than one silently ignored.
        let e = settings(&["--tolerance", "0.2", "--bases", "7"]).unwrap_err();
        assert!(e.to_string().contains("not both"), "{e}");
    }

    #[test]
    fn every_flag_the_docs_and_scripts_use_still_parses() {
        let s = settings(&[
            "--spp=2",
            "--light-samples=3",
            "--indirect-samples=2",
            "--bounces=2",
            "--bounce-budget=0.01",
            "--sampling=guided",
            "--seed=5",
            "--resolution=64x32",
            "--resolution-scale=0.5",
            "--precision=f32",
            "--bases=5",
            "--ns-min=2",
            "--ns-max=300",
            "--lobe=principled",
            "--threads=2",
            "--drop-budget=0.001",
            "--light-groups=per-light",
            "--subsurface-samples=1024",
            "--subsurface-theta=0.3",
            "--denoise-direct=1",
            "--denoise-bounce=2",
            "--memory-budget-mb=512",
            "--compression-step=4",
            "--compression-tolerance=0.01",
        ])
        .unwrap();
        assert_eq!(
            (s.spp, s.light_samples, s.indirect_samples, s.seed),
            (2, 3, 2, 5)
        );
        assert_eq!((s.bounces, s.bounce_budget), (2, 0.01));
        assert_eq!(s.sampling, IndirectSampling::Guided);
        assert_eq!(
            s.resolution,
            Some(Resolution {
                width: 32,
                height: 16
            })
        );
        assert_eq!(s.precision, relume_engine::stack::Precision::F32);
        assert!(matches!(s.basis.count, BasisCount::Fixed(5)));
        assert_eq!((s.basis.ns_min, s.basis.ns_max), (2.0, 300.0));
        assert!(s.principled_basis.is_some());
        assert_eq!((s.threads, s.drop_budget), (2, 0.001));
        assert_eq!(s.light_grouping, LightGrouping::PerLight);
        assert_eq!((s.subsurface_samples, s.subsurface_theta), (1024, 0.3));
        assert_eq!(
            (s.denoise.direct_iterations, s.denoise.bounce_iterations),
            (1, 2)
        );
        assert_eq!(s.memory_budget, Some(512 * 1024 * 1024));
        assert_eq!((s.compression.step, s.compression.tolerance), (4, 0.01));
        let s = settings(&["--light-groups", "none"]).unwrap();
        assert_eq!(s.light_grouping, LightGrouping::All);
    }

    #[test]
    fn a_bad_value_is_refused_naming_its_flag() {
        for (args, flag) in [
            (&["--spp", "0"][..], "--spp"),
            (&["--spp", "many"][..], "--spp"),
            (&["--sampling", "best"][..], "--sampling"),
            (&["--resolution", "wide"][..], "--resolution"),
            (&["--memory-budget-mb", "0"][..], "--memory-budget-mb"),
            (&["--threads", "100000"][..], "--threads"),
        ] {
            let e = settings(args).unwrap_err().to_string();
            assert!(e.contains(flag), "{args:?}: {e}");
        }
        let e = settings(&["--sampling", "best"]).unwrap_err().to_string();
        assert!(e.contains("uniform") && e.contains("guided"), "{e}");
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

//! The bake settings as the front ends name them: one flat key per value a user sets, each
//! documented here once. The command line's flags (`--light-samples`), the Python keyword
//! arguments (`light_samples=`) and the add-on's mapping are these keys, converted by serde
//! with no rules of their own: [`BakeSettings::validate`] judges the values.
//!
//! [`BakeSettings`] stays the engine's shape (nested, as stacks and farm files record it);
//! [`BakeFields`] is its flat face, with the resolution scale the fronts add on top.

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use super::presets::Preset;
use super::settings::{AdaptiveSampling, BakeSettings, BounceCompression, DEFAULT_BOUNCES};
use crate::brdf::principled_basis::PrincipledBasisConfig;
use crate::brdf::{BasisConfig, BasisCount};
use crate::options::{Denoise, IndirectSampling, LightGrouping, Precision};
use crate::scene::Resolution;
use crate::{RelumeError, Result};

/// One key of [`BakeFields`] and its documentation, for the command line's help and the
/// generated reference.
#[derive(Clone, Copy, Debug)]
pub struct Field {
    /// The key as Python and JSON spell it (`light_samples`).
    pub key: &'static str,
    raw_doc: &'static str,
}

impl Field {
    /// The key as a command-line flag spells it (`light-samples`).
    pub fn flag(&self) -> String {
        self.key.replace('_', "-")
    }

    /// The doc comment as one paragraph.
    pub fn doc(&self) -> String {
        let words: Vec<&str> = self.raw_doc.split_whitespace().collect();
        words.join(" ")
    }
}

/// Declares [`BakeFields`] and [`FIELDS`] from one list, so that a field's documentation is
/// written once and reaches the struct, the command line and the reference alike. A serde
/// attribute is written `@serde(...)` after the doc (a `#[...]` there would be ambiguous).
macro_rules! bake_fields {
    ($( $(#[doc = $doc:literal])+ $(@serde($($serde:tt)*))? $key:ident : $ty:ty, )+) => {
        /// Every bake setting a user sets, flat (see the module's doc).
        #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct BakeFields {
            $( $(#[doc = $doc])+ $(#[serde($($serde)*)])? pub $key: $ty, )+
        }

        /// Every key of [`BakeFields`], in declaration order (the order overrides apply in).
        pub const FIELDS: &[Field] = &[
            $( Field { key: stringify!($key), raw_doc: concat!($($doc, "\n"),+) }, )+
        ];
    };
}

bake_fields! {
    /// Eye samples per pixel (anti-aliasing; the eye region is in the layer key).
    spp: u32,
    /// Samples per light (and for the world) at the eye's shading point, and past it unless
    /// `bounce_light_samples` is given; at most 1024.
    light_samples: u32,
    /// Samples per light at the vertices past the eye (the bounces), at most 1024; null: as
    /// many as `light_samples`. Draft and preview set 1, as Cycles takes one per vertex
    /// (light there is averaged by the indirect samples anyway); final sets 4.
    bounce_light_samples: Option<u32>,
    /// Indirect directions per eye hit; at most 1024.
    indirect_samples: u32,
    /// Indirect bounces as Cycles' Max Bounces counts them (0: direct light only; 1: one
    /// bounce, the paper's, exact under edits; more: bounces 2.. traced with the bake-time
    /// materials, following albedo and colour edits through the tail-edit layers), at most
    /// 128. With a bounce budget it is the cap, and
    /// the bake measures how many the scene needs; a preset sets 12, Blender's default.
    bounces: u32,
    /// Most diffuse bounces a path takes, as Cycles' Diffuse light path limit (Blender's
    /// default 4); null: only `bounces` limits them. With `glossy_bounces`, a path that
    /// alternates glossy and diffuse surfaces goes on past either alone, as in Cycles.
    diffuse_bounces: Option<u32>,
    /// Most glossy bounces a path takes, as Cycles' Glossy light path limit (Blender's
    /// default 4); null: only `bounces` limits them.
    glossy_bounces: Option<u32>,
    /// Share of the image's light the bounces past the baked count may leave out, in
    /// [0, 1) (0: bake exactly `bounces`).
    bounce_budget: f32,
    /// Indirect directions: `uniform` over the hemisphere (the paper), a cosine + lobes
    /// `mixture`, or `guided` by a short first pass.
    sampling: IndirectSampling,
    /// Seed of every random sequence: the same seed and settings give the same stack.
    seed: u64,
    /// Overrides the scene's resolution: `WIDTHxHEIGHT` or `[width, height]`; null keeps
    /// the scene's. Setting it resets the resolution scale to 1 unless that is given too.
    @serde(with = "resolution_text")
    resolution: Option<Resolution>,
    /// Scales each side of the resolution (the scene's or the one given), in (0, 16]; a
    /// preset sets its own (draft: 0.5).
    resolution_scale: f64,
    /// Storage precision of the layers: `f16` (half the memory, relative rounding ≤ 2⁻¹¹)
    /// or `f32`.
    precision: Precision,
    /// Basis count N_b, the diffuse basis included; null when a tolerance picks it.
    bases: Option<u32>,
    /// The smallest basis whose worst lobe error is at most this (e.g. 0.03) instead of a
    /// fixed count; null for a fixed count. Give this or `bases`, not both.
    basis_tolerance: Option<f32>,
    /// Smallest Blinn–Phong exponent of editable regions without a range of their own
    /// (the default is the fitted exponent at Principled roughness 1).
    ns_min: f32,
    /// Largest exponent of that range (the default is the fitted exponent at roughness 0.1).
    ns_max: f32,
    /// The lobes editable regions are baked in: `principled`, Cycles' Principled lobes plus
    /// each region's bake-time lobe as a slot of its own, for opaque, untextured Principled
    /// materials (the presets' choice; textured and translucent ones keep Blinn–Phong, with
    /// a warning), or the paper's `blinn-phong` basis with the fitted mapping (the default
    /// without a preset).
    lobe: Lobe,
    /// Slots of the Principled basis, its constant included (each region's bake-time lobe
    /// adds one), 2 to 31; null: 21, the basis of the study. A preset sets its own (draft 8,
    /// preview 17, final 21): more slots carry roughness and metallic edits further.
    principled_bases: Option<u32>,
    /// Worker threads (0: every core); the result does not depend on it.
    threads: usize,
    /// Leaves out layers whose worst-case contribution to any relit image stays within this
    /// relative L2 error, in [0, 1) (0 keeps every layer a path reached).
    drop_budget: f32,
    /// Which lights share layers: `all` (also spelled `none`: no groups), `per-light` (one
    /// group per light and one for the world) or `scene` (the scene file's light groups).
    /// Each group's strength and colour stay editable; storage and relight cost grow with
    /// the number of groups.
    light_grouping: LightGrouping,
    /// Surface samples per translucent region (uniform by area), unless the region sets
    /// `subsurface.samples`.
    subsurface_samples: u32,
    /// Opening criterion θ of the subsurface octree (> 0): smaller is closer to the
    /// brute-force sum and slower.
    subsurface_theta: f32,
    /// À-trous iterations of the stack's linear denoiser on the direct layers (0 to 8);
    /// each doubles the kernel's reach.
    denoise_direct: u32,
    /// À-trous iterations on the one-bounce layers (0 to 8).
    denoise_bounce: u32,
    /// Memory the bake may plan to use at its peak, in MiB (> 0); a bake whose estimate
    /// exceeds it is refused before tracing. Null: 80 % of the available memory.
    memory_budget_mb: Option<f64>,
    /// Bounce-layer compression: pixels between lattice nodes (1 to 16), 0 to store every
    /// layer per pixel. Turning it on alone also sets the default tolerance (0.02).
    compression_step: u32,
    /// Relative L2 error of each tile's bake-time image the bounce-layer compression may
    /// spend, in [0, 1); needs a compression step.
    compression_tolerance: f32,
    /// Per-tile adaptive sampling's noise threshold, in [0, 1) (0: off, every pixel takes
    /// `spp` samples): a 16 × 16 tile stops once its estimated error — Cycles' per-pixel
    /// error (the noise from the full and a half-sample image of the bake-time materials,
    /// over the square root of the intensity), its RMS over the tile — is at most this.
    /// Not with a progressive bake or a farm split.
    adaptive_threshold: f32,
    /// Eye samples every tile takes before adaptive sampling first checks it (then after
    /// every doubling); 0: an eighth of `spp`, at least 4. Needs an adaptive threshold.
    adaptive_min_spp: u32,
}

/// The basis editable regions are baked in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Lobe {
    BlinnPhong,
    Principled,
}

/// Keys that name one engine value two ways: giving one clears the other.
const EXCLUSIVE: [(&str, &str); 1] = [("bases", "basis_tolerance")];

const MIB: f64 = 1024.0 * 1024.0;

impl Default for BakeFields {
    /// The engine's defaults, unscaled.
    fn default() -> Self {
        BakeFields::from_settings(&BakeSettings::default(), 1.0)
    }
}

impl BakeFields {
    /// The flat face of `s`, with the front's resolution scale.
    pub fn from_settings(s: &BakeSettings, resolution_scale: f64) -> BakeFields {
        let (bases, basis_tolerance) = match s.basis.count {
            BasisCount::Fixed(n) => (Some(n), None),
            BasisCount::Tolerance(t) => (None, Some(t)),
        };
        BakeFields {
            spp: s.spp,
            light_samples: s.light_samples,
            bounce_light_samples: s.bounce_light_samples,
            indirect_samples: s.indirect_samples,
            bounces: s.bounces,
            diffuse_bounces: s.diffuse_bounces,
            glossy_bounces: s.glossy_bounces,
            bounce_budget: s.bounce_budget,
            sampling: s.sampling,
            seed: s.seed,
            resolution: s.resolution,
            resolution_scale,
            precision: s.precision,
            bases,
            basis_tolerance,
            ns_min: s.basis.ns_min,
            ns_max: s.basis.ns_max,
            lobe: match s.principled_basis {
                None => Lobe::BlinnPhong,
                Some(_) => Lobe::Principled,
            },
            principled_bases: s.principled_basis.as_ref().map(|c| c.bases as u32),
            threads: s.threads,
            drop_budget: s.drop_budget,
            light_grouping: s.light_grouping,
            subsurface_samples: s.subsurface_samples,
            subsurface_theta: s.subsurface_theta,
            denoise_direct: s.denoise.direct_iterations,
            denoise_bounce: s.denoise.bounce_iterations,
            memory_budget_mb: s.memory_budget.map(|b| b as f64 / MIB),
            compression_step: s.compression.step,
            compression_tolerance: s.compression.tolerance,
            adaptive_threshold: s.adaptive.threshold,
            adaptive_min_spp: s.adaptive.min_spp,
        }
    }

    /// A named preset's fields: its values over the defaults, its resolution scale, and
    /// Blender's default bounce count as the cap of the bounces the bake measures.
    pub fn preset(preset: Preset) -> BakeFields {
        let mut s = BakeSettings::default();
        let scale = preset.apply(&mut s);
        s.bounces = DEFAULT_BOUNCES;
        BakeFields::from_settings(&s, scale)
    }

    /// The engine's settings at the resolution given (or the scene's), before the scale.
    fn unscaled(&self) -> BakeSettings {
        let default = BakeSettings::default();
        BakeSettings {
            spp: self.spp,
            light_samples: self.light_samples,
            bounce_light_samples: self.bounce_light_samples,
            indirect_samples: self.indirect_samples,
            bounces: self.bounces,
            diffuse_bounces: self.diffuse_bounces,
            glossy_bounces: self.glossy_bounces,
            bounce_budget: self.bounce_budget,
            sampling: self.sampling,
            seed: self.seed,
            resolution: self.resolution,
            precision: self.precision,
            basis: BasisConfig {
                count: match (self.bases, self.basis_tolerance) {
                    (_, Some(t)) => BasisCount::Tolerance(t),
                    (Some(n), None) => BasisCount::Fixed(n),
                    (None, None) => default.basis.count,
                },
                ns_min: self.ns_min,
                ns_max: self.ns_max,
                ..default.basis
            },
            principled_basis: match self.lobe {
                Lobe::BlinnPhong => None,
                Lobe::Principled => {
                    let study = PrincipledBasisConfig::default();
                    Some(PrincipledBasisConfig {
                        bases: self.principled_bases.map_or(study.bases, |n| n as usize),
                        ..study
                    })
                }
            },
            threads: self.threads,
            drop_budget: self.drop_budget,
            light_grouping: self.light_grouping,
            subsurface_samples: self.subsurface_samples,
            subsurface_theta: self.subsurface_theta,
            denoise: Denoise {
                direct_iterations: self.denoise_direct,
                bounce_iterations: self.denoise_bounce,
            },
            // `as` saturates: a negative or NaN budget becomes 0 bytes, which `validate`
            // refuses.
            memory_budget: self.memory_budget_mb.map(|mb| (mb * MIB) as u64),
            compression: BounceCompression {
                step: 0,
                tolerance: self.compression_tolerance,
            }
            .with_step(self.compression_step),
            adaptive: AdaptiveSampling {
                threshold: self.adaptive_threshold,
                min_spp: self.adaptive_min_spp,
            },
        }
    }

    /// The engine's settings for a scene of `scene_resolution`, checked by
    /// [`BakeSettings::validate`]; the resolution scale applies to the resolution given, or
    /// else the scene's.
    pub fn settings(&self, scene_resolution: Resolution) -> Result<BakeSettings> {
        self.check()?;
        let mut s = self.unscaled();
        if self.resolution_scale != 1.0 {
            let base = s.resolution.unwrap_or(scene_resolution);
            s.resolution = Some(base.scaled(self.resolution_scale).map_err(|e| match e {
                RelumeError::InvalidValue { message, .. } => {
                    RelumeError::invalid("resolution_scale", message)
                }
                other => other,
            })?);
        }
        s.validate()?;
        Ok(s)
    }

    /// Every rule that does not need the scene: [`BakeSettings::validate`], and the scale's
    /// range.
    pub fn check(&self) -> Result<()> {
        let unit = Resolution {
            width: 1,
            height: 1,
        };
        unit.scaled(self.resolution_scale).map_err(|e| match e {
            RelumeError::InvalidValue { message, .. } => {
                RelumeError::invalid("resolution_scale", message)
            }
            other => other,
        })?;
        self.unscaled().validate()
    }

    /// Applies `overrides` (key → JSON value) in [`FIELDS`] order, whatever order they come
    /// in, and checks the result; on an error (naming the key) nothing changes. Giving both
    /// keys of a pair that name one value (`bases`, `basis_tolerance`) is refused; giving one
    /// clears the other. A resolution resets the scale to 1, a compression step of 0
    /// clears the tolerance and an adaptive threshold of 0 the adaptive minimum, unless
    /// those are given too.
    pub fn apply(&mut self, overrides: &Map<String, Value>) -> Result<()> {
        if let Some(key) = overrides
            .keys()
            .find(|k| !FIELDS.iter().any(|f| f.key == k.as_str()))
        {
            let keys: Vec<&str> = FIELDS.iter().map(|f| f.key).collect();
            return Err(RelumeError::invalid(
                key.as_str(),
                format!("no such bake setting (settings: {})", keys.join(", ")),
            ));
        }
        let given = |k: &str| overrides.get(k).is_some_and(|v| !v.is_null());
        for (a, b) in EXCLUSIVE {
            if given(a) && given(b) {
                return Err(RelumeError::invalid(
                    a,
                    format!("give {a} or {b}, not both (they name one value)"),
                ));
            }
        }
        let Value::Object(mut map) = serde_json::to_value(&*self).expect("plain data") else {
            unreachable!("a struct serialises to an object")
        };
        for field in FIELDS {
            let Some(value) = overrides.get(field.key) else {
                continue;
            };
            map.insert(field.key.into(), value.clone());
            for (a, b) in EXCLUSIVE {
                if field.key == a && given(a) {
                    map.insert(b.into(), Value::Null);
                } else if field.key == b && given(b) {
                    map.insert(a.into(), Value::Null);
                }
            }
            let reset = |map: &mut Map<String, Value>, key: &str, value: Value| {
                if !overrides.contains_key(key) {
                    map.insert(key.into(), value);
                }
            };
            match field.key {
                "resolution" if given("resolution") => {
                    reset(&mut map, "resolution_scale", Value::from(1.0))
                }
                "compression_step" if value.as_u64() == Some(0) => {
                    reset(&mut map, "compression_tolerance", Value::from(0.0))
                }
                "adaptive_threshold" if value.as_f64() == Some(0.0) => {
                    reset(&mut map, "adaptive_min_spp", Value::from(0))
                }
                _ => {}
            }
            serde_json::from_value::<BakeFields>(Value::Object(map.clone()))
                .map_err(|e| RelumeError::invalid(field.key, e.to_string()))?;
        }
        let next: BakeFields = serde_json::from_value(Value::Object(map))
            .map_err(|e| RelumeError::invalid("settings", e.to_string()))?;
        next.check()?;
        // Round trip through the engine's shape: coupled values (a step turning the
        // compression on gives it its default tolerance) read back as the bake will use them.
        *self = BakeFields::from_settings(&next.unscaled(), next.resolution_scale);
        Ok(())
    }

    /// These fields as a JSON object (for the Python bindings' `to_dict`).
    pub fn to_map(&self) -> Map<String, Value> {
        match serde_json::to_value(self) {
            Ok(Value::Object(map)) => map,
            _ => unreachable!("a struct of plain data serialises to an object"),
        }
    }
}

/// `resolution` as `WIDTHxHEIGHT` text or a `[width, height]` pair (written as the pair).
mod resolution_text {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use crate::scene::Resolution;

    pub fn serialize<S: Serializer>(r: &Option<Resolution>, s: S) -> Result<S::Ok, S::Error> {
        r.map(|r| [r.width, r.height]).serialize(s)
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Given {
        Pair([u32; 2]),
        Text(String),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Resolution>, D::Error> {
        let bad = |what: &str| {
            serde::de::Error::custom(format!(
                "{what} (expected WIDTHxHEIGHT, e.g. 512x512, or [width, height])"
            ))
        };
        let given = Option::<Given>::deserialize(d).map_err(|_| bad("not a resolution"))?;
        let (width, height) = match given {
            None => return Ok(None),
            Some(Given::Pair([w, h])) => (w, h),
            Some(Given::Text(text)) => {
                let (w, h) = text
                    .split_once(['x', 'X'])
                    .ok_or_else(|| bad(&format!("\"{text}\"")))?;
                let side = |v: &str| {
                    v.trim()
                        .parse::<u32>()
                        .map_err(|_| bad(&format!("\"{text}\"")))
                };
                (side(w)?, side(h)?)
            }
        };
        Ok(Some(Resolution { width, height }))
    }
}

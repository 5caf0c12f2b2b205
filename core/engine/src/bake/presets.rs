//! Named quality presets: draft, preview, final.
//!
//! A preset fixes the settings that trade bake time against accuracy — eye samples, light
//! samples, indirect samples, indirect sampling, the editable materials' bases (Cycles'
//! Principled lobes for Principled materials, and both bases' sizes) and a resolution scale —
//! and leaves the rest (seed, precision, ns range, light grouping, threads) as the caller set them.
//! It also sets the error budget of bounces ("what the scene needs", measured before the
//! bake); the bounce count itself stays the caller's, as the cap (the command line and the
//! Python bindings give a preset Blender's default, 12, when the caller says nothing).
//! The same table serves the command line (`relume bake --preset`), the Python bindings
//! (`BakeSettings.preset`) and the add-on's preferences, so a preset means the same bake
//! everywhere. What each preset costs and how close it gets is measured, not promised: see
//! the README's preset table.

use serde::Serialize;

use super::settings::{BakeSettings, BounceCompression, Denoise, IndirectSampling};
use crate::brdf::principled_basis::PrincipledBasisConfig;
use crate::brdf::BasisCount;

/// Per-entry tolerance of the draft and preview presets' bounce-layer compression
/// ([`BounceCompression::tolerance`]).
const COMPRESSION_TOLERANCE: f32 = BounceCompression::DEFAULT_TOLERANCE;

/// The final preset's compression tolerance: tighter, so that the error the compression
/// adds stays small against the final preset's own error against a converged reference
/// (measured: docs/scale.md, "Lattice fits and the sign").
const FINAL_COMPRESSION_TOLERANCE: f32 = 0.005;

/// A named quality preset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Seconds at half resolution: for checking the set-up, not for judging materials.
    Draft,
    /// The default: a usable image at full resolution in seconds to a minute on 2 cores.
    Preview,
    /// Many samples and a tight basis, for final frames.
    Final,
}

/// The values a preset sets.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PresetValues {
    pub spp: u32,
    pub light_samples: u32,
    /// Light samples at the vertices past the eye. Draft and preview take one, as Cycles
    /// does: a bounce vertex's direct light is averaged over the indirect samples anyway,
    /// and each further sample costs a shadow ray and the vertex's basis values; measured on
    /// the shared glossy scenes as the same error for a quarter to a third less bake
    /// (docs/trade.md). Final keeps as many as the eye takes: with one, its smoothest metal
    /// sphere moved outside the per-material goal against Cycles over four bake seeds
    /// (docs/trade.md, "Light samples past the eye"), which is not yet told apart from
    /// noise.
    pub bounce_light_samples: u32,
    pub indirect_samples: u32,
    pub sampling: IndirectSampling,
    /// Largest relative L2 error of the BRDF basis (picks N_b). Each preset's value is
    /// chosen for the count it yields over the default roughness range: the count sets the
    /// layers, and so the stack's size and the bake's time, while the relit image follows
    /// the lobes' average error at that count (docs/measurements.md, "Presets").
    pub basis_tolerance: f32,
    /// Fraction of the scene's resolution baked (each side).
    pub resolution_scale: f64,
    /// The stack's linear denoiser ([`crate::bake::finish::denoise`]): biased, measured.
    pub denoise: Denoise,
    /// Share of the image's light the bounces past the baked count may leave out: the bake
    /// measures what each bounce adds and bakes as many as that needs, up to the caller's
    /// `bounces` ([`crate::bake::prepare::bounces`]).
    pub bounce_budget: f32,
    /// Lattice compression of the bounce layers: an approximation whose error the bake
    /// measures and reports.
    pub compression: BounceCompression,
    /// Slots of the Principled basis editable Principled materials are baked in (the
    /// constant included; the region's bake-time lobe adds one). The bake-time slot makes
    /// the unedited image exact at any size, so the size decides how far a roughness or
    /// metallic edit stays close (docs/fidelity.md, "What an edit keeps") and what the bake
    /// costs: the layers grow with the square of the slots of all editable regions. Draft,
    /// not for judging materials, takes the fewest; preview a middle size whose bake costs
    /// about what the Blinn–Phong basis' does with two editable materials; final the
    /// study's basis.
    pub principled_bases: usize,
}

impl Preset {
    /// Every preset, cheapest first.
    pub const ALL: [Preset; 3] = [Preset::Draft, Preset::Preview, Preset::Final];

    /// The preset's name as the command line and the add-on spell it.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Draft => "draft",
            Preset::Preview => "preview",
            Preset::Final => "final",
        }
    }

    /// Parses a name written by [`Preset::name`].
    pub fn parse(name: &str) -> Option<Preset> {
        Preset::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The values this preset sets. Preview and final draw their indirect directions
    /// guided: their guide pass (a quarter of their indirect paths) is a small share of
    /// their rays and pays for itself where light is concentrated. Draft keeps the mixture:
    /// with its few samples even the smallest guide pass would be a large share of its rays.
    ///
    /// The error of a relit image is Monte Carlo noise far more than basis error, and the
    /// noise is shared between the direct light at the eye vertex (light samples × eye
    /// samples) and the one indirect bounce (indirect samples × eye samples), which a single
    /// indirect direction per eye sample leaves dominant. Indirect samples are cheaper than
    /// eye samples (no camera ray, no direct light at the eye vertex), so the presets spend
    /// on them. The figures behind these choices are in docs/measurements.md ("Presets",
    /// "Sampling", and "Figures that were in code comments").
    pub fn values(self) -> PresetValues {
        match self {
            Preset::Draft => PresetValues {
                spp: 4,
                light_samples: 2,
                bounce_light_samples: 1,
                indirect_samples: 2,
                sampling: IndirectSampling::Mixture,
                basis_tolerance: 0.045,
                resolution_scale: 0.5,
                denoise: Denoise {
                    direct_iterations: 0,
                    bounce_iterations: 2,
                },
                bounce_budget: 0.03,
                compression: BounceCompression {
                    step: 8,
                    tolerance: COMPRESSION_TOLERANCE,
                },
                principled_bases: 8,
            },
            Preset::Preview => PresetValues {
                spp: 16,
                light_samples: 4,
                bounce_light_samples: 1,
                indirect_samples: 4,
                sampling: IndirectSampling::Guided,
                basis_tolerance: 0.028,
                resolution_scale: 1.0,
                denoise: Denoise {
                    direct_iterations: 0,
                    bounce_iterations: 3,
                },
                bounce_budget: 0.01,
                compression: BounceCompression {
                    step: 4,
                    tolerance: COMPRESSION_TOLERANCE,
                },
                principled_bases: 17,
            },
            Preset::Final => PresetValues {
                spp: 128,
                light_samples: 4,
                bounce_light_samples: 4,
                indirect_samples: 2,
                sampling: IndirectSampling::Guided,
                basis_tolerance: 0.009,
                resolution_scale: 1.0,
                denoise: Denoise {
                    direct_iterations: 0,
                    bounce_iterations: 2,
                },
                bounce_budget: 0.005,
                // Lattice fits keep the sign of the layers they stand in for
                // (`stack::tiled::lattice_sign`), so compression no longer risks negative
                // pixels; final spends a quarter of the other presets' tolerance.
                compression: BounceCompression {
                    step: 4,
                    tolerance: FINAL_COMPRESSION_TOLERANCE,
                },
                principled_bases: 21,
            },
        }
    }

    /// Writes the preset's values into `settings`, keeping every other field. The resolution
    /// scale is returned rather than applied, because the scene's resolution is not known here.
    pub fn apply(self, settings: &mut BakeSettings) -> f64 {
        let v = self.values();
        settings.spp = v.spp;
        settings.light_samples = v.light_samples;
        settings.bounce_light_samples = Some(v.bounce_light_samples);
        settings.indirect_samples = v.indirect_samples;
        settings.sampling = v.sampling;
        settings.basis.count = BasisCount::Tolerance(v.basis_tolerance);
        settings.denoise = v.denoise;
        settings.bounce_budget = v.bounce_budget;
        settings.compression = v.compression;
        settings.principled_basis = Some(PrincipledBasisConfig {
            bases: v.principled_bases,
            ..PrincipledBasisConfig::default()
        });
        v.resolution_scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::basis::LobeWeighting;
    use crate::brdf::{BasisConfig, BrdfBasis};

    #[test]
    fn names_round_trip_and_presets_grow_in_cost() {
        for p in Preset::ALL {
            assert_eq!(Preset::parse(p.name()), Some(p));
        }
        assert_eq!(Preset::parse("ultra"), None);
        let cost = |p: Preset| {
            let v = p.values();
            v.spp as f64
                * (v.light_samples + v.indirect_samples) as f64
                * v.resolution_scale.powi(2)
        };
        assert!(cost(Preset::Draft) < cost(Preset::Preview));
        assert!(cost(Preset::Preview) < cost(Preset::Final));
        assert!(Preset::Final.values().basis_tolerance < Preset::Preview.values().basis_tolerance);
        assert!(Preset::Final.values().bounce_budget < Preset::Preview.values().bounce_budget);
        assert!(Preset::Preview.values().bounce_budget < Preset::Draft.values().bounce_budget);
        let tolerance = |p: Preset| p.values().compression.tolerance;
        assert!(tolerance(Preset::Final) > 0.0);
        assert!(tolerance(Preset::Final) < tolerance(Preset::Preview));
    }

    #[test]
    fn apply_keeps_the_fields_a_preset_does_not_own() {
        let mut s = BakeSettings {
            seed: 77,
            bounces: 0,
            ..BakeSettings::default()
        };
        let scale = Preset::Draft.apply(&mut s);
        assert_eq!(scale, 0.5);
        assert_eq!((s.seed, s.bounces, s.spp), (77, 0, 4));
        assert!(matches!(s.basis.count, BasisCount::Tolerance(t) if t == 0.045));
    }

    fn with(f: impl FnOnce(&mut BasisConfig)) -> BasisConfig {
        let mut c = BasisConfig::default();
        f(&mut c);
        c
    }

    #[test]
    fn capped_search_keeps_the_unit_weightings_average() {
        // Over the default roughness range at each preset's tolerance, the capped search must
        // meet the tolerance without giving up the low average of the unit-weighted PCA at the
        // same count (the lowest-average weighting tried). Started from the lobes as they are,
        // the search levelled most lobes towards the cap and its average was 1.3–1.5× the
        // unit PCA's.
        let [ns_min, ns_max] = crate::bake::settings::default_ns_range();
        for preset in Preset::ALL {
            let tol = preset.values().basis_tolerance;
            let capped = BrdfBasis::build(&with(|c| {
                (c.ns_min, c.ns_max) = (ns_min, ns_max);
                c.count = BasisCount::Tolerance(tol);
            }))
            .unwrap();
            let unit = BrdfBasis::build(&with(|c| {
                (c.ns_min, c.ns_max) = (ns_min, ns_max);
                c.weighting = LobeWeighting::Unit;
                c.count = BasisCount::Fixed(capped.count() as u32);
            }))
            .unwrap();
            let (c, u) = (capped.error_report(), unit.error_report());
            eprintln!(
                "{preset:?} (tolerance {tol}): N_b {} capped avg {:.5} max {:.5}, unit avg {:.5} \
                 max {:.5}",
                capped.count(),
                c.avg_rel_l2,
                c.max_rel_l2,
                u.avg_rel_l2,
                u.max_rel_l2
            );
            assert!(c.max_rel_l2 <= tol as f64, "{preset:?}: {c:?}");
            assert!(
                c.avg_rel_l2 <= 1.05 * u.avg_rel_l2,
                "{preset:?}: {c:?} vs {u:?}"
            );
        }
    }
}

//! The bases of a loaded stack: rebuilt from the configurations in its header (the build is
//! deterministic), and the coefficients a relight needs for given materials.

use std::collections::HashMap;
use std::sync::Arc;

use crate::brdf::principled_basis::PrincipledBasis;
use crate::brdf::{BrdfBasis, MaterialSpec, RegionBasis};
use crate::bssrdf::{region_slot_coefficients, SssBasis, SubsurfaceInfo};
use crate::stack::StackHeader;
use crate::{RelumeError, Result, Rgb};

/// Moved to the BRDF basis, which the subsurface weights build on too; kept here for the
/// callers that knew it as part of a stack's bases.
pub use crate::brdf::basis::coefficients::slot_coefficients;

/// One basis per editable region, in editable order (shared when configurations are equal).
pub struct StackBases {
    pub bases: Vec<RegionBasis>,
    /// Whether each editable region is textured (its last slot is the untextured constant).
    pub textured: Vec<bool>,
    /// Each editable region's subsurface basis and slot layout (translucent regions).
    pub subsurface: Vec<Option<(Arc<SssBasis>, SubsurfaceInfo)>>,
}

impl StackBases {
    /// Rebuilds the bases named in `header`.
    pub fn from_header(header: &StackHeader) -> Result<StackBases> {
        let mut cache: HashMap<String, Arc<BrdfBasis>> = HashMap::new();
        let mut bases = Vec::new();
        let mut textured = Vec::new();
        let mut subsurface = Vec::new();
        let mut sss_cache: HashMap<String, Arc<SssBasis>> = HashMap::new();
        for region in header.regions.iter().filter(|r| r.editable) {
            if let Some(cfg) = &region.principled_basis_with_bake_lobe {
                let b = PrincipledBasis::shared(cfg)?;
                let crate::brdf::MaterialSpec::Principled(p) = &region.material else {
                    return Err(RelumeError::Basis(format!(
                        "editable region \"{}\" has its bake-time lobe as a slot but no \
                         Principled material in the stack header",
                        region.name
                    )));
                };
                let lobe = b.shared_bake_lobe(&p.bsdf);
                bases.push(RegionBasis::PrincipledWithBakeLobe(b, lobe));
            } else if let Some(cfg) = &region.principled_basis {
                bases.push(RegionBasis::Principled(PrincipledBasis::shared(cfg)?));
            } else {
                let cfg = region.basis.as_ref().ok_or_else(|| {
                    RelumeError::Basis(format!(
                        "editable region \"{}\" has no basis in the stack header",
                        region.name
                    ))
                })?;
                let key = serde_json::to_string(cfg).unwrap_or_default();
                let basis = match cache.get(&key) {
                    Some(b) => b.clone(),
                    None => {
                        let b = Arc::new(BrdfBasis::build(cfg)?);
                        cache.insert(key, b.clone());
                        b
                    }
                };
                bases.push(RegionBasis::BlinnPhong(basis));
            }
            textured.push(region.textured);
            subsurface.push(match &region.subsurface {
                None => None,
                Some(info) => {
                    let key = serde_json::to_string(&info.basis).unwrap_or_default();
                    let b = match sss_cache.get(&key) {
                        Some(b) => b.clone(),
                        None => {
                            let b = Arc::new(SssBasis::build(&info.basis)?);
                            sss_cache.insert(key, b.clone());
                            b
                        }
                    };
                    Some((b, info.clone()))
                }
            });
        }
        Ok(StackBases {
            bases,
            textured,
            subsurface,
        })
    }

    /// Coefficients per editable region and basis for `materials` (editable order).
    pub fn coefficients(&self, materials: &[MaterialSpec]) -> Result<Vec<Vec<Rgb>>> {
        if materials.len() != self.bases.len() {
            return Err(RelumeError::Materials(format!(
                "{} materials for {} editable regions",
                materials.len(),
                self.bases.len()
            )));
        }
        (0..self.bases.len())
            .map(|r| self.region_coefficients(r, &materials[r]))
            .collect()
    }

    /// Coefficients of one editable region: its BRDF slots and, when translucent, its
    /// eye-diffuse and subsurface slots ([`region_slot_coefficients`]).
    pub fn region_coefficients(&self, region: usize, material: &MaterialSpec) -> Result<Vec<Rgb>> {
        let basis = self.bases.get(region).ok_or_else(|| {
            RelumeError::Materials(format!(
                "editable region {region} does not exist ({} editable)",
                self.bases.len()
            ))
        })?;
        region_slot_coefficients(
            basis,
            self.textured[region],
            self.subsurface[region]
                .as_ref()
                .map(|(b, info)| (&**b, info)),
            material,
        )
    }
}

/// An editable material whose exponent lies outside the ns range its region's basis was
/// baked for. The relight still runs — with the nearest exponent the basis represents
/// (`rendered_ns`, [`BrdfBasis::spec_coefficients`] clamps) — but never silently: the
/// relighters (command line, Python, add-on) report every one of these with its consequence.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct NsOutOfRange {
    /// Editable index of the region.
    pub region: usize,
    /// The exponent the material asks for (after the Principled mapping).
    pub ns: f32,
    /// The baked range `[ns_min, ns_max]`.
    pub ns_range: [f32; 2],
    /// The exponent the relight renders instead.
    pub rendered_ns: f32,
    /// The Principled roughness range the baked ns range corresponds to (`ns = 2/α² − 2`,
    /// `α = r²`): `[r(ns_max), r(ns_min)]`.
    pub roughness_range: [f32; 2],
}

impl NsOutOfRange {
    /// One sentence naming the region, the value and what the image shows instead.
    pub fn message(&self, region_name: &str) -> String {
        let r = ns_to_roughness(self.ns);
        let smoother = self.ns > self.ns_range[1];
        format!(
            "region \"{region_name}\": ns {:.4} (roughness {r:.3}) is outside the baked range \
             ns [{:.4}, {:.4}] (roughness [{:.3}, {:.3}]); relit as ns {:.4}, so its highlight \
             is {} than Cycles renders it — rebake with a wider roughness range",
            self.ns,
            self.ns_range[0],
            self.ns_range[1],
            self.roughness_range[0],
            self.roughness_range[1],
            self.rendered_ns,
            if smoother {
                "broader and dimmer"
            } else {
                "sharper"
            }
        )
    }
}

/// Principled roughness for a Blinn–Phong exponent: the inverse of the core's mapping
/// ([`crate::brdf::principled_fit::fitted_ns`]), so warnings and estimates name the slider
/// value a user would set to get that exponent.
pub fn ns_to_roughness(ns: f32) -> f32 {
    crate::brdf::principled_fit::roughness_for_fitted_ns(ns)
}

/// A Principled material smoother than a Principled basis' range, in the terms of
/// [`NsOutOfRange`] (exponents of the fitted mapping), for the same warnings.
fn principled_out_of_range(
    region: usize,
    basis: &PrincipledBasis,
    material: &MaterialSpec,
) -> Option<NsOutOfRange> {
    let MaterialSpec::Principled(p) = material else {
        return None;
    };
    let r_min = basis.config().roughness_min as f32;
    if !(p.bsdf.roughness < r_min * (1.0 - NS_RANGE_SLACK)) {
        return None;
    }
    let ns = crate::brdf::principled_fit::fitted_ns(p.bsdf.roughness);
    let (lo, hi) = basis.config().fitted_ns_range();
    Some(NsOutOfRange {
        region,
        ns,
        ns_range: [lo, hi],
        rendered_ns: hi,
        roughness_range: [r_min, 1.0],
    })
}

/// Relative slack before an exponent counts as outside (the range itself is stored as f32
/// and mapped through `f32` logs).
const NS_RANGE_SLACK: f32 = 1e-4;

impl StackBases {
    /// `Some` when `material`'s exponent lies outside the ns range of editable region
    /// `region`'s basis and the material reflects specularly at all (`Ks > 0`); a material
    /// without specular reflection renders the same whatever its exponent.
    pub fn ns_out_of_range(&self, region: usize, material: &MaterialSpec) -> Option<NsOutOfRange> {
        let basis = match self.bases.get(region)? {
            RegionBasis::BlinnPhong(b) => b,
            RegionBasis::Principled(b) | RegionBasis::PrincipledWithBakeLobe(b, _) => {
                return principled_out_of_range(region, b, material)
            }
        };
        let cfg = basis.config();
        let m = material.to_blinn_phong();
        if m.ks.iter().all(|&k| k <= 0.0) || !m.ns.is_finite() {
            return None;
        }
        let (lo, hi) = (cfg.ns_min, cfg.ns_max);
        if m.ns >= lo * (1.0 - NS_RANGE_SLACK) && m.ns <= hi * (1.0 + NS_RANGE_SLACK) {
            return None;
        }
        Some(NsOutOfRange {
            region,
            ns: m.ns,
            ns_range: [lo, hi],
            rendered_ns: m.ns.clamp(lo, hi),
            roughness_range: [ns_to_roughness(hi), ns_to_roughness(lo)],
        })
    }

    /// [`Self::ns_out_of_range`] for every editable region (editable order).
    pub fn out_of_range(&self, materials: &[MaterialSpec]) -> Vec<NsOutOfRange> {
        materials
            .iter()
            .enumerate()
            .filter_map(|(r, m)| self.ns_out_of_range(r, m))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::{principled_fit::fitted_ns, BasisConfig, Principled, PrincipledMaterial};

    fn principled(roughness: f32, metallic: f32) -> MaterialSpec {
        MaterialSpec::Principled(PrincipledMaterial::from(Principled {
            base_color: [0.8; 3],
            metallic,
            roughness,
            ior: 1.5,
            specular_ior_level: 0.5,
        }))
    }

    fn bases(ns_min: f32, ns_max: f32) -> StackBases {
        let cfg = BasisConfig {
            ns_min,
            ns_max,
            ..BasisConfig::default()
        };
        StackBases {
            bases: vec![RegionBasis::BlinnPhong(Arc::new(
                BrdfBasis::build(&cfg).unwrap(),
            ))],
            textured: vec![false],
            subsurface: vec![None],
        }
    }

    #[test]
    fn roughness_round_trips_through_ns() {
        // The fitted exponent is nearly flat near roughness 0.9 (docs/principled_fit.md), so
        // the inverse is checked on the exponent it gives back.
        for r in [0.1f32, 0.2, 0.32, 0.5, 0.7, 0.9] {
            let ns = fitted_ns(r);
            let back = ns_to_roughness(ns);
            let again = fitted_ns(back);
            assert!(
                (again / ns - 1.0).abs() < 1e-3,
                "{r} → ns {ns} → {back} → {again}"
            );
            if r <= 0.7 {
                assert!((back - r).abs() < 1e-3, "{r} → {back}");
            }
        }
    }

    /// The paper's range [1, 200] misses smooth materials: a ground at 0.15 is outside and says
    /// so (relit at ns 200, broader); inside the range, nothing is reported; the add-on's
    /// default range (roughness 0.1–1) covers 0.15 and roughness 1.
    #[test]
    fn an_exponent_outside_the_baked_range_is_reported_not_silently_clamped() {
        let paper = bases(1.0, 200.0);
        let w = paper.ns_out_of_range(0, &principled(0.15, 0.0)).unwrap();
        assert_eq!(w.rendered_ns, 200.0);
        let mapped = |r: f32| principled(r, 0.0).to_blinn_phong().ns;
        assert!((w.ns - mapped(0.15)).abs() < 1.0, "{w:?}");
        // The range's smooth end names the roughness the mapping gives ns 200 at.
        assert!(
            (fitted_ns(w.roughness_range[0]) / 200.0 - 1.0).abs() < 1e-3,
            "{w:?}"
        );
        let msg = w.message("Floor");
        assert!(msg.contains("Floor") && msg.contains("broader"), "{msg}");
        assert!(paper.ns_out_of_range(0, &principled(0.5, 0.0)).is_none());
        // Roughness 1 maps to ns ≈ 10⁻³, below the paper's ns_min = 1: rendered sharper. (A
        // black metal: the fit gives brighter rough metals Ks = 0, where ns is moot.)
        let mut black_metal = principled(1.0, 1.0);
        if let MaterialSpec::Principled(p) = &mut black_metal {
            p.bsdf.base_color = [0.0; 3];
        }
        let w = paper.ns_out_of_range(0, &black_metal).unwrap();
        assert!(w.message("M").contains("sharper"));
        // No specular reflection (Specular IOR Level 0, dielectric): the exponent is moot.
        let mut spec = principled(0.15, 0.0);
        if let MaterialSpec::Principled(p) = &mut spec {
            p.bsdf.specular_ior_level = 0.0;
        }
        assert!(paper.ns_out_of_range(0, &spec).is_none());

        // The add-on's range from the mapping's exponents (services/export.py `_ns_range`).
        let wide = bases(mapped(1.0), mapped(0.1));
        for r in [0.1, 0.15, 0.25, 0.5, 1.0] {
            assert!(
                wide.ns_out_of_range(0, &principled(r, 0.5)).is_none(),
                "{r}"
            );
        }
        assert!(wide.ns_out_of_range(0, &principled(0.05, 0.5)).is_some());
        assert_eq!(wide.out_of_range(&[principled(0.05, 1.0)]).len(), 1);
    }
}

//! The bases of a loaded stack: rebuilt from the configurations in its header (the build is
//! deterministic), and the coefficients a relight needs for given materials.

use std::collections::HashMap;
use std::sync::Arc;

use crate::brdf::{BlinnPhong, BrdfBasis, MaterialSpec};
use crate::bssrdf::{region_slot_coefficients, SssBasis, SubsurfaceInfo};
use crate::stack::StackHeader;
use crate::{RelumeError, Result, Rgb};

/// One basis per editable region, in editable order (shared when configurations are equal).
pub struct StackBases {
    pub bases: Vec<Arc<BrdfBasis>>,
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
            bases.push(basis);
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
        Ok(region_slot_coefficients(
            basis,
            self.textured[region],
            self.subsurface[region]
                .as_ref()
                .map(|(b, info)| (&**b, info)),
            material,
        ))
    }
}

/// The coefficient of every slot of an editable region for material `m`: the basis
/// coefficients, except that a textured region (with the diffuse basis in the specular fit)
/// has [Kd (textured diffuse layer), Ks·c̃₁, …, Ks·c₀ (untextured constant layer)].
pub fn slot_coefficients(basis: &BrdfBasis, textured: bool, m: &BlinnPhong) -> Vec<Rgb> {
    if textured && basis.spec_constant() {
        let (kd, ks_c0, mut rest) = basis.split_coefficients(m);
        rest.insert(0, kd);
        rest.push(ks_c0);
        rest
    } else {
        basis.material_coefficients(m)
    }
}

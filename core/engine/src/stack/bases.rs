//! The bases of a loaded stack: rebuilt from the configurations in its header (the build is
//! deterministic), and the coefficients a relight needs for given materials.

use std::collections::HashMap;
use std::sync::Arc;

use crate::brdf::{BrdfBasis, MaterialSpec};
use crate::stack::StackHeader;
use crate::{RelumeError, Result, Rgb};

/// One basis per editable region, in editable order (shared when configurations are equal).
pub struct StackBases {
    pub bases: Vec<Arc<BrdfBasis>>,
}

impl StackBases {
    /// Rebuilds the bases named in `header`.
    pub fn from_header(header: &StackHeader) -> Result<StackBases> {
        let mut cache: HashMap<String, Arc<BrdfBasis>> = HashMap::new();
        let mut bases = Vec::new();
        for region in header.regions.iter().filter(|r| r.editable) {
            let cfg = region.basis.as_ref().ok_or_else(|| {
                RelumeError::Basis(format!("editable region \"{}\" has no basis in the stack header", region.name))
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
        }
        Ok(StackBases { bases })
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
        Ok(self.bases.iter().zip(materials).map(|(b, m)| b.material_coefficients(&m.to_blinn_phong())).collect())
    }

    /// Coefficients of one editable region.
    pub fn region_coefficients(&self, region: usize, material: &MaterialSpec) -> Result<Vec<Rgb>> {
        let basis = self.bases.get(region).ok_or_else(|| {
            RelumeError::Materials(format!("editable region {region} does not exist ({} editable)", self.bases.len()))
        })?;
        Ok(basis.material_coefficients(&material.to_blinn_phong()))
    }
}

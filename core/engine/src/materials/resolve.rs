//! The rules an edit must pass, whoever makes it (the command line's materials file, the
//! Python bindings, the add-on through them): which regions may be edited, the material
//! values ([`MaterialSpec::validate`]: Kd/Ks/ns, the Principled inputs, subsurface), and the
//! light-group gains. Every front end calls these, so they refuse the same edits in the
//! same words.

use crate::brdf::MaterialSpec;
use crate::stack::{RegionInfo, StackHeader};
use crate::{RelumeError, Result, Rgb};

use super::file::MaterialsFile;

/// The gain of every light group of `header` (editable order of its `light_groups`) from
/// `edits`, or `None` when the file edits no group. Errors: a group the stack does not have
/// (its groups are listed), anything [`super::LightGroupEdit::validate`] refuses (a negative,
/// non-finite or too large strength or colour).
pub fn resolve_light_gains(
    header: &StackHeader,
    edits: &MaterialsFile,
) -> Result<Option<Vec<Rgb>>> {
    if edits.light_groups.is_empty() {
        return Ok(None);
    }
    let names: Vec<&str> = header
        .light_groups
        .iter()
        .map(|g| g.name.as_str())
        .collect();
    for (name, e) in &edits.light_groups {
        if !names.contains(&name.as_str()) {
            return Err(RelumeError::Materials(format!(
                "light group \"{name}\" is not in this stack (its groups: {}; bake with --light-groups to keep lights apart)",
                if names.is_empty() { "none".to_string() } else { names.join(", ") }
            )));
        }
        e.validate(name)?;
    }
    Ok(Some(
        header
            .light_groups
            .iter()
            .map(|g| {
                edits
                    .light_groups
                    .get(&g.name)
                    .map_or(Rgb::ONE, |e| Rgb::from(e.color) * e.strength)
            })
            .collect(),
    ))
}

/// Materials of the editable regions, in editable order (the order of
/// `PathVertex::Editable::region`): each region's bake-time material, replaced by the
/// file's where it names the region.
///
/// Errors ([`RelumeError::Materials`]): a name that is no region of the stack (the message
/// lists the editable ones), a name of a fixed region (its material is baked into the
/// layers: rebake with it editable).
pub fn resolve_materials(
    regions: &[RegionInfo],
    edits: &MaterialsFile,
) -> Result<Vec<MaterialSpec>> {
    for name in edits.regions.keys() {
        match regions.iter().find(|r| &r.name == name) {
            None => {
                let editable: Vec<String> = regions
                    .iter()
                    .filter(|r| r.editable)
                    .map(|r| format!("{:?}", r.name))
                    .collect();
                let list = if editable.is_empty() {
                    "none".to_string()
                } else {
                    editable.join(", ")
                };
                return Err(RelumeError::Materials(format!(
                    "no region named {name:?} in this stack; editable regions: {list}"
                )));
            }
            Some(r) if !r.editable => {
                return Err(RelumeError::Materials(format!(
                    "region {name:?} is fixed in this stack: rebake with it editable to edit its material"
                )));
            }
            Some(_) => {}
        }
    }
    for (name, spec) in &edits.regions {
        spec.validate(&format!("region \"{name}\""))?;
    }
    Ok(regions
        .iter()
        .filter(|r| r.editable)
        .map(|r| edits.regions.get(&r.name).unwrap_or(&r.material).clone())
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::BlinnPhong;

    fn region(name: &str, editable: bool, kd: f32) -> RegionInfo {
        RegionInfo {
            name: name.into(),
            editable,
            material: MaterialSpec::BlinnPhong(BlinnPhong {
                kd: [kd; 3],
                ks: [0.1; 3],
                ns: 20.0,
            }),
            basis: None,
            textured: false,
            subsurface: None,
            principled_basis: None,
            principled_basis_with_bake_lobe: None,
        }
    }
    #[test]
    fn resolve_overrides_named_editable_regions_only() {
        let regions = [
            region("Bunny", true, 0.3),
            region("Floor", false, 0.5),
            region("Walls", true, 0.7),
        ];
        // No edits: bake-time materials of the editable regions, in editable order.
        let base = resolve_materials(&regions, &MaterialsFile::default()).unwrap();
        assert_eq!(
            base,
            vec![regions[0].material.clone(), regions[2].material.clone()]
        );
        // One edit: that region changes, the other keeps its bake-time material.
        let mut edits = MaterialsFile::default();
        let new = MaterialSpec::BlinnPhong(BlinnPhong {
            kd: [0.9, 0.1, 0.1],
            ks: [0.0; 3],
            ns: 5.0,
        });
        edits.regions.insert("Walls".into(), new.clone());
        let got = resolve_materials(&regions, &edits).unwrap();
        assert_eq!(got, vec![regions[0].material.clone(), new]);
    }

    #[test]
    fn resolve_refuses_unknown_and_fixed_regions() {
        let regions = [
            region("Bunny", true, 0.3),
            region("Floor", false, 0.5),
            region("Walls", true, 0.7),
        ];
        let spec = regions[0].material.clone();
        let mut edits = MaterialsFile::default();
        edits.regions.insert("Bunyy".into(), spec.clone());
        match resolve_materials(&regions, &edits) {
            Err(RelumeError::Materials(m)) => {
                assert!(
                    m.contains("\"Bunyy\"") && m.contains("\"Bunny\", \"Walls\""),
                    "{m}"
                );
                assert!(!m.contains("Floor"), "fixed regions are not offered: {m}");
            }
            other => panic!("{other:?}"),
        }
        let mut edits = MaterialsFile::default();
        edits.regions.insert("Floor".into(), spec);
        match resolve_materials(&regions, &edits) {
            Err(RelumeError::Materials(m)) => assert!(
                m.contains("fixed in this stack") && m.contains("rebake"),
                "{m}"
            ),
            other => panic!("{other:?}"),
        }
    }
}

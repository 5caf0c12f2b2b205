//! The materials file behind `relume relight --materials M.json`: its format and parser.
//!
//! A stack remembers the material every region had at bake time ([`RegionInfo::material`]);
//! a materials file overrides some editable regions by name and leaves the others as baked.
//!
//! ```json
//! { "format": "relume-materials", "version": 1,
//!   "regions": {
//!     "Bunny": {"model": "blinn_phong", "kd": [0.2, 0.2, 0.2], "ks": [0.4, 0.4, 0.4], "ns": 50},
//!     "Walls": {"model": "principled", "base_color": [0.8, 0.8, 0.8], "roughness": 0.4} } }
//! ```
//!
//! - `format` must be `"relume-materials"` and `version` must be
//!   [`MATERIALS_FORMAT_VERSION`] (1): a file of another kind or a later layout is refused,
//!   not half-read.
//! - `regions` maps region names (Blender material names) to a [`MaterialSpec`]:
//!   `"model": "blinn_phong"` with `kd`, `ks` (RGB albedos) and `ns` (exponent), or
//!   `"model": "principled"` with `base_color` and optionally `metallic` (0), `roughness`
//!   (0.5), `ior` (1.5), `specular_ior_level` (0.5), mapped by
//!   [`crate::brdf::principled_to_blinn_phong`]; for translucent regions also
//!   `subsurface_weight` (0), `subsurface_radius` ([1, 0.2, 0.1]) and `subsurface_scale`
//!   (0.05, scene units), mapped to dipole parameters by [`crate::bssrdf::mapping`] — e.g.
//!   `"Wax": {"model": "principled", "base_color": [0.9, 0.75, 0.55], "subsurface_weight": 1,
//!   "subsurface_radius": [1, 0.5, 0.25], "subsurface_scale": 0.1}`.
//! - Unknown fields are errors, at the top and in every material: a misspelt
//!   `"roughnes"` would otherwise silently leave the default in place.
//! - Only editable regions can be edited; naming a fixed region is an error, because its
//!   material was baked into the layers.
//! - `light_groups` (optional) maps light group names of a stack baked with
//!   `--light-groups` to `{"strength": s, "color": [r, g, b]}` (defaults 1 and white):
//!   that group's light is multiplied by `color × strength`.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use crate::brdf::MaterialSpec;
use crate::{RelumeError, Result};

/// The `format` string of a materials file.
pub const MATERIALS_FORMAT: &str = "relume-materials";
/// The only `version` this build reads.
pub const MATERIALS_FORMAT_VERSION: u32 = 1;

/// A parsed materials file: material per region name, and live light-group edits.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialsFile {
    pub regions: BTreeMap<String, MaterialSpec>,
    /// Strength and colour per light group name (stacks baked with light groups).
    pub light_groups: BTreeMap<String, LightGroupEdit>,
}

/// A light group's live edit: its layers are multiplied by `color × strength`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightGroupEdit {
    #[serde(default = "one")]
    pub strength: f32,
    #[serde(default = "white")]
    pub color: [f32; 3],
}

/// Largest gain (`strength × colour`, per channel) a light group edit may apply. The relight
/// sums `gain · weight · layer` in f32 over every layer: a baked layer holds radiance of
/// order 1 (f16 layers at most 65 504), so a gain of 10⁶ keeps each term below 10¹¹ and the
/// sum of even millions of layers 20 orders of magnitude below f32's 3.4·10³⁸, where a
/// strength of 3·10³⁸ overflows to inf at the first layer. 10⁶ is 20 stops above the baked
/// light: no real edit (the add-on's slider goes to 10) comes near it.
pub const MAX_LIGHT_GAIN: f32 = 1e6;

impl LightGroupEdit {
    /// The rule for a light group edit, whoever makes it (the materials file, the Python
    /// bindings, the add-on): strength and colour finite and ≥ 0, and `strength × colour`
    /// at most [`MAX_LIGHT_GAIN`] in every channel. Errors ([`RelumeError::Materials`]) name
    /// the group, the value and the limit.
    pub fn validate(&self, name: &str) -> Result<()> {
        let values = [self.strength, self.color[0], self.color[1], self.color[2]];
        if values.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(RelumeError::Materials(format!(
                "light group \"{name}\": strength and colour must be finite and ≥ 0, got strength {} and colour {:?}",
                self.strength, self.color
            )));
        }
        let gain = self.color.iter().fold(0.0f64, |m, c| m.max(*c as f64)) * self.strength as f64;
        if gain > MAX_LIGHT_GAIN as f64 {
            return Err(RelumeError::Materials(format!(
                "light group \"{name}\": strength × colour = {gain:e} exceeds the limit of {MAX_LIGHT_GAIN:e} (beyond it the relit sum can overflow f32 to inf)"
            )));
        }
        Ok(())
    }
}

fn one() -> f32 {
    1.0
}
fn white() -> [f32; 3] {
    [1.0; 3]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    #[allow(dead_code)]
    format: String,
    #[allow(dead_code)]
    version: u32,
    #[serde(default)]
    regions: BTreeMap<String, MaterialSpec>,
    #[serde(default)]
    light_groups: BTreeMap<String, LightGroupEdit>,
}

/// Reads and parses a materials file. Errors: the file cannot be read
/// ([`RelumeError::Io`]); anything [`parse_materials`] refuses, prefixed by the path.
pub fn load_materials(path: &Path) -> Result<MaterialsFile> {
    let text = std::fs::read_to_string(path).map_err(|e| RelumeError::io(path, e))?;
    parse_materials(&text).map_err(|e| match e {
        RelumeError::Materials(m) => RelumeError::Materials(format!("{}: {m}", path.display())),
        other => other,
    })
}

/// Parses the text of a materials file. Errors ([`RelumeError::Materials`]): invalid JSON
/// or a field of the wrong type (with serde's line and column), a missing or other
/// `format`, a missing or other `version`, an unknown field.
pub fn parse_materials(json: &str) -> Result<MaterialsFile> {
    let value: serde_json::Value = serde_json::from_str(json)
        .map_err(|e| RelumeError::Materials(format!("invalid JSON: {e}")))?;
    let obj = value.as_object().ok_or_else(|| {
        RelumeError::Materials(
            "expected a JSON object with \"format\", \"version\" and \"regions\"".into(),
        )
    })?;
    match obj.get("format") {
        Some(serde_json::Value::String(f)) if f == MATERIALS_FORMAT => {}
        Some(other) => {
            return Err(RelumeError::Materials(format!(
            "\"format\" is {other}, expected \"{MATERIALS_FORMAT}\": not a Relume materials file"
        )))
        }
        None => {
            return Err(RelumeError::Materials(format!(
                "no \"format\" field (expected \"{MATERIALS_FORMAT}\"): not a Relume materials file"
            )))
        }
    }
    match obj.get("version").map(|v| v.as_u64()) {
        Some(Some(v)) if v == MATERIALS_FORMAT_VERSION as u64 => {}
        Some(Some(v)) => {
            return Err(RelumeError::Materials(format!(
                "materials file version {v}; this build reads version {MATERIALS_FORMAT_VERSION}"
            )))
        }
        Some(None) => {
            return Err(RelumeError::Materials(format!(
            "\"version\" must be an unsigned integer (this build reads {MATERIALS_FORMAT_VERSION})"
        )))
        }
        None => {
            return Err(RelumeError::Materials(format!(
                "no \"version\" field (this build reads {MATERIALS_FORMAT_VERSION})"
            )))
        }
    }
    // Typed parse of the text (not of `value`) so that field errors keep line and column.
    let raw: RawFile = serde_json::from_str(json)
        .map_err(|e| RelumeError::Materials(format!("invalid materials file: {e}")))?;
    // `MaterialSpec` ignores unknown fields; catch them by comparing each material's keys
    // with those of the parsed value written back.
    let given = obj.get("regions").and_then(|r| r.as_object());
    for (name, spec) in &raw.regions {
        let Some(serde_json::Value::Object(fields)) = given.and_then(|g| g.get(name)) else {
            continue;
        };
        let known = serde_json::to_value(spec)
            .map_err(|e| RelumeError::Materials(format!("region {name:?}: {e}")))?;
        let mut known = known.as_object().cloned().unwrap_or_default();
        if let MaterialSpec::Principled(_) = spec {
            // Subsurface fields at their defaults are not serialised; they are still known.
            for k in crate::brdf::Subsurface::KEYS {
                known
                    .entry(k.to_string())
                    .or_insert(serde_json::Value::Null);
            }
        }
        if let Some(bad) = fields.keys().find(|k| !known.contains_key(*k)) {
            let names: Vec<&str> = known
                .keys()
                .map(|k| k.as_str())
                .filter(|k| *k != "model")
                .collect();
            return Err(RelumeError::Materials(format!(
                "region {name:?}: unknown field {bad:?} (fields of this model: {})",
                names.join(", ")
            )));
        }
    }
    Ok(MaterialsFile {
        regions: raw.regions,
        light_groups: raw.light_groups,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::{BlinnPhong, Principled};

    const EXAMPLE: &str = r#"{ "format": "relume-materials", "version": 1,
      "regions": { "Bunny": {"model": "blinn_phong", "kd": [0.2,0.2,0.2], "ks": [0.4,0.4,0.4], "ns": 50},
                   "Walls": {"model": "principled", "base_color": [0.8,0.8,0.8], "roughness": 0.4} } }"#;

    fn err(json: &str) -> String {
        match parse_materials(json) {
            Err(RelumeError::Materials(m)) => m,
            other => panic!("expected a materials error for {json}, got {other:?}"),
        }
    }

    #[test]
    fn parses_the_documented_example() {
        let m = parse_materials(EXAMPLE).unwrap();
        assert_eq!(
            m.regions["Bunny"],
            MaterialSpec::BlinnPhong(BlinnPhong {
                kd: [0.2; 3],
                ks: [0.4; 3],
                ns: 50.0
            })
        );
        assert_eq!(
            m.regions["Walls"],
            MaterialSpec::principled(Principled {
                base_color: [0.8; 3],
                metallic: 0.0,
                roughness: 0.4,
                ior: 1.5,
                specular_ior_level: 0.5,
            })
        );
    }

    #[test]
    fn subsurface_fields_parse_and_misspellings_are_refused() {
        let m = parse_materials(
            r#"{"format":"relume-materials","version":1,"regions":{"Wax":{"model":"principled","base_color":[0.9,0.8,0.6],"subsurface_weight":0.7,"subsurface_radius":[1,0.5,0.25],"subsurface_scale":0.1}}}"#,
        )
        .unwrap();
        match &m.regions["Wax"] {
            MaterialSpec::Principled(p) => {
                assert_eq!(p.subsurface.weight, 0.7);
                assert_eq!(p.subsurface.radius, [1.0, 0.5, 0.25]);
                assert_eq!(p.subsurface.scale, 0.1);
            }
            other => panic!("{other:?}"),
        }
        // Defaults are known fields too (they are not serialised).
        assert!(parse_materials(
            r#"{"format":"relume-materials","version":1,"regions":{"W":{"model":"principled","base_color":[1,1,1],"subsurface_scale":0.05}}}"#
        )
        .is_ok());
        let e = err(
            r#"{"format":"relume-materials","version":1,"regions":{"W":{"model":"principled","base_color":[1,1,1],"subsurface_radus":[1,1,1]}}}"#,
        );
        assert!(
            e.contains("subsurface_radus") && e.contains("subsurface_radius"),
            "{e}"
        );
    }

    #[test]
    fn bad_json_reports_line_and_column() {
        let m =
            err("{ \"format\": \"relume-materials\",\n  \"version\": 1,\n  \"regions\": { ]\n}");
        assert!(m.contains("line 3") && m.contains("column"), "{m}");
        // A type error inside a material also keeps its position.
        let m = err(
            r#"{"format":"relume-materials","version":1,"regions":{"A":{"model":"blinn_phong","kd":"red","ks":[0,0,0],"ns":1}}}"#,
        );
        assert!(m.contains("line 1") && m.contains("column"), "{m}");
    }

    #[test]
    fn wrong_format_and_version_are_refused() {
        assert!(err(r#"{"format":"relume-scene","version":1,"regions":{}}"#)
            .contains("not a Relume materials file"));
        assert!(err(r#"{"version":1,"regions":{}}"#).contains("no \"format\""));
        assert!(
            err(r#"{"format":"relume-materials","version":2,"regions":{}}"#).contains("version 2")
        );
        assert!(err(r#"{"format":"relume-materials","regions":{}}"#).contains("no \"version\""));
        assert!(
            err(r#"{"format":"relume-materials","version":"1","regions":{}}"#)
                .contains("unsigned integer")
        );
        assert!(err("[1, 2]").contains("expected a JSON object"));
    }

    #[test]
    fn unknown_fields_are_refused() {
        let m = err(
            r#"{"format":"relume-materials","version":1,"regions":{"W":{"model":"principled","base_color":[1,1,1],"roughnes":0.2}}}"#,
        );
        assert!(m.contains("\"roughnes\"") && m.contains("roughness"), "{m}");
        let m = err(r#"{"format":"relume-materials","version":1,"regions":{},"extra":1}"#);
        assert!(m.contains("extra"), "{m}");
        let m =
            err(r#"{"format":"relume-materials","version":1,"regions":{"W":{"model":"lambert"}}}"#);
        assert!(m.contains("lambert"), "{m}");
    }

    #[test]
    fn load_reports_io_and_prefixes_the_path() {
        let dir = std::env::temp_dir().join(format!("relume-materials-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("missing.json");
        assert!(matches!(
            load_materials(&missing),
            Err(RelumeError::Io { .. })
        ));
        let bad = dir.join("bad.json");
        std::fs::write(&bad, "{").unwrap();
        match load_materials(&bad) {
            Err(RelumeError::Materials(m)) => {
                assert!(m.contains("bad.json") && m.contains("line 1"), "{m}")
            }
            other => panic!("{other:?}"),
        }
        let good = dir.join("good.json");
        std::fs::write(&good, EXAMPLE).unwrap();
        assert_eq!(load_materials(&good).unwrap().regions.len(), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

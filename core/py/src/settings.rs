//! `relume.BakeSettings`: the engine's bake fields ([`relume_engine::bake::fields`]) as
//! keyword arguments and attributes, plus `passes` (the progressive bake, which only the
//! bindings' bake takes). Values cross as JSON (Python's `json`, serde here), so no field is
//! spelled in this file and the engine's rules judge every value: an unknown field or a bad
//! value is a `ValueError` naming it, and a refused change leaves the settings as they were.
//!
//! Presets: `BakeSettings.preset(name, **overrides)` starts from the engine's named preset
//! (draft, preview, final: [`relume_engine::bake::presets`]) and then applies the overrides.

use pyo3::exceptions::{PyAttributeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use relume_engine::bake::fields::{BakeFields, FIELDS};
use relume_engine::bake::presets::Preset;
use relume_engine::bake::BakeSettings as Engine;
use relume_engine::scene::Resolution;
use relume_engine::RelumeError;
use serde_json::{Map, Value};

use crate::json::to_py;

/// The one key the bindings add to the engine's fields.
const PASSES: &str = "passes";

/// Most progressive passes (each doubles the samples of the one before).
const MAX_PASSES: u32 = 16;

/// Bake settings (all keyword fields, readable and writable; see `to_dict()`).
#[pyclass(module = "relume")]
#[derive(Clone)]
pub struct BakeSettings {
    pub(crate) fields: BakeFields,
    pub(crate) passes: u32,
}

fn bad(field: &str, message: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("BakeSettings.{field}: {message}"))
}

/// An engine error about a setting, as the `ValueError` Python code expects.
fn field_error(e: RelumeError) -> PyErr {
    match e {
        RelumeError::InvalidValue { what, message } => bad(&what, message),
        other => PyValueError::new_err(format!("BakeSettings: {other}")),
    }
}

impl BakeSettings {
    /// The engine settings for `scene_resolution` (the resolution scale applied), checked by
    /// the engine's [`Engine::validate`].
    pub(crate) fn for_scene(&self, scene_resolution: Resolution) -> Result<Engine, RelumeError> {
        self.fields.settings(scene_resolution)
    }

    /// Applies `given` (keyword → value) all together, or nothing on an error.
    fn update(&mut self, given: &Bound<'_, PyDict>) -> PyResult<()> {
        let py = given.py();
        let dumps = py.import("json")?.getattr("dumps")?;
        let strict = PyDict::new(py);
        strict.set_item("allow_nan", false)?;
        let mut overrides = Map::new();
        let mut passes = self.passes;
        for (k, v) in given.iter() {
            let key: String = k.extract()?;
            if key == PASSES {
                let shown = v.repr()?.to_string();
                passes = v
                    .extract::<u32>()
                    .ok()
                    .filter(|n| (1..=MAX_PASSES).contains(n))
                    .ok_or_else(|| bad(PASSES, format!("{shown} (1 to {MAX_PASSES} passes)")))?;
                continue;
            }
            let text: String = dumps
                .call((&v,), Some(&strict))
                .and_then(|t| t.extract())
                .map_err(|_| {
                    let shown = v.repr().map(|r| r.to_string()).unwrap_or_default();
                    bad(
                        &key,
                        format!("{shown} (expected a finite number, a string, a list or None)"),
                    )
                })?;
            let value: Value = serde_json::from_str(&text).map_err(|e| bad(&key, e))?;
            overrides.insert(key, value);
        }
        let mut fields = self.fields.clone();
        fields.apply(&overrides).map_err(field_error)?;
        self.fields = fields;
        self.passes = passes;
        Ok(())
    }

    fn get<'py>(&self, py: Python<'py>, field: &str) -> PyResult<Bound<'py, PyAny>> {
        if field == PASSES {
            return Ok(self.passes.into_pyobject(py)?.into_any());
        }
        match self.fields.to_map().get(field) {
            Some(value) => to_py(py, value),
            None => Err(PyAttributeError::new_err(format!(
                "BakeSettings has no field \"{field}\""
            ))),
        }
    }

    /// Every key, in the engine's order, then `passes`.
    fn keys() -> impl Iterator<Item = &'static str> {
        FIELDS.iter().map(|f| f.key).chain([PASSES])
    }
}

#[pymethods]
impl BakeSettings {
    /// `BakeSettings(spp=16, light_samples=4, …)`: the engine's defaults for every field
    /// not given. Giving both `bases` and `basis_tolerance` is an error.
    #[new]
    #[pyo3(signature = (**fields))]
    fn new(fields: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut s = BakeSettings {
            fields: BakeFields::default(),
            passes: 1,
        };
        if let Some(fields) = fields {
            s.update(fields)?;
        }
        Ok(s)
    }

    /// `BakeSettings.preset("preview", bounces=0)`: a named preset (`"draft"`, `"preview"`,
    /// `"final"`; docs/measurements.md gives each one's measured time and error), then
    /// `overrides`. `bounces` is 12 (Blender's default) unless overridden: the cap of the
    /// bounce count the bake measures the scene needs.
    #[staticmethod]
    #[pyo3(signature = (name, **overrides))]
    fn preset(name: &str, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let preset = Preset::parse(name).ok_or_else(|| {
            let names: Vec<_> = Preset::ALL.iter().map(|p| p.name()).collect();
            PyValueError::new_err(format!(
                "no Relume preset \"{name}\" (presets: {})",
                names.join(", ")
            ))
        })?;
        let mut s = BakeSettings {
            fields: BakeFields::preset(preset),
            passes: 1,
        };
        if let Some(overrides) = overrides {
            s.update(overrides)?;
        }
        Ok(s)
    }

    fn __getattr__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        self.get(py, name)
    }

    fn __setattr__(&mut self, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let one = PyDict::new(value.py());
        one.set_item(name, value)?;
        self.update(&one)
    }

    /// Every field as a dict (JSON-able; `resolution` a list or None).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for key in Self::keys() {
            d.set_item(key, self.get(py, key)?)?;
        }
        Ok(d)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let mut parts = Vec::new();
        for key in Self::keys() {
            parts.push(format!("{key}={}", self.get(py, key)?.repr()?));
        }
        Ok(format!("BakeSettings({})", parts.join(", ")))
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        match other.extract::<PyRef<BakeSettings>>() {
            Ok(o) => self.fields == o.fields && self.passes == o.passes,
            Err(_) => false,
        }
    }
}

//! Rust values to plain Python objects (dict, list, str, float, int, bool, None) through
//! their serde JSON form: reports and headers reach Python JSON-able by construction.

use pyo3::prelude::*;
use serde::Serialize;

use crate::errors::new_err;

/// `value` as Python objects (via `json.loads` of its JSON text).
pub fn to_py<'py>(py: Python<'py>, value: &impl Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| {
        new_err(
            py,
            "InternalError",
            format!("a report did not serialise: {e}"),
        )
    })?;
    py.import("json")?.call_method1("loads", (text,))
}

//! Material arguments from Python (a colour is one number or three) and the one
//! Principled → Blinn–Phong mapping of the core, exposed as a function.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use relume_engine::brdf::principled::principled_to_blinn_phong_analytic as map_analytic;
use relume_engine::brdf::{principled_to_blinn_phong as map, BlinnPhong, Principled};

use crate::guard::guard;

/// An RGB triple from a number (grey) or a sequence of 3 numbers (a 4th, alpha, is
/// ignored so that Blender's RGBA colour sockets can be passed as they are).
pub fn rgb(what: &str, v: &Bound<'_, PyAny>) -> PyResult<[f32; 3]> {
    if let Ok(x) = v.extract::<f32>() {
        return Ok([x; 3]);
    }
    let values: Vec<f32> = v.extract().map_err(|_| {
        PyValueError::new_err(format!("{what}: expected a number or 3 numbers (RGB)"))
    })?;
    match values.as_slice() {
        [r, g, b] | [r, g, b, _] => Ok([*r, *g, *b]),
        _ => Err(PyValueError::new_err(format!(
            "{what}: {} numbers given, expected 3 (RGB) or 4 (RGBA)",
            values.len()
        ))),
    }
}

/// `{"kd": [r, g, b], "ks": [r, g, b], "ns": float}`.
pub fn blinn_phong_dict<'py>(py: Python<'py>, m: &BlinnPhong) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("kd", m.kd.to_vec())?;
    d.set_item("ks", m.ks.to_vec())?;
    d.set_item("ns", m.ns)?;
    Ok(d)
}

/// The Principled inputs as the core's struct.
pub fn principled(
    base_color: &Bound<'_, PyAny>,
    metallic: f32,
    roughness: f32,
    ior: f32,
    specular_ior_level: f32,
) -> PyResult<Principled> {
    Ok(Principled {
        base_color: rgb("base_color", base_color)?,
        metallic,
        roughness,
        ior,
        specular_ior_level,
    })
}

/// Blender's Principled BSDF inputs → Blinn–Phong `{"kd", "ks", "ns"}`: the core's mapping,
/// the Blinn–Phong fitted to Cycles' Principled BSDF (total: out-of-range inputs are clamped,
/// see the core's `brdf::principled` and `brdf::principled_fit`).
#[pyfunction]
#[pyo3(signature = (base_color, metallic = 0.0, roughness = 0.5, ior = 1.5, specular_ior_level = 0.5))]
pub fn principled_to_blinn_phong<'py>(
    py: Python<'py>,
    base_color: &Bound<'py, PyAny>,
    metallic: f32,
    roughness: f32,
    ior: f32,
    specular_ior_level: f32,
) -> PyResult<Bound<'py, PyDict>> {
    guard(py, "principled_to_blinn_phong", || {
        let p = principled(base_color, metallic, roughness, ior, specular_ior_level)?;
        blinn_phong_dict(py, &map(&p))
    })
}

/// The analytic Principled → Blinn–Phong mapping the fit replaced (F0 = 0.04 at IOR 1.5,
/// metals Ks = base colour, `ns = 2/α² − 2`): the documented fallback, for comparisons.
#[pyfunction]
#[pyo3(signature = (base_color, metallic = 0.0, roughness = 0.5, ior = 1.5, specular_ior_level = 0.5))]
pub fn principled_to_blinn_phong_analytic<'py>(
    py: Python<'py>,
    base_color: &Bound<'py, PyAny>,
    metallic: f32,
    roughness: f32,
    ior: f32,
    specular_ior_level: f32,
) -> PyResult<Bound<'py, PyDict>> {
    guard(py, "principled_to_blinn_phong_analytic", || {
        let p = principled(base_color, metallic, roughness, ior, specular_ior_level)?;
        blinn_phong_dict(py, &map_analytic(&p))
    })
}

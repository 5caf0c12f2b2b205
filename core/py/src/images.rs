//! Image files from numpy arrays: scene-linear OpenEXR (what Blender opens), 8-bit sRGB
//! PNG previews, and reading an EXR back. Writes are atomic (the core's write_atomic).

use std::path::PathBuf;

use numpy::ndarray::Array3;
use numpy::{AllowTypeChange, IntoPyArray, PyArray3, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use relume_engine::image_io::{read_rgb_exr, write_png_srgb, write_rgba_exr};

use crate::errors::{new_err, IntoPy};
use crate::guard::guard_detached;

/// `(width, height, rgba)` from a float array of shape (h, w, 4) or (h, w, 3) (alpha 1
/// added), any layout.
fn rgba_of(obj: &Bound<'_, PyAny>) -> PyResult<(u32, u32, Vec<f32>)> {
    let array: PyArrayLikeDyn<f32, AllowTypeChange> = obj.extract().map_err(|e| {
        PyValueError::new_err(format!(
            "expected a float image of shape (h, w, 4) or (h, w, 3): {e}"
        ))
    })?;
    let view = array.as_array();
    let shape = view.shape();
    if view.ndim() != 3 || !(shape[2] == 3 || shape[2] == 4) || shape[0] == 0 || shape[1] == 0 {
        return Err(PyValueError::new_err(format!(
            "image of shape {shape:?}: expected (h, w, 4) or (h, w, 3)"
        )));
    }
    let (h, w, c) = (shape[0], shape[1], shape[2]);
    let mut rgba = Vec::with_capacity(h * w * 4);
    for y in 0..h {
        for x in 0..w {
            for k in 0..3 {
                rgba.push(view[[y, x, k]]);
            }
            rgba.push(if c == 4 { view[[y, x, 3]] } else { 1.0 });
        }
    }
    Ok((w as u32, h as u32, rgba))
}

/// Writes a scene-linear float image (rows top first) as an RGBA f32 OpenEXR, atomically.
#[pyfunction]
pub fn write_exr(py: Python<'_>, path: PathBuf, rgba: &Bound<'_, PyAny>) -> PyResult<()> {
    let (w, h, data) = rgba_of(rgba)?;
    guard_detached(py, "write_exr", move || write_rgba_exr(&path, w, h, &data))?.py_err(py)
}

/// Writes a scene-linear image as an 8-bit sRGB PNG (RGB × 2^exposure, clamped), atomically.
#[pyfunction]
#[pyo3(signature = (path, rgba, exposure = 0.0))]
pub fn write_png(
    py: Python<'_>,
    path: PathBuf,
    rgba: &Bound<'_, PyAny>,
    exposure: f32,
) -> PyResult<()> {
    let (w, h, data) = rgba_of(rgba)?;
    if !exposure.is_finite() {
        return Err(PyValueError::new_err(format!(
            "exposure {exposure} is not finite"
        )));
    }
    guard_detached(py, "write_png", move || {
        write_png_srgb(&path, w, h, &data, exposure)
    })?
    .py_err(py)
}

/// Reads an OpenEXR image as float32 (h, w, 3) scene-linear RGB, rows top first.
#[pyfunction]
pub fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let (w, h, rgb) = guard_detached(py, "read_exr", move || read_rgb_exr(&path))?.py_err(py)?;
    let array = Array3::from_shape_vec((h as usize, w as usize, 3), rgb)
        .map_err(|e| new_err(py, "InternalError", format!("image of the wrong size: {e}")))?;
    Ok(array.into_pyarray(py))
}

//! numpy (or any array-like) input to the flat Rust arrays of a mesh. Any layout is accepted
//! (non-contiguous, any float or int dtype numpy can cast); a wrong shape or dtype is a
//! `SceneError` naming the argument and the shape expected.

use numpy::{
    AllowTypeChange, PyArrayDescrMethods, PyArrayLikeDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::errors::new_err;

fn scene_err(py: Python<'_>, what: &str, message: String) -> PyErr {
    new_err(py, "SceneError", format!("invalid {what}: {message}"))
}

fn shape_of(a: &Bound<'_, PyAny>) -> String {
    a.getattr("shape")
        .and_then(|s| s.str())
        .map(|s| s.to_string())
        .unwrap_or_else(|_| "unknown".into())
}

/// Rows of `N` floats from an `(n, N)` array (`(N,)` is refused: one row must still be 2D).
pub fn float_rows<const N: usize>(
    py: Python<'_>,
    what: &str,
    obj: &Bound<'_, PyAny>,
) -> PyResult<Vec<[f32; N]>> {
    let array: PyArrayLikeDyn<f32, AllowTypeChange> = obj.extract().map_err(|e| {
        scene_err(
            py,
            what,
            format!("expected a float array of shape (n, {N}): {e}"),
        )
    })?;
    let view = array.as_array();
    if view.ndim() != 2 || view.shape()[1] != N {
        return Err(scene_err(
            py,
            what,
            format!("shape {:?}, expected (n, {N})", view.shape()),
        ));
    }
    Ok(view
        .outer_iter()
        .map(|row| std::array::from_fn(|k| row[k]))
        .collect())
}

/// Integers from an integer array of shape `shape` (`None`: any length along that axis),
/// checked to fit in `u32` (negative or too large → `SceneError`). Float arrays are refused:
/// truncating 2.7 to 2 would silently pick another vertex.
pub fn index_array(
    py: Python<'_>,
    what: &str,
    obj: &Bound<'_, PyAny>,
    columns: Option<usize>,
) -> PyResult<(Vec<u32>, usize)> {
    if let Ok(untyped) = obj.cast::<PyUntypedArray>() {
        let kind = untyped.dtype().kind();
        if !matches!(kind, b'i' | b'u' | b'b') {
            return Err(scene_err(
                py,
                what,
                format!(
                    "dtype {} is not an integer type (uint32, int32 or int64 expected)",
                    untyped.dtype()
                ),
            ));
        }
    }
    let expected = match columns {
        Some(c) => format!("(m, {c})"),
        None => "(m,)".into(),
    };
    let array: PyArrayLikeDyn<i64, AllowTypeChange> = obj.extract().map_err(|e| {
        scene_err(
            py,
            what,
            format!("expected an integer array of shape {expected}: {e}"),
        )
    })?;
    let view = array.as_array();
    let ok = match columns {
        Some(c) => view.ndim() == 2 && view.shape()[1] == c,
        None => view.ndim() == 1,
    };
    if !ok {
        return Err(scene_err(
            py,
            what,
            format!("shape {}, expected {expected}", shape_of(obj)),
        ));
    }
    let rows = view.shape()[0];
    let mut out = Vec::with_capacity(view.len());
    for (i, &v) in view.iter().enumerate() {
        if !(0..=u32::MAX as i64).contains(&v) {
            return Err(new_err(
                py,
                "SceneError",
                format!("{what}: entry {i} is {v}, outside 0…{}", u32::MAX),
            ));
        }
        out.push(v as u32);
    }
    Ok((out, rows))
}

//! The panic boundary: no Rust panic reaches Python as pyo3's `PanicException` (a
//! `BaseException` that `except Exception` misses and Blender reports as fatal), and none
//! unwinds out of a worker thread unnoticed. Every entry point runs its body through
//! [`guard`] (or [`guard_detached`] when the GIL is released); worker threads catch their
//! panics with [`catch`] and report them as a value.

use std::panic::{catch_unwind, AssertUnwindSafe};

use pyo3::prelude::*;

use crate::errors::new_err;

/// The text of a panic payload (`panic!` gives a `&str` or a `String`).
pub fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic without a message".to_string()
    }
}

/// The message of an `InternalError` for a panic with text `text`, `where_` naming the call.
pub fn internal_message(where_: &str, text: &str) -> String {
    format!("internal error in {where_} (a Rust panic, caught; please report it): {text}")
}

/// Runs `f`, turning a panic into `Err(panic text)`. For code that holds no Python state
/// (worker threads, closures run with the GIL released).
pub fn catch<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| panic_text(&*p))
}

/// Runs the body of a Python-facing function; a panic becomes `relume.InternalError`.
pub fn guard<T>(py: Python<'_>, where_: &str, f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch(f) {
        Ok(r) => r,
        Err(text) => Err(new_err(
            py,
            "InternalError",
            internal_message(where_, &text),
        )),
    }
}

/// Runs `f` with the GIL released (other Python threads run meanwhile); a panic inside
/// becomes `relume.InternalError` once the GIL is back.
pub fn guard_detached<T: Send>(
    py: Python<'_>,
    where_: &str,
    f: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    match py.detach(|| catch(f)) {
        Ok(v) => Ok(v),
        Err(text) => Err(new_err(
            py,
            "InternalError",
            internal_message(where_, &text),
        )),
    }
}

//! The Python exception hierarchy and the one mapping from Rust errors to it.
//!
//! Every class derives from `relume.RelumeError(Exception)`; `RelumeIOError` derives from it
//! *and* from `OSError`, so `except OSError` catches a missing file as Python code expects.
//! The classes are made at import with `type(...)` (pyo3's `create_exception!` allows one
//! base only) and kept for the life of the process.

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};
use relume_engine::RelumeError as Engine;
use relume_gpu::GpuError;

/// One exception class: name, base names (earlier entries of [`CLASSES`] or builtins), doc.
struct Class {
    name: &'static str,
    bases: &'static [&'static str],
    doc: &'static str,
}

/// Every exception of the module, bases before the classes that derive from them.
const CLASSES: &[Class] = &[
    Class { name: "RelumeError", bases: &["Exception"], doc: "Base of every error Relume raises." },
    Class { name: "SceneError", bases: &["RelumeError"], doc: "A scene that cannot be read or baked: bad format or version, NaN, an index out of range, nothing to bake, an invalid value (the message names the mesh, region or light)." },
    Class { name: "StackError", bases: &["RelumeError"], doc: "A transfer stack that cannot be read, written or used." },
    Class { name: "StaleStackError", bases: &["StackError"], doc: "The stack was baked from another version of the scene (the message says what differs): rebake." },
    Class { name: "TruncatedStackError", bases: &["StackError"], doc: "The stack file is cut short or damaged." },
    Class { name: "ForeignStackError", bases: &["StackError"], doc: "The file is not a Relume transfer stack." },
    Class { name: "StackVersionError", bases: &["StackError"], doc: "The stack has a format version this build does not read." },
    Class { name: "CancelledError", bases: &["RelumeError"], doc: "The bake was cancelled; no partial stack was written." },
    Class { name: "MaterialsError", bases: &["RelumeError"], doc: "A material or light-group edit that cannot apply: unknown or fixed region, negative albedo, Kd + Ks > 1, ns outside (0, inf)." },
    Class { name: "BasisError", bases: &["RelumeError"], doc: "The BRDF basis cannot be built as asked." },
    Class { name: "DeviceError", bases: &["RelumeError"], doc: "The relight device asked for cannot be used (no GPU with device='gpu', a GPU failure)." },
    Class { name: "RelumeIOError", bases: &["RelumeError", "OSError"], doc: "A file cannot be read or written (also an OSError); an image file that is not what it should be." },
    Class { name: "OutOfMemoryError", bases: &["RelumeError", "MemoryError"], doc: "Not enough memory: a bake whose estimated peak exceeds the memory budget (refused before tracing, the estimate in the message), or a large allocation the system refused. Nothing was written; the process is unharmed." },
    Class { name: "InternalError", bases: &["RelumeError"], doc: "A bug in Relume: a Rust panic caught at the boundary (the message has the panic text). The process is unharmed." },
];

static TYPES: PyOnceLock<Vec<(&'static str, Py<PyType>)>> = PyOnceLock::new();

/// Makes the classes (once) and adds them to `module`.
pub fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = module.py();
    let types = TYPES.get_or_try_init(py, || make_classes(py))?;
    for (name, ty) in types {
        module.add(*name, ty.bind(py))?;
    }
    Ok(())
}

fn make_classes(py: Python<'_>) -> PyResult<Vec<(&'static str, Py<PyType>)>> {
    let builtins = py.import("builtins")?;
    let type_fn = builtins.getattr("type")?;
    let mut made: Vec<(&'static str, Py<PyType>)> = Vec::new();
    for class in CLASSES {
        let mut bases = Vec::new();
        for base in class.bases {
            let b = match made.iter().find(|(n, _)| n == base) {
                Some((_, t)) => t.bind(py).clone().into_any(),
                None => builtins.getattr(*base)?,
            };
            bases.push(b);
        }
        let dict = PyDict::new(py);
        dict.set_item("__module__", "relume")?;
        dict.set_item("__doc__", class.doc)?;
        let ty = type_fn.call1((class.name, PyTuple::new(py, bases)?, dict))?;
        made.push((class.name, ty.cast_into::<PyType>()?.unbind()));
    }
    Ok(made)
}

/// A new exception of class `name` with `message`.
pub fn new_err(py: Python<'_>, name: &str, message: impl Into<String>) -> PyErr {
    let message = message.into();
    match TYPES
        .get(py)
        .and_then(|t| t.iter().find(|(n, _)| *n == name))
    {
        Some((_, ty)) => PyErr::from_type(ty.bind(py).clone(), (message,)),
        // Only before the module is initialised, which cannot run Relume code.
        None => pyo3::exceptions::PyRuntimeError::new_err(format!("{name}: {message}")),
    }
}

/// The class of an engine error.
pub fn class_of(e: &Engine) -> &'static str {
    match e {
        Engine::Io { .. } | Engine::Image { .. } => "RelumeIOError",
        Engine::SceneFormat { .. }
        | Engine::SceneVersion { .. }
        | Engine::NonFinite { .. }
        | Engine::IndexOutOfRange { .. }
        | Engine::EmptyScene(_)
        | Engine::InvalidValue { .. } => "SceneError",
        Engine::StackFormat { .. } => "StackError",
        Engine::StackTruncated { .. } => "TruncatedStackError",
        Engine::StackVersion { .. } => "StackVersionError",
        Engine::StackForeign { .. } => "ForeignStackError",
        Engine::StackStale { .. } => "StaleStackError",
        Engine::Cancelled => "CancelledError",
        Engine::Materials(_) => "MaterialsError",
        Engine::Basis(_) => "BasisError",
        Engine::OutOfMemory { .. } => "OutOfMemoryError",
        Engine::OutputIsInput { .. }
        | Engine::OutputsCollide { .. }
        | Engine::OutputNotAFile { .. } => "RelumeIOError",
    }
}

/// An engine error as its Python exception. `RelumeIOError` gets `errno` and `filename`
/// when the error came from the OS.
pub fn engine_err(py: Python<'_>, e: &Engine) -> PyErr {
    let err = new_err(py, class_of(e), e.to_string());
    if let Engine::Io { path, source } = e {
        let value = err.value(py);
        if let Some(code) = source.raw_os_error() {
            let _ = value.setattr("errno", code);
        }
        let _ = value.setattr("filename", path.to_string_lossy().into_owned());
    }
    err
}

/// A relight-device error: engine errors keep their class, the rest are `DeviceError`.
pub fn gpu_err(py: Python<'_>, e: &GpuError) -> PyErr {
    match e {
        GpuError::Engine(inner) => engine_err(py, inner),
        other => new_err(py, "DeviceError", other.to_string()),
    }
}

/// Converts `Result<T, RelumeError>` at the boundary.
pub trait IntoPy<T> {
    fn py_err(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> IntoPy<T> for Result<T, Engine> {
    fn py_err(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| engine_err(py, &e))
    }
}

impl<T> IntoPy<T> for Result<T, GpuError> {
    fn py_err(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| gpu_err(py, &e))
    }
}

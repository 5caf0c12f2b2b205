//! `relume._core`: Python bindings of the Relume core (re-exported by the `relume`
//! package). Thin: every class wraps one engine concept and calls the same engine
//! functions as the command line.
//!
//! Guarantees at the boundary, whatever the input:
//! - every engine error becomes a specific subclass of `relume.RelumeError` ([`errors`]);
//! - a Rust panic becomes `relume.InternalError`, never pyo3's `PanicException` and never
//!   an abort — on the calling thread and on worker threads ([`guard`], [`worker`]);
//! - heavy calls (load, validate, bake wait, relight, image files) release the GIL.
//!
//! Module map: [`scene`], [`settings`], [`job`] (BakeJob, bake), [`stack`], [`relighter`],
//! [`images`], [`materials`]; helpers [`arrays`] (numpy input), [`json`] (reports out).

mod arrays;
mod errors;
mod guard;
mod images;
mod job;
mod json;
mod materials;
mod relighter;
mod scene;
mod settings;
mod stack;
mod worker;

use pyo3::prelude::*;
use rayon::prelude::*;

/// Test hook: panics inside Rust — on the calling thread, or (`in_thread=True`) inside a
/// rayon task of a worker thread started like a bake's — so tests can check that the panic
/// arrives as `relume.InternalError` and the process lives on.
#[pyfunction]
#[pyo3(signature = (in_thread = false))]
fn _debug_panic(py: Python<'_>, in_thread: bool) -> PyResult<()> {
    if !in_thread {
        return guard::guard(py, "_debug_panic", || {
            panic!("relume debug panic (calling thread)")
        });
    }
    let (completion, _handle) = worker::spawn("relume-debug-panic", || {
        (0..64u32).into_par_iter().for_each(|i| {
            if i == 37 {
                panic!("relume debug panic (worker thread)");
            }
        });
    })
    .map_err(|e| errors::new_err(py, "RelumeError", e.to_string()))?;
    let c = completion.clone();
    py.detach(move || c.wait(None));
    completion.with_outcome(|o| match o {
        Some(worker::Outcome::Panicked(text)) => Err(errors::new_err(
            py,
            "InternalError",
            guard::internal_message("a worker thread", text),
        )),
        _ => Ok(()),
    })
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<settings::BakeSettings>()?;
    m.add_class::<job::BakeJob>()?;
    m.add_class::<stack::Stack>()?;
    m.add_class::<relighter::Relighter>()?;
    m.add_function(wrap_pyfunction!(job::bake, m)?)?;
    m.add_function(wrap_pyfunction!(job::estimate_bake, m)?)?;
    m.add_function(wrap_pyfunction!(materials::principled_to_blinn_phong, m)?)?;
    m.add_function(wrap_pyfunction!(
        materials::principled_to_blinn_phong_analytic,
        m
    )?)?;
    m.add_function(wrap_pyfunction!(images::write_exr, m)?)?;
    m.add_function(wrap_pyfunction!(images::write_png, m)?)?;
    m.add_function(wrap_pyfunction!(images::read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(_debug_panic, m)?)?;
    Ok(())
}

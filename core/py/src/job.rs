//! `relume.BakeJob` and `relume.bake`: a bake on a Rust worker thread, with progress and
//! cancel through the engine's atomic [`Progress`], and the stack written by the engine's
//! [`bake_to_file`] (atomically, after every pass of a progressive bake).
//!
//! The worker never touches Python: the job object only reads atomics and a few mutexes,
//! so Blender's UI thread can poll `progress` from a timer at no cost. Dropping the job
//! object cancels the bake (keep a reference for as long as it should run).

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use relume_engine::bake::doubling_passes;
use relume_engine::bake::to_file::bake_to_file;
use relume_engine::progress::Progress;
use relume_engine::RelumeError;
use serde_json::{json, Value};

use crate::errors::{engine_err, new_err};
use crate::guard::{guard, internal_message};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::worker::{spawn, Completion, Outcome};

/// What the worker and the job object share.
struct JobState {
    progress: Progress,
    started: Instant,
    /// Cumulative samples per pixel after each pass.
    pass_spp: Vec<u32>,
    stacks_written: AtomicUsize,
    /// Estimated relative noise after the last written pass.
    noise: Mutex<Option<f64>>,
}

type JobResult = Result<Value, RelumeError>;

/// A bake running on a worker thread (started by the constructor).
#[pyclass(module = "relume", frozen)]
pub struct BakeJob {
    state: Arc<JobState>,
    completion: Arc<Completion<JobResult>>,
}

impl Drop for BakeJob {
    fn drop(&mut self) {
        // Nobody can collect the result any more: stop the work (the file stays as the
        // last completed pass left it).
        self.state.progress.cancel();
    }
}

impl BakeJob {
    fn start(
        py: Python<'_>,
        scene: &Scene,
        settings: &BakeSettings,
        stack_path: PathBuf,
    ) -> PyResult<BakeJob> {
        let scene = scene.snapshot();
        let engine_settings = settings
            .for_scene(scene.resolution)
            .map_err(|e| engine_err(py, &e))?;
        let passes = settings.passes;
        let dir = match stack_path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !dir.is_dir() {
            let e = RelumeError::io(
                &stack_path,
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!("the folder {} does not exist", dir.display()),
                ),
            );
            return Err(engine_err(py, &e));
        }
        let state = Arc::new(JobState {
            progress: Progress::new(),
            started: Instant::now(),
            pass_spp: doubling_passes(engine_settings.spp, passes),
            stacks_written: AtomicUsize::new(0),
            noise: Mutex::new(None),
        });
        let s = state.clone();
        let work = move || -> JobResult {
            let baked = bake_to_file(
                &scene,
                &engine_settings,
                passes,
                &stack_path,
                &s.progress,
                |pass, _| {
                    *s.noise.lock().unwrap_or_else(|e| e.into_inner()) = pass.estimated_rel_error;
                    s.stacks_written.fetch_add(1, Ordering::SeqCst);
                },
            )?;
            let r = &baked.report;
            Ok(json!({
                "stack_path": stack_path,
                "seconds": s.started.elapsed().as_secs_f64(),
                "bake_seconds": r.seconds,
                "write_seconds": baked.write_seconds,
                "width": r.width,
                "height": r.height,
                "layers": baked.stack.layers.len(),
                "stack_bytes": baked.file_bytes,
                "sample_bytes": r.sample_bytes,
                "rays_per_second": r.rays_per_second,
                "stacks_written": baked.stacks_written,
                "passes": baked.passes,
                "noise": baked.passes.last().and_then(|p| p.estimated_rel_error),
                "warnings": r.warnings,
                "drop": r.layers,
                "bounces": r.bounces,
                "bounce_estimate": r.bounce_estimate,
                "report": r,
            }))
        };
        let (completion, _handle) = spawn("relume-bake", work).map_err(|e| {
            new_err(
                py,
                "RelumeError",
                format!("could not start the bake thread: {e}"),
            )
        })?;
        Ok(BakeJob { state, completion })
    }

    fn progress_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let st = &self.state;
        let p = &st.progress;
        let written = st.stacks_written.load(Ordering::SeqCst);
        let pass_count = st.pass_spp.len();
        let ended = self.completion.with_outcome(|o| match o {
            None => None,
            Some(Outcome::Finished(Ok(_))) => Some("done"),
            Some(Outcome::Finished(Err(RelumeError::Cancelled))) => Some("cancelled"),
            Some(_) => Some("failed"),
        });
        let fraction = if ended == Some("done") {
            1.0
        } else {
            p.fraction()
        };
        let stage = match ended {
            Some(s) => s,
            None if p.is_cancelled() => "cancelling",
            None if !p.is_started() => "preparing",
            None => {
                // A pass's tracing ends at its share of all samples; after that it is
                // assembled and written.
                let total = *st.pass_spp.last().unwrap_or(&1) as f64;
                let end = st.pass_spp.get(written).map_or(1.0, |&n| n as f64 / total);
                if fraction + 1e-9 >= end {
                    "writing"
                } else {
                    "tracing"
                }
            }
        };
        let d = PyDict::new(py);
        d.set_item("fraction", fraction)?;
        d.set_item(
            "eta_s",
            match ended {
                Some(_) => Some(0.0),
                None => p.eta_seconds(),
            },
        )?;
        d.set_item("elapsed_s", st.started.elapsed().as_secs_f64())?;
        d.set_item("pass_index", written.min(pass_count.saturating_sub(1)))?;
        d.set_item("pass_count", pass_count)?;
        d.set_item("stage", stage)?;
        d.set_item("noise", *st.noise.lock().unwrap_or_else(|e| e.into_inner()))?;
        d.set_item("stacks_written", written)?;
        Ok(d)
    }

    fn wait_detached(&self, py: Python<'_>, timeout: Option<Duration>) -> bool {
        let c = self.completion.clone();
        py.detach(move || c.wait(timeout))
    }

    fn result_value<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let value = self.completion.with_outcome(|o| match o {
            None => Err(new_err(
                py,
                "RelumeError",
                "the bake is still running: wait() for it (or poll done) before result()",
            )),
            Some(Outcome::Finished(Ok(v))) => Ok(v.clone()),
            Some(Outcome::Finished(Err(e))) => Err(engine_err(py, e)),
            Some(Outcome::Panicked(text)) => Err(new_err(
                py,
                "InternalError",
                internal_message("the bake worker thread", text),
            )),
        })?;
        crate::json::to_py(py, &value)
    }
}

fn timeout_of(timeout: Option<f64>) -> PyResult<Option<Duration>> {
    match timeout {
        None => Ok(None),
        Some(t) if t.is_finite() && t >= 0.0 => Ok(Some(Duration::from_secs_f64(t.min(1e9)))),
        Some(t) => Err(PyValueError::new_err(format!(
            "timeout {t}: expected a number of seconds ≥ 0 or None"
        ))),
    }
}

#[pymethods]
impl BakeJob {
    /// Starts baking `scene` with `settings` into `stack_path` on a worker thread.
    #[new]
    fn new(
        py: Python<'_>,
        scene: PyRef<'_, Scene>,
        settings: PyRef<'_, BakeSettings>,
        stack_path: PathBuf,
    ) -> PyResult<Self> {
        guard(py, "BakeJob()", || {
            BakeJob::start(py, &scene, &settings, stack_path)
        })
    }

    /// `{"fraction", "eta_s", "elapsed_s", "pass_index", "pass_count", "stage", "noise",
    /// "stacks_written"}`; stage is preparing | tracing | writing | cancelling | done |
    /// cancelled | failed.
    #[getter]
    fn progress<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        guard(py, "BakeJob.progress", || self.progress_dict(py))
    }

    /// Asks the worker to stop (it does within a pixel row); returns at once.
    fn cancel(&self) {
        self.state.progress.cancel();
    }

    #[getter]
    fn done(&self) -> bool {
        self.completion.is_done()
    }

    /// Waits (GIL released) until the bake ends or `timeout` seconds pass; whether it ended.
    #[pyo3(signature = (timeout = None))]
    fn wait(&self, py: Python<'_>, timeout: Option<f64>) -> PyResult<bool> {
        let t = timeout_of(timeout)?;
        Ok(self.wait_detached(py, t))
    }

    /// The bake report; raises the bake's error (CancelledError after a cancel), or
    /// RelumeError while it is still running.
    fn result<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        guard(py, "BakeJob.result", || self.result_value(py))
    }
}

/// Bakes and blocks until done, calling `progress(dict)` about every 0.1 s from this thread
/// (GIL released in between); `progress` returning False cancels (→ CancelledError), an
/// exception it raises cancels and propagates, and so does Ctrl-C.
#[pyfunction]
#[pyo3(signature = (scene, settings, stack_path, progress = None))]
pub fn bake<'py>(
    py: Python<'py>,
    scene: PyRef<'_, Scene>,
    settings: PyRef<'_, BakeSettings>,
    stack_path: PathBuf,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let job = guard(py, "bake", || {
        BakeJob::start(py, &scene, &settings, stack_path)
    })?;
    let mut cancelled = false;
    loop {
        let ended = job.wait_detached(py, Some(Duration::from_millis(100)));
        let interrupt = || -> PyResult<()> {
            py.check_signals()?;
            if let (Some(cb), false) = (&progress, cancelled) {
                let r = cb.call1((job.progress_dict(py)?,))?;
                if r.is_instance_of::<pyo3::types::PyBool>() && !r.is_truthy()? {
                    job.cancel();
                }
            }
            Ok(())
        };
        if let Err(e) = interrupt() {
            job.cancel();
            job.wait_detached(py, None);
            return Err(e);
        }
        cancelled = job.state.progress.is_cancelled();
        if ended {
            break;
        }
    }
    job.result(py)
}

/// The memory forecast of a bake with these settings, without baking (validation, bases,
/// BVH and a probe trace: about a second): a dict with the layers possible and reached, the
/// forecast peak and stack bytes, and `budget_bytes` (what a bake may use here; None when
/// unknown). A bake whose `peak_bytes` exceeds `budget_bytes` is refused with
/// `OutOfMemoryError`.
#[pyfunction]
pub fn estimate_bake<'py>(
    py: Python<'py>,
    scene: PyRef<'_, Scene>,
    settings: PyRef<'_, BakeSettings>,
) -> PyResult<Bound<'py, PyAny>> {
    guard(py, "estimate_bake", || {
        let scene = scene.snapshot();
        let engine_settings = settings
            .for_scene(scene.resolution)
            .map_err(|e| engine_err(py, &e))?;
        let passes = settings.passes as usize;
        let estimate = py
            .detach(|| {
                relume_engine::bake::prepare::estimate::estimate_bake(
                    &scene,
                    &engine_settings,
                    passes,
                    &Progress::new(),
                )
            })
            .map_err(|e| engine_err(py, &e))?;
        let mut value = serde_json::to_value(&estimate)
            .map_err(|e| new_err(py, "InternalError", e.to_string()))?;
        value["budget_bytes"] = json!(relume_engine::memory::budget_bytes(
            engine_settings.memory_budget
        ));
        crate::json::to_py(py, &value)
    })
}

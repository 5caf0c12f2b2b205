//! `relume.Stack`: a transfer stack loaded from its OpenEXR file, its header, and the check
//! that it belongs to a scene.

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::prelude::*;
use relume_engine::scene::hash::scene_hash;
use relume_engine::stack::staleness::scene_differences;
use relume_engine::stack::tiled::{file::read_tiled, TiledStack};
use serde_json::json;

use crate::errors::{new_err, IntoPy};
use crate::guard::{guard, guard_detached};
use crate::json::to_py;
use crate::scene::Scene;

/// A loaded transfer stack in the tiled layout (per 16×16 tile only the layers present
/// there; all in memory; share it between relighters). Version 1 files are converted.
#[pyclass(module = "relume", frozen)]
pub struct Stack {
    pub(crate) inner: Arc<TiledStack>,
    path: PathBuf,
    file_bytes: u64,
}

#[pymethods]
impl Stack {
    /// Reads and checks a stack file: TruncatedStackError, ForeignStackError,
    /// StackVersionError, StackError for anything else wrong inside, RelumeIOError when it
    /// cannot be read.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Stack> {
        let p = path.clone();
        let (stack, file_bytes) = guard_detached(py, "Stack.load", move || {
            let bytes = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
            read_tiled(&p).map(|s| (s, bytes))
        })?
        .py_err(py)?;
        Ok(Stack {
            inner: Arc::new(stack),
            path,
            file_bytes,
        })
    }

    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }
    #[getter]
    fn scene_hash(&self) -> String {
        self.inner.header.scene_hash.clone()
    }
    #[getter]
    fn width(&self) -> u32 {
        self.inner.header.width
    }
    #[getter]
    fn height(&self) -> u32 {
        self.inner.header.height
    }
    #[getter]
    fn region_names(&self) -> Vec<String> {
        self.inner
            .header
            .regions
            .iter()
            .map(|r| r.name.clone())
            .collect()
    }
    #[getter]
    fn editable_regions(&self) -> Vec<String> {
        self.inner
            .header
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| r.name.clone())
            .collect()
    }
    /// Names of the light groups kept apart (empty when all lights share the layers).
    #[getter]
    fn light_groups(&self) -> Vec<String> {
        self.inner
            .header
            .light_groups
            .iter()
            .map(|g| g.name.clone())
            .collect()
    }
    #[getter]
    fn layer_count(&self) -> usize {
        self.inner.layers.len()
    }
    /// Bytes of layer samples in memory (what a full relight reads): the stored bytes.
    #[getter]
    fn bytes(&self) -> usize {
        self.inner.sample_bytes()
    }
    /// Bytes of stored values (the tiles' non-zero layers), as `bytes`.
    #[getter]
    fn stored_bytes(&self) -> usize {
        self.inner.sample_bytes()
    }
    /// Bytes the dense layout (every layer a full frame) would hold for the same layers.
    #[getter]
    fn dense_bytes(&self) -> usize {
        self.inner.dense_sample_bytes()
    }
    /// Bytes of the whole stack in memory: values, tile tables, layer information.
    #[getter]
    fn memory_bytes(&self) -> usize {
        self.inner.memory_bytes()
    }
    /// Number of (tile, layer) entries stored.
    #[getter]
    fn tile_entries(&self) -> usize {
        self.inner.entry_count()
    }
    /// Number of layers present in at least one tile (of `layer_count` listed).
    #[getter]
    fn stored_layer_count(&self) -> usize {
        self.inner.stored_layer_count()
    }

    /// Size of the file it was loaded from.
    #[getter]
    fn file_bytes(&self) -> u64 {
        self.file_bytes
    }

    /// How it was baked: samples, bounces, sampling, seed, precision, the basis of every
    /// editable region.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let h = &self.inner.header;
        let bases: serde_json::Map<String, serde_json::Value> = h
            .regions
            .iter()
            .filter_map(|r| {
                r.basis
                    .as_ref()
                    .map(|b| (r.name.clone(), serde_json::to_value(b).unwrap_or_default()))
            })
            .collect();
        to_py(
            py,
            &json!({
                "spp": h.spp,
                "light_samples": h.light_samples,
                "bounce_light_samples": h.bounce_light_samples.unwrap_or(h.light_samples),
                "bounces": h.bounces,
                "diffuse_bounces": h.diffuse_bounces,
                "glossy_bounces": h.glossy_bounces,
                "sampling": h.sampling,
                "seed": h.seed,
                "precision": h.precision,
                "resolution": [h.width, h.height],
                "light_groups": h.light_groups.iter().map(|g| &g.name).collect::<Vec<_>>(),
                "bases": bases,
            }),
        )
    }

    /// Everything in the header (JSON-able).
    #[getter]
    fn header<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.inner.header)
    }

    /// Raises StaleStackError, saying what differs, unless this stack was baked from
    /// `scene` (as it is now: editable materials may differ).
    fn check_scene(&self, py: Python<'_>, scene: PyRef<'_, Scene>) -> PyResult<()> {
        let snapshot = scene.snapshot();
        let header = &self.inner.header;
        let (hash, diffs) = guard_detached(py, "Stack.check_scene", || {
            (scene_hash(&snapshot), scene_differences(header, &snapshot))
        })?;
        guard(py, "Stack.check_scene", || {
            if hash == header.scene_hash {
                return Ok(());
            }
            Err(new_err(
                py,
                "StaleStackError",
                format!(
                    "the stack {} was baked from another scene (stack hash {}, scene hash {hash}); what differs: {}. Rebake it.",
                    self.path.display(),
                    header.scene_hash,
                    diffs.join("; ")
                ),
            ))
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "<relume.Stack {} {}×{}, {} layers, {} tile entries, {:.1} MB (dense {:.1} MB)>",
            self.path.display(),
            self.inner.header.width,
            self.inner.header.height,
            self.inner.layers.len(),
            self.inner.entry_count(),
            self.inner.sample_bytes() as f64 / 1e6,
            self.inner.dense_sample_bytes() as f64 / 1e6
        )
    }
}

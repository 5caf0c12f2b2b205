//! `relume.Scene`: the core's scene, from a scene file, from JSON text, or built mesh by
//! mesh from numpy arrays (what the Blender exporter does).

use std::path::{Path, PathBuf};

use pyo3::prelude::*;
use relume_engine::scene::file::{load_scene, parse_scene, save_scene};
use relume_engine::scene::hash::scene_hash;
use relume_engine::scene::validate::validate_scene;
use relume_engine::scene::{Mesh, Scene as EngineScene};

use crate::arrays::{float_rows, index_array};
use crate::errors::{new_err, IntoPy};
use crate::guard::{guard, guard_detached};

/// A scene as the core bakes it (docs/scene-format.md). Meshes may be added after loading a
/// file whose `"meshes"` is `[]`; everything is validated by `validate()` and before a bake.
#[pyclass(module = "relume", frozen)]
pub struct Scene {
    pub(crate) inner: std::sync::RwLock<EngineScene>,
}

impl Scene {
    /// A copy of the engine scene (for a bake on another thread, or a hash).
    pub(crate) fn snapshot(&self) -> EngineScene {
        self.inner.read().unwrap_or_else(|e| e.into_inner()).clone()
    }
    fn read(&self) -> std::sync::RwLockReadGuard<'_, EngineScene> {
        self.inner.read().unwrap_or_else(|e| e.into_inner())
    }
    fn wrap(scene: EngineScene) -> Scene {
        Scene {
            inner: std::sync::RwLock::new(scene),
        }
    }
}

#[pymethods]
impl Scene {
    /// Reads a scene file (textures and environments given by path are read too).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Scene> {
        let scene = guard_detached(py, "Scene.load", || load_scene(&path))?.py_err(py)?;
        Ok(Scene::wrap(scene))
    }

    /// Parses scene JSON; relative image paths are resolved against `base_dir`.
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = None))]
    fn from_json(py: Python<'_>, text: &str, base_dir: Option<PathBuf>) -> PyResult<Scene> {
        let base_dir = base_dir.unwrap_or_else(|| PathBuf::from("."));
        let text = text.to_string();
        let scene = guard_detached(py, "Scene.from_json", move || {
            parse_scene(&text, Path::new("<json text>"), &base_dir)
        })?
        .py_err(py)?;
        Ok(Scene::wrap(scene))
    }

    /// Appends a triangle mesh. `positions` (n, 3) float, `indices` (m, 3) integer;
    /// optional `normals` (n, 3), `uvs` (n, 2), `triangle_regions` (m,) (else every triangle
    /// is in `region`). Shapes are checked here (SceneError); index ranges, NaN and the
    /// rest by `validate()`.
    #[pyo3(signature = (name, positions, indices, normals = None, uvs = None, triangle_regions = None, region = 0))]
    #[allow(clippy::too_many_arguments)]
    fn add_mesh(
        &self,
        py: Python<'_>,
        name: String,
        positions: &Bound<'_, PyAny>,
        indices: &Bound<'_, PyAny>,
        normals: Option<&Bound<'_, PyAny>>,
        uvs: Option<&Bound<'_, PyAny>>,
        triangle_regions: Option<&Bound<'_, PyAny>>,
        region: u32,
    ) -> PyResult<()> {
        guard(py, "Scene.add_mesh", || {
            let what = |field: &str| format!("mesh \"{name}\" {field}");
            let positions = float_rows::<3>(py, &what("positions"), positions)?;
            let (flat, triangles) = index_array(py, &what("indices"), indices, Some(3))?;
            let indices: Vec<[u32; 3]> = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let normals = normals
                .map(|n| float_rows::<3>(py, &what("normals"), n))
                .transpose()?;
            let uvs = uvs
                .map(|u| float_rows::<2>(py, &what("uvs"), u))
                .transpose()?;
            let triangle_regions = match triangle_regions {
                None => None,
                Some(t) => {
                    let (regions, n) = index_array(py, &what("triangle_regions"), t, None)?;
                    if n != triangles {
                        return Err(new_err(
                            py,
                            "SceneError",
                            format!(
                                "{}: {n} entries for {triangles} triangles",
                                what("triangle_regions")
                            ),
                        ));
                    }
                    Some(regions)
                }
            };
            for (field, len) in [
                ("normals", normals.as_ref().map(|n| n.len())),
                ("uvs", uvs.as_ref().map(|u| u.len())),
            ] {
                if let Some(len) = len {
                    if len != positions.len() {
                        return Err(new_err(
                            py,
                            "SceneError",
                            format!(
                                "{}: {len} rows for {} vertices",
                                what(field),
                                positions.len()
                            ),
                        ));
                    }
                }
            }
            let mesh = Mesh {
                name: name.clone(),
                positions,
                normals,
                uvs,
                indices,
                region,
                triangle_regions,
            };
            self.inner
                .write()
                .unwrap_or_else(|e| e.into_inner())
                .meshes
                .push(mesh);
            Ok(())
        })
    }

    /// Full validation (what a bake checks first): SceneError naming the mesh, region or
    /// light at fault. Returns the warnings (degenerate triangles, no light, …).
    fn validate(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        let scene = self.read();
        let scene = &*scene;
        let report = guard_detached(py, "Scene.validate", || validate_scene(scene))?.py_err(py)?;
        Ok(report.warnings)
    }

    /// Writes the scene file atomically (temp file + rename).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let scene = self.read();
        let scene = &*scene;
        guard_detached(py, "Scene.save", || save_scene(&path, scene))?.py_err(py)
    }

    /// The hash a stack baked from this scene records (editable materials left out).
    fn hash(&self, py: Python<'_>) -> PyResult<String> {
        let scene = self.read();
        let scene = &*scene;
        guard_detached(py, "Scene.hash", || scene_hash(scene))
    }

    #[getter]
    fn triangle_count(&self) -> usize {
        self.read().triangle_count()
    }

    #[getter]
    fn region_names(&self) -> Vec<String> {
        self.read().regions.iter().map(|r| r.name.clone()).collect()
    }

    #[getter]
    fn editable_regions(&self) -> Vec<String> {
        self.read()
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| r.name.clone())
            .collect()
    }

    #[getter]
    fn resolution(&self) -> (u32, u32) {
        let r = self.read().resolution;
        (r.width, r.height)
    }

    #[getter]
    fn light_count(&self) -> usize {
        self.read().lights.len()
    }

    fn __repr__(&self) -> String {
        let s = self.read();
        format!(
            "<relume.Scene {} meshes, {} triangles, {} regions, {} lights, {}×{}>",
            s.meshes.len(),
            s.triangle_count(),
            s.regions.len(),
            s.lights.len(),
            s.resolution.width,
            s.resolution.height
        )
    }
}

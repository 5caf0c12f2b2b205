//! `relume.Relighter`: live relight of a stack for material and light-group edits, on the
//! GPU or the CPU (relume-gpu's `Relighter`, which falls back to the CPU in `auto` mode).
//!
//! Edits only record the new material in the core's `LiveMaterials`, which checks it by the
//! rules of a materials file and tracks what changed; `relight()` then re-sums the regions
//! changed since the last call (the core's incremental `relight_region`, which itself re-sums everything
//! every 64 edits to bound float drift), or everything on the first call. The sum runs
//! with the GIL released.
//!
//! `relight(denoise="oidn")` returns the shown image instead of the relit one: the relit
//! image through OpenImageDenoise (relume-denoise's `ShownImage`, which holds the policy:
//! the search, the fallback to the linear image and the report) with the pixel features of
//! the scene given to the constructor, traced at the first such call, the albedo from the
//! current materials at every call.
//!
//! `refine()` traces, with the GIL released, what the relight misses past the second path
//! vertex for the current edit (the core's `refine`), continuing the same edit's refinement
//! across calls and starting anew after an edit; `relight(refined=True)` adds it;
//! `cancel_refine()` stops a running `refine()` from another thread.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use relume_denoise::oidn::{DeviceChoice, LibrarySearch, Quality};
use relume_denoise::{DenoiseMode, DenoiseReport, FeatureImages, ShownImage};
use relume_engine::brdf::{
    principled_to_blinn_phong, BlinnPhong, MaterialSpec, PrincipledMaterial, Subsurface,
};
use relume_engine::features::{albedo_of, PixelFeatures, FEATURE_SAMPLES_PER_AXIS};
use relume_engine::materials::{LightGroupEdit, LiveMaterials};
use relume_engine::progress::Progress;
use relume_engine::refine::{Refinement, TailRefiner};
use relume_engine::scene::{hash::scene_hash, Scene as EngineScene};
use relume_engine::stack::bases::StackBases;
use relume_engine::stack::tiled::TiledStack;
use relume_engine::RelumeError;
use relume_engine::Rgb;
use relume_gpu::{DevicePreference, GpuError, Relighter as Engine};

use crate::errors::{engine_err, new_err, IntoPy};
use crate::guard::{guard, guard_detached};
use crate::materials::{blinn_phong_dict, principled, rgb};
use crate::scene::Scene;
use crate::stack::Stack;

struct State {
    engine: Engine,
    /// The materials and light-group edits, and what changed since the last relight (the
    /// core's rules and bookkeeping: this layer only converts arguments and errors).
    live: LiveMaterials,
    last_ms: f64,
    last_denoise: Option<DenoiseReport>,
}

/// The shown image's denoiser, under a lock of its own: OIDN takes up to seconds, and a
/// relight of the raw image (the next slider step) must not wait for it.
#[derive(Default)]
struct ShownState {
    /// The shown-image denoiser and the folders it searched (made at the first
    /// `denoise="oidn"`, made again when the folders asked for change).
    shown: Option<(Vec<PathBuf>, ShownImage)>,
    /// The scene's pixel features, traced at the first OIDN run; the reason there are none.
    features: Option<Result<PixelFeatures, String>>,
}

/// The refinement of the current edit: the scene prepared for tracing (at the first
/// `refine()`), and the last edit's refinement with the materials and gains it is for.
#[derive(Default)]
struct RefineState {
    refiner: Option<Arc<TailRefiner>>,
    /// `None` while a `refine()` runs on it (taken out, so that a relight never waits for
    /// a pass).
    current: Option<(Vec<MaterialSpec>, Option<Vec<Rgb>>, Refinement)>,
    /// The running `refine()`'s cancel flag.
    progress: Arc<Progress>,
}

/// Relights one stack live.
#[pyclass(module = "relume", frozen)]
pub struct Relighter {
    stack: Arc<TiledStack>,
    bases: StackBases,
    /// The scene baked, for the denoiser's features (its hash checked against the stack's).
    scene: Option<EngineScene>,
    state: Mutex<State>,
    shown: Mutex<ShownState>,
    refine: Mutex<RefineState>,
}

/// An edit the core refused: a value outside its rules is a `MaterialsError`.
fn materials_err(py: Python<'_>, e: RelumeError) -> PyErr {
    match e {
        RelumeError::InvalidValue { .. } | RelumeError::NonFinite { .. } => {
            new_err(py, "MaterialsError", e.to_string())
        }
        other => engine_err(py, &other),
    }
}

impl Relighter {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn set(&self, py: Python<'_>, region: &str, spec: MaterialSpec) -> PyResult<()> {
        self.lock()
            .live
            .set_material(&self.stack.header, region, spec)
            .map_err(|e| materials_err(py, e))
    }

    /// Runs the sums the edits since the last call need; returns the image (RGBA, rows in
    /// the order asked).
    fn run(&self, flip_y: bool) -> Result<Vec<f32>, GpuError> {
        let mut guard = self.lock();
        let st = &mut *guard;
        let t = Instant::now();
        st.live
            .update(&self.stack.header, &self.bases, &mut st.engine)?;
        let image = st.engine.image();
        let (w, _) = st.engine.size();
        let out = if flip_y {
            // Row by row into one buffer of the right size: element-wise collecting through
            // an iterator chain grew the vector by doubling and cost as much as the relight.
            let row = w * 4;
            let mut flipped = Vec::with_capacity(image.len());
            for r in image.rchunks_exact(row) {
                flipped.extend_from_slice(r);
            }
            flipped
        } else {
            image.to_vec()
        };
        st.last_ms = t.elapsed().as_secs_f64() * 1e3;
        Ok(out)
    }

    /// The relit image brought up to date (rows top first), the materials and the light
    /// groups' gains it was relit with, taken under one lock.
    #[allow(clippy::type_complexity)]
    fn run_with_materials(
        &self,
    ) -> Result<(Vec<f32>, Vec<MaterialSpec>, Option<Vec<Rgb>>), GpuError> {
        let mut guard = self.lock();
        let st = &mut *guard;
        let t = Instant::now();
        st.live
            .update(&self.stack.header, &self.bases, &mut st.engine)?;
        let image = st.engine.image().to_vec();
        st.last_ms = t.elapsed().as_secs_f64() * 1e3;
        let gains = st.live.gains(&self.stack.header)?;
        Ok((image, st.live.materials().to_vec(), gains))
    }

    fn refine_lock(&self) -> std::sync::MutexGuard<'_, RefineState> {
        self.refine.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Adds the refinement of exactly these materials and gains to `image` (rows top
    /// first); returns its passes (0: none there, or one of another edit).
    fn add_refinement(
        &self,
        image: &mut [f32],
        materials: &[MaterialSpec],
        gains: &Option<Vec<Rgb>>,
    ) -> Result<u32, RelumeError> {
        let st = self.refine_lock();
        match (&st.refiner, &st.current) {
            (Some(refiner), Some((m, g, r)))
                if m.as_slice() == materials && g == gains && r.is_needed() =>
            {
                refiner.add_to(r, image)?;
                Ok(r.passes())
            }
            _ => Ok(0),
        }
    }

    /// `refine()` without the GIL: continues the current edit's refinement (or starts
    /// one) for `seconds` or `max_passes`.
    fn refine_detached(
        &self,
        seconds: f64,
        max_passes: u32,
    ) -> Result<(bool, u32, u32, f64), RelumeError> {
        let (materials, gains) = {
            let st = self.lock();
            (
                st.live.materials().to_vec(),
                st.live.gains(&self.stack.header)?,
            )
        };
        // The scene is prepared for tracing (seconds) outside the lock: `cancel_refine()`,
        // which the add-on calls on every edit, must never wait for it.
        let prepared = self.refine_lock().refiner.clone();
        let refiner = match prepared {
            Some(r) => r,
            None => {
                let Some(scene) = &self.scene else {
                    return Err(RelumeError::invalid(
                        "refine",
                        "the Relighter was made without the scene: refine() traces it",
                    ));
                };
                let r = Arc::new(TailRefiner::for_stack(scene, &self.stack.header, 0)?);
                self.refine_lock().refiner.get_or_insert(r).clone()
            }
        };
        let (current, progress) = {
            let mut st = self.refine_lock();
            st.progress = Arc::new(Progress::new());
            (st.current.take(), st.progress.clone())
        };
        let mut current = match current {
            Some((m, g, r)) if m == materials && g == gains => r,
            _ => refiner.start(&materials, gains.as_deref())?,
        };
        let t = Instant::now();
        let result = refiner.refine_for(&mut current, seconds, max_passes, &progress);
        let out = (
            current.is_needed(),
            current.passes(),
            refiner.bake_samples(),
            t.elapsed().as_secs_f64(),
        );
        self.refine_lock().current = Some((materials, gains, current));
        result.map(|()| out)
    }

    /// The shown image of the relit `image` (rows top first, relit with `materials`) under
    /// `mode`, searching `dirs` for OIDN; the report is kept for `last_denoise`. Holds only
    /// the denoiser's lock while OIDN runs.
    fn shown(
        &self,
        image: Vec<f32>,
        materials: &[MaterialSpec],
        mode: DenoiseMode,
        dirs: Vec<PathBuf>,
        quality: Quality,
    ) -> Result<Vec<f32>, RelumeError> {
        let (w, h) = (self.stack.header.width, self.stack.header.height);
        let mut guard = self.shown.lock().unwrap_or_else(|e| e.into_inner());
        let st = &mut *guard;
        if st.shown.as_ref().is_none_or(|(d, _)| *d != dirs) {
            let search = LibrarySearch::with_dirs(dirs.clone());
            st.shown = Some((dirs, ShownImage::new(search, DeviceChoice::Default)));
        }
        let shown = &mut st.shown.as_mut().expect("set above").1;
        shown.set_quality(quality);
        let t = Instant::now();
        // Features only for an OIDN that is there (tracing them costs primary rays).
        if mode == DenoiseMode::Oidn && st.features.is_none() && shown.oidn().is_ok() {
            st.features = Some(match &self.scene {
                Some(scene) => PixelFeatures::trace(scene, w, h, FEATURE_SAMPLES_PER_AXIS)
                    .map_err(|e| e.to_string()),
                None => Err("no scene was given to the Relighter".to_string()),
            });
        }
        let albedo = match &st.features {
            Some(Ok(f)) if mode == DenoiseMode::Oidn => Some(albedo_of(f, materials)?),
            _ => None,
        };
        let features = match (&st.features, &albedo) {
            (Some(Ok(f)), Some(albedo)) => FeatureImages::Clean {
                albedo,
                normal: f.normal(),
            },
            (Some(Err(e)), _) => FeatureImages::Missing(e.clone()),
            _ => FeatureImages::Missing("not traced".to_string()),
        };
        let (out, mut report) = shown.show(&image, w, h, mode, features)?;
        let out = out.into_owned();
        if report.ran == DenoiseMode::Oidn {
            report.milliseconds = t.elapsed().as_secs_f64() * 1e3;
        }
        drop(guard);
        self.lock().last_denoise = Some(report);
        Ok(out)
    }
}

/// `rows` (RGBA, `width` pixels a row) with the row order reversed.
fn flip_rows(rows: &[f32], width: usize) -> Vec<f32> {
    let mut flipped = Vec::with_capacity(rows.len());
    for r in rows.rchunks_exact(width * 4) {
        flipped.extend_from_slice(r);
    }
    flipped
}

/// The folder of the `bpy` module's libraries (the bpy wheel's `bpy/lib`), found without
/// importing bpy; `None` where there is no bpy package.
fn bpy_lib_dir(py: Python<'_>) -> Option<PathBuf> {
    let spec = py
        .import("importlib.util")
        .ok()?
        .call_method1("find_spec", ("bpy",))
        .ok()?;
    if spec.is_none() {
        return None;
    }
    let locations: Vec<String> = spec
        .getattr("submodule_search_locations")
        .ok()?
        .extract()
        .ok()?;
    let dir = PathBuf::from(locations.first()?).join("lib");
    dir.is_dir().then_some(dir)
}

#[pymethods]
impl Relighter {
    /// Builds the relighter of `stack` on `device` ("auto": a real GPU, else the CPU;
    /// "gpu": insist, DeviceError without one; "cpu").
    /// `scene`: the scene the stack was baked from (StaleStackError otherwise), whose pixel
    /// features (albedo, normals) OpenImageDenoise then uses.
    #[new]
    #[pyo3(signature = (stack, device = "auto", scene = None))]
    fn new(
        py: Python<'_>,
        stack: PyRef<'_, Stack>,
        device: &str,
        scene: Option<PyRef<'_, Scene>>,
    ) -> PyResult<Self> {
        let preference: DevicePreference = device
            .parse()
            .map_err(pyo3::exceptions::PyValueError::new_err)?;
        let stack = stack.inner.clone();
        let scene = scene.map(|s| s.snapshot());
        if let Some(scene) = &scene {
            let hash = guard_detached(py, "Relighter()", || scene_hash(scene))?;
            if hash != stack.header.scene_hash {
                return Err(new_err(
                    py,
                    "StaleStackError",
                    "the scene given is not the one the stack was baked from (its features would not match the image)".to_string(),
                ));
            }
        }
        let s = stack.clone();
        let (engine, bases) = guard_detached(py, "Relighter()", move || {
            let bases = StackBases::from_header(&s.header)?;
            let engine = Engine::new(s, preference).map_err(|e| match e {
                relume_gpu::GpuError::Engine(e) => e,
                other => RelumeError::invalid("device", other.to_string()),
            });
            Ok::<_, RelumeError>((engine, bases))
        })?
        .py_err(py)?;
        let engine = match engine {
            Ok(e) => e,
            Err(RelumeError::InvalidValue { message, .. }) => {
                return Err(new_err(
                    py,
                    "DeviceError",
                    format!("{message}; device=\"auto\" falls back to the CPU"),
                ))
            }
            Err(e) => return Err(engine_err(py, &e)),
        };
        let live = LiveMaterials::new(&stack.header).py_err(py)?;
        Ok(Relighter {
            stack,
            bases,
            scene,
            state: Mutex::new(State {
                engine,
                live,
                last_ms: 0.0,
                last_denoise: None,
            }),
            shown: Mutex::new(ShownState::default()),
            refine: Mutex::new(RefineState::default()),
        })
    }

    /// "gpu" or "cpu": where the relight runs now.
    #[getter]
    fn device(&self) -> String {
        self.lock().engine.device().to_string()
    }

    /// Why this device, one sentence starting with "GPU:" or "CPU:".
    #[getter]
    fn device_reason(&self) -> String {
        self.lock().engine.device_reason().to_string()
    }

    /// The GPU failure that moved the relight to the CPU, if one did.
    #[getter]
    fn fallback(&self) -> Option<String> {
        self.lock().engine.fallback().map(str::to_string)
    }

    /// Sets an editable region's Blinn–Phong material (kd, ks: a number or RGB; ns > 0).
    fn set_material(
        &self,
        py: Python<'_>,
        region: &str,
        kd: &Bound<'_, PyAny>,
        ks: &Bound<'_, PyAny>,
        ns: f32,
    ) -> PyResult<()> {
        guard(py, "Relighter.set_material", || {
            let m = BlinnPhong {
                kd: rgb("kd", kd)?,
                ks: rgb("ks", ks)?,
                ns,
            };
            self.set(py, region, MaterialSpec::BlinnPhong(m))
        })
    }

    /// Sets an editable region from Principled inputs; returns the {"kd", "ks", "ns"} they
    /// map to. The subsurface inputs (Blender's Subsurface Weight, Radius, Scale; `ior` is
    /// the η of the dipole) relight a translucent region's subsurface layers; on a region
    /// baked opaque they change nothing.
    #[pyo3(signature = (region, base_color, metallic = 0.0, roughness = 0.5, ior = 1.5, specular_ior_level = 0.5, subsurface_weight = 0.0, subsurface_radius = None, subsurface_scale = None))]
    #[allow(clippy::too_many_arguments)]
    fn set_principled<'py>(
        &self,
        py: Python<'py>,
        region: &str,
        base_color: &Bound<'py, PyAny>,
        metallic: f32,
        roughness: f32,
        ior: f32,
        specular_ior_level: f32,
        subsurface_weight: f32,
        subsurface_radius: Option<&Bound<'py, PyAny>>,
        subsurface_scale: Option<f32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guard(py, "Relighter.set_principled", || {
            let p = principled(base_color, metallic, roughness, ior, specular_ior_level)?;
            let mut subsurface = Subsurface {
                weight: subsurface_weight,
                ..Subsurface::default()
            };
            if let Some(r) = subsurface_radius {
                subsurface.radius = rgb("subsurface_radius", r)?;
            }
            if let Some(scale) = subsurface_scale {
                subsurface.scale = scale;
            }
            let m = principled_to_blinn_phong(&p);
            self.set(
                py,
                region,
                MaterialSpec::Principled(PrincipledMaterial {
                    bsdf: p,
                    subsurface,
                }),
            )?;
            blinn_phong_dict(py, &m)
        })
    }

    /// Sets a light group's strength and colour (stacks baked with light groups).
    #[pyo3(signature = (name, strength = 1.0, color = None))]
    fn set_light_group(
        &self,
        py: Python<'_>,
        name: &str,
        strength: f32,
        color: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        guard(py, "Relighter.set_light_group", || {
            let color = match color {
                Some(c) => rgb("color", c)?,
                None => [1.0; 3],
            };
            self.lock()
                .live
                .set_light_group(&self.stack.header, name, LightGroupEdit { strength, color })
                .map_err(|e| materials_err(py, e))
        })
    }

    /// The image for the current materials: float32 (height, width, 4) RGBA, alpha 1,
    /// scene-linear; rows top first, or bottom first with flip_y=True (Blender's order).
    /// `denoise`: "none" (the relit image, exact), "linear" (the same pixels: the stack's
    /// layers as the bake's linear denoiser left them) or "oidn" (through OpenImageDenoise,
    /// searched in RELUME_OIDN_LIBRARY, `oidn_dirs` — by default the bpy wheel's lib folder
    /// when there is one — and the system; the linear image when none is found).
    /// `oidn_quality`: "high" (renders), "balanced" (OIDN's advice for interactive use,
    /// faster) or "fast". `last_denoise` says which ran and why. `refined`: with what
    /// `refine()` traced for exactly the current materials and gains added before the
    /// denoiser (nothing when it traced another edit or nothing yet).
    #[pyo3(signature = (flip_y = false, denoise = "none", oidn_dirs = None, oidn_quality = "high", refined = false))]
    fn relight<'py>(
        &self,
        py: Python<'py>,
        flip_y: bool,
        denoise: &str,
        oidn_dirs: Option<Vec<PathBuf>>,
        oidn_quality: &str,
        refined: bool,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let mode: DenoiseMode = denoise
            .parse()
            .map_err(pyo3::exceptions::PyValueError::new_err)?;
        let quality =
            Quality::parse(oidn_quality).map_err(pyo3::exceptions::PyValueError::new_err)?;
        let dirs = match oidn_dirs {
            Some(d) => d,
            None if mode == DenoiseMode::Oidn => bpy_lib_dir(py).into_iter().collect(),
            None => Vec::new(),
        };
        let (w, h) = (
            self.stack.header.width as usize,
            self.stack.header.height as usize,
        );
        let out = guard_detached(py, "Relighter.relight", || -> Result<Vec<f32>, GpuError> {
            if mode == DenoiseMode::None && !refined {
                let image = self.run(flip_y)?;
                self.lock().last_denoise = Some(DenoiseReport::nothing(mode, mode, None));
                return Ok(image);
            }
            let (mut image, materials, gains) = self.run_with_materials()?;
            if refined {
                self.add_refinement(&mut image, &materials, &gains)?;
            }
            // The core's last check on a relit image comes first (the shown image's input).
            relume_engine::relight::check_finite_image(&image, w as u32)?;
            let shown = if mode == DenoiseMode::None {
                self.lock().last_denoise = Some(DenoiseReport::nothing(mode, mode, None));
                image
            } else {
                self.shown(image, &materials, mode, dirs, quality)?
            };
            Ok(if flip_y { flip_rows(&shown, w) } else { shown })
        })?;
        let pixels = out.py_err(py)?;
        // The core's last check on a relit image, as `relume relight` makes it: an image
        // with a NaN or an infinity is an error naming where, never shown as if right.
        relume_engine::relight::check_finite_image(&pixels, w as u32).py_err(py)?;
        let array = Array3::from_shape_vec((h, w, 4), pixels).map_err(|e| {
            new_err(
                py,
                "InternalError",
                format!("relit image of the wrong size: {e}"),
            )
        })?;
        Ok(array.into_pyarray(py))
    }

    /// Refines the current edit for about `seconds` (whole passes, at least one and two in
    /// all: one pass has no estimate of its noise and shows nothing; at most `max_passes`
    /// in all for this edit): bounces past the second vertex traced again with the edited
    /// materials, what the relight misses there summed for `relight(refined=True)`, which
    /// adds it shrunk where it is within its own noise.
    /// Continues the same edit's refinement across calls; an edit starts a new one. Needs
    /// the scene given to the constructor (the first call prepares it for tracing:
    /// seconds). Returns {"needed" (False: one bounce or the bake-time materials, nothing
    /// to trace), "passes" (so far for this edit), "bake_samples" (the bake's samples per
    /// pixel: after as many passes the refinement has covered the bake's own paths),
    /// "seconds" (this call's)}. `cancel_refine()` from another thread stops it after
    /// the pass under way, keeping the passes done.
    #[pyo3(signature = (seconds = 1.0, max_passes = None))]
    fn refine<'py>(
        &self,
        py: Python<'py>,
        seconds: f64,
        max_passes: Option<u32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "seconds must be finite and >= 0, got {seconds}"
            )));
        }
        let max_passes = max_passes.unwrap_or(u32::MAX);
        let (needed, passes, bake_samples, took) = guard_detached(py, "Relighter.refine", || {
            self.refine_detached(seconds, max_passes)
        })?
        .py_err(py)?;
        let d = PyDict::new(py);
        d.set_item("needed", needed)?;
        d.set_item("passes", passes)?;
        d.set_item("bake_samples", bake_samples)?;
        d.set_item("seconds", took)?;
        Ok(d)
    }

    /// Stops a `refine()` running on another thread after its current pass.
    fn cancel_refine(&self) {
        self.refine_lock().progress.cancel();
    }

    /// Wall time of the last relight() inside Rust, in milliseconds (sums and the copy out).
    /// Bytes of stored values of the stack relit (its tiles' non-zero layers).
    #[getter]
    fn stored_bytes(&self) -> usize {
        self.stack.sample_bytes()
    }
    /// Bytes the dense layout (every layer a full frame) would hold for the same layers.
    #[getter]
    fn dense_bytes(&self) -> usize {
        self.stack.dense_sample_bytes()
    }
    /// Number of (tile, layer) entries of the stack relit.
    #[getter]
    fn tile_entries(&self) -> usize {
        self.stack.entry_count()
    }
    #[getter]
    fn last_ms(&self) -> f64 {
        self.lock().last_ms
    }

    /// What the last relight() did to the image shown: {"asked", "ran" ("oidn", "linear" or
    /// "none"), "note" (why not what was asked, or what OIDN ran without), "features"
    /// ("albedo+normal" or "none"), "device", "library", "version", "negative_values",
    /// "quality", "ms", "summary"}; None before the first relight.
    #[getter]
    fn last_denoise<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let st = self.lock();
        let Some(r) = &st.last_denoise else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("asked", r.asked.as_str())?;
        d.set_item("ran", r.ran.as_str())?;
        d.set_item("note", r.note.as_deref())?;
        d.set_item("features", r.features)?;
        d.set_item("device", r.device.as_deref())?;
        d.set_item(
            "library",
            r.library.as_ref().map(|p| p.display().to_string()),
        )?;
        d.set_item("version", r.version.as_deref())?;
        d.set_item("quality", r.quality.map(|q| q.as_str()))?;
        d.set_item("negative_values", r.negative_values)?;
        d.set_item("ms", r.milliseconds)?;
        d.set_item("summary", r.summary())?;
        Ok(Some(d))
    }

    /// Current material of every editable region: {name: {"kd", "ks", "ns"}}.
    #[getter]
    fn materials<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let st = self.lock();
        let d = PyDict::new(py);
        let live = &st.live;
        for (name, m) in live.editable_names().iter().zip(live.materials()) {
            d.set_item(name, blinn_phong_dict(py, &m.to_blinn_phong())?)?;
        }
        Ok(d)
    }

    /// Editable materials whose exponent lies outside the ns range their region was baked
    /// for: a list of {"region", "ns", "ns_range", "rendered_ns", "roughness_range",
    /// "message"}. Such a material is relit with the nearest exponent the basis represents
    /// (`rendered_ns`); this list is how the caller learns it — never a silent clamp.
    #[getter]
    fn warnings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyList>> {
        let st = self.lock();
        let list = pyo3::types::PyList::empty(py);
        let names = st.live.editable_names();
        for w in self.bases.out_of_range(st.live.materials()) {
            let name = names.get(w.region).map(String::as_str).unwrap_or("?");
            let d = PyDict::new(py);
            d.set_item("region", name)?;
            d.set_item("ns", w.ns)?;
            d.set_item("ns_range", (w.ns_range[0], w.ns_range[1]))?;
            d.set_item("rendered_ns", w.rendered_ns)?;
            d.set_item(
                "roughness_range",
                (w.roughness_range[0], w.roughness_range[1]),
            )?;
            d.set_item("message", w.message(name))?;
            list.append(d)?;
        }
        Ok(list)
    }

    fn __repr__(&self) -> String {
        let editable = self.lock().live.editable_names().len();
        format!(
            "<relume.Relighter {}×{} on the {} ({} editable regions)>",
            self.stack.header.width,
            self.stack.header.height,
            self.device().to_uppercase(),
            editable
        )
    }
}

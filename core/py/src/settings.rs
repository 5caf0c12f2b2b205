//! `relume.BakeSettings`: the engine's bake settings as keyword fields, plus the two the
//! bindings add: `resolution_scale` (a preview scale on the scene's or the given
//! resolution) and `passes` (progressive bake). Every field is checked when set: an unknown
//! field or a bad value is a `ValueError` naming it.
//!
//! Presets: `BakeSettings.preset(name, **overrides)` starts from the engine's named preset
//! (draft, preview, final: [`relume_engine::bake::presets`]) and then applies the overrides.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use relume_engine::bake::presets::Preset;
use relume_engine::bake::settings::{DEFAULT_BOUNCES, MAX_BOUNCES, MAX_THREADS};
use relume_engine::bake::{BakeSettings as Engine, IndirectSampling, LightGrouping};
use relume_engine::brdf::principled_basis::PrincipledBasisConfig;
use relume_engine::brdf::BasisCount;
use relume_engine::scene::Resolution;
use relume_engine::stack::Precision;

/// Every field, in `to_dict()` order.
pub const FIELDS: &[&str] = &[
    "spp",
    "light_samples",
    "indirect_samples",
    "bounces",
    "bounce_budget",
    "sampling",
    "seed",
    "resolution",
    "resolution_scale",
    "precision",
    "basis_tolerance",
    "bases",
    "ns_min",
    "ns_max",
    "lobe",
    "threads",
    "drop_budget",
    "light_grouping",
    "denoise_direct",
    "denoise_bounce",
    "passes",
    "memory_budget_mb",
    "compression_step",
    "compression_tolerance",
];

/// Bake settings (all keyword fields, readable and writable; see `to_dict()`).
#[pyclass(module = "relume")]
#[derive(Clone)]
pub struct BakeSettings {
    pub(crate) engine: Engine,
    pub(crate) resolution_scale: f64,
    pub(crate) passes: u32,
}

fn bad(field: &str, message: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("BakeSettings.{field}: {message}"))
}

fn positive_u32(field: &str, v: &Bound<'_, PyAny>) -> PyResult<u32> {
    let n: i64 = v.extract().map_err(|_| bad(field, "expected an integer"))?;
    if !(1..=u32::MAX as i64).contains(&n) {
        return Err(bad(field, format!("{n} (must be ≥ 1)")));
    }
    Ok(n as u32)
}

fn finite(field: &str, v: &Bound<'_, PyAny>) -> PyResult<f64> {
    let x: f64 = v.extract().map_err(|_| bad(field, "expected a number"))?;
    if !x.is_finite() {
        return Err(bad(field, format!("{x} is not finite")));
    }
    Ok(x)
}

impl BakeSettings {
    /// The engine settings for `scene_resolution` (the scale applied by the engine's
    /// [`Resolution::scaled`]), checked by the engine's [`Engine::validate`].
    pub(crate) fn for_scene(
        &self,
        scene_resolution: Resolution,
    ) -> Result<Engine, relume_engine::RelumeError> {
        let mut s = self.engine.clone();
        if self.resolution_scale != 1.0 || s.resolution.is_some() {
            let base = s.resolution.unwrap_or(scene_resolution);
            s.resolution = Some(base.scaled(self.resolution_scale)?);
        }
        s.validate()?;
        Ok(s)
    }

    fn set(&mut self, field: &str, v: &Bound<'_, PyAny>) -> PyResult<()> {
        let e = &mut self.engine;
        match field {
            "spp" => e.spp = positive_u32(field, v)?,
            "light_samples" => e.light_samples = positive_u32(field, v)?,
            "indirect_samples" => e.indirect_samples = positive_u32(field, v)?,
            "bounces" => {
                let n: i64 = v.extract().map_err(|_| bad(field, "expected an integer"))?;
                if !(0..=MAX_BOUNCES as i64).contains(&n) {
                    return Err(bad(
                        field,
                        format!("{n} (this build bakes 0 to {MAX_BOUNCES})"),
                    ));
                }
                e.bounces = n as u32;
            }
            "sampling" => {
                let s: String = v.extract().map_err(|_| bad(field, "expected a string"))?;
                e.sampling = match s.as_str() {
                    "uniform" => IndirectSampling::Uniform,
                    "mixture" => IndirectSampling::Mixture,
                    "guided" => IndirectSampling::Guided,
                    _ => {
                        return Err(bad(
                            field,
                            format!("\"{s}\" (expected \"uniform\", \"mixture\" or \"guided\")"),
                        ))
                    }
                };
            }
            "seed" => {
                e.seed = v
                    .extract()
                    .map_err(|_| bad(field, "expected an integer 0…2⁶⁴−1"))?
            }
            "resolution" => {
                e.resolution = if v.is_none() {
                    None
                } else {
                    let (w, h): (i64, i64) = v
                        .extract()
                        .map_err(|_| bad(field, "expected (width, height) or None"))?;
                    if !(1..=65536).contains(&w) || !(1..=65536).contains(&h) {
                        return Err(bad(field, format!("({w}, {h}) (each side 1…65536)")));
                    }
                    Some(Resolution {
                        width: w as u32,
                        height: h as u32,
                    })
                }
            }
            "resolution_scale" => {
                let x = finite(field, v)?;
                if !(x > 0.0 && x <= 16.0) {
                    return Err(bad(field, format!("{x} (must be in (0, 16])")));
                }
                self.resolution_scale = x;
            }
            "precision" => {
                let s: String = v.extract().map_err(|_| bad(field, "expected a string"))?;
                e.precision = match s.as_str() {
                    "f16" => Precision::F16,
                    "f32" => Precision::F32,
                    _ => return Err(bad(field, format!("\"{s}\" (expected \"f16\" or \"f32\")"))),
                };
            }
            "basis_tolerance" => {
                if v.is_none() {
                    if let BasisCount::Tolerance(_) = e.basis.count {
                        e.basis.count = BasisCount::Fixed(6);
                    }
                } else {
                    let t = finite(field, v)?;
                    if !(t > 0.0 && t < 1.0) {
                        return Err(bad(field, format!("{t} (must be in (0, 1), e.g. 0.03)")));
                    }
                    e.basis.count = BasisCount::Tolerance(t as f32);
                }
            }
            "bases" => {
                if v.is_none() {
                    if let BasisCount::Fixed(_) = e.basis.count {
                        e.basis.count = BasisCount::Fixed(6);
                    }
                } else {
                    let n = positive_u32(field, v)?;
                    if !(2..=64).contains(&n) {
                        return Err(bad(field, format!("{n} (must be 2…64)")));
                    }
                    e.basis.count = BasisCount::Fixed(n);
                }
            }
            "ns_min" | "ns_max" => {
                let x = finite(field, v)?;
                if x <= 0.0 {
                    return Err(bad(field, format!("{x} (must be > 0)")));
                }
                if field == "ns_min" {
                    e.basis.ns_min = x as f32;
                } else {
                    e.basis.ns_max = x as f32;
                }
            }
            "lobe" => {
                let name: String = v
                    .extract()
                    .map_err(|_| bad(field, "expected \"blinn-phong\" or \"principled\""))?;
                e.principled_basis = match name.as_str() {
                    "blinn-phong" => None,
                    "principled" => Some(PrincipledBasisConfig::default()),
                    other => {
                        return Err(bad(
                            field,
                            format!("{other:?} (expected \"blinn-phong\" or \"principled\")"),
                        ))
                    }
                };
            }
            "threads" => {
                let n: i64 = v.extract().map_err(|_| bad(field, "expected an integer"))?;
                if !(0..=MAX_THREADS as i64).contains(&n) {
                    return Err(bad(
                        field,
                        format!("{n} (0 = all cores, else 1…{MAX_THREADS})"),
                    ));
                }
                e.threads = n as usize;
            }
            "denoise_direct" | "denoise_bounce" => {
                let n: i64 = v.extract().map_err(|_| bad(field, "expected an integer"))?;
                if !(0..=8).contains(&n) {
                    return Err(bad(field, format!("{n} (À-trous iterations, 0…8)")));
                }
                if field == "denoise_direct" {
                    e.denoise.direct_iterations = n as u32;
                } else {
                    e.denoise.bounce_iterations = n as u32;
                }
            }
            "compression_step" | "compression_tolerance" => {
                // The values are judged by the engine's own rules (`BakeSettings::validate`),
                // as the command line's flags are; a refused value leaves the settings as
                // they were.
                let mut c = e.compression;
                if field == "compression_step" {
                    let n: i64 = v.extract().map_err(|_| bad(field, "expected an integer"))?;
                    let step = u32::try_from(n)
                        .map_err(|_| bad(field, format!("{n} (pixels, 0 = off)")))?;
                    c = c.with_step(step);
                } else {
                    c.tolerance = finite(field, v)? as f32;
                }
                let mut trial = e.clone();
                trial.compression = c;
                trial.validate().map_err(|err| bad(field, err))?;
                e.compression = c;
            }
            "bounce_budget" => {
                let x = finite(field, v)?;
                if !(0.0..1.0).contains(&x) {
                    return Err(bad(field, format!("{x} (must be in [0, 1))")));
                }
                e.bounce_budget = x as f32;
            }
            "drop_budget" => {
                let x = finite(field, v)?;
                if !(0.0..1.0).contains(&x) {
                    return Err(bad(field, format!("{x} (must be in [0, 1))")));
                }
                e.drop_budget = x as f32;
            }
            "light_grouping" => {
                let s: String = v.extract().map_err(|_| bad(field, "expected a string"))?;
                e.light_grouping = match s.as_str() {
                    "all" => LightGrouping::All,
                    "per-light" => LightGrouping::PerLight,
                    "scene" => LightGrouping::Scene,
                    _ => {
                        return Err(bad(
                            field,
                            format!("\"{s}\" (expected \"all\", \"per-light\" or \"scene\")"),
                        ))
                    }
                };
            }
            "memory_budget_mb" => {
                e.memory_budget = if v.is_none() {
                    None
                } else {
                    let x = finite(field, v)?;
                    if x <= 0.0 {
                        return Err(bad(
                            field,
                            format!("{x} (MiB, must be > 0; None: 80 % of the available memory)"),
                        ));
                    }
                    Some((x * 1024.0 * 1024.0) as u64)
                }
            }
            "passes" => {
                let n = positive_u32(field, v)?;
                if n > 16 {
                    return Err(bad(field, format!("{n} (at most 16 doubling passes)")));
                }
                self.passes = n;
            }
            _ => {
                return Err(PyValueError::new_err(format!(
                    "BakeSettings has no field \"{field}\" (fields: {})",
                    FIELDS.join(", ")
                )))
            }
        }
        Ok(())
    }

    fn get<'py>(&self, py: Python<'py>, field: &str) -> PyResult<Bound<'py, PyAny>> {
        let e = &self.engine;
        Ok(match field {
            "spp" => e.spp.into_pyobject(py)?.into_any(),
            "light_samples" => e.light_samples.into_pyobject(py)?.into_any(),
            "indirect_samples" => e.indirect_samples.into_pyobject(py)?.into_any(),
            "bounces" => e.bounces.into_pyobject(py)?.into_any(),
            "sampling" => e.sampling.name().into_pyobject(py)?.into_any(),
            "seed" => e.seed.into_pyobject(py)?.into_any(),
            "resolution" => match e.resolution {
                None => py.None().into_bound(py),
                Some(r) => PyTuple::new(py, [r.width, r.height])?.into_any(),
            },
            "resolution_scale" => self.resolution_scale.into_pyobject(py)?.into_any(),
            "precision" => match e.precision {
                Precision::F16 => "f16",
                Precision::F32 => "f32",
            }
            .into_pyobject(py)?
            .into_any(),
            "basis_tolerance" => match e.basis.count {
                BasisCount::Tolerance(t) => (t as f64).into_pyobject(py)?.into_any(),
                BasisCount::Fixed(_) => py.None().into_bound(py),
            },
            "bases" => match e.basis.count {
                BasisCount::Fixed(n) => n.into_pyobject(py)?.into_any(),
                BasisCount::Tolerance(_) => py.None().into_bound(py),
            },
            "ns_min" => (e.basis.ns_min as f64).into_pyobject(py)?.into_any(),
            "ns_max" => (e.basis.ns_max as f64).into_pyobject(py)?.into_any(),
            "lobe" => match e.principled_basis {
                None => "blinn-phong",
                Some(_) => "principled",
            }
            .into_pyobject(py)?
            .into_any(),
            "threads" => e.threads.into_pyobject(py)?.into_any(),
            "drop_budget" => (e.drop_budget as f64).into_pyobject(py)?.into_any(),
            "bounce_budget" => (e.bounce_budget as f64).into_pyobject(py)?.into_any(),
            "denoise_direct" => e.denoise.direct_iterations.into_pyobject(py)?.into_any(),
            "denoise_bounce" => e.denoise.bounce_iterations.into_pyobject(py)?.into_any(),
            "light_grouping" => match e.light_grouping {
                LightGrouping::All => "all",
                LightGrouping::PerLight => "per-light",
                LightGrouping::Scene => "scene",
            }
            .into_pyobject(py)?
            .into_any(),
            "passes" => self.passes.into_pyobject(py)?.into_any(),
            "compression_step" => e.compression.step.into_pyobject(py)?.into_any(),
            "compression_tolerance" => (e.compression.tolerance as f64)
                .into_pyobject(py)?
                .into_any(),
            "memory_budget_mb" => match e.memory_budget {
                None => py.None().into_bound(py),
                Some(b) => (b as f64 / (1024.0 * 1024.0)).into_pyobject(py)?.into_any(),
            },
            _ => {
                return Err(pyo3::exceptions::PyAttributeError::new_err(format!(
                    "BakeSettings has no field \"{field}\""
                )))
            }
        })
    }

    /// The ns range must be ordered; checked after all fields are set (either may come first).
    fn check_range(&self) -> PyResult<()> {
        let b = &self.engine.basis;
        // Not `<=`: a NaN must fail too.
        if b.ns_max.partial_cmp(&b.ns_min) != Some(std::cmp::Ordering::Greater) {
            return Err(bad(
                "ns_max",
                format!("{} must be greater than ns_min = {}", b.ns_max, b.ns_min),
            ));
        }
        Ok(())
    }
}

#[pymethods]
impl BakeSettings {
    /// `BakeSettings(spp=16, light_samples=4, …)`: the command line's defaults for every
    /// field not given. Giving both `bases` and `basis_tolerance` is an error.
    #[new]
    #[pyo3(signature = (**fields))]
    fn new(fields: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut s = BakeSettings {
            engine: Engine::default(),
            resolution_scale: 1.0,
            passes: 1,
        };
        if let Some(fields) = fields {
            let given = |k: &str| -> bool {
                fields
                    .get_item(k)
                    .ok()
                    .flatten()
                    .is_some_and(|v| !v.is_none())
            };
            if given("bases") && given("basis_tolerance") {
                return Err(bad(
                    "bases",
                    "give bases or basis_tolerance, not both (a tolerance picks the count)",
                ));
            }
            for (k, v) in fields.iter() {
                let k: String = k.extract()?;
                s.set(&k, &v)?;
            }
        }
        s.check_range()?;
        Ok(s)
    }

    /// `BakeSettings.preset("preview", bounces=0)`: a named preset (`"draft"`, `"preview"`,
    /// `"final"`: eye, light and indirect samples, sampling, basis tolerance, resolution
    /// scale and bounce budget; the README's table gives each one's measured time and
    /// error), then `overrides`. `bounces` is 12 (Blender's default) unless overridden: the
    /// cap of the bounce count the bake measures the scene needs.
    #[staticmethod]
    #[pyo3(signature = (name, **overrides))]
    fn preset(name: &str, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let preset = Preset::parse(name).ok_or_else(|| {
            let names: Vec<_> = Preset::ALL.iter().map(|p| p.name()).collect();
            PyValueError::new_err(format!(
                "no Relume preset \"{name}\" (presets: {})",
                names.join(", ")
            ))
        })?;
        let mut s = BakeSettings {
            engine: Engine::default(),
            resolution_scale: 1.0,
            passes: 1,
        };
        s.resolution_scale = preset.apply(&mut s.engine);
        // A preset bakes what the scene needs, up to Blender's default bounce count unless
        // `bounces=` says otherwise.
        s.engine.bounces = DEFAULT_BOUNCES;
        if let Some(fields) = overrides {
            for (k, v) in fields.iter() {
                let k: String = k.extract()?;
                s.set(&k, &v)?;
            }
        }
        s.check_range()?;
        Ok(s)
    }

    fn __getattr__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        self.get(py, name)
    }

    fn __setattr__(&mut self, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let before = self.clone();
        self.set(name, value)?;
        if let Err(e) = self.check_range() {
            *self = before;
            return Err(e);
        }
        Ok(())
    }

    /// Every field as a dict (JSON-able; `resolution` a list or None).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for f in FIELDS {
            d.set_item(*f, self.get(py, f)?)?;
        }
        Ok(d)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let mut parts = Vec::new();
        for f in FIELDS {
            parts.push(format!("{f}={}", self.get(py, f)?.repr()?));
        }
        Ok(format!("BakeSettings({})", parts.join(", ")))
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        match other.extract::<PyRef<BakeSettings>>() {
            Ok(o) => {
                serde_json::to_string(&self.engine).ok() == serde_json::to_string(&o.engine).ok()
                    && self.resolution_scale == o.resolution_scale
                    && self.passes == o.passes
            }
            Err(_) => false,
        }
    }
}

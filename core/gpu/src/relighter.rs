//! [`Relighter`]: one type for the command line and the add-on, relighting on the GPU or
//! on the CPU as [`choose_device`] decided, with the same methods either way.
//!
//! **Failures.** With [`DevicePreference::Auto`] a GPU that cannot be used — no device, an
//! out-of-memory upload, a lost device or a backend error during an edit — never fails
//! the relight: the relighter switches to the CPU, redoes the edit there (a full relight
//! with the current coefficients, so the image is right), and says so in
//! [`device_reason`](Relighter::device_reason) and [`fallback`](Relighter::fallback).
//! With [`DevicePreference::Gpu`] the caller asked for the GPU, so the same failures are
//! returned as errors and nothing switches; the caller may then call
//! [`fall_back_to_cpu`](Relighter::fall_back_to_cpu) itself. Errors in the stack or the
//! coefficients are returned whatever the device: the CPU would refuse them too.

use std::sync::Arc;

use relume_engine::relight::{CpuRelighter, RelightStats};
use relume_engine::stack::tiled::TiledStack;
use relume_engine::stack::TransferStack;
use relume_engine::Rgb;

use crate::device::{choose_device, DeviceKind, DevicePreference};
use crate::error::GpuError;
use crate::kernel::GpuOptions;
use crate::relight::{GpuRelighter, GpuTimings};

enum Engine {
    Gpu(Box<GpuRelighter>),
    Cpu(Box<CpuRelighter>),
}

/// A stack to relight, in either layout. Loaders hand over the tiled layout
/// (`read_tiled`); the dense one is accepted for tests and older callers, and converted.
pub enum StackSource {
    Tiled(Arc<TiledStack>),
    Dense(Arc<TransferStack>),
}

impl From<Arc<TiledStack>> for StackSource {
    fn from(s: Arc<TiledStack>) -> Self {
        StackSource::Tiled(s)
    }
}

impl From<Arc<TransferStack>> for StackSource {
    fn from(s: Arc<TransferStack>) -> Self {
        StackSource::Dense(s)
    }
}

/// A relighter on the device chosen for a [`DevicePreference`].
pub struct Relighter {
    engine: Engine,
    /// The stack in the tiled layout (the CPU's, and what a fall-back starts from).
    tiled: Arc<TiledStack>,
    preference: DevicePreference,
    reason: String,
    fallback: Option<String>,
    /// Coefficients of the current image (to redo it on the CPU after a GPU failure).
    coefs: Option<Vec<Vec<Rgb>>>,
    /// Light group gains of the current image, when set.
    gains: Option<Vec<Rgb>>,
}

impl Relighter {
    /// Chooses the device for `preference` and builds the relighter of `stack` on it.
    ///
    /// Errors: `Gpu` without a usable GPU; a stack the relight refuses (either device).
    pub fn new(
        stack: impl Into<StackSource>,
        preference: DevicePreference,
    ) -> Result<Self, GpuError> {
        Self::with_options(stack, preference, GpuOptions::default())
    }

    /// [`new`](Self::new) with options for the GPU context.
    ///
    /// Both devices relight the tiled layout, shared with the caller: the GPU holds its own
    /// copy in device memory, the host none. A dense stack is checked in the dense layout's
    /// words, then converted once.
    pub fn with_options(
        stack: impl Into<StackSource>,
        preference: DevicePreference,
        options: GpuOptions,
    ) -> Result<Self, GpuError> {
        let choice = choose_device(preference)?;
        let tiled = match stack.into() {
            StackSource::Tiled(t) => t,
            StackSource::Dense(d) => CpuRelighter::new(d)?.stack().clone(),
        };
        let cpu = |tiled: &Arc<TiledStack>| -> Result<Engine, GpuError> {
            Ok(Engine::Cpu(Box::new(CpuRelighter::from_tiled(
                tiled.clone(),
            )?)))
        };
        let (engine, fallback) = match &choice.adapter {
            None => (cpu(&tiled)?, None),
            Some(adapter) => match GpuRelighter::new(tiled.clone(), adapter, options) {
                Ok(g) => (Engine::Gpu(Box::new(g)), None),
                Err(e @ GpuError::Engine(_)) => return Err(e),
                Err(e) if preference == DevicePreference::Auto => {
                    let why = format!("CPU: the GPU could not be used ({e})");
                    (cpu(&tiled)?, Some(why))
                }
                Err(e) => return Err(e),
            },
        };
        Ok(Relighter {
            engine,
            tiled,
            preference,
            reason: fallback.clone().unwrap_or(choice.reason),
            fallback,
            coefs: None,
            gains: None,
        })
    }

    /// The stack relit, in the tiled layout.
    pub fn stack(&self) -> &Arc<TiledStack> {
        &self.tiled
    }

    /// Which device relights now.
    pub fn device(&self) -> DeviceKind {
        match self.engine {
            Engine::Gpu(_) => DeviceKind::Gpu,
            Engine::Cpu(_) => DeviceKind::Cpu,
        }
    }

    /// Why this device, in one sentence starting with "GPU:" or "CPU:" (after a fallback,
    /// the GPU error that caused it).
    pub fn device_reason(&self) -> &str {
        &self.reason
    }

    /// The GPU failure that moved the relight to the CPU, if one did.
    pub fn fallback(&self) -> Option<&str> {
        self.fallback.as_deref()
    }

    /// The GPU context, when the GPU relights (adapter, upload time, timings).
    pub fn gpu(&mut self) -> Option<&mut GpuRelighter> {
        match &mut self.engine {
            Engine::Gpu(g) => Some(g),
            Engine::Cpu(_) => None,
        }
    }

    /// Times of the last relight on the GPU (`None` on the CPU).
    pub fn gpu_timings(&self) -> Option<GpuTimings> {
        match &self.engine {
            Engine::Gpu(g) => Some(g.last_timings()),
            Engine::Cpu(_) => None,
        }
    }

    pub fn editable_count(&self) -> usize {
        match &self.engine {
            Engine::Gpu(g) => g.editable_count(),
            Engine::Cpu(c) => c.editable_count(),
        }
    }

    pub fn basis_count(&self, region: usize) -> usize {
        match &self.engine {
            Engine::Gpu(g) => g.basis_count(region),
            Engine::Cpu(c) => c.basis_count(region),
        }
    }

    pub fn size(&self) -> (usize, usize) {
        match &self.engine {
            Engine::Gpu(g) => g.size(),
            Engine::Cpu(c) => c.size(),
        }
    }

    /// The current image: RGBA f32, rows top-down, alpha 1.
    pub fn image(&self) -> &[f32] {
        match &self.engine {
            Engine::Gpu(g) => g.image(),
            Engine::Cpu(c) => c.image(),
        }
    }

    pub fn last_stats(&self) -> RelightStats {
        match &self.engine {
            Engine::Gpu(g) => g.last_stats(),
            Engine::Cpu(c) => c.last_stats(),
        }
    }

    /// Full relight: `coefs[region][basis]` RGB for every editable region.
    pub fn relight(&mut self, coefs: &[Vec<Rgb>]) -> Result<&[f32], GpuError> {
        let done = match &mut self.engine {
            Engine::Gpu(g) => g.relight(coefs).map(|_| ()),
            Engine::Cpu(c) => c.relight(coefs).map(|_| ()).map_err(GpuError::Engine),
        };
        self.settle(done, coefs.to_vec())?;
        Ok(self.image())
    }

    /// Incremental relight: only editable region `region` changed, to `coefs`. Needs a
    /// full [`relight`](Self::relight) first.
    pub fn relight_region(&mut self, region: usize, coefs: &[Rgb]) -> Result<&[f32], GpuError> {
        let done = match &mut self.engine {
            Engine::Gpu(g) => g.relight_region(region, coefs).map(|_| ()),
            Engine::Cpu(c) => c
                .relight_region(region, coefs)
                .map(|_| ())
                .map_err(GpuError::Engine),
        };
        let mut all = self.coefs.clone().unwrap_or_default();
        if let Some(slot) = all.get_mut(region) {
            *slot = coefs.to_vec();
        }
        self.settle(done, all)?;
        Ok(self.image())
    }

    /// Light groups' live gains (one per group of the stack), then a full relight.
    pub fn set_light_group_gains(&mut self, gains: &[Rgb]) -> Result<&[f32], GpuError> {
        let done = match &mut self.engine {
            Engine::Gpu(g) => g.set_light_group_gains(gains).map(|_| ()),
            Engine::Cpu(c) => c
                .set_light_group_gains(gains)
                .map(|_| ())
                .map_err(GpuError::Engine),
        };
        if done.is_ok() {
            self.gains = Some(gains.to_vec());
        }
        let coefs = self.coefs.clone().unwrap_or_default();
        self.settle(done, coefs)?;
        Ok(self.image())
    }

    /// Moves the relight to the CPU now, saying `why` in the device reason; the current
    /// image is recomputed there. (The relighter does it by itself in `auto` mode when the
    /// GPU fails; a caller that forced the GPU may do it after an error.)
    pub fn fall_back_to_cpu(&mut self, why: &str) -> Result<(), GpuError> {
        if let Engine::Cpu(_) = &self.engine {
            return Ok(());
        }
        let mut cpu = CpuRelighter::from_tiled(self.tiled.clone())?;
        if let Some(coefs) = &self.coefs {
            cpu.relight(coefs)?;
            if let Some(gains) = &self.gains {
                cpu.set_light_group_gains(gains)?;
            }
        }
        self.engine = Engine::Cpu(Box::new(cpu));
        self.reason = format!("CPU: fell back from the GPU ({why})");
        self.fallback = Some(why.to_string());
        Ok(())
    }

    /// After an edit: keeps the coefficients on success; on a GPU failure in `auto` mode
    /// falls back to the CPU with `coefs` as the current materials.
    fn settle(&mut self, done: Result<(), GpuError>, coefs: Vec<Vec<Rgb>>) -> Result<(), GpuError> {
        match done {
            Ok(()) => {
                self.coefs = Some(coefs);
                Ok(())
            }
            Err(e @ GpuError::Engine(_)) => Err(e),
            Err(e) if self.preference == DevicePreference::Auto => {
                // Only an edit the GPU accepted reaches the kernel, so `coefs` are valid.
                self.coefs = Some(coefs);
                self.fall_back_to_cpu(&e.to_string())
            }
            Err(e) => Err(e),
        }
    }
}

/// A live material session (the Python bindings' relighter) drives this relighter.
impl relume_engine::materials::LiveRelighter for Relighter {
    type Error = GpuError;
    fn relight_all(&mut self, coefs: &[Vec<Rgb>]) -> Result<(), GpuError> {
        self.relight(coefs).map(|_| ())
    }
    fn relight_one(&mut self, region: usize, coefs: &[Rgb]) -> Result<(), GpuError> {
        self.relight_region(region, coefs).map(|_| ())
    }
    fn set_gains(&mut self, gains: &[Rgb]) -> Result<(), GpuError> {
        self.set_light_group_gains(gains).map(|_| ())
    }
}

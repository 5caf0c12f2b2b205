//! Progress and cancellation of long work, readable and settable from any thread.
//!
//! The bake checks the cancel flag at every stage ([`Stage`]): before every tile and every
//! pixel row of a tile while tracing, per region and tile while setting up, per layer while
//! assembling, per iteration and layer while denoising, per chunk while writing — each step
//! well under a second on one core — so a cancel is honoured within a second wherever it
//! arrives, until the stack file's final rename (after which the bake is done).

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// What a bake is doing now, for status text and for tests that cancel at a given stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Stage {
    /// Validation, bases, BVH, subsurface samples, the guide pass.
    Setup = 0,
    Tracing = 1,
    /// Averaging the sums into layers, grey detection.
    Assembly = 2,
    Denoising = 3,
    /// Leaving out negligible layers, converting to the stored precision.
    Finishing = 4,
    /// Writing the stack file (until its atomic rename).
    Writing = 5,
    Done = 6,
}

impl Stage {
    /// Lower-case name for status text and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Setup => "setup",
            Stage::Tracing => "tracing",
            Stage::Assembly => "assembly",
            Stage::Denoising => "denoising",
            Stage::Finishing => "finishing",
            Stage::Writing => "writing",
            Stage::Done => "done",
        }
    }
    fn from_u8(v: u8) -> Stage {
        [
            Stage::Setup,
            Stage::Tracing,
            Stage::Assembly,
            Stage::Denoising,
            Stage::Finishing,
            Stage::Writing,
            Stage::Done,
        ]
        .get(v as usize)
        .copied()
        .unwrap_or(Stage::Done)
    }
}

/// Shared progress of a bake (or any tiled job).
#[derive(Debug, Default)]
pub struct Progress {
    total: AtomicU64,
    done: AtomicU64,
    cancelled: AtomicBool,
    stage: AtomicU8,
    started: Mutex<Option<Instant>>,
}

impl Progress {
    /// A fresh, not-cancelled progress.
    pub fn new() -> Self {
        Self::default()
    }
    /// Starts counting `total` units of work.
    pub fn start(&self, total: u64) {
        self.total.store(total, Ordering::SeqCst);
        self.done.store(0, Ordering::SeqCst);
        *self.started.lock().unwrap_or_else(|e| e.into_inner()) = Some(Instant::now());
    }
    /// Whether [`start`](Self::start) was called: the work is past its set-up (validation,
    /// basis, BVH) and counting.
    pub fn is_started(&self) -> bool {
        self.started
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some()
    }
    /// Marks `n` units done.
    pub fn advance(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
    }
    /// Fraction done in [0, 1].
    pub fn fraction(&self) -> f64 {
        let total = self.total.load(Ordering::Relaxed);
        if total == 0 {
            return 0.0;
        }
        (self.done.load(Ordering::Relaxed) as f64 / total as f64).min(1.0)
    }
    /// Seconds since start.
    pub fn elapsed(&self) -> f64 {
        self.started
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .map(|s| s.elapsed().as_secs_f64())
            .unwrap_or(0.0)
    }
    /// Estimated seconds left (linear in the fraction done); `None` before any work is done.
    pub fn eta_seconds(&self) -> Option<f64> {
        let f = self.fraction();
        if f <= 0.0 {
            return None;
        }
        Some(self.elapsed() * (1.0 - f) / f)
    }
    /// Asks the work to stop; it returns [`crate::RelumeError::Cancelled`] soon after.
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::SeqCst);
    }
    /// Whether a cancel was asked.
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }
    /// [`crate::RelumeError::Cancelled`] when a cancel was asked: `progress.check()?` between
    /// steps of work.
    pub fn check(&self) -> crate::Result<()> {
        if self.is_cancelled() {
            Err(crate::RelumeError::Cancelled)
        } else {
            Ok(())
        }
    }
    /// Records the stage the work has reached.
    pub fn set_stage(&self, stage: Stage) {
        self.stage.store(stage as u8, Ordering::SeqCst);
    }
    /// The stage the work has reached.
    pub fn stage(&self) -> Stage {
        Stage::from_u8(self.stage.load(Ordering::SeqCst))
    }
}

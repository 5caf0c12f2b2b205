//! Progress and cancellation of long work, readable and settable from any thread.
//!
//! The bake checks the cancel flag before every tile and every pixel row of a tile (a row of
//! 16 pixels at 64 spp is ~20k paths, well under 100 ms on one core), so a cancel is honoured
//! within a second.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Shared progress of a bake (or any tiled job).
#[derive(Debug, Default)]
pub struct Progress {
    total: AtomicU64,
    done: AtomicU64,
    cancelled: AtomicBool,
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
}

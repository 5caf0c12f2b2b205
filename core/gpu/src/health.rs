//! What the device-lost callback and the uncaptured-error handler saw, checked by every
//! submission so that a GPU failure becomes a [`GpuError`] value, never a panic (wgpu's
//! default uncaptured-error handler panics).

use std::sync::{Arc, Mutex};

use crate::error::GpuError;

/// Failures reported by wgpu's callbacks since the last check.
#[derive(Default)]
pub(crate) struct Health {
    lost: Mutex<Option<String>>,
    error: Mutex<Option<String>>,
}

impl Health {
    /// Installs the device-lost callback and the uncaptured-error handler on `device`.
    pub fn watch(device: &wgpu::Device) -> Arc<Health> {
        let health = Arc::new(Health::default());
        let h = health.clone();
        device.set_device_lost_callback(move |reason, message| {
            *lock(&h.lost) = Some(format!("{reason:?}: {message}"));
        });
        let h = health.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            lock(&h.error).get_or_insert_with(|| e.to_string());
        }));
        health
    }

    /// The device loss or the first uncaptured error seen, as an error naming `during`.
    pub fn check(&self, during: &str) -> Result<(), GpuError> {
        if let Some(why) = lock(&self.lost).clone() {
            return Err(GpuError::DeviceLost(why));
        }
        if let Some(message) = lock(&self.error).take() {
            return Err(GpuError::Backend {
                during: during.into(),
                message,
            });
        }
        Ok(())
    }
}

/// A poisoned lock only means a callback panicked; its value is still the best we have.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

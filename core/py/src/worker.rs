//! A Rust worker thread whose outcome — value, error or panic — is kept for Python to
//! collect, and whose end can be awaited with a timeout (with the GIL released by the
//! caller). The thread never touches Python.

use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::guard::catch;

/// How a worker ended: its own result, or the text of a panic it caught.
pub enum Outcome<T> {
    Finished(T),
    Panicked(String),
}

struct Slot<T> {
    outcome: Option<Outcome<T>>,
}

/// The shared end of a worker: set once by the thread, read by everyone.
pub struct Completion<T> {
    slot: Mutex<Slot<T>>,
    ended: Condvar,
}

impl<T> Completion<T> {
    fn lock(&self) -> std::sync::MutexGuard<'_, Slot<T>> {
        self.slot.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Whether the worker has ended.
    pub fn is_done(&self) -> bool {
        self.lock().outcome.is_some()
    }

    /// Waits until the worker ends or `timeout` passes (`None`: forever); whether it ended.
    pub fn wait(&self, timeout: Option<Duration>) -> bool {
        let deadline = timeout.map(|t| Instant::now() + t);
        let mut slot = self.lock();
        while slot.outcome.is_none() {
            match deadline {
                None => slot = self.ended.wait(slot).unwrap_or_else(|e| e.into_inner()),
                Some(d) => {
                    let now = Instant::now();
                    if now >= d {
                        return false;
                    }
                    slot = self
                        .ended
                        .wait_timeout(slot, d - now)
                        .unwrap_or_else(|e| e.into_inner())
                        .0;
                }
            }
        }
        true
    }

    /// Reads the outcome, if the worker has ended.
    pub fn with_outcome<R>(&self, f: impl FnOnce(Option<&Outcome<T>>) -> R) -> R {
        f(self.lock().outcome.as_ref())
    }
}

/// Starts `work` on a new thread named `name`. A panic anywhere in it — rayon workers
/// included, whose panics rayon carries to the thread that waits on them — ends the worker
/// as [`Outcome::Panicked`] instead of unwinding further.
pub fn spawn<T: Send + 'static>(
    name: &str,
    work: impl FnOnce() -> T + Send + 'static,
) -> std::io::Result<(Arc<Completion<T>>, JoinHandle<()>)> {
    let completion = Arc::new(Completion {
        slot: Mutex::new(Slot { outcome: None }),
        ended: Condvar::new(),
    });
    let c = completion.clone();
    let handle = std::thread::Builder::new()
        .name(name.to_string())
        .spawn(move || {
            let outcome = match catch(work) {
                Ok(v) => Outcome::Finished(v),
                Err(text) => Outcome::Panicked(text),
            };
            c.lock().outcome = Some(outcome);
            c.ended.notify_all();
        })?;
    Ok((completion, handle))
}

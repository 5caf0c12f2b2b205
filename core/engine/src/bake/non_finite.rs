//! What the bake does with a value that is not finite: each stage keeps its output finite
//! by construction (a path's NaN or inf contribution is discarded, a layer value that came
//! out non-finite is stored as 0, a lattice fit with a non-finite coefficient gives way to
//! the exact per-pixel values), counts what it changed, and the report names the stage.
//! A bake is minutes of the user's time: one bad sample must never cost the whole stack,
//! and a count that is not zero must never go unsaid.

use std::sync::atomic::{AtomicU64, Ordering};

use serde::Serialize;

/// The counts a bake gathers while it runs (shared by its threads).
#[derive(Debug, Default)]
pub struct NonFiniteCounter {
    path_contributions: AtomicU64,
}

impl NonFiniteCounter {
    /// Adds path contributions discarded by [`super::path::integrator::trace_eye_sample`].
    pub fn add_path_contributions(&self, n: u64) {
        if n > 0 {
            self.path_contributions.fetch_add(n, Ordering::Relaxed);
        }
    }

    pub fn path_contributions(&self) -> u64 {
        self.path_contributions.load(Ordering::Relaxed)
    }
}

/// Per stage, how many values were not finite and what became of them.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct NonFiniteReport {
    /// Path contributions (one layer's RGB from one eye sample) with a NaN or infinite
    /// channel: discarded, as Cycles discards such samples.
    pub path_contributions: u64,
    /// Averaged or denoised layer values that were NaN or infinite (a sum that overflowed
    /// f32, a filter fed an extreme value): stored as 0.
    pub layer_values: u64,
    /// Lattice fits with a non-finite coefficient or reconstruction: the layer was stored
    /// with its exact per-pixel values instead.
    pub lattice_fits: u64,
    /// Values the stack builder, the last guard before the file, found NaN or infinite:
    /// stored as 0. The stages before it keep this at 0; a count here is a bug to report.
    pub stored_values: u64,
}

impl NonFiniteReport {
    /// Values changed by any stage.
    pub fn total(&self) -> u64 {
        self.path_contributions + self.layer_values + self.lattice_fits + self.stored_values
    }

    /// The report's warning when any stage changed something: what, where and how it was
    /// kept finite.
    pub fn warning(&self) -> Option<String> {
        if self.total() == 0 {
            return None;
        }
        let mut parts = Vec::new();
        if self.path_contributions > 0 {
            parts.push(format!(
                "{} path contributions discarded (NaN or infinite)",
                self.path_contributions
            ));
        }
        if self.layer_values > 0 {
            parts.push(format!(
                "{} averaged or denoised layer values stored as 0",
                self.layer_values
            ));
        }
        if self.lattice_fits > 0 {
            parts.push(format!(
                "{} compressed bounce entries stored exactly instead",
                self.lattice_fits
            ));
        }
        if self.stored_values > 0 {
            parts.push(format!(
                "{} values stored as 0 by the stack writer's last check",
                self.stored_values
            ));
        }
        Some(format!(
            "non-finite values were kept out of the stack: {}",
            parts.join("; ")
        ))
    }
}

/// `data` with every NaN or infinite value set to 0; how many were.
pub(crate) fn zero_non_finite(data: &mut [f32]) -> u64 {
    let mut n = 0;
    for v in data.iter_mut().filter(|v| !v.is_finite()) {
        *v = 0.0;
        n += 1;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stage_is_named_and_a_clean_bake_says_nothing() {
        assert_eq!(NonFiniteReport::default().warning(), None);
        let r = NonFiniteReport {
            path_contributions: 3,
            layer_values: 2,
            lattice_fits: 1,
            stored_values: 4,
        };
        assert_eq!(r.total(), 10);
        let w = r.warning().unwrap();
        for needle in ["3 path", "2 averaged", "1 compressed", "4 values"] {
            assert!(w.contains(needle), "{w}");
        }
    }

    #[test]
    fn zeroing_keeps_finite_values_and_counts_the_rest() {
        let mut v = [1.0, f32::NAN, -2.0, f32::INFINITY, f32::NEG_INFINITY, 1e-45];
        assert_eq!(zero_non_finite(&mut v), 3);
        assert_eq!(v, [1.0, 0.0, -2.0, 0.0, 0.0, 1e-45]);
    }
}

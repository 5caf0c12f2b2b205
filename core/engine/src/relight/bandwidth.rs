//! How fast this machine reads memory: the floor under any relight.
//!
//! A relight reads every sample of the layers it sums once, so `bytes / bandwidth` is a
//! time no implementation can beat; reporting relight times beside it shows how much is
//! left on the table (figures for this project's machines: `docs/measurements.md`).

use rayon::prelude::*;
use std::time::Instant;

/// Smallest buffer measured: 64 MiB is several times any last-level cache of the machines
/// this runs on, so the figure is DRAM's, not a cache's.
pub const MIN_BYTES: usize = 64 << 20;

/// Read bandwidth in GB/s (10⁹ bytes per second): the best of `repeats` rayon-parallel sums
/// over a buffer of `bytes` (raised to [`MIN_BYTES`]), split in 1 MiB chunks across the
/// rayon pool — the same pool and the same kind of access as the relight, so it is what a
/// relight that reads N bytes cannot beat. Best-of because interference from other
/// processes only ever makes a run slower. `repeats` of 0 counts as 1.
pub fn measure_read_bandwidth(bytes: usize, repeats: usize) -> f64 {
    let words = bytes.max(MIN_BYTES) / 8;
    // Distinct non-zero values, written once so every page is mapped before timing.
    let buf: Vec<u64> = (0..words as u64).into_par_iter().map(|i| i | 1).collect();
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let sum: u64 = buf
            .par_chunks(1 << 17)
            .map(|c| c.iter().fold(0u64, |a, &x| a.wrapping_add(x)))
            .reduce(|| 0, |a, b| a.wrapping_add(b));
        std::hint::black_box(sum);
        best = best.min(t.elapsed().as_secs_f64());
    }
    (words * 8) as f64 / best / 1e9
}

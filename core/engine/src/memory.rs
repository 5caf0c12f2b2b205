//! Memory as a budget: sizes computed with checked arithmetic, large buffers allocated
//! through `try_reserve`, and what the machine can give read from the OS.
//!
//! A failed allocation in Rust aborts the process (inside Blender: Blender dies with the
//! user's unsaved work). Every allocation whose size comes from a file, a scene or a
//! setting goes through [`try_zeroed`] / [`try_with_capacity`] instead, so it fails as
//! [`RelumeError::OutOfMemory`], and the bake estimates its peak first and refuses up front
//! when the estimate is over the budget ([`budget_bytes`]).

pub use crate::byte_size::human_bytes;
use crate::{RelumeError, Result};

/// Share of the available memory a bake may plan to use when no budget is given: the rest
/// is left to the host (Blender, the OS's caches) and to the estimate's own error.
pub const DEFAULT_BUDGET_FRACTION: f64 = 0.8;

/// Memory the OS says a new allocation can get, in bytes: `MemAvailable` of
/// `/proc/meminfo`, lowered to the cgroup's remaining limit when one is set (containers,
/// CI). `None` where neither can be read (not Linux): callers then apply no budget unless
/// one is given explicitly.
pub fn available_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok().and_then(|t| {
        t.lines()
            .find(|l| l.starts_with("MemAvailable:"))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<u64>().ok())
            .map(|kb| kb.saturating_mul(1024))
    });
    let cgroup = (|| {
        let max = std::fs::read_to_string("/sys/fs/cgroup/memory.max").ok()?;
        let max: u64 = max.trim().parse().ok()?; // "max" (no limit) does not parse
        let current: u64 = std::fs::read_to_string("/sys/fs/cgroup/memory.current")
            .ok()?
            .trim()
            .parse()
            .ok()?;
        Some(max.saturating_sub(current))
    })();
    match (meminfo, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The budget a large piece of work may plan for: `explicit` when given (bytes), else
/// [`DEFAULT_BUDGET_FRACTION`] of [`available_bytes`]; `None` when neither is known.
pub fn budget_bytes(explicit: Option<u64>) -> Option<u64> {
    explicit.or_else(|| available_bytes().map(|a| (a as f64 * DEFAULT_BUDGET_FRACTION) as u64))
}

/// Refuses `needed` bytes for `what` when a budget is known and `needed` exceeds it.
pub fn check_budget(what: &str, needed: u64, explicit_budget: Option<u64>) -> Result<()> {
    match budget_bytes(explicit_budget) {
        Some(budget) if needed > budget => Err(RelumeError::OutOfMemory {
            what: what.to_string(),
            needed,
            available: budget,
            budget: true,
        }),
        _ => Ok(()),
    }
}

/// The product of `factors` (a size in elements or bytes), or `OutOfMemory` naming `what`
/// when it overflows `u64` (or `usize` on the way to an allocation).
pub fn checked_product(what: &str, factors: &[u64]) -> Result<u64> {
    let mut p: u64 = 1;
    for &f in factors {
        p = p.checked_mul(f).ok_or_else(|| overflow(what))?;
    }
    if usize::try_from(p).is_err() {
        return Err(overflow(what));
    }
    Ok(p)
}

fn overflow(what: &str) -> RelumeError {
    RelumeError::OutOfMemory {
        what: what.to_string(),
        needed: u64::MAX,
        available: available_bytes().unwrap_or(0),
        budget: false,
    }
}

/// An empty vector with room for `len` elements, or `OutOfMemory` naming `what` when the
/// allocator refuses (instead of aborting the process).
pub fn try_with_capacity<T>(len: usize, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| RelumeError::OutOfMemory {
            what: what.to_string(),
            needed: (len as u64).saturating_mul(std::mem::size_of::<T>() as u64),
            available: available_bytes().unwrap_or(0),
            budget: false,
        })?;
    Ok(v)
}

/// `len` copies of `T::default()` (zeros for numbers), allocated as [`try_with_capacity`].
pub fn try_zeroed<T: Clone + Default>(len: usize, what: &str) -> Result<Vec<T>> {
    let mut v = try_with_capacity(len, what)?;
    v.resize(len, T::default());
    Ok(v)
}

/// Hands the allocator's free memory back to the OS where it can (glibc's `malloc_trim`:
/// free pages inside its heaps, not only at their top), so that memory freed by one stage
/// of a long piece of work — a streaming bake's finished tile rows, scattered between the
/// stack's tiles that stay — is not still resident when the next stage peaks. A no-op
/// where the allocator is not glibc's.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        extern "C" {
            fn malloc_trim(pad: usize) -> std::ffi::c_int;
        }
        // SAFETY: malloc_trim takes no pointer and only returns free pages of glibc's own
        // heaps to the OS; it is safe to call from any thread at any time.
        unsafe {
            malloc_trim(0);
        }
    }
}

/// Peak resident memory of this process so far (`VmHWM`), for benchmarks and the
/// estimate's accuracy test; `None` off Linux.
pub fn peak_rss_bytes() -> Option<u64> {
    status_kib("VmHWM:").map(|kb| kb * 1024)
}

/// Resident memory of this process now (`VmRSS`); `None` off Linux.
pub fn current_rss_bytes() -> Option<u64> {
    status_kib("VmRSS:").map(|kb| kb * 1024)
}

fn status_kib(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_impossible_allocation_is_an_error_not_an_abort() {
        let e = try_zeroed::<f32>(usize::MAX / 8, "a test buffer").unwrap_err();
        assert!(matches!(e, RelumeError::OutOfMemory { .. }), "got {e}");
        assert!(e.to_string().contains("a test buffer"), "{e}");
    }

    #[test]
    fn overflowing_sizes_are_refused() {
        let e = checked_product("layers", &[1 << 40, 1 << 40]).unwrap_err();
        assert!(e.to_string().contains("overflows"), "{e}");
        assert_eq!(checked_product("x", &[3, 4, 5]).unwrap(), 60);
    }

    #[test]
    fn a_budget_refuses_what_exceeds_it_and_names_both_sizes() {
        let e = check_budget("the bake", 3 << 30, Some(1 << 30)).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("3.0 GiB") && text.contains("1.0 GiB"),
            "{text}"
        );
        assert!(check_budget("the bake", 1 << 20, Some(1 << 30)).is_ok());
    }

    #[test]
    fn human_bytes_reads_well() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(1536 * 1024), "1.5 MiB");
    }
}

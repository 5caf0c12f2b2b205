//! The walk over the next tile's values that a full sum makes while it sums a tile
//! ([`super::tiled_sum`]): the loads of that tile then find its values in the cache instead
//! of each waiting on memory. A tile's values are not read front to back (per-pixel entries
//! in groups, lattice entries segment by segment), an order the hardware prefetchers follow
//! poorly.
//!
//! The walk is paced by the tile's own reading: the loops that read the current tile's
//! values (and its entry table) report the bytes they read, and the walk asks for the next
//! tile's lines at the rate that has it fetched a little before the current tile is done.
//! Asked for all at once (say, a few lines per entry in the loop over the entries, which is
//! short), the prefetches pile up on the core's outstanding misses and stall it, and then the
//! summing of the tile runs with no fetch in flight.

use crate::stack::tiled::TileValues;

/// A pacing of prefetches over the next tile's values (or none: [`Ahead::default`]).
#[derive(Default)]
pub(crate) struct Ahead {
    /// Address of the next line to fetch, and the end of the values (0, 0: nothing).
    next: usize,
    end: usize,
    /// Lines owed per byte read, in units of 2^-[`Ahead::SHIFT`] lines.
    rate: u64,
    /// Lines owed so far, in the same units.
    owed: u64,
}

impl Ahead {
    const LINE: usize = 64;
    /// Fixed-point precision of [`rate`](Self::rate) and [`owed`](Self::owed).
    const SHIFT: u32 = 24;

    /// A walk over `next`, paced so that it ends once about [`FINISH_SHARE`] % of
    /// `current_bytes` (what the current tile's sum reads) has been reported read.
    pub(crate) fn over(next: &TileValues, current_bytes: usize) -> Ahead {
        let (start, bytes) = (next.address(), next.bytes());
        let lines = bytes.div_ceil(Self::LINE) as u64;
        let paced = (current_bytes as u64 * FINISH_SHARE / 100).max(1);
        Ahead {
            next: start,
            end: start + bytes,
            rate: ((lines << Self::SHIFT) / paced).max(1),
            owed: 0,
        }
    }

    /// Reports `bytes` of the current tile read: prefetches the lines of the next tile owed
    /// by then.
    #[inline(always)]
    pub(crate) fn read(&mut self, bytes: usize) {
        self.owed += bytes as u64 * self.rate;
        while self.owed >= 1 << Self::SHIFT {
            self.owed -= 1 << Self::SHIFT;
            if self.next >= self.end {
                self.owed = 0;
                return;
            }
            fetch_line(self.next);
            self.next += Self::LINE;
        }
    }
}

/// Asks for the lines of `bytes` bytes from `start` at once (a hint: nothing is read into
/// the program and it never faults).
#[inline(always)]
pub(crate) fn fetch_range(start: usize, bytes: usize) {
    let mut at = start & !(Ahead::LINE - 1);
    while at < start + bytes {
        fetch_line(at);
        at += Ahead::LINE;
    }
}

/// Asks for the cache line at `address` into the L2 cache (on other CPUs than x86-64,
/// nothing).
#[inline(always)]
fn fetch_line(address: usize) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is only a hint: it reads nothing into the program and never
    // faults, whatever the address.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T1};
        _mm_prefetch::<_MM_HINT_T1>(address as *const i8);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = address;
}

/// Share (in %) of the current tile's reading by which the walk over the next tile is done:
/// below 100 so that the next tile's first values are in the cache before it starts, with
/// room for the reports' own unevenness.
const FINISH_SHARE: u64 = 75;

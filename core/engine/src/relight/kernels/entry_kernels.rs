//! What every implementation of the relight's inner loops offers ([`EntryKernels`]), the
//! entries they are handed, and the padding of their accumulators to whole vectors.

use crate::relight::ahead::Ahead;
use crate::relight::tile_output::TileOutputKernels;

use super::sample::Sample;

/// Lanes of one vector step: accumulators are padded to a multiple of this.
pub(crate) const LANES: usize = 8;

/// Floats an accumulator for `len` values must hold: `len` rounded up to whole vectors.
#[inline(always)]
pub(crate) const fn padded(len: usize) -> usize {
    len.div_ceil(LANES) * LANES
}

/// Zeroes the planar R, G, B rows for `len` values, padding lanes included.
#[inline(always)]
pub(super) fn zero_rows(r: &mut [f32], g: &mut [f32], b: &mut [f32], len: usize) {
    let end = padded(len);
    r[..end].fill(0.0);
    g[..end].fill(0.0);
    b[..end].fill(0.0);
}

/// A grey lattice entry of a tile waiting for its segments to be summed
/// ([`EntryKernels::grey_many`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PendingEntry {
    /// Where its values for the next segment it covers start in the tile's values: segments
    /// are summed in ascending order, so this moves on by each covered segment's node count.
    pub cursor: usize,
    /// The segments it covers (bit `s`: segment `s`).
    pub segments: u32,
    /// Weight × scale.
    pub weight: [f32; 3],
}

/// A grey per-pixel entry of a tile, gathered to be summed with the tile's others
/// ([`EntryKernels::grey_rows`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GreyEntry {
    /// Where its values start in the tile's values.
    pub start: usize,
    /// Weight × scale.
    pub weight: [f32; 3],
}

/// An RGB entry of a tile, gathered to be added after the tile's grey lattice entries.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RgbEntry {
    /// Where its values start in the tile's values.
    pub start: usize,
    /// Weight × scale.
    pub weight: [f32; 3],
    /// Whether it is a lattice entry (its values are node coefficients).
    pub lattice: bool,
}

/// The two inner loops of one implementation. `len` values of `src` are added; `src` may
/// hold more (the tile's later values), which a vector implementation may read into
/// padding lanes.
pub(crate) trait EntryKernels: Copy + std::fmt::Debug + TileOutputKernels {
    /// Planar grey: `r[p] += w[0]·src[p]`, `g[p] += w[1]·src[p]`, `b[p] += w[2]·src[p]`
    /// for `p < len`. Each accumulator holds at least [`padded`]`(len)` floats; those from
    /// `len` on may change (padding).
    ///
    /// # Panics
    /// If an accumulator is shorter than that or `src` shorter than `len`.
    fn grey<S: Sample>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        src: &[S],
        len: usize,
        w: [f32; 3],
    );

    /// Interleaved RGB: `acc[i] += w[i mod 3]·src[i]` for `i < len` (a multiple of 3).
    /// `acc` holds at least [`padded`]`(len)` floats; those from `len` on may change.
    ///
    /// # Panics
    /// If `acc` is shorter than that, `src` shorter than `len`, or `len` not a multiple of 3.
    fn rgb<S: Sample>(self, acc: &mut [f32], src: &[S], len: usize, w: [f32; 3]);

    /// [`grey`](Self::grey) for each `(start, weight)` of `entries` in order into the same
    /// rows, `len` values of `values` from its start. A vector implementation keeps short
    /// rows (a lattice segment's nodes) in registers across the entries and stores them
    /// once, instead of once per entry: it sums the entries first and adds the sum to the
    /// rows, which for rows that start at 0 (a tile's node rows) are the same additions in
    /// the same order as `grey` per entry. `entries` is an iterator so that its caller can
    /// gather other entries on the way (the loop over a tile's entries drives it), and it is
    /// handed back, run out, so that the caller reads what it gathered from its fields:
    /// taken by value, its state can live in registers through the loop, where through a
    /// reference it would be stored and reloaded per entry.
    ///
    /// # Panics
    /// As [`grey`](Self::grey), for any entry.
    #[inline(always)]
    fn grey_stream<S: Sample, I: Iterator<Item = Option<(usize, [f32; 3])>>>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        values: &[S],
        len: usize,
        mut entries: I,
    ) -> I {
        for (start, weight) in entries.by_ref().flatten() {
            self.grey(r, g, b, &values[start..], len, weight);
        }
        entries
    }

    /// [`grey_stream`](Self::grey_stream) for the entries of `pending` that cover segment
    /// bit `segment`: `len` values of `values` from each one's cursor, in `pending`'s order;
    /// each such cursor then moves on by `len` (to its next segment's values), and the
    /// values read are reported to `ahead`.
    ///
    /// # Panics
    /// As [`grey`](Self::grey), for any entry.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn grey_many<S: Sample>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        values: &[S],
        len: usize,
        segment: u32,
        pending: &mut [PendingEntry],
        ahead: &mut Ahead,
    ) {
        // An item per pending entry, `None` for one that does not cover the segment (a
        // filter would nest a loop in the kernel's and have its accumulators spilled).
        let entries = pending.iter_mut().map(|p| {
            if p.segments & segment == 0 {
                return None;
            }
            let start = p.cursor;
            p.cursor += len;
            ahead.read(len * std::mem::size_of::<S>());
            Some((start, p.weight))
        });
        // Run out: nothing to read back from it.
        let _ = self.grey_stream(r, g, b, values, len, entries);
    }

    /// Sets the rows to zero, then [`grey`](Self::grey) for each of `entries` in order:
    /// `len` values of `values` from its start. The rows' first [`padded`]`(len)` floats
    /// are overwritten. A vector implementation adds a few entries per pass over the rows,
    /// so each row vector is loaded and stored once per few entries instead of once per
    /// entry; per value the additions are the same, in the same order, from the same 0.
    ///
    /// # Panics
    /// As [`grey`](Self::grey), for any entry.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn grey_rows<S: Sample>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        values: &[S],
        len: usize,
        entries: &[GreyEntry],
        ahead: &mut Ahead,
    ) {
        zero_rows(r, g, b, len);
        for e in entries {
            self.grey(r, g, b, &values[e.start..], len, e.weight);
            ahead.read(len * std::mem::size_of::<S>());
        }
    }
}

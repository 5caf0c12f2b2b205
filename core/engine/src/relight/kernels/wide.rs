//! The AVX2 loops with their two busiest ones in 512-bit steps, for CPUs with AVX-512F and
//! AVX-512VL ([`Avx512`]).
//!
//! The relight's loops issue, per stored value, a conversion, three fused multiply-adds
//! and their share of loads, stores and bookkeeping; on two cores that arithmetic takes
//! most of what the memory reads take, so it cannot all hide under them. A 512-bit step
//! does sixteen lanes' work in one instruction where the AVX2 loops need two, so the core
//! has half the instructions to get through per byte read and more of its reorder window
//! free for loads in flight. Two loops carry most of the values and get the wide steps:
//! - the grey lattice entries' sum into a segment's node rows held in registers
//!   ([`EntryKernels::grey_stream`]), for rows of 16 or 32 lanes (a 5 × 5-node segment is 25
//!   values, padded to 32: two steps instead of four);
//! - the grey per-pixel entries' sum into the planar rows ([`EntryKernels::grey_rows`]),
//!   eight entries per pass over the rows instead of four (eight entries' weights, the
//!   three sums and one loaded value fill 28 of the 32 registers), so each row vector is
//!   loaded and stored once per eight entries.
//!
//! Each lane does the same fused multiply-adds in the same order as in the AVX2 loops, from
//! the same starting values, so the images are the same bit for bit (`super::super::tests`
//! checks it). The other loops are the AVX2 ones.

use std::arch::x86_64::*;

use super::x86::Avx2;
use super::{padded, zero_rows, Ahead, EntryKernels, GreyEntry, Sample, LANES};
use crate::relight::tile_output::{ColumnHats, TileOutputKernels};

/// Lanes of one 512-bit step.
const WIDE: usize = 2 * LANES;

/// The AVX2 loops with 512-bit steps in [`EntryKernels::grey_stream`] and
/// [`EntryKernels::grey_rows`]. Only [`Avx512::new`] makes one, after checking that the CPU
/// has AVX2, FMA, F16C, AVX-512F and AVX-512VL, which is what makes its safe methods sound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx512 {
    avx2: Avx2,
}

impl Avx512 {
    /// The wide loops, when this CPU has the features they need.
    pub(crate) fn new() -> Option<Avx512> {
        let avx2 = Avx2::new()?;
        (is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512vl"))
            .then_some(Avx512 { avx2 })
    }
}

impl TileOutputKernels for Avx512 {
    #[inline(always)]
    fn along_x(self, row: &[f32], hats: &ColumnHats, out: &mut [f32]) {
        self.avx2.along_x(row, hats, out)
    }

    #[inline(always)]
    fn image_row(self, px: &mut [f32], r: &[f32], g: &[f32], b: &[f32], reset: bool) {
        self.avx2.image_row(px, r, g, b, reset)
    }

    #[inline(always)]
    fn end_of_band(self) {
        self.avx2.end_of_band()
    }
}

impl EntryKernels for Avx512 {
    #[inline(always)]
    fn grey<S: Sample>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        src: &[S],
        len: usize,
        w: [f32; 3],
    ) {
        self.avx2.grey(r, g, b, src, len, w)
    }

    #[inline(always)]
    fn rgb<S: Sample>(self, acc: &mut [f32], src: &[S], len: usize, w: [f32; 3]) {
        self.avx2.rgb(acc, src, len, w)
    }

    #[inline(always)]
    fn grey_stream<S: Sample, I: Iterator<Item = Option<(usize, [f32; 3])>>>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        values: &[S],
        len: usize,
        entries: I,
    ) -> I {
        // Rows of whole 512-bit steps; the others (an odd number of 8-lane vectors) as
        // AVX2 does them.
        let args = (values, len);
        match padded(len) / LANES {
            2 => wide_in_registers::<S, 1, I>(r, g, b, args, entries),
            4 => wide_in_registers::<S, 2, I>(r, g, b, args, entries),
            _ => self.avx2.grey_stream(r, g, b, values, len, entries),
        }
    }

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
        if entries.is_empty() {
            zero_rows(r, g, b, len);
            return;
        }
        let (first, rest) = entries.split_at(entries.len().min(GROUP));
        wide_group::<S, true>(self, r, g, b, (values, len), first, ahead);
        for group in rest.chunks(GROUP) {
            wide_group::<S, false>(self, r, g, b, (values, len), group, ahead);
        }
    }
}

/// Entries [`Avx512`]'s `grey_rows` adds per pass over the rows: eight value streams'
/// weights (24 registers), three sums and a loaded value fit the 32 registers.
const GROUP: usize = 8;

/// One pass over the rows for up to [`GROUP`] entries, dispatched to a loop per count so
/// that each loop's weights stay in registers; `SET`: the rows start from 0 instead of
/// their contents.
#[inline(always)]
fn wide_group<S: Sample, const SET: bool>(
    k: Avx512,
    r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    args: (&[S], usize),
    group: &[GreyEntry],
    ahead: &mut Ahead,
) {
    match group.len() {
        1 => wide_pass::<S, 1, SET>(k, r, g, b, args, group, ahead),
        2 => wide_pass::<S, 2, SET>(k, r, g, b, args, group, ahead),
        3 => wide_pass::<S, 3, SET>(k, r, g, b, args, group, ahead),
        4 => wide_pass::<S, 4, SET>(k, r, g, b, args, group, ahead),
        5 => wide_pass::<S, 5, SET>(k, r, g, b, args, group, ahead),
        6 => wide_pass::<S, 6, SET>(k, r, g, b, args, group, ahead),
        7 => wide_pass::<S, 7, SET>(k, r, g, b, args, group, ahead),
        _ => wide_pass::<S, 8, SET>(k, r, g, b, args, group, ahead),
    }
}

/// [`wide_group`] for `N` entries: per 16 lanes of the rows, one load of each row (none
/// when `SET`), per entry one conversion and three fused multiply-adds in entry order, one
/// store of each row; a last 8 lanes (rows of an odd number of vectors) the same in a
/// 256-bit step. When an entry's last vector would read past the tile's values, the group
/// goes through [`EntryKernels::grey`] per entry instead (the same additions).
#[inline(always)]
fn wide_pass<S: Sample, const N: usize, const SET: bool>(
    k: Avx512,
    r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    (values, len): (&[S], usize),
    group: &[GreyEntry],
    ahead: &mut Ahead,
) {
    let end = padded(len);
    assert!(
        group.len() == N && r.len() >= end && g.len() >= end && b.len() >= end,
        "planar grey: accumulators of whole vectors, {len} values"
    );
    if group.iter().any(|e| e.start + end > values.len()) {
        // Only at the end of a tile's values.
        if SET {
            zero_rows(r, g, b, len);
        }
        for e in group {
            k.grey(r, g, b, &values[e.start..], len, e.weight);
            ahead.read(len * std::mem::size_of::<S>());
        }
        return;
    }
    let mut src = [values.as_ptr(); N];
    for (p, e) in src.iter_mut().zip(group) {
        // SAFETY: `e.start + end ≤ values.len()` (checked above).
        *p = unsafe { values.as_ptr().add(e.start) };
    }
    let (rp, gp, bp) = (r.as_mut_ptr(), g.as_mut_ptr(), b.as_mut_ptr());
    // SAFETY: an `Avx512` exists only on a CPU with AVX2, FMA, F16C, AVX-512F and VL; the
    // 16 lanes from i (i + 16 ≤ end) and the last 8 (i + 8 = end) are inside the rows and
    // inside every entry's values (both checked above).
    unsafe {
        let mut w = [[_mm512_setzero_ps(); 3]; N];
        for (w, e) in w.iter_mut().zip(group) {
            *w = [
                _mm512_set1_ps(e.weight[0]),
                _mm512_set1_ps(e.weight[1]),
                _mm512_set1_ps(e.weight[2]),
            ];
        }
        let mut i = 0;
        while i + WIDE <= end {
            let (mut ar, mut ag, mut ab) = if SET {
                let zero = _mm512_setzero_ps();
                (zero, zero, zero)
            } else {
                (
                    _mm512_loadu_ps(rp.add(i)),
                    _mm512_loadu_ps(gp.add(i)),
                    _mm512_loadu_ps(bp.add(i)),
                )
            };
            for e in 0..N {
                let x = S::load16(src[e].add(i));
                ar = _mm512_fmadd_ps(x, w[e][0], ar);
                ag = _mm512_fmadd_ps(x, w[e][1], ag);
                ab = _mm512_fmadd_ps(x, w[e][2], ab);
            }
            _mm512_storeu_ps(rp.add(i), ar);
            _mm512_storeu_ps(gp.add(i), ag);
            _mm512_storeu_ps(bp.add(i), ab);
            ahead.read(N * WIDE * std::mem::size_of::<S>());
            i += WIDE;
        }
        if i < end {
            let (mut ar, mut ag, mut ab) = if SET {
                let zero = _mm256_setzero_ps();
                (zero, zero, zero)
            } else {
                (
                    _mm256_loadu_ps(rp.add(i)),
                    _mm256_loadu_ps(gp.add(i)),
                    _mm256_loadu_ps(bp.add(i)),
                )
            };
            for e in 0..N {
                let x = S::load8(src[e].add(i));
                ar = _mm256_fmadd_ps(x, _mm512_castps512_ps256(w[e][0]), ar);
                ag = _mm256_fmadd_ps(x, _mm512_castps512_ps256(w[e][1]), ag);
                ab = _mm256_fmadd_ps(x, _mm512_castps512_ps256(w[e][2]), ab);
            }
            _mm256_storeu_ps(rp.add(i), ar);
            _mm256_storeu_ps(gp.add(i), ag);
            _mm256_storeu_ps(bp.add(i), ab);
            ahead.read(N * LANES * std::mem::size_of::<S>());
        }
    }
}

/// Sixteen samples from `src[i..]`: read in place when sixteen are there, else the ones
/// that are, zero-filled (a last, partial step at the end of a tile's values).
///
/// # Safety
/// AVX-512F and F16C present; `i < src.len()`.
#[inline(always)]
unsafe fn load16_at<S: Sample>(src: &[S], i: usize) -> __m512 {
    if i + WIDE <= src.len() {
        // SAFETY: sixteen values from i are in `src`; features as the caller promises.
        unsafe { S::load16(src.as_ptr().add(i)) }
    } else {
        let mut buf = [S::ZERO; WIDE];
        let rest = &src[i..];
        buf[..rest.len()].copy_from_slice(rest);
        // SAFETY: `buf` holds sixteen values; features as the caller promises.
        unsafe { S::load16(buf.as_ptr()) }
    }
}

/// [`EntryKernels::grey_stream`] for rows of `Z` 512-bit steps (`padded(len) == Z · 16`),
/// held in registers: per entry, per step one load and three fused multiply-adds, and one
/// add into the rows at the end (the AVX2 loop's additions, sixteen lanes at a time). The
/// loop calls nothing but the iterator (inlined), so the sums stay in registers.
#[inline(always)]
fn wide_in_registers<S: Sample, const Z: usize, I: Iterator<Item = Option<(usize, [f32; 3])>>>(
    r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    (values, len): (&[S], usize),
    mut entries: I,
) -> I {
    let end = Z * WIDE;
    assert!(
        padded(len) == end && r.len() >= end && g.len() >= end && b.len() >= end,
        "planar grey: accumulators of whole vectors, {len} values"
    );
    // SAFETY: only reached through an `Avx512`, which exists only on a CPU with AVX2, FMA,
    // F16C, AVX-512F and VL; loads of whole steps below `end ≤ src.len()`, else through
    // `load16_at` from `z · 16 < len ≤ src.len()` (checked per entry: `len > end − 8`),
    // stores below `end`, inside the rows (checked above).
    unsafe {
        let zero = _mm512_setzero_ps();
        let (mut ar, mut ag, mut ab) = ([zero; Z], [zero; Z], [zero; Z]);
        // One pass of the loop per item, skipped ones included (a nested loop to skip them
        // would have the compiler spill the sums).
        for item in entries.by_ref() {
            let Some((start, weight)) = item else {
                continue;
            };
            let src = &values[start..];
            assert!(src.len() >= len, "planar grey: {len} values");
            let (wr, wg, wb) = (
                _mm512_set1_ps(weight[0]),
                _mm512_set1_ps(weight[1]),
                _mm512_set1_ps(weight[2]),
            );
            let whole = src.len() >= end;
            for z in 0..Z {
                let x = if whole {
                    S::load16(src.as_ptr().add(z * WIDE))
                } else {
                    load16_at(src, z * WIDE)
                };
                ar[z] = _mm512_fmadd_ps(x, wr, ar[z]);
                ag[z] = _mm512_fmadd_ps(x, wg, ag[z]);
                ab[z] = _mm512_fmadd_ps(x, wb, ab[z]);
            }
        }
        for (row, sums) in [(r, ar), (g, ag), (b, ab)] {
            let p = row.as_mut_ptr();
            for (z, sum) in sums.iter().enumerate() {
                let at = p.add(z * WIDE);
                _mm512_storeu_ps(at, _mm512_add_ps(_mm512_loadu_ps(at), *sum));
            }
        }
    }
    entries
}

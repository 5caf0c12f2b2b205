//! The AVX2 + FMA + F16C loops ([`Avx2`]): eight samples per step, `vcvtph2ps` converting
//! f16 in registers. The planar grey loops are written over [`Lanes`] so that the 512-bit
//! kernels ([`super::wide`]) run the same code sixteen lanes at a time.

use super::entry_kernels::{padded, zero_rows, EntryKernels, GreyEntry, LANES};
use super::lanes::Lanes;
use super::sample::Sample;
use crate::relight::ahead::Ahead;
use crate::relight::tile_output::{self, ColumnHats, TileOutputKernels};
use std::arch::x86_64::*;

impl TileOutputKernels for Avx2 {
    #[inline(always)]
    fn along_x(self, row: &[f32], hats: &ColumnHats, out: &mut [f32]) {
        // SAFETY: an `Avx2` exists only on a CPU with AVX2.
        unsafe { tile_output::x86::along_x(row, hats, out) }
    }

    #[inline(always)]
    fn image_row(self, px: &mut [f32], r: &[f32], g: &[f32], b: &[f32], reset: bool) {
        // SAFETY: as above.
        unsafe { tile_output::x86::image_row(px, r, g, b, reset) }
    }

    #[inline(always)]
    fn end_of_band(self) {
        tile_output::x86::end_of_band();
    }
}

/// The AVX2 + FMA + F16C loops. Only [`Avx2::new`] makes one, after checking that the
/// CPU has those features, which is what makes its safe methods sound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx2 {
    _checked: (),
}

impl Avx2 {
    /// The AVX2 loops, when this CPU has AVX2, FMA and F16C.
    pub(crate) fn new() -> Option<Avx2> {
        (is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("f16c"))
        .then_some(Avx2 { _checked: () })
    }
}

impl EntryKernels for Avx2 {
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
        let end = padded(len);
        assert!(
            r.len() >= end && g.len() >= end && b.len() >= end && src.len() >= len,
            "planar grey: accumulators of whole vectors, {len} values"
        );
        let (rp, gp, bp) = (r.as_mut_ptr(), g.as_mut_ptr(), b.as_mut_ptr());
        // SAFETY: `self` exists only on a CPU with AVX2, FMA and F16C; every lane
        // i..i + 8 < end is inside the accumulators (checked above) and `i < len ≤
        // src.len()` for the loads.
        unsafe {
            let (wr, wg, wb) = (
                _mm256_set1_ps(w[0]),
                _mm256_set1_ps(w[1]),
                _mm256_set1_ps(w[2]),
            );
            let mut i = 0;
            while i < len {
                let v = <__m256 as Lanes>::load_at(src, i);
                _mm256_storeu_ps(
                    rp.add(i),
                    _mm256_fmadd_ps(v, wr, _mm256_loadu_ps(rp.add(i))),
                );
                _mm256_storeu_ps(
                    gp.add(i),
                    _mm256_fmadd_ps(v, wg, _mm256_loadu_ps(gp.add(i))),
                );
                _mm256_storeu_ps(
                    bp.add(i),
                    _mm256_fmadd_ps(v, wb, _mm256_loadu_ps(bp.add(i))),
                );
                i += LANES;
            }
        }
    }

    #[inline(always)]
    fn rgb<S: Sample>(self, acc: &mut [f32], src: &[S], len: usize, w: [f32; 3]) {
        assert!(
            len.is_multiple_of(3) && acc.len() >= padded(len) && src.len() >= len,
            "interleaved RGB: whole pixels, accumulator of whole vectors"
        );
        let ap = acc.as_mut_ptr();
        // SAFETY: as in `grey`: features checked at construction, lanes below
        // `padded(len) ≤ acc.len()`, loads from `i < len ≤ src.len()`.
        unsafe {
            // The weights of lanes 0..8, 8..16, 16..24 of each 24-sample (8-pixel) step.
            let rotations = [
                _mm256_setr_ps(w[0], w[1], w[2], w[0], w[1], w[2], w[0], w[1]),
                _mm256_setr_ps(w[2], w[0], w[1], w[2], w[0], w[1], w[2], w[0]),
                _mm256_setr_ps(w[1], w[2], w[0], w[1], w[2], w[0], w[1], w[2]),
            ];
            let mut i = 0;
            while i + 3 * LANES <= len {
                for (k, wk) in rotations.iter().enumerate() {
                    let at = i + k * LANES;
                    let v = S::load8(src.as_ptr().add(at));
                    _mm256_storeu_ps(
                        ap.add(at),
                        _mm256_fmadd_ps(v, *wk, _mm256_loadu_ps(ap.add(at))),
                    );
                }
                i += 3 * LANES;
            }
            for wk in rotations {
                if i >= len {
                    break;
                }
                let v = <__m256 as Lanes>::load_at(src, i);
                _mm256_storeu_ps(
                    ap.add(i),
                    _mm256_fmadd_ps(v, wk, _mm256_loadu_ps(ap.add(i))),
                );
                i += LANES;
            }
        }
    }

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
        // Rows of up to four vectors (a lattice segment at the presets' steps) stay in
        // twelve registers; longer ones go through memory per entry.
        let args = (values, len);
        match padded(len) / LANES {
            1 => grey_in_registers::<S, __m256, 1, I>(r, g, b, args, entries),
            2 => grey_in_registers::<S, __m256, 2, I>(r, g, b, args, entries),
            3 => grey_in_registers::<S, __m256, 3, I>(r, g, b, args, entries),
            4 => grey_in_registers::<S, __m256, 4, I>(r, g, b, args, entries),
            _ => {
                for (start, weight) in entries.by_ref().flatten() {
                    self.grey(r, g, b, &values[start..], len, weight);
                }
                entries
            }
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
        grey_rows_grouped::<S, __m256>(r, g, b, (values, len), entries, ahead);
    }
}

/// [`EntryKernels::grey_rows`] with [`grey_pass`] at `V` lanes (also [`super::wide`]'s):
/// the entries [`Lanes::GROUP`] at a time, the first group setting the rows.
#[inline(always)]
pub(super) fn grey_rows_grouped<S: Sample, V: Lanes>(
    r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    (values, len): (&[S], usize),
    entries: &[GreyEntry],
    ahead: &mut Ahead,
) {
    if entries.is_empty() {
        zero_rows(r, g, b, len);
        return;
    }
    let (first, rest) = entries.split_at(entries.len().min(V::GROUP));
    grey_group::<S, V, true>(r, g, b, (values, len), first, ahead);
    for group in rest.chunks(V::GROUP) {
        grey_group::<S, V, false>(r, g, b, (values, len), group, ahead);
    }
}

/// One pass over the rows for up to [`Lanes::GROUP`] (at most eight) entries, dispatched to
/// a loop per count so that each loop's weights stay in registers; `SET`: the rows start
/// from 0 instead of their contents.
#[inline(always)]
fn grey_group<S: Sample, V: Lanes, const SET: bool>(
    r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    args: (&[S], usize),
    group: &[GreyEntry],
    ahead: &mut Ahead,
) {
    match group.len() {
        1 => grey_pass::<S, V, 1, SET>(r, g, b, args, group, ahead),
        2 => grey_pass::<S, V, 2, SET>(r, g, b, args, group, ahead),
        3 => grey_pass::<S, V, 3, SET>(r, g, b, args, group, ahead),
        4 => grey_pass::<S, V, 4, SET>(r, g, b, args, group, ahead),
        5 => grey_pass::<S, V, 5, SET>(r, g, b, args, group, ahead),
        6 => grey_pass::<S, V, 6, SET>(r, g, b, args, group, ahead),
        7 => grey_pass::<S, V, 7, SET>(r, g, b, args, group, ahead),
        _ => grey_pass::<S, V, 8, SET>(r, g, b, args, group, ahead),
    }
}

/// [`grey_group`] for `N` entries, `V` lanes at a time (also [`super::wide`]'s, at 16): per
/// vector of the rows, one load (none when `SET`), per entry one conversion and three fused
/// multiply-adds in entry order, one store; where the rows end eight lanes short of a whole
/// `V`, the last eight lanes the same in a 256-bit step. When an entry's last vector would
/// read past the tile's values, the group goes through [`EntryKernels::grey`] per entry
/// instead (the same additions).
///
/// Only called from the kernels' methods, so the CPU has the features of `V`.
#[inline(always)]
pub(super) fn grey_pass<S: Sample, V: Lanes, const N: usize, const SET: bool>(
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
        let k = Avx2 { _checked: () };
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
    let rows = [r.as_mut_ptr(), g.as_mut_ptr(), b.as_mut_ptr()];
    // SAFETY: only reached through the kernels' methods, on a CPU with the features of `V`
    // (the kernel types exist only there); lanes i..i + V::LANES ≤ end (and the last eight,
    // i + 8 = end) are inside the rows and inside every entry's values (both checked
    // above).
    unsafe {
        let mut w = [[V::zero(); 3]; N];
        for (w, e) in w.iter_mut().zip(group) {
            *w = [
                V::splat(e.weight[0]),
                V::splat(e.weight[1]),
                V::splat(e.weight[2]),
            ];
        }
        let (rp, gp, bp) = (rows[0], rows[1], rows[2]);
        let mut i = 0;
        while i + V::LANES <= end {
            let (mut ar, mut ag, mut ab) = if SET {
                (V::zero(), V::zero(), V::zero())
            } else {
                (
                    V::load_f32(rp.add(i)),
                    V::load_f32(gp.add(i)),
                    V::load_f32(bp.add(i)),
                )
            };
            for e in 0..N {
                let x = V::load(src[e].add(i));
                ar = V::fmadd(x, w[e][0], ar);
                ag = V::fmadd(x, w[e][1], ag);
                ab = V::fmadd(x, w[e][2], ab);
            }
            ar.store(rp.add(i));
            ag.store(gp.add(i));
            ab.store(bp.add(i));
            ahead.read(N * V::LANES * std::mem::size_of::<S>());
            i += V::LANES;
        }
        if i < end {
            let mut acc = if SET {
                [<__m256 as Lanes>::zero(); 3]
            } else {
                rows.map(|p| <__m256 as Lanes>::load_f32(p.add(i)))
            };
            for e in 0..N {
                let x = <__m256 as Lanes>::load(src[e].add(i));
                for c in 0..3 {
                    acc[c] = <__m256 as Lanes>::fmadd(x, w[e][c].low8(), acc[c]);
                }
            }
            for c in 0..3 {
                acc[c].store(rows[c].add(i));
            }
            ahead.read(N * LANES * std::mem::size_of::<S>());
        }
    }
}

/// [`EntryKernels::grey_stream`] for rows of `N` vectors of `V` lanes
/// (`padded(len) == N · V::LANES`; also [`super::wide`]'s, at 16 lanes), held in registers:
/// per entry, per vector one load and three fused multiply-adds, and one add into the rows
/// at the end. The loop calls nothing but the iterator (inlined), so the accumulators stay
/// in registers (every vector register is caller-saved).
///
/// Only called from the kernels' methods, so the CPU has the features of `V`.
#[inline(always)]
pub(super) fn grey_in_registers<
    S: Sample,
    V: Lanes,
    const N: usize,
    I: Iterator<Item = Option<(usize, [f32; 3])>>,
>(
    r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    (values, len): (&[S], usize),
    mut entries: I,
) -> I {
    let end = N * V::LANES;
    assert!(
        padded(len) == end && r.len() >= end && g.len() >= end && b.len() >= end,
        "planar grey: accumulators of whole vectors, {len} values"
    );
    // SAFETY: only reached through the kernels' methods, on a CPU with the features of `V`;
    // loads of whole vectors below `end ≤ src.len()`, else through `load_at` from
    // `v · V::LANES < len ≤ src.len()` (checked per entry; `len > end − 8`), stores below
    // `end`, inside the rows (checked above).
    unsafe {
        let zero = V::zero();
        let (mut ar, mut ag, mut ab) = ([zero; N], [zero; N], [zero; N]);
        // One pass of the loop per item, skipped ones included (a nested loop to skip
        // them had the compiler spill the accumulators).
        for item in entries.by_ref() {
            let Some((start, weight)) = item else {
                continue;
            };
            let src = &values[start..];
            assert!(src.len() >= len, "planar grey: {len} values");
            let (wr, wg, wb) = (
                V::splat(weight[0]),
                V::splat(weight[1]),
                V::splat(weight[2]),
            );
            // Whole vectors read in place except at the end of the tile's values, so
            // the loop loads straight into registers.
            let whole = src.len() >= end;
            for v in 0..N {
                let x = if whole {
                    V::load(src.as_ptr().add(v * V::LANES))
                } else {
                    V::load_at(src, v * V::LANES)
                };
                ar[v] = V::fmadd(x, wr, ar[v]);
                ag[v] = V::fmadd(x, wg, ag[v]);
                ab[v] = V::fmadd(x, wb, ab[v]);
            }
        }
        for (row, sums) in [(r, ar), (g, ag), (b, ab)] {
            let p = row.as_mut_ptr();
            for (v, sum) in sums.iter().enumerate() {
                let at = p.add(v * V::LANES);
                V::add(V::load_f32(at), *sum).store(at);
            }
        }
    }
    entries
}

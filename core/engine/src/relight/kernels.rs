//! The inner loops of the relight: `acc += w(RGB) · values`, for one tile entry (a layer's
//! pixels in a tile, or one segment's lattice coefficients) into the tile's accumulators
//! (`tile_accumulators.rs`), which are merged into the RGBA image once per tile.
//!
//! Every relight ends here, so this is where its time goes: the sum reads each sample once,
//! so memory bandwidth is its floor, and the arithmetic (one multiply-add per sample and
//! channel, plus one f16 → f32 conversion per sample) must hide under the reads as far as
//! it can (on two cores it does not quite: `docs/scale.md`).
//!
//! Two shapes of accumulator, so that neither inner loop needs a permute:
//! - **Planar grey** ([`EntryKernels::grey`]): a grey sample adds to three separate R, G
//!   and B rows, three fused multiply-adds per 8 values.
//! - **Interleaved RGB** ([`EntryKernels::rgb`]): an RGB sample adds to the same position
//!   of an interleaved RGB row, with the weight vector rotated per 8-lane step (the pattern
//!   repeats every 24 samples).
//!
//! A third loop, [`EntryKernels::grey_stream`], adds many grey entries into one short row (a
//! lattice segment's nodes), the entries handed over one by one by an iterator (the loop
//! over a tile's entries, or [`EntryKernels::grey_many`] over the gathered ones): the AVX2
//! one keeps the row in registers across the entries.
//! A fourth, [`EntryKernels::grey_rows`], sums a tile's grey per-pixel entries into its
//! planar rows from zero: the AVX2 one adds four entries per pass over the rows, so the rows
//! (too long for registers) go through L1 once per four entries rather than once per entry.
//!
//! Entries are short (a lattice segment holds a few dozen values), so the loops are built
//! for that: the accumulators are padded to whole 8-lane vectors ([`padded`]) and a last,
//! partial vector is added whole — reading past the entry where the tile's values go on,
//! else from a zero-filled copy — into padding lanes nobody reads. No scalar tail.
//!
//! Three implementations, each a type implementing [`EntryKernels`], so the tile loop that
//! calls them is compiled once per implementation with the calls inlined (no dispatch per
//! entry); [`Kernels`] says which one runs, chosen once per [`Kernels::detect`]:
//! - **AVX2 + FMA + F16C** ([`Avx2`], `kernels/avx2.rs`; x86-64, detected at run time
//!   because the workspace builds for baseline x86-64): 8 samples per step, `vcvtph2ps`
//!   converts f16 in registers, one fused multiply-add per 8 samples and accumulator. Its
//!   methods are meant to be inlined into a function compiled with those features
//!   (`tiled_sum.rs` does so). Its planar grey loops are written over a vector width
//!   (`kernels/lanes.rs`), so that the next implementation runs them at 16 lanes.
//! - **AVX-512F + VL** besides ([`Avx512`], `kernels/wide.rs`): the AVX2 loops with the
//!   two that carry most values in 16-lane steps, in a tile loop compiled with those
//!   features (32 vector registers instead of 16); the same additions per lane, so the same
//!   results, bit for bit.
//! - **Portable** ([`Portable`]): converts a chunk of at most [`CHUNK`] samples into a
//!   stack buffer with `half`'s slice conversion, then plain loops over exactly the entry.
//!   Used on other CPUs, and by the tests to check the vector paths against it.
//!
//! The accumulators hold colour only; the image's alpha of 1 is never touched by a sum.

use super::tile_output::TileOutputKernels;

/// Pixels converted per step of the portable path (64 px × 3 channels × 4 B = 768 B of
/// stack: small enough for L1, large enough to amortise the per-call dispatch of `half`).
pub(crate) const CHUNK: usize = 64;

/// Which implementation of the inner loops runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kernels {
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    /// The AVX2 loops with the two busiest in 512-bit steps ([`Avx512`]), in a tile loop
    /// compiled with AVX-512F and AVX-512VL as well: the same additions per lane (so the
    /// same results, bit for bit), in half the instructions, with 32 vector registers
    /// instead of 16, so the lattice sums' accumulators, weights and loaded values all fit
    /// and nothing is spilled to the stack.
    #[cfg(target_arch = "x86_64")]
    Avx512(Avx512),
}

impl Kernels {
    /// The fastest implementation this CPU runs.
    pub(crate) fn detect() -> Kernels {
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(k) = Avx512::new() {
                return Kernels::Avx512(k);
            }
            if let Some(k) = Avx2::new() {
                return Kernels::Avx2(k);
            }
        }
        Kernels::Portable
    }

    /// Every implementation this CPU runs, slowest first (the tests compare them).
    #[cfg(test)]
    pub(crate) fn available() -> Vec<Kernels> {
        let mut all = vec![Kernels::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(k) = Avx2::new() {
                all.push(Kernels::Avx2(k));
            }
            if let Some(k) = Avx512::new() {
                all.push(Kernels::Avx512(k));
            }
        }
        all
    }
}

/// The portable loops: exactly `len` values, no padding lanes touched.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable;

/// The scalar per-pixel loops (the trait's defaults).
impl TileOutputKernels for Portable {}

impl Kernels {
    /// [`TileOutputKernels::end_of_band`] of the implementation that runs.
    pub(crate) fn end_of_band(self) {
        match self {
            Kernels::Portable => Portable.end_of_band(),
            #[cfg(target_arch = "x86_64")]
            Kernels::Avx2(k) => k.end_of_band(),
            #[cfg(target_arch = "x86_64")]
            Kernels::Avx512(k) => k.end_of_band(),
        }
    }
}

impl EntryKernels for Portable {
    #[inline]
    fn grey<S: Sample>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        src: &[S],
        len: usize,
        w: [f32; 3],
    ) {
        grey_planar_portable(&mut r[..len], &mut g[..len], &mut b[..len], &src[..len], w);
    }

    #[inline]
    fn rgb<S: Sample>(self, acc: &mut [f32], src: &[S], len: usize, w: [f32; 3]) {
        assert!(len.is_multiple_of(3), "interleaved RGB: whole pixels");
        rgb_interleaved_portable(&mut acc[..len], &src[..len], w);
    }
}

fn grey_planar_portable<S: Sample>(
    r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    src: &[S],
    w: [f32; 3],
) {
    let mut buf = [0.0f32; CHUNK];
    for (k, chunk) in src.chunks(CHUNK).enumerate() {
        let t = &mut buf[..chunk.len()];
        S::convert(chunk, t);
        let o = k * CHUNK;
        let (r, g, b) = (
            &mut r[o..o + t.len()],
            &mut g[o..o + t.len()],
            &mut b[o..o + t.len()],
        );
        for (i, v) in t.iter().enumerate() {
            r[i] += w[0] * v;
            g[i] += w[1] * v;
            b[i] += w[2] * v;
        }
    }
}

fn rgb_interleaved_portable<S: Sample>(acc: &mut [f32], src: &[S], w: [f32; 3]) {
    let mut buf = [0.0f32; 3 * CHUNK];
    for (k, chunk) in src.chunks(3 * CHUNK).enumerate() {
        let t = &mut buf[..chunk.len()];
        S::convert(chunk, t);
        let o = k * 3 * CHUNK;
        for (a, v) in acc[o..o + t.len()]
            .chunks_exact_mut(3)
            .zip(t.chunks_exact(3))
        {
            a[0] += w[0] * v[0];
            a[1] += w[1] * v[1];
            a[2] += w[2] * v[2];
        }
    }
}

mod entry_kernels;
mod sample;
pub(crate) use entry_kernels::{padded, EntryKernels, GreyEntry, PendingEntry, RgbEntry};
pub(crate) use sample::Sample;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod lanes;
#[cfg(target_arch = "x86_64")]
mod wide;
#[cfg(target_arch = "x86_64")]
pub(crate) use wide::Avx512;

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::relight::ahead::Ahead;
    use half::f16;

    /// `n` pseudo-random values in [−1, 1] from `seed` (xorshift), for the kernels' tests.
    pub(crate) fn pseudo(n: usize, seed: u32) -> Vec<f32> {
        let mut x = seed.wrapping_mul(2654435761).max(1);
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                (x % 2001) as f32 / 1000.0 - 1.0
            })
            .collect()
    }

    const W: [f32; 3] = [0.5, -1.25, 2.0];

    /// One implementation against a scalar sum: `len` values of a source that ends there
    /// or goes on (values past the entry, as in a tile), f16 and f32, grey and RGB, lengths
    /// that exercise whole vectors, 24-sample steps and every partial last vector.
    fn check<K: EntryKernels>(k: K) {
        for len in (0..=26).chain([48, 64, 65, 75, 200, 256]) {
            for extra in [0usize, 3, 8, 30] {
                let vals = pseudo(len + extra, (len * 7 + extra) as u32);
                let halves: Vec<f16> = vals.iter().map(|&v| f16::from_f32(v)).collect();
                let exact: Vec<f32> = halves.iter().map(|h| h.to_f32()).collect();
                let end = padded(len);
                // Grey: three planes.
                let init = pseudo(3 * end, 99);
                let mut expect = init.clone();
                for p in 0..len {
                    for c in 0..3 {
                        expect[c * end + p] += W[c] * exact[p];
                    }
                }
                for src in [Source::Half(&halves), Source::Single(&exact)] {
                    let mut got = init.clone();
                    let (r, gb) = got.split_at_mut(end);
                    let (g, b) = gb.split_at_mut(end);
                    match src {
                        Source::Half(s) => k.grey(r, g, b, s, len, W),
                        Source::Single(s) => k.grey(r, g, b, s, len, W),
                    }
                    for c in 0..3 {
                        for p in 0..len {
                            let (x, y) = (got[c * end + p], expect[c * end + p]);
                            // FMA rounds once instead of twice.
                            assert!(
                                (x - y).abs() <= 1e-6 * (1.0 + y.abs()),
                                "{k:?} grey len {len} +{extra}: {x} vs {y}"
                            );
                        }
                    }
                }
                // RGB: whole pixels of the same values.
                let len3 = len / 3 * 3;
                let end3 = padded(len3);
                let init = pseudo(end3, 7);
                let mut expect = init.clone();
                for i in 0..len3 {
                    expect[i] += W[i % 3] * exact[i];
                }
                for src in [Source::Half(&halves), Source::Single(&exact)] {
                    let mut got = init.clone();
                    match src {
                        Source::Half(s) => k.rgb(&mut got, s, len3, W),
                        Source::Single(s) => k.rgb(&mut got, s, len3, W),
                    }
                    for i in 0..len3 {
                        let (x, y) = (got[i], expect[i]);
                        assert!(
                            (x - y).abs() <= 1e-6 * (1.0 + y.abs()),
                            "{k:?} rgb len {len3} +{extra}: {x} vs {y}"
                        );
                    }
                }
            }
        }
    }

    #[derive(Clone, Copy)]
    enum Source<'a> {
        Half(&'a [f16]),
        Single(&'a [f32]),
    }

    /// `grey_many` against a scalar sum: entries covering the segment or not, rows of one
    /// to five vectors (registers, and memory past four), cursors moved on by exactly the
    /// covered entries.
    fn check_many<K: EntryKernels>(k: K) {
        for len in [1usize, 7, 8, 9, 16, 25, 31, 32, 33, 40] {
            let values: Vec<f16> = pseudo(6 * len + 5, len as u32)
                .iter()
                .map(|&v| f16::from_f32(v))
                .collect();
            let mut pending: Vec<PendingEntry> = (0..6)
                .map(|i| PendingEntry {
                    cursor: i * len,
                    segments: if i % 3 == 1 { 0b10 } else { 0b11 },
                    weight: [0.5 - i as f32 * 0.1, 1.0, -0.25 * i as f32],
                })
                .collect();
            let end = padded(len);
            let mut rows = vec![0.0f32; 3 * end];
            let mut expect = vec![0.0f32; 3 * end];
            for p in pending.iter().filter(|p| p.segments & 1 != 0) {
                for i in 0..len {
                    for c in 0..3 {
                        expect[c * end + i] += p.weight[c] * values[p.cursor + i].to_f32();
                    }
                }
            }
            let (r, gb) = rows.split_at_mut(end);
            let (g, b) = gb.split_at_mut(end);
            k.grey_many(
                r,
                g,
                b,
                &values,
                len,
                1,
                &mut pending,
                &mut Ahead::default(),
            );
            for c in 0..3 {
                for i in 0..len {
                    let (x, y) = (rows[c * end + i], expect[c * end + i]);
                    assert!(
                        (x - y).abs() <= 1e-6 * (1.0 + y.abs()),
                        "{k:?} len {len}: {x} vs {y}"
                    );
                }
            }
            for (i, p) in pending.iter().enumerate() {
                let moved = if i % 3 == 1 { 0 } else { len };
                assert_eq!(
                    p.cursor,
                    i * len + moved,
                    "{k:?} len {len}: cursor of entry {i}"
                );
            }
        }
    }

    /// `grey_rows` against a scalar sum from zero: no entry to several groups and a partial
    /// one, rows that held something before (overwritten), entries whose last vector ends
    /// at the end of the values (the per-entry path), partial last vectors.
    fn check_rows<K: EntryKernels>(k: K) {
        for len in [1usize, 8, 13, 64, 256] {
            for count in [0usize, 1, 2, 3, 4, 5, 7, 9] {
                let end = padded(len);
                // Entries back to back; the last one ends exactly where the values do.
                let values: Vec<f16> = pseudo(count * len, (len * 31 + count) as u32)
                    .iter()
                    .map(|&v| f16::from_f32(v))
                    .collect();
                let entries: Vec<GreyEntry> = (0..count)
                    .map(|i| GreyEntry {
                        start: i * len,
                        weight: [0.5 - i as f32 * 0.1, 1.0 + i as f32, -0.25 * i as f32],
                    })
                    .collect();
                let mut expect = vec![0.0f32; 3 * end];
                for e in &entries {
                    for i in 0..len {
                        for c in 0..3 {
                            expect[c * end + i] += e.weight[c] * values[e.start + i].to_f32();
                        }
                    }
                }
                let mut rows = pseudo(3 * end, 3);
                let (r, gb) = rows.split_at_mut(end);
                let (g, b) = gb.split_at_mut(end);
                k.grey_rows(r, g, b, &values, len, &entries, &mut Ahead::default());
                for c in 0..3 {
                    for i in 0..len {
                        let (x, y) = (rows[c * end + i], expect[c * end + i]);
                        assert!(
                            (x - y).abs() <= 1e-6 * (1.0 + y.abs()),
                            "{k:?} len {len}, {count} entries: {x} vs {y}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn portable_kernels_match_scalar() {
        check(Portable);
        check_many(Portable);
        check_rows(Portable);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_kernels_match_scalar() {
        match Avx2::new() {
            Some(k) => {
                check(k);
                check_many(k);
                check_rows(k);
            }
            None => eprintln!("no AVX2 + FMA + F16C on this CPU: only the portable loops run"),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_kernels_match_scalar() {
        match Avx512::new() {
            // SAFETY: `Avx512::new` checked the features the test is compiled with.
            Some(k) => unsafe { wide_checks(k) },
            None => eprintln!("no AVX-512F + VL on this CPU: the 512-bit loops are not run"),
        }
    }

    /// The checks compiled with the wide loops' features, as the relight compiles its tile
    /// loop for them (`tiled_sum.rs`), so their instructions are inlined the same way.
    ///
    /// # Safety
    /// The CPU has AVX2, FMA, F16C, AVX-512F and AVX-512VL.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c,avx512f,avx512vl")]
    unsafe fn wide_checks(k: Avx512) {
        check(k);
        check_many(k);
        check_rows(k);
    }

    #[test]
    fn portable_kernels_leave_the_padding_alone() {
        let src = pseudo(13, 5);
        let mut acc = vec![0.0f32; padded(12)];
        Portable.rgb(&mut acc, &src, 12, W);
        assert!(acc[..12].iter().any(|v| *v != 0.0));
        assert!(acc[12..].iter().all(|v| *v == 0.0));
    }
}

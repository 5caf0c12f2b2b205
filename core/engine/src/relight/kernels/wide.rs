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
//! Both are the AVX2 kernels' loops (`avx2.rs`, written over [`super::lanes::Lanes`]) at
//! sixteen lanes: each lane does the same fused multiply-adds in the same order from the
//! same starting values, so the images are the same bit for bit (`super::super::tests`
//! checks it). The other loops are the AVX2 ones.

use std::arch::x86_64::*;

use super::avx2::{grey_in_registers, grey_rows_grouped, Avx2};
use super::entry_kernels::{padded, EntryKernels, GreyEntry, LANES};
use super::sample::Sample;
use crate::relight::ahead::Ahead;
use crate::relight::tile_output::{ColumnHats, TileOutputKernels};

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
            2 => grey_in_registers::<S, __m512, 1, I>(r, g, b, args, entries),
            4 => grey_in_registers::<S, __m512, 2, I>(r, g, b, args, entries),
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
        grey_rows_grouped::<S, __m512>(r, g, b, (values, len), entries, ahead);
    }
}

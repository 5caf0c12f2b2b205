//! A vector of f32 lanes as the relight's vector loops use it, for both widths they run at:
//! 256-bit (eight lanes, AVX2 + FMA + F16C) and 512-bit (sixteen, AVX-512F). The loops are
//! written once over [`Lanes`] and compiled per width (`avx2.rs`, `wide.rs`); each method
//! is one or two instructions and inlines into the loop, whose function carries the target
//! features.

use std::arch::x86_64::*;

use super::sample::Sample;

/// The operations the planar grey loops need from a vector of f32 lanes.
///
/// # Safety
/// Every method needs the CPU features of its width (AVX2, FMA and F16C for `__m256`;
/// AVX-512F besides for `__m512`); the pointers must be valid for [`Self::LANES`] values.
pub(super) trait Lanes: Copy {
    /// Lanes of one vector.
    const LANES: usize;
    /// Grey per-pixel entries summed per pass over a tile's rows (at most eight): as many
    /// value streams' three weights as fit the width's registers beside the three sums and
    /// a loaded value (sixteen registers at 256 bits, 32 at 512).
    const GROUP: usize;
    unsafe fn zero() -> Self;
    unsafe fn splat(x: f32) -> Self;
    /// [`Self::LANES`] samples from `p`, converted to f32.
    unsafe fn load<S: Sample>(p: *const S) -> Self;
    unsafe fn load_f32(p: *const f32) -> Self;
    unsafe fn store(self, p: *mut f32);
    /// `a · b + c`, rounded once.
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self;
    unsafe fn add(a: Self, b: Self) -> Self;
    /// The first eight lanes (for a last, eight-lane step of a wider loop).
    unsafe fn low8(self) -> __m256;

    /// [`Self::LANES`] samples from `src[i..]`: read in place when that many are there, else
    /// the ones that are, zero-filled (a last, partial vector at the end of a tile's values).
    ///
    /// # Safety
    /// The features of the width; `i < src.len()`.
    #[inline(always)]
    unsafe fn load_at<S: Sample>(src: &[S], i: usize) -> Self {
        const {
            assert!(
                Self::LANES <= PARTIAL,
                "the partial load's buffer holds a vector"
            )
        };
        if i + Self::LANES <= src.len() {
            // SAFETY: `LANES` values from i are in `src`; features as the caller promises.
            unsafe { Self::load(src.as_ptr().add(i)) }
        } else {
            let mut buf = [S::ZERO; PARTIAL];
            let rest = &src[i..];
            buf[..rest.len()].copy_from_slice(rest);
            // SAFETY: `buf` holds `PARTIAL` ≥ `LANES` values (checked at compile time);
            // features as the caller promises.
            unsafe { Self::load(buf.as_ptr()) }
        }
    }
}

/// Values of the zero-filled copy [`Lanes::load_at`] reads a last, partial vector from: the
/// widest vector's lanes.
const PARTIAL: usize = 16;

// SAFETY (every method below): the caller guarantees the features and valid pointers.
impl Lanes for __m256 {
    const LANES: usize = 8;
    const GROUP: usize = 4;
    #[inline(always)]
    unsafe fn zero() -> Self {
        unsafe { _mm256_setzero_ps() }
    }
    #[inline(always)]
    unsafe fn splat(x: f32) -> Self {
        unsafe { _mm256_set1_ps(x) }
    }
    #[inline(always)]
    unsafe fn load<S: Sample>(p: *const S) -> Self {
        unsafe { S::load8(p) }
    }
    #[inline(always)]
    unsafe fn load_f32(p: *const f32) -> Self {
        unsafe { _mm256_loadu_ps(p) }
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        unsafe { _mm256_storeu_ps(p, self) }
    }
    #[inline(always)]
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self {
        unsafe { _mm256_fmadd_ps(a, b, c) }
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        unsafe { _mm256_add_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn low8(self) -> __m256 {
        self
    }
}

// SAFETY (every method below): the caller guarantees the features and valid pointers.
impl Lanes for __m512 {
    const LANES: usize = 16;
    const GROUP: usize = 8;
    #[inline(always)]
    unsafe fn zero() -> Self {
        unsafe { _mm512_setzero_ps() }
    }
    #[inline(always)]
    unsafe fn splat(x: f32) -> Self {
        unsafe { _mm512_set1_ps(x) }
    }
    #[inline(always)]
    unsafe fn load<S: Sample>(p: *const S) -> Self {
        unsafe { S::load16(p) }
    }
    #[inline(always)]
    unsafe fn load_f32(p: *const f32) -> Self {
        unsafe { _mm512_loadu_ps(p) }
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        unsafe { _mm512_storeu_ps(p, self) }
    }
    #[inline(always)]
    unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self {
        unsafe { _mm512_fmadd_ps(a, b, c) }
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        unsafe { _mm512_add_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn low8(self) -> __m256 {
        unsafe { _mm512_castps512_ps256(self) }
    }
}

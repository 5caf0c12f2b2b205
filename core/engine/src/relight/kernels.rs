//! The inner loops of the relight: `acc += w(RGB) · layer row segment`, into the per-row
//! accumulators of the packed row sum (`packed.rs`), which merges them into the RGBA image
//! once per row.
//!
//! Every relight ends here, so this is where its time goes: the sum is bound by the memory
//! bandwidth, and the arithmetic (one multiply-add per sample and channel, plus one
//! f16 → f32 conversion per sample) must hide under the reads.
//!
//! Two shapes of accumulator, so that neither inner loop needs a permute:
//! - **Planar grey** ([`Kernels::add_grey_planar`]): a grey sample adds to three separate
//!   R, G and B rows, three fused multiply-adds per 8 pixels.
//! - **Interleaved RGB** ([`Kernels::add_rgb_interleaved`]): an RGB sample adds to the same
//!   position of an interleaved RGB row, with the weight vector rotated per 8-lane step
//!   (the pattern repeats every 24 samples).
//!
//! Two implementations, chosen once per [`Kernels::detect`]:
//! - **AVX2 + FMA + F16C** (x86-64, detected at run time because the workspace builds for
//!   baseline x86-64): 8 samples per step, `vcvtph2ps` converts f16 in registers, one fused
//!   multiply-add per 8 samples and accumulator. No temporary buffer, no bounds checks.
//! - **Portable**: converts a chunk of at most [`CHUNK`] samples into a stack buffer with
//!   `half`'s slice conversion (which itself uses F16C where present), then plain loops.
//!   Used on other CPUs, and by the tests to check the AVX2 path against it.
//!
//! The accumulators hold colour only; the image's alpha of 1 is never touched by a sum.

use half::f16;

/// Pixels converted per step of the portable path (64 px × 3 channels × 4 B = 768 B of
/// stack: small enough for L1, large enough to amortise the per-call dispatch of `half`).
pub(crate) const CHUNK: usize = 64;

/// A sample type a layer can be stored in.
pub(crate) trait Sample: Copy + Send + Sync + 'static {
    /// Converts `src` to f32 into `dst` (same length).
    fn convert(src: &[Self], dst: &mut [f32]);
    /// Loads 8 consecutive samples as f32.
    ///
    /// # Safety
    /// `p` must be valid for reading 8 values, and the CPU must have AVX2 and F16C.
    #[cfg(target_arch = "x86_64")]
    unsafe fn load8(p: *const Self) -> std::arch::x86_64::__m256;
}

impl Sample for f32 {
    #[inline(always)]
    fn convert(src: &[f32], dst: &mut [f32]) {
        dst.copy_from_slice(src);
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn load8(p: *const f32) -> std::arch::x86_64::__m256 {
        // SAFETY: the caller guarantees 8 readable values and AVX.
        unsafe { std::arch::x86_64::_mm256_loadu_ps(p) }
    }
}

impl Sample for f16 {
    #[inline(always)]
    fn convert(src: &[f16], dst: &mut [f32]) {
        use half::slice::HalfFloatSliceExt;
        src.convert_to_f32_slice(dst);
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn load8(p: *const f16) -> std::arch::x86_64::__m256 {
        use std::arch::x86_64::*;
        // SAFETY: the caller guarantees 8 readable halves (16 bytes) and F16C; f16 is a
        // transparent u16, so the bytes are IEEE binary16 as `vcvtph2ps` expects.
        unsafe { _mm256_cvtph_ps(_mm_loadu_si128(p as *const __m128i)) }
    }
}

/// Which implementation of the inner loops runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kernels {
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx2,
}

impl Kernels {
    /// The fastest implementation this CPU runs.
    pub(crate) fn detect() -> Kernels {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
                && std::arch::is_x86_feature_detected!("f16c")
            {
                return Kernels::Avx2;
            }
        }
        Kernels::Portable
    }

    /// Planar grey: `r[p] += w[0]·src[p]`, `g[p] += w[1]·src[p]`, `b[p] += w[2]·src[p]`.
    /// Three fused multiply-adds per 8 pixels and no permutes: the form the packed row sum
    /// uses for grey layers (the majority), merged into RGBA once per row.
    #[inline]
    pub(crate) fn add_grey_planar<S: Sample>(
        self,
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        src: &[S],
        w: [f32; 3],
    ) {
        assert!(
            r.len() == src.len() && g.len() == src.len() && b.len() == src.len(),
            "planar grey: one output per sample"
        );
        match self {
            Kernels::Portable => grey_planar_portable(r, g, b, src, w),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Avx2` is only built by `detect` after checking AVX2, FMA and F16C;
            // the lengths were checked above.
            Kernels::Avx2 => unsafe { x86::grey_planar_avx2(r, g, b, src, w) },
        }
    }

    /// Interleaved RGB: `acc[i] += w[i mod 3]·src[i]`. With weights rotated per 8-lane
    /// vector (period 24) it needs no permutes either.
    #[inline]
    pub(crate) fn add_rgb_interleaved<S: Sample>(self, acc: &mut [f32], src: &[S], w: [f32; 3]) {
        assert!(
            acc.len() == src.len() && src.len().is_multiple_of(3),
            "interleaved RGB: one output per sample"
        );
        match self {
            Kernels::Portable => rgb_interleaved_portable(acc, src, w),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `add_grey_planar`.
            Kernels::Avx2 => unsafe { x86::rgb_interleaved_avx2(acc, src, w) },
        }
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
        for (i, v) in t.iter().enumerate() {
            r[o + i] += w[0] * v;
            g[o + i] += w[1] * v;
            b[o + i] += w[2] * v;
        }
    }
}

fn rgb_interleaved_portable<S: Sample>(acc: &mut [f32], src: &[S], w: [f32; 3]) {
    let mut buf = [0.0f32; 3 * CHUNK];
    for (k, chunk) in src.chunks(3 * CHUNK).enumerate() {
        let t = &mut buf[..chunk.len()];
        S::convert(chunk, t);
        let o = k * 3 * CHUNK;
        for (i, v) in t.iter().enumerate() {
            acc[o + i] += w[i % 3] * v;
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{grey_planar_portable, rgb_interleaved_portable, Sample};
    use std::arch::x86_64::*;

    /// Planar grey, 8 samples per step.
    ///
    /// # Safety
    /// AVX2, FMA and F16C present; all slices as long as `src`.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn grey_planar_avx2<S: Sample>(
        r: &mut [f32],
        g: &mut [f32],
        b: &mut [f32],
        src: &[S],
        w: [f32; 3],
    ) {
        let n8 = src.len() / 8 * 8;
        let (wr, wg, wb) = (
            _mm256_set1_ps(w[0]),
            _mm256_set1_ps(w[1]),
            _mm256_set1_ps(w[2]),
        );
        let (rp, gp, bp, sp) = (r.as_mut_ptr(), g.as_mut_ptr(), b.as_mut_ptr(), src.as_ptr());
        let mut i = 0;
        while i < n8 {
            // SAFETY: i + 8 ≤ len of every slice.
            unsafe {
                let v = S::load8(sp.add(i));
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
            }
            i += 8;
        }
        grey_planar_portable(&mut r[n8..], &mut g[n8..], &mut b[n8..], &src[n8..], w);
    }

    /// Interleaved RGB, 24 samples (8 pixels) per step with three rotated weight vectors.
    ///
    /// # Safety
    /// AVX2, FMA and F16C present; `acc.len() == src.len()`.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn rgb_interleaved_avx2<S: Sample>(acc: &mut [f32], src: &[S], w: [f32; 3]) {
        let n24 = src.len() / 24 * 24;
        let w0 = _mm256_setr_ps(w[0], w[1], w[2], w[0], w[1], w[2], w[0], w[1]);
        let w1 = _mm256_setr_ps(w[2], w[0], w[1], w[2], w[0], w[1], w[2], w[0]);
        let w2 = _mm256_setr_ps(w[1], w[2], w[0], w[1], w[2], w[0], w[1], w[2]);
        let (ap, sp) = (acc.as_mut_ptr(), src.as_ptr());
        let mut i = 0;
        while i < n24 {
            // SAFETY: i + 24 ≤ len of both slices.
            unsafe {
                for (k, wk) in [(0, w0), (8, w1), (16, w2)] {
                    let v = S::load8(sp.add(i + k));
                    _mm256_storeu_ps(
                        ap.add(i + k),
                        _mm256_fmadd_ps(v, wk, _mm256_loadu_ps(ap.add(i + k))),
                    );
                }
            }
            i += 24;
        }
        rgb_interleaved_portable(&mut acc[n24..], &src[n24..], w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pseudo(n: usize, seed: u32) -> Vec<f32> {
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

    /// The planar grey kernel applied to an RGBA buffer (split, add, merge).
    fn add_grey_rgba<S: Sample>(k: Kernels, rgba: &mut [f32], src: &[S]) {
        let n = src.len();
        let mut planes: Vec<Vec<f32>> = (0..3)
            .map(|c| (0..n).map(|p| rgba[4 * p + c]).collect())
            .collect();
        let (r, gb) = planes.split_at_mut(1);
        let (g, b) = gb.split_at_mut(1);
        k.add_grey_planar(&mut r[0], &mut g[0], &mut b[0], src, W);
        for p in 0..n {
            for c in 0..3 {
                rgba[4 * p + c] = planes[c][p];
            }
        }
    }

    /// The interleaved RGB kernel applied to an RGBA buffer.
    fn add_rgb_rgba<S: Sample>(k: Kernels, rgba: &mut [f32], src: &[S]) {
        let n = src.len() / 3;
        let mut acc: Vec<f32> = (0..n)
            .flat_map(|p| rgba[4 * p..4 * p + 3].to_vec())
            .collect();
        k.add_rgb_interleaved(&mut acc, src, W);
        for p in 0..n {
            rgba[4 * p..4 * p + 3].copy_from_slice(&acc[3 * p..3 * p + 3]);
        }
    }

    /// Every kernel against a scalar sum, for lengths that exercise the 8-pixel steps and
    /// the tails (0..=8 leftover pixels), f16 and f32, grey and RGB.
    #[test]
    fn kernels_match_scalar() {
        let w = W;
        let mut kinds = vec![Kernels::Portable];
        if Kernels::detect() != Kernels::Portable {
            kinds.push(Kernels::detect());
        }
        for k in kinds {
            for px in [0usize, 1, 7, 8, 9, 16, 23, 64, 65, 200] {
                for ch in [1usize, 3] {
                    let vals = pseudo(px * ch, (px * 7 + ch) as u32);
                    let halves: Vec<f16> = vals.iter().map(|&v| f16::from_f32(v)).collect();
                    let init = pseudo(px * 4, 99);
                    let mut expect = init.clone();
                    for p in 0..px {
                        for c in 0..3 {
                            let v = if ch == 1 {
                                halves[p]
                            } else {
                                halves[3 * p + c]
                            };
                            expect[4 * p + c] += w[c] * v.to_f32();
                        }
                    }
                    let mut got16 = init.clone();
                    let exact: Vec<f32> = halves.iter().map(|h| h.to_f32()).collect();
                    let mut got32 = init.clone();
                    if ch == 1 {
                        add_grey_rgba(k, &mut got16, &halves);
                        add_grey_rgba(k, &mut got32, &exact);
                    } else {
                        add_rgb_rgba(k, &mut got16, &halves);
                        add_rgb_rgba(k, &mut got32, &exact);
                    }
                    for i in 0..expect.len() {
                        // FMA rounds once instead of twice: allow one ulp-scale difference.
                        let tol = 1e-6 * (1.0 + expect[i].abs());
                        assert!(
                            (got16[i] - expect[i]).abs() <= tol,
                            "{k:?} px {px} ch {ch} i {i}"
                        );
                        assert!(
                            (got32[i] - expect[i]).abs() <= tol,
                            "{k:?} px {px} ch {ch} i {i}"
                        );
                    }
                }
            }
        }
    }
}

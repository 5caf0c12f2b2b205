//! The inner loops of the relight: `out(RGBA) += w(RGB) · layer row segment`.
//!
//! Every relight ends here, so this is where its time goes. A 512×512 stack of the paper's
//! size (55 grey + 29 RGB layers, f16) is 74 MB of samples; at the ≈ 16 GB/s this machine
//! reads with two threads that is 4.6 ms that no relight can beat, and the arithmetic
//! (≈ 66 M multiply-adds, plus one f16 → f32 conversion per sample) must hide under it.
//!
//! Two implementations, chosen once per [`Kernels::detect`]:
//! - **AVX2 + FMA + F16C** (x86-64, detected at run time because the workspace builds for
//!   baseline x86-64): 8 samples per step, `vcvtph2ps` converts f16 in registers, the
//!   grey/RGB value is spread over the RGBA accumulator with `vpermps` and added with one
//!   fused multiply-add per 2 pixels. No temporary buffer, no bounds checks.
//! - **Portable**: converts a chunk of at most [`CHUNK`] samples into a stack buffer with
//!   `half`'s slice conversion (which itself uses F16C where present), then plain loops.
//!   Used on other CPUs, and by the tests to check the AVX2 path against it.
//!
//! The alpha lane gets weight 0, and samples are checked finite when a relighter is built,
//! so `alpha += 0·finite` leaves the alpha of 1 exact.

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

    /// `out[4p + c] += w[c] · src[p]` for every pixel p of a grey row segment
    /// (`out.len() == 4 · src.len()`).
    #[inline]
    pub(crate) fn add_grey<S: Sample>(self, out: &mut [f32], src: &[S], w: [f32; 3]) {
        assert_eq!(
            out.len(),
            4 * src.len(),
            "grey segment: 4 outputs per sample"
        );
        match self {
            Kernels::Portable => grey_portable(out, src, w),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Avx2` is only built by `detect` after checking AVX2, FMA and F16C;
            // the lengths were checked above.
            Kernels::Avx2 => unsafe { x86::grey_avx2(out, src, w) },
        }
    }

    /// `out[4p + c] += w[c] · src[3p + c]` for every pixel p of an RGB row segment
    /// (`out.len() / 4 == src.len() / 3`).
    #[inline]
    pub(crate) fn add_rgb<S: Sample>(self, out: &mut [f32], src: &[S], w: [f32; 3]) {
        assert!(
            src.len() % 3 == 0 && out.len() == src.len() / 3 * 4,
            "RGB segment: 4 outputs per 3 samples"
        );
        match self {
            Kernels::Portable => rgb_portable(out, src, w),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `add_grey`.
            Kernels::Avx2 => unsafe { x86::rgb_avx2(out, src, w) },
        }
    }
}

fn grey_portable<S: Sample>(out: &mut [f32], src: &[S], w: [f32; 3]) {
    let mut buf = [0.0f32; CHUNK];
    for (o, s) in out.chunks_mut(4 * CHUNK).zip(src.chunks(CHUNK)) {
        let b = &mut buf[..s.len()];
        S::convert(s, b);
        for (px, &v) in o.chunks_exact_mut(4).zip(b.iter()) {
            px[0] += w[0] * v;
            px[1] += w[1] * v;
            px[2] += w[2] * v;
        }
    }
}

fn rgb_portable<S: Sample>(out: &mut [f32], src: &[S], w: [f32; 3]) {
    let mut buf = [0.0f32; 3 * CHUNK];
    for (o, s) in out.chunks_mut(4 * CHUNK).zip(src.chunks(3 * CHUNK)) {
        let b = &mut buf[..s.len()];
        S::convert(s, b);
        for (px, v) in o.chunks_exact_mut(4).zip(b.chunks_exact(3)) {
            px[0] += w[0] * v[0];
            px[1] += w[1] * v[1];
            px[2] += w[2] * v[2];
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{grey_portable, rgb_portable, Sample};
    use std::arch::x86_64::*;

    /// Grey: 8 samples → 32 RGBA floats; each output vector (2 pixels) is the sample
    /// vector permuted to `[a a a a b b b b]` times `[wr wg wb 0 wr wg wb 0]`.
    ///
    /// # Safety
    /// AVX2, FMA and F16C present; `out.len() == 4 · src.len()`.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn grey_avx2<S: Sample>(out: &mut [f32], src: &[S], w: [f32; 3]) {
        let n8 = src.len() / 8 * 8;
        let wv = _mm256_setr_ps(w[0], w[1], w[2], 0.0, w[0], w[1], w[2], 0.0);
        let i0 = _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1);
        let i1 = _mm256_setr_epi32(2, 2, 2, 2, 3, 3, 3, 3);
        let i2 = _mm256_setr_epi32(4, 4, 4, 4, 5, 5, 5, 5);
        let i3 = _mm256_setr_epi32(6, 6, 6, 6, 7, 7, 7, 7);
        let sp = src.as_ptr();
        let op = out.as_mut_ptr();
        let mut i = 0;
        while i < n8 {
            // SAFETY: i + 8 ≤ src.len() and 4·(i + 8) ≤ out.len().
            unsafe {
                let v = S::load8(sp.add(i));
                let o = op.add(4 * i);
                let a0 = _mm256_fmadd_ps(_mm256_permutevar8x32_ps(v, i0), wv, _mm256_loadu_ps(o));
                let a1 = _mm256_fmadd_ps(
                    _mm256_permutevar8x32_ps(v, i1),
                    wv,
                    _mm256_loadu_ps(o.add(8)),
                );
                let a2 = _mm256_fmadd_ps(
                    _mm256_permutevar8x32_ps(v, i2),
                    wv,
                    _mm256_loadu_ps(o.add(16)),
                );
                let a3 = _mm256_fmadd_ps(
                    _mm256_permutevar8x32_ps(v, i3),
                    wv,
                    _mm256_loadu_ps(o.add(24)),
                );
                _mm256_storeu_ps(o, a0);
                _mm256_storeu_ps(o.add(8), a1);
                _mm256_storeu_ps(o.add(16), a2);
                _mm256_storeu_ps(o.add(24), a3);
            }
            i += 8;
        }
        grey_portable(&mut out[4 * n8..], &src[n8..], w);
    }

    /// RGB: 24 samples (8 pixels) in three vectors
    /// `v0 = r0 g0 b0 r1 g1 b1 r2 g2`, `v1 = b2 r3 g3 b3 r4 g4 b4 r5`,
    /// `v2 = g5 b5 r6 g6 b6 r7 g7 b7` are regrouped into four RGBx pairs by six
    /// permutes and two blends; the x lane is multiplied by weight 0.
    ///
    /// # Safety
    /// AVX2, FMA and F16C present; `out.len() / 4 == src.len() / 3`.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn rgb_avx2<S: Sample>(out: &mut [f32], src: &[S], w: [f32; 3]) {
        let px = src.len() / 3;
        let n8 = px / 8 * 8;
        let wv = _mm256_setr_ps(w[0], w[1], w[2], 0.0, w[0], w[1], w[2], 0.0);
        // Pixels 0,1 from v0.
        let p0 = _mm256_setr_epi32(0, 1, 2, 2, 3, 4, 5, 5);
        // Pixels 2,3: r2 g2 from v0[6,7], b2 r3 g3 b3 from v1[0..4].
        let p1a = _mm256_setr_epi32(6, 7, 7, 7, 7, 7, 7, 7);
        let p1b = _mm256_setr_epi32(0, 0, 0, 0, 1, 2, 3, 3);
        // Pixels 4,5: r4 g4 b4 r5 from v1[4..8], g5 b5 from v2[0,1].
        let p2a = _mm256_setr_epi32(4, 5, 6, 6, 7, 7, 7, 7);
        let p2b = _mm256_setr_epi32(0, 0, 0, 0, 0, 0, 1, 1);
        // Pixels 6,7 from v2.
        let p3 = _mm256_setr_epi32(2, 3, 4, 4, 5, 6, 7, 7);
        let sp = src.as_ptr();
        let op = out.as_mut_ptr();
        let mut i = 0;
        while i < n8 {
            // SAFETY: 3·(i + 8) ≤ src.len() and 4·(i + 8) ≤ out.len().
            unsafe {
                let s = sp.add(3 * i);
                let v0 = S::load8(s);
                let v1 = S::load8(s.add(8));
                let v2 = S::load8(s.add(16));
                let q0 = _mm256_permutevar8x32_ps(v0, p0);
                // Blend mask bit k set = take lane k from the second operand.
                let q1 = _mm256_blend_ps::<0b1111_1100>(
                    _mm256_permutevar8x32_ps(v0, p1a),
                    _mm256_permutevar8x32_ps(v1, p1b),
                );
                let q2 = _mm256_blend_ps::<0b1110_0000>(
                    _mm256_permutevar8x32_ps(v1, p2a),
                    _mm256_permutevar8x32_ps(v2, p2b),
                );
                let q3 = _mm256_permutevar8x32_ps(v2, p3);
                let o = op.add(4 * i);
                let a0 = _mm256_fmadd_ps(q0, wv, _mm256_loadu_ps(o));
                let a1 = _mm256_fmadd_ps(q1, wv, _mm256_loadu_ps(o.add(8)));
                let a2 = _mm256_fmadd_ps(q2, wv, _mm256_loadu_ps(o.add(16)));
                let a3 = _mm256_fmadd_ps(q3, wv, _mm256_loadu_ps(o.add(24)));
                _mm256_storeu_ps(o, a0);
                _mm256_storeu_ps(o.add(8), a1);
                _mm256_storeu_ps(o.add(16), a2);
                _mm256_storeu_ps(o.add(24), a3);
            }
            i += 8;
        }
        rgb_portable(&mut out[4 * n8..], &src[3 * n8..], w);
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

    /// Every kernel against a scalar sum, for lengths that exercise the 8-pixel steps and
    /// the tails (0..=8 leftover pixels), f16 and f32, grey and RGB.
    #[test]
    fn kernels_match_scalar() {
        let w = [0.5f32, -1.25, 2.0];
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
                        k.add_grey(&mut got16, &halves, w);
                        k.add_grey(&mut got32, &exact, w);
                    } else {
                        k.add_rgb(&mut got16, &halves, w);
                        k.add_rgb(&mut got32, &exact, w);
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

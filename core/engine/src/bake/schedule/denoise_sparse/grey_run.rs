//! One step of the sparse denoiser on a one-channel (grey) layer, eight pixels of a row at
//! a time (most of a bake's layers are grey, and the filter is most of the per-layer work).
//!
//! Per pixel it is the scalar filter's arithmetic exactly (`super::filter_pixel`): from
//! +0, for each of the 25 taps in order whose weight is not 0, `acc = acc + weight · value`
//! (a multiply, then an add: no fused multiply-add); a pixel the filter leaves alone keeps
//! its value. In eight lanes a tap whose weight is 0 adds +0 instead of being skipped, which
//! leaves every sum as it was: a sum from +0 is never −0, and +0 added to anything else
//! changes nothing. A lane's product with a zero weight is masked to +0 before the add, so
//! a tap outside the window (whose weight is 0, and whose load reads the row's
//! neighbours or is refused below) cannot bring a NaN in.

/// Pixels per step.
pub(super) const LANES: usize = 8;

/// One filter step's 25 taps as offsets in the window's buffer (pixels, in the order the
/// weights list them), with their least and greatest, computed once per step.
pub(super) struct Taps {
    pub offsets: [isize; 25],
    lo: isize,
    hi: isize,
}

impl Taps {
    /// The taps of a step `step` pixels apart in a window `width` pixels wide.
    pub(super) fn new(width: usize, step: usize) -> Taps {
        let offsets: [isize; 25] = std::array::from_fn(|t| {
            ((t as isize / 5 - 2) * width as isize + (t as isize % 5 - 2)) * step as isize
        });
        Taps {
            offsets,
            lo: offsets[0],
            hi: offsets[24],
        }
    }
}

/// The AVX2 step, where the CPU has AVX2; `None` elsewhere (the scalar filter runs).
#[derive(Clone, Copy)]
pub(super) struct GreyRun {
    _checked: (),
}

impl GreyRun {
    pub(super) fn detect() -> Option<GreyRun> {
        #[cfg(target_arch = "x86_64")]
        {
            if is_x86_feature_detected!("avx2") {
                return Some(GreyRun { _checked: () });
            }
        }
        None
    }

    /// Filters pixels `p0..p0 + 8` of `src` into `out`: lane `i` is computed where
    /// `computed[i]`, else copied. Returns false, touching nothing, when a tap's eight
    /// values from `p0 + offset` are not all inside `src` (the caller then filters the
    /// pixels one by one).
    ///
    /// # Panics
    /// If `p0 + 8` exceeds `weights`, `src` or `out`.
    #[inline]
    pub(super) fn filter8(
        self,
        weights: &[[f32; 25]],
        src: &[f32],
        out: &mut [f32],
        taps: &Taps,
        p0: usize,
        computed: [bool; LANES],
    ) -> bool {
        let end = p0 + LANES;
        assert!(
            end <= weights.len() && end <= src.len() && end <= out.len(),
            "a run of eight pixels inside the window"
        );
        if (p0 as isize) + taps.lo < 0 || (end as isize) + taps.hi > src.len() as isize {
            return false;
        }
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a `GreyRun` exists only where the CPU has AVX2; every load reads
        // `weights[p0..end]` (checked above; the gather's indices step one pixel's 25
        // weights) or `src[p0 + offset..end + offset]` (inside `src`: every offset lies
        // between the taps' least and greatest, checked above), every store `out[p0..end]`.
        unsafe {
            x86::filter8(weights, src, out, &taps.offsets, p0, computed);
        }
        #[cfg(not(target_arch = "x86_64"))]
        unreachable!("a GreyRun is made only on x86-64");
        true
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::LANES;

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn filter8(
        weights: &[[f32; 25]],
        src: &[f32],
        out: &mut [f32],
        offsets: &[isize; 25],
        p0: usize,
        computed: [bool; LANES],
    ) {
        let lane_weights = _mm256_setr_epi32(0, 25, 50, 75, 100, 125, 150, 175);
        let keep = _mm256_setr_epi32(
            -(computed[0] as i32),
            -(computed[1] as i32),
            -(computed[2] as i32),
            -(computed[3] as i32),
            -(computed[4] as i32),
            -(computed[5] as i32),
            -(computed[6] as i32),
            -(computed[7] as i32),
        );
        let zero = _mm256_setzero_ps();
        let base = weights.as_ptr().add(p0).cast::<f32>();
        let mut acc = zero;
        for (t, &offset) in offsets.iter().enumerate() {
            let w = _mm256_i32gather_ps::<4>(base.add(t), lane_weights);
            let v = _mm256_loadu_ps(src.as_ptr().offset(p0 as isize + offset));
            let used = _mm256_cmp_ps::<_CMP_NEQ_UQ>(w, zero);
            acc = _mm256_add_ps(acc, _mm256_and_ps(_mm256_mul_ps(w, v), used));
        }
        let old = _mm256_loadu_ps(src.as_ptr().add(p0));
        let result = _mm256_blendv_ps(old, acc, _mm256_castsi256_ps(keep));
        _mm256_storeu_ps(out.as_mut_ptr().add(p0), result);
    }
}

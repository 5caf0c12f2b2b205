//! How much of a refinement's correction to show: its noise estimated from two halves of
//! its passes, and the correction shrunk towards zero where it is within that noise.
//!
//! A correction from a few passes is an unbiased but noisy estimate; added in full, the
//! first passes of a sharp-lobe edit make the image noisier than the relight it corrects.
//! Scaling it by `max(0, 1 − noise² / correction²)` — the positive-part James–Stein
//! estimator, summed over a window of pixels so that the two sums are themselves steady —
//! keeps a correction that stands out of its noise and drops one that does not, and has a
//! lower expected squared error than the unshrunk mean. The price is a bias towards the
//! relit image where the correction is small next to its noise; it fades as passes add up
//! and the noise falls.

use crate::Rgb;

/// Half the side of the window (in pixels) the noise and correction energies are summed
/// over: about a bake tile, wide enough for a steady ratio, narrow enough to follow where
/// the correction is.
pub const WINDOW_RADIUS: usize = 8;

/// The weight of the correction at each pixel: `max(0, 1 − Σ noise / Σ |mean|²)` over
/// the window around it (0 where the window has no correction). `mean` is the correction
/// over all passes; `noise` each pixel's estimated variance of it (summed over channels).
pub fn weights(mean: &[Rgb], noise: &[f32], width: usize, height: usize) -> Vec<f32> {
    debug_assert_eq!(mean.len(), width * height);
    debug_assert_eq!(noise.len(), width * height);
    let signal: Vec<f64> = mean.iter().map(|d| d.dot(*d) as f64).collect();
    let noise: Vec<f64> = noise.iter().map(|v| *v as f64).collect();
    let signal = WindowSums::new(&signal, width, height);
    let noise = WindowSums::new(&noise, width, height);
    let r = WINDOW_RADIUS;
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(height));
        for x in 0..width {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(width));
            let s = signal.sum(x0, y0, x1, y1);
            let n = noise.sum(x0, y0, x1, y1);
            out.push(if s > 0.0 {
                (1.0 - n / s).max(0.0) as f32
            } else {
                0.0
            });
        }
    }
    out
}

/// The estimated variance of a mean over `k_even + k_odd` passes, per pixel (summed over
/// channels), from the means of its even and odd passes: the two are independent with
/// variances σ²/k_even and σ²/k_odd, so E|even − odd|² = σ² (1/k_even + 1/k_odd) and the
/// whole mean's variance σ²/k is that times k_even·k_odd/k².
pub fn variance_of_mean(even: &[Rgb], odd: &[Rgb], k_even: u32, k_odd: u32) -> Vec<f32> {
    let k = (k_even + k_odd) as f32;
    let scale = k_even as f32 * k_odd as f32 / (k * k);
    even.iter()
        .zip(odd)
        .map(|(e, o)| {
            let d = *e - *o;
            d.dot(d) * scale
        })
        .collect()
}

/// Summed-area table: the sum over any rectangle in four reads.
struct WindowSums {
    table: Vec<f64>,
    stride: usize,
}

impl WindowSums {
    fn new(values: &[f64], width: usize, height: usize) -> Self {
        let stride = width + 1;
        let mut table = vec![0.0; stride * (height + 1)];
        for y in 0..height {
            let mut row = 0.0;
            for x in 0..width {
                row += values[y * width + x];
                table[(y + 1) * stride + x + 1] = table[y * stride + x + 1] + row;
            }
        }
        Self { table, stride }
    }

    /// Sum over `x0..x1` × `y0..y1`.
    fn sum(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
        let t = |x: usize, y: usize| self.table[y * self.stride + x];
        t(x1, y1) - t(x0, y1) - t(x1, y0) + t(x0, y0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stand-in for noise: a hash of the pixel and pass mapped to ±1.
    fn jitter(i: usize, pass: usize) -> f32 {
        let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (pass as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 31;
        h = h.wrapping_mul(0x94D0_49BB_1331_11EB);
        h ^= h >> 29;
        if h & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// Means of `passes` noisy passes of `truth` (noise amplitude `a`): all, even, odd.
    fn passes(truth: &[f32], a: f32, passes: usize) -> (Vec<Rgb>, Vec<Rgb>, Vec<Rgb>) {
        let mean = |sel: &dyn Fn(usize) -> bool| -> Vec<Rgb> {
            truth
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    let ks: Vec<usize> = (0..passes).filter(|k| sel(*k)).collect();
                    let v = ks.iter().map(|k| t + a * jitter(i, *k)).sum::<f32>() / ks.len() as f32;
                    Rgb::splat(v)
                })
                .collect()
        };
        (
            mean(&|_| true),
            mean(&|k| k % 2 == 0),
            mean(&|k| k % 2 == 1),
        )
    }

    fn shrunk(truth: &[f32], a: f32, k: usize, w: usize, h: usize) -> (Vec<Rgb>, Vec<f32>) {
        let (all, even, odd) = passes(truth, a, k);
        let noise = variance_of_mean(&even, &odd, k.div_ceil(2) as u32, (k / 2) as u32);
        let wts = weights(&all, &noise, w, h);
        (all, wts)
    }

    #[test]
    fn a_correction_well_above_its_noise_is_kept_and_pure_noise_is_dropped() {
        let (w, h, k) = (48, 40, 8);
        // A strong correction: weights near 1.
        let strong = vec![1.0f32; w * h];
        let (_, wts) = shrunk(&strong, 0.5, k, w, h);
        let mean_w = wts.iter().sum::<f32>() / wts.len() as f32;
        assert!(mean_w > 0.95, "{mean_w}");
        // No correction, only noise: the shown correction's energy falls far below the raw
        // mean's.
        let zero = vec![0.0f32; w * h];
        let (all, wts) = shrunk(&zero, 0.5, k, w, h);
        let raw: f32 = all.iter().map(|d| d.dot(*d)).sum();
        let kept: f32 = all.iter().zip(&wts).map(|(d, w)| d.dot(*d) * w * w).sum();
        assert!(kept < 0.1 * raw, "{kept} of {raw}");
        // Half the frame corrected, half noise: the error against the truth is below the
        // unshrunk mean's.
        let half: Vec<f32> = (0..w * h)
            .map(|i| if i % w < w / 2 { 0.6 } else { 0.0 })
            .collect();
        let (all, wts) = shrunk(&half, 0.5, k, w, h);
        let err = |scale: &dyn Fn(usize) -> f32| -> f32 {
            all.iter()
                .enumerate()
                .map(|(i, d)| {
                    let e = d.x * scale(i) - half[i];
                    e * e
                })
                .sum()
        };
        let (raw, kept) = (err(&|_| 1.0), err(&|i| wts[i]));
        assert!(kept < raw, "{kept} vs {raw}");
    }

    #[test]
    fn the_variance_estimate_matches_the_noise_it_was_made_from() {
        // ±a noise over k passes: the mean's variance is a²/k per channel.
        let (w, h, k, a) = (64, 64, 8, 0.5f32);
        let (_, even, odd) = passes(&vec![0.3; w * h], a, k);
        let noise = variance_of_mean(&even, &odd, 4, 4);
        let mean = noise.iter().sum::<f32>() / noise.len() as f32;
        let expected = 3.0 * a * a / k as f32;
        assert!((mean / expected - 1.0).abs() < 0.1, "{mean} vs {expected}");
    }
}

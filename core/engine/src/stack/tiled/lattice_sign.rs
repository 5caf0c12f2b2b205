//! Lattice fits that keep the sign of what they stand in for.
//!
//! Why: a least-squares fit of a layer by bilinear hats can undershoot — next to a bright
//! step or a peak inside a segment the fitted surface dips below zero where the layer is
//! dark, and a stored negative radiance shows up as a negative pixel of the relit image.
//! Two guards, both applied at the bake while the tile's values are still in memory:
//!
//! - **Per layer** ([`solve_nonnegative`], used by
//!   [`LatticeFitter::fit`](super::lattice::LatticeFitter::fit)): where a layer is ≥ 0 on a
//!   segment (per channel), its fit there is the least-squares fit under the constraint
//!   that every node coefficient is ≥ 0. Hats are ≥ 0, so the fitted layer is then ≥ 0 at
//!   every pixel, and any relight whose weights keep such layers' contributions ≥ 0 (every
//!   diffuse edit) stays ≥ 0 — whatever the edit, not only at the bake-time materials. It
//!   is stronger than needed (a pixel's value only needs its own ≤ 4 nodes' weighted sum ≥
//!   0), so it can cost a little accuracy; the bake measures the error of what it keeps.
//! - **Per tile** ([`repair_negative_pixels`]): layers that are signed themselves (the PCA
//!   bases past the first) and negative bake-time weights are not covered by the first
//!   guard, so the tile's image at the bake-time materials is recomputed with the kept
//!   fits, and wherever the uncompressed image is ≥ 0 but the compressed one is not, the
//!   fit pulling that pixel down the most is given up (its layer stays per pixel) until no
//!   such pixel is left.
//!
//! Neither changes the relight: what is stored is still linear coefficients, and the
//! relight is exact with respect to them.

use crate::linalg::{cholesky_in_place, cholesky_solve};

/// Minimises `½ xᵀ A x − bᵀ x` over `x ≥ 0` (every component), `A` symmetric positive
/// definite, `n × n` row-major — the least-squares fit of hats to data with non-negative
/// coefficients, given the fit's normal matrix `A` and right-hand side `b`. The result
/// goes to `x`.
///
/// Method: the active-set method of Lawson and Hanson written for the normal equations.
/// Coefficients start at 0 (all held at the bound); the free coefficient whose gradient
/// `b − A x` most wants it to grow is freed, the system is solved on the free ones, and
/// where that solution would leave the feasible set the step is cut at the first bound hit
/// and those coefficients are held at 0 again. Each outer step frees one more coefficient,
/// so it ends after at most a few passes over `n` (capped, the cap being far beyond what a
/// lattice segment's ≤ 81 nodes need; at the cap the current feasible point is returned,
/// still non-negative).
pub(crate) fn solve_nonnegative(a: &[f64], n: usize, b: &[f64], x: &mut [f64]) {
    x[..n].fill(0.0);
    let mut free = vec![false; n];
    let scale = (0..n)
        .map(|i| a[i * n + i])
        .fold(0.0f64, f64::max)
        .max(1e-300);
    let b_scale = b[..n].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if b_scale == 0.0 {
        return;
    }
    // A gradient this small is rounding, not a reason to free a coefficient.
    let tiny = 1e-12 * b_scale;
    let mut z = vec![0.0f64; n];
    let mut sub = Vec::new();
    let mut rhs = Vec::new();
    let cap = 3 * n + 10;
    let mut passes = 0;
    loop {
        let gradient =
            |x: &[f64], i: usize| b[i] - (0..n).map(|j| a[i * n + j] * x[j]).sum::<f64>();
        let entering = (0..n)
            .filter(|&i| !free[i])
            .map(|i| (i, gradient(x, i)))
            .filter(|&(_, g)| g > tiny)
            .max_by(|p, q| p.1.total_cmp(&q.1));
        let Some((entering, _)) = entering else {
            return;
        };
        free[entering] = true;
        loop {
            passes += 1;
            if passes > cap {
                return;
            }
            solve_on(a, n, b, &free, scale, &mut sub, &mut rhs, &mut z);
            if (0..n).all(|i| !free[i] || z[i] > 0.0) {
                x[..n].copy_from_slice(&z);
                break;
            }
            // Step from x towards z only as far as the first free coefficient reaching 0;
            // that one (and any other the step leaves at or below 0) is held at 0 again.
            let mut alpha = 1.0f64;
            let mut blocking = None;
            for i in (0..n).filter(|&i| free[i] && z[i] <= 0.0) {
                let room = x[i] - z[i];
                let t = if room > 0.0 { x[i] / room } else { 0.0 };
                if blocking.is_none() || t < alpha {
                    alpha = alpha.min(t);
                    blocking = Some(i);
                }
            }
            for (xi, zi) in x[..n].iter_mut().zip(&z) {
                *xi += alpha * (zi - *xi);
            }
            if let Some(i) = blocking {
                x[i] = 0.0;
            }
            for (xi, fi) in x[..n].iter_mut().zip(free.iter_mut()) {
                if *fi && *xi <= 0.0 {
                    *xi = 0.0;
                    *fi = false;
                }
            }
            if !free.iter().any(|f| *f) {
                break;
            }
        }
    }
}

/// Solves `A_FF z_F = b_F` on the free coefficients `F` (the rest of `z` set to 0) by a
/// Cholesky factorisation of the sub-matrix; a pivot that rounding leaves non-positive is
/// raised to a tiny share of `scale` so the solve stays finite.
#[allow(clippy::too_many_arguments)]
fn solve_on(
    a: &[f64],
    n: usize,
    b: &[f64],
    free: &[bool],
    scale: f64,
    sub: &mut Vec<f64>,
    rhs: &mut Vec<f64>,
    z: &mut [f64],
) {
    let idx: Vec<usize> = (0..n).filter(|&i| free[i]).collect();
    let m = idx.len();
    sub.clear();
    for &i in &idx {
        sub.extend(idx.iter().map(|&j| a[i * n + j]));
    }
    rhs.clear();
    rhs.extend(idx.iter().map(|&i| b[i]));
    cholesky_in_place(sub, m, 1e-300 * scale);
    cholesky_solve(sub, m, rhs);
    z[..n].fill(0.0);
    for (k, &i) in idx.iter().enumerate() {
        z[i] = rhs[k];
    }
}

/// One fitted layer as the per-tile check sees it.
pub struct SignedFit<'a> {
    /// The layer's bake-time weight per RGB channel.
    pub weight: [f64; 3],
    /// Channels of `data` and `fitted`: 1 (grey) or 3.
    pub channels: u8,
    /// The layer over the tile, row-major, channels interleaved.
    pub data: &'a [f32],
    /// Its fit over the same pixels.
    pub fitted: &'a [f32],
}

/// Which fits to give up so that the tile's image at the bake-time weights stays ≥ 0
/// wherever the uncompressed `image` (RGB interleaved, f64, the sum of every layer at its
/// weight) is ≥ 0: returns one flag per fit, `true` = keep. A fit is given up only where
/// some pixel needs it: at each offending pixel channel the kept fit with the most
/// negative contribution `w · (fitted − data)` there goes, and the pixel is re-checked.
/// Giving up every fit with a negative contribution at a pixel restores the uncompressed
/// value there, so this always ends with no offending pixel.
pub fn repair_negative_pixels(image: &[f64], fits: &[SignedFit]) -> Vec<bool> {
    let mut keep = vec![true; fits.len()];
    if fits.is_empty() {
        return keep;
    }
    let contribution = |f: &SignedFit, p: usize, ch: usize| -> f64 {
        let c = f.channels as usize;
        let i = p * c + ch.min(c - 1);
        f.weight[ch] * (f.fitted[i] as f64 - f.data[i] as f64)
    };
    let pixels = image.len() / 3;
    for p in 0..pixels {
        for ch in 0..3 {
            let truth = image[p * 3 + ch];
            if truth < 0.0 {
                continue;
            }
            loop {
                let compressed = truth
                    + fits
                        .iter()
                        .zip(&keep)
                        .filter(|(_, k)| **k)
                        .map(|(f, _)| contribution(f, p, ch))
                        .sum::<f64>();
                if compressed >= 0.0 {
                    break;
                }
                let worst = fits
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| keep[*k])
                    .map(|(k, f)| (k, contribution(f, p, ch)))
                    .filter(|(_, d)| *d < 0.0)
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                match worst {
                    Some((k, _)) => keep[k] = false,
                    None => break,
                }
            }
        }
    }
    keep
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `A = HᵀH`, `b = Hᵀd` of a small random problem, and the brute-force optimum of the
    /// non-negative problem by trying every set of free coefficients.
    fn brute_force(a: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
        let objective = |x: &[f64]| -> f64 {
            let mut v = 0.0;
            for i in 0..n {
                for j in 0..n {
                    v += 0.5 * x[i] * a[i * n + j] * x[j];
                }
                v -= b[i] * x[i];
            }
            v
        };
        let mut best = vec![0.0; n];
        let mut best_value = objective(&best);
        let scale = (0..n).map(|i| a[i * n + i]).fold(0.0f64, f64::max);
        let (mut sub, mut rhs, mut z) = (Vec::new(), Vec::new(), vec![0.0; n]);
        for set in 1u32..(1 << n) {
            let free: Vec<bool> = (0..n).map(|i| set & (1 << i) != 0).collect();
            solve_on(a, n, b, &free, scale, &mut sub, &mut rhs, &mut z);
            if z.iter().all(|v| *v >= 0.0) && objective(&z) < best_value {
                best_value = objective(&z);
                best = z.clone();
            }
        }
        best
    }

    #[test]
    fn the_non_negative_solve_finds_the_constrained_optimum() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for n in [1usize, 2, 4, 6] {
            for _ in 0..20 {
                let rows = n + 3;
                let h: Vec<f64> = (0..rows * n).map(|_| next()).collect();
                let d: Vec<f64> = (0..rows).map(|_| next()).collect();
                let mut a = vec![0.0; n * n];
                let mut b = vec![0.0; n];
                for r in 0..rows {
                    for i in 0..n {
                        b[i] += h[r * n + i] * d[r];
                        for j in 0..n {
                            a[i * n + j] += h[r * n + i] * h[r * n + j];
                        }
                    }
                }
                let mut x = vec![0.0; n];
                solve_nonnegative(&a, n, &b, &mut x);
                let expected = brute_force(&a, n, &b);
                assert!(x.iter().all(|v| *v >= 0.0), "{x:?}");
                for (got, want) in x.iter().zip(&expected) {
                    assert!((got - want).abs() < 1e-9, "{x:?} vs {expected:?}");
                }
            }
        }
    }

    #[test]
    fn a_fit_that_drags_a_pixel_below_zero_is_given_up_and_only_that_one() {
        // Two pixels, grey layers at weight 1: the true image is 0.1 and 0.5.
        let (a_data, a_fit) = ([0.1f32, 0.2], [-0.05f32, 0.2]);
        let (b_data, b_fit) = ([0.0f32, 0.3], [0.01f32, 0.28]);
        let fits = [
            SignedFit {
                weight: [1.0; 3],
                channels: 1,
                data: &a_data,
                fitted: &a_fit,
            },
            SignedFit {
                weight: [1.0; 3],
                channels: 1,
                data: &b_data,
                fitted: &b_fit,
            },
        ];
        let image = [0.1, 0.1, 0.1, 0.5, 0.5, 0.5];
        assert_eq!(repair_negative_pixels(&image, &fits), vec![false, true]);
    }
}

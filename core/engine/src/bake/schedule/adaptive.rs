//! Per-tile adaptive sampling: a tile takes eye samples in rounds and stops once its
//! estimated error reaches the threshold ([`crate::bake::settings::AdaptiveSampling`]).
//!
//! **The rounds.** A tile first takes half of `first_check`'s samples, then doubles its
//! count (`n → min(2n, spp)`), checking after every round but the first, until it stops or
//! reaches `spp`. Each round traces its sample range
//! with the same per-pixel code as a whole bake and keeps the range's aligned blocks of the
//! canonical summation tree ([`super::blocks`]); after the last round the blocks are
//! combined as that tree combines them, so a tile that runs to `spp` holds the same bits as
//! a bake without adaptive sampling, and one that stops at `n` holds the bits of a bake of
//! `n` samples there.
//!
//! **The error estimate** follows Cycles' adaptive sampling: the image of all `n` samples
//! against the image of the first `a` (a "half-sample" image). Here the image is the bake's
//! **bake-time image** — every layer weighted by its weight at the scene's materials and
//! summed, i.e. what the relight shows before any edit. With `A₁` the mean of samples
//! `[0, a)`, `A₂` that of `[a, n)` and `A` that of all `n`, independent halves give
//! `Var(A₁ − A₂) = σ²·(1/a + 1/(n − a))`, so the noise of `A` per channel is estimated as
//! `|A₁ − A₂|·√(a(n − a))/n` (for `a = n/2`: `|A₁ − A₂|/2`, Cycles' `|I − A_half|`). Per
//! pixel, as Cycles does, the three channels' noise is summed and divided by
//! `10⁻⁴ + √(A_r + A_g + A_b)`: dark pixels may carry more relative noise, since the eye
//! sees it less (and the shown image is denoised). The tile's error is the RMS of that
//! over its pixels — one pixel's estimate comes from one difference and is itself noisy;
//! 256 of them give a steady figure (Cycles instead stops pixel by pixel and dilates).
//!
//! **What it costs in exactness.** The stop rule reads the samples it stops on, so the
//! estimate is not unbiased: a tile whose early samples happen to agree stops with them.
//! This is the same approximation Cycles makes; `tests/engine/adaptive_sampling.rs` measures the
//! bias on the Cornell scene and bounds it by the image's noise. The edit-time weights do
//! not enter the rule: a tile stops on its bake-time image, and its layers keep the noise
//! of `n` samples whatever the edit.
//!
//! **Determinism.** The rule reads only the tile's own samples, which depend only on the
//! seed, so a tile's sample count, and the stack, are the same for any thread count. A farm
//! split by sample ranges cannot apply it (a partition does not know whether a tile
//! stopped before its range), so a farm bake refuses adaptive sampling by name.

use std::ops::Range;

use super::blocks::{combine, dyadic_blocks, siblings};
use super::tiles::Tile;
use super::trace::trace_tile_records;
use crate::bake::finish::denoise::FEATURE_STRIDE;
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::bake::settings::AdaptiveSampling;
use crate::progress::Progress;
use crate::{RelumeError, Result, Rgb};

/// The cumulative sample counts a tile reaches, one per round: `first`, then doubling,
/// the last one `spp`.
pub fn rounds(first: u32, spp: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let mut n = first.clamp(1, spp.max(1));
    loop {
        out.push(n);
        if n >= spp {
            return out;
        }
        n = n.saturating_mul(2).min(spp);
    }
}

/// Per pixel the bake-time image's RGB sum of `tp` records (layer sums then features,
/// [`super::blocks::combine`]'s layout) under the layers' bake-time `weights`, in f64.
pub fn bake_time_image(records: &[f32], tp: usize, weights: &[Rgb]) -> Vec<[f64; 3]> {
    let layer_floats = weights.len() * 3;
    let record = layer_floats + FEATURE_STRIDE;
    (0..tp)
        .map(|p| {
            let texels = &records[p * record..p * record + layer_floats];
            let mut v = [0.0f64; 3];
            for (w, t) in weights.iter().zip(texels.chunks_exact(3)) {
                v[0] += w.x as f64 * t[0] as f64;
                v[1] += w.y as f64 * t[1] as f64;
                v[2] += w.z as f64 * t[2] as f64;
            }
            v
        })
        .collect()
}

/// The tile's estimated error (see the module's doc) from its pixels' bake-time image
/// sums over samples `[0, a)` (`first`) and `[0, n)` (`all`), `0 < a < n`.
pub fn tile_error(first: &[[f64; 3]], all: &[[f64; 3]], a: u32, n: u32) -> f64 {
    debug_assert!(0 < a && a < n && first.len() == all.len());
    let (a, n) = (a as f64, n as f64);
    let spread = (a * (n - a)).sqrt() / n;
    let mut sum = 0.0;
    for (f, t) in first.iter().zip(all) {
        let mut noise = 0.0;
        let mut intensity = 0.0;
        for c in 0..3 {
            let (a1, a2) = (f[c] / a, (t[c] - f[c]) / (n - a));
            noise += (a1 - a2).abs() * spread;
            intensity += (t[c] / n).max(0.0);
        }
        let e = noise / (1e-4 + intensity.sqrt());
        sum += e * e;
    }
    (sum / all.len().max(1) as f64).sqrt()
}

/// A tile's samples summed by [`trace_adaptive`]: per pixel its record (layer sums then
/// features) over samples `[0, samples)`.
pub(crate) struct AdaptiveTile {
    pub records: Vec<f32>,
    pub samples: u32,
}

/// Traces `tile` in rounds until its error is at most `adaptive.threshold` or it has `spp`
/// samples; `weights` are the layers' bake-time weights. The records are the canonical
/// tree's root over the samples taken.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_adaptive(
    ctx: &BakeContext,
    brdf: &BasisBrdf,
    tile: &Tile,
    spp: u32,
    adaptive: AdaptiveSampling,
    weights: &[Rgb],
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<AdaptiveTile> {
    let tp = tile.pixels();
    let layer_floats = ctx.layer_count() * 3;
    let record = layer_floats + FEATURE_STRIDE;
    let mut store: Vec<(Range<u32>, Vec<f32>)> = Vec::new();
    let mut image: Vec<[f64; 3]> = vec![[0.0; 3]; tp];
    let mut done = 0u32;
    let threshold = adaptive.threshold as f64;
    // The first round is half the first check's samples: the check compares it with the
    // second half.
    let first = adaptive.first_check(spp);
    for n in rounds((first / 2).max(1), spp) {
        let ranges = dyadic_blocks(done, n);
        let buf = trace_tile_records(
            ctx,
            brdf,
            ranges.len(),
            false,
            tile,
            done..n,
            progress,
            rays,
        )?
        .ok_or(RelumeError::Cancelled)?;
        let before = image.clone();
        for (b, range) in ranges.into_iter().enumerate() {
            let block = buf[b * tp * record..(b + 1) * tp * record].to_vec();
            for (sum, v) in image.iter_mut().zip(bake_time_image(&block, tp, weights)) {
                for c in 0..3 {
                    sum[c] += v[c];
                }
            }
            push_block(&mut store, range, block, tp, record, layer_floats);
        }
        let half = done;
        done = n;
        if n < spp && half > 0 && tile_error(&before, &image, half, n) <= threshold {
            break;
        }
    }
    Ok(AdaptiveTile {
        records: fold_blocks(store, tp, record, layer_floats),
        samples: done,
    })
}

/// Appends a tile's block (the next samples in order) and sums siblings as they meet, per
/// pixel — [`super::tile_sums::TileBlocks::push`] on one tile's records.
fn push_block(
    store: &mut Vec<(Range<u32>, Vec<f32>)>,
    range: Range<u32>,
    block: Vec<f32>,
    tp: usize,
    record: usize,
    layer_floats: usize,
) {
    store.push((range, block));
    while store.len() >= 2 {
        let k = store.len() - 1;
        if !siblings(&store[k - 1].0, &store[k].0) {
            break;
        }
        let (right_range, right) = store.pop().expect("two blocks");
        let left = store.last_mut().expect("one block");
        add_records(&mut left.1, &right, tp, record, layer_floats);
        left.0.end = right_range.end;
    }
}

/// The right fold `b₀ + (b₁ + (…))` of the stored blocks: the canonical tree's root.
fn fold_blocks(
    mut store: Vec<(Range<u32>, Vec<f32>)>,
    tp: usize,
    record: usize,
    layer_floats: usize,
) -> Vec<f32> {
    while store.len() >= 2 {
        let (_, right) = store.pop().expect("two blocks");
        let left = store.last_mut().expect("one block");
        add_records(&mut left.1, &right, tp, record, layer_floats);
    }
    store.pop().map(|(_, b)| b).unwrap_or_default()
}

fn add_records(into: &mut [f32], from: &[f32], tp: usize, record: usize, layer_floats: usize) {
    for p in 0..tp {
        let at = p * record..(p + 1) * record;
        combine(&mut into[at.clone()], &from[at], layer_floats);
    }
}

/// A tile's eye-feature records of `samples` eye samples as the denoiser reads those of
/// `spp`: it filters a pixel only when every eye sample hit one surface (its hit count is
/// the sample count) and takes the mean position, so a pixel whose `samples` samples all hit
/// gets the count `spp` and its position sum scaled to match. Other pixels keep a count
/// below `spp`, and stay unfiltered, as in a full bake.
pub(crate) fn features_as_of_spp(features: &mut [f32], samples: u32, spp: u32) {
    if samples == spp {
        return;
    }
    let scale = spp as f32 / samples as f32;
    for rec in features.chunks_exact_mut(FEATURE_STRIDE) {
        if rec[0] == samples as f32 {
            rec[0] = spp as f32;
            for v in &mut rec[6..9] {
                *v *= scale;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_double_up_to_spp() {
        assert_eq!(rounds(4, 16), vec![4, 8, 16]);
        assert_eq!(rounds(4, 20), vec![4, 8, 16, 20]);
        assert_eq!(rounds(16, 16), vec![16]);
        assert_eq!(rounds(0, 3), vec![1, 2, 3]);
    }

    /// The estimate's scale: two halves drawn with a known per-sample noise σ give an
    /// error near σ/√n over √intensity, for equal and unequal halves.
    #[test]
    fn the_estimate_measures_the_noise_of_the_mean() {
        let sigma = 0.3f64;
        let mean = 1.0f64;
        let mut state = 12345u64;
        let mut normal = || {
            // Box–Muller on a xorshift: deterministic and good enough for a scale check.
            let mut u = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            let (u1, u2) = (u().max(1e-12), u());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        for (a, n) in [(8u32, 16u32), (16, 20)] {
            let pixels = 4096;
            let mut first = Vec::new();
            let mut all = Vec::new();
            for _ in 0..pixels {
                let mut f = [0.0; 3];
                let mut t = [0.0; 3];
                for s in 0..n {
                    for c in 0..3 {
                        let v = mean + sigma * normal();
                        t[c] += v;
                        if s < a {
                            f[c] += v;
                        }
                    }
                }
                first.push(f);
                all.push(t);
            }
            let e = tile_error(&first, &all, a, n);
            // Per channel E|X| = σ_mean·√(2/π) for the normal noise X of the mean, summed
            // over three channels; RMS over pixels gives √(E X²)-like: 3·σ_mean·(between
            // √(2/π) and 1). Use the RMS of a sum of three half-normals: √(3 + 6·(2/π))·σ.
            let sigma_mean = sigma / (n as f64).sqrt();
            let want = (3.0 + 6.0 * 2.0 / std::f64::consts::PI).sqrt() * sigma_mean
                / (1e-4 + (3.0 * mean).sqrt());
            assert!((e / want - 1.0).abs() < 0.05, "a {a} n {n}: {e} vs {want}");
        }
    }
}

//! Sampling helpers: orthonormal frames, hemispheres, disks, cones, Blinn–Phong lobes,
//! and the counter-based random numbers that make a bake independent of thread count.

use glam::Vec3;
use std::f32::consts::PI;

/// A right-handed orthonormal frame around `n` (Duff et al. 2017, branchless).
pub fn frame(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Local (x, y, z) in the frame of `n` → world.
pub fn to_world(n: Vec3, local: Vec3) -> Vec3 {
    let (t, b) = frame(n);
    t * local.x + b * local.y + n * local.z
}

/// Uniform direction on the hemisphere around +Z; pdf 1/(2π).
pub fn uniform_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let z = u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Cosine-weighted direction around +Z; pdf cos θ/π.
pub fn cosine_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let (x, y) = concentric_disk(u1, u2);
    Vec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
}

/// Shirley–Chiu concentric map of the unit square to the unit disk (area-preserving).
pub fn concentric_disk(u1: f32, u2: f32) -> (f32, f32) {
    let a = 2.0 * u1 - 1.0;
    let b = 2.0 * u2 - 1.0;
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, PI / 4.0 * (b / a))
    } else {
        (b, PI / 2.0 - PI / 4.0 * (a / b))
    };
    (r * phi.cos(), r * phi.sin())
}

/// Uniform direction in the cone of half-angle with cosine `cos_max` around +Z;
/// pdf 1/(2π(1 − cos_max)).
pub fn uniform_cone(u1: f32, u2: f32, cos_max: f32) -> Vec3 {
    let z = 1.0 - u1 * (1.0 - cos_max);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Half vector around +Z with pdf (ns+1)/(2π)·cos^ns θh (Blinn–Phong lobe sampling).
pub fn blinn_phong_half_vector(u1: f32, u2: f32, ns: f32) -> Vec3 {
    let z = u1.max(1e-30).powf(1.0 / (ns + 1.0));
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Solid-angle pdf of [`blinn_phong_half_vector`] for `wi` reflected about the half vector
/// of cosine `cos_h` (with the normal), where `wo·h = wo_dot_h`: pdf_h / (4·wo·h).
pub fn blinn_phong_pdf(cos_h: f32, wo_dot_h: f32, ns: f32) -> f32 {
    if cos_h <= 0.0 || wo_dot_h <= 0.0 {
        return 0.0;
    }
    let pdf_h = (ns + 1.0) / (2.0 * PI) * (ns * cos_h.ln()).exp();
    pdf_h / (4.0 * wo_dot_h)
}

/// Counter-based, randomised quasi-Monte Carlo numbers: the same numbers for a pixel
/// whatever the tiling and thread count, and stratified across a pixel's samples.
///
/// Every call draws from its own *dimension pair* of an Owen-scrambled 2-D Sobol sequence
/// (Burley 2020, "Practical hash-based Owen scrambling": the index is shuffled and each
/// coordinate scrambled by hash, with seeds from (seed, pixel, dimension)), at the stream's
/// `index` — the eye sample for a fresh stream. So the 16 pixel jitters of 16 eye samples
/// are one stratified 16-point set rather than 16 independent points, and so is every other
/// dimension. Loops inside an eye sample (light samples, indirect directions) take a
/// [`SampleStream::branch`] and a [`SampleStream::child`] per iteration, whose index
/// is `index · count + j`: the 4 light samples of 16 eye samples are one 64-point set.
///
/// Each number is still uniform on [0, 1) (over the scrambles) and numbers of different
/// dimensions are independent, so every estimator stays unbiased; only the variance falls.
/// Measured on the Cornell scene (16 eye × 4 light × 4 indirect samples): see the README.
#[derive(Clone, Copy, Debug)]
pub struct SampleStream {
    /// Seeds the dimensions of this stream (hash of seed and pixel, and of the branch).
    key: u64,
    /// Index of the point in every dimension's sequence.
    index: u32,
    /// Next dimension pair.
    dim: u32,
}

impl SampleStream {
    /// The stream of eye sample `sample` of pixel `pixel` for bake seed `seed`.
    pub fn new(seed: u64, pixel: u64, sample: u32) -> Self {
        let key = mix64(seed ^ mix64(pixel.wrapping_mul(0x9E3779B97F4A7C15) ^ 0x5bd1e995));
        SampleStream {
            key,
            index: sample,
            dim: 0,
        }
    }
    /// The next uniform number in [0, 1) (the first coordinate of a fresh dimension pair).
    #[allow(clippy::should_implement_trait)]
    #[inline]
    pub fn next(&mut self) -> f32 {
        self.next2().0
    }
    /// Two numbers: one point of a fresh dimension pair.
    #[inline]
    pub fn next2(&mut self) -> (f32, f32) {
        let k = mix64(self.key ^ (self.dim as u64 + 1).wrapping_mul(0xD1B54A32D192ED03));
        self.dim += 1;
        sobol_owen_2d(self.index, k)
    }
    /// Opens a nested loop: takes one dimension of this stream and returns the stream whose
    /// [`SampleStream::child`]ren the loop's iterations draw from.
    #[inline]
    pub fn branch(&mut self) -> SampleStream {
        let key = mix64(self.key ^ (self.dim as u64 + 1).wrapping_mul(0x9FB21C651E98DF25));
        self.dim += 1;
        SampleStream {
            key,
            index: self.index,
            dim: 0,
        }
    }
    /// Iteration `j` of `count` of the loop `self` was branched for: index `index · count + j`,
    /// so the iterations of all eye samples together form one stratified sequence.
    #[inline]
    pub fn child(&self, j: u32, count: u32) -> SampleStream {
        SampleStream {
            key: self.key,
            index: self.index.wrapping_mul(count).wrapping_add(j),
            dim: 0,
        }
    }
}

/// Point `index` of the first two Sobol dimensions, index shuffled and both coordinates
/// Owen-scrambled by hash with seeds drawn from `key`.
#[inline]
fn sobol_owen_2d(index: u32, key: u64) -> (f32, f32) {
    let i = nested_uniform_scramble(index, key as u32);
    let x = nested_uniform_scramble(i.reverse_bits(), (key >> 32) as u32);
    let y = nested_uniform_scramble(sobol_second_dimension(i), mix64(key) as u32);
    (to_unit(x), to_unit(y))
}

/// Direction numbers of Sobol's second dimension (polynomial x + 1), most significant bit
/// first: bit k of the index contributes `SOBOL_SECOND[k]`.
const SOBOL_SECOND: [u32; 32] = {
    let mut t = [0u32; 32];
    let mut v = 1u32 << 31;
    let mut k = 0;
    while k < 32 {
        t[k] = v;
        v ^= v >> 1;
        k += 1;
    }
    t
};

/// Sobol's second dimension, most significant bit first: 0, ½, ¾, ¼, …
#[inline]
fn sobol_second_dimension(mut i: u32) -> u32 {
    let mut r = 0u32;
    while i != 0 {
        let k = i.trailing_zeros();
        r ^= SOBOL_SECOND[k as usize];
        i &= i - 1;
    }
    r
}

/// Owen scrambling of a 32-bit fraction (most significant bit first) by hash: each bit is
/// flipped by a function of the bits above it (Laine–Karras permutation on the reversed bits).
#[inline]
fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    let mut v = x.reverse_bits().wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50b47c);
    v ^= v.wrapping_mul(0xb82f1e52);
    v ^= v.wrapping_mul(0xc7afe638);
    v ^= v.wrapping_mul(0x8d22f6e6);
    v.reverse_bits()
}

/// The top 24 bits of a fraction as an f32 in [0, 1).
#[inline]
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// SplitMix64 finaliser.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
            Vec3::new(1e-8, 0.0, -1.0).normalize(),
        ] {
            let (t, b) = frame(n);
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
            assert!(t.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5 && t.dot(b).abs() < 1e-5);
        }
    }

    #[test]
    fn lobe_pdf_integrates_to_one_over_the_sphere() {
        // ∫ pdf(wi) dωi over all wi = 1 for wo = +Z (mass below the horizon included).
        for ns in [1.0f32, 20.0, 200.0] {
            let wo = Vec3::new(0.0, 0.0, 1.0);
            let n = 400usize;
            let mut sum = 0.0f64;
            for i in 0..n {
                for j in 0..2 * n {
                    let z = -1.0 + 2.0 * (i as f32 + 0.5) / n as f32;
                    let phi = 2.0 * PI * (j as f32 + 0.5) / (2 * n) as f32;
                    let r = (1.0 - z * z).sqrt();
                    let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    let h = (wi + wo).normalize();
                    sum += blinn_phong_pdf(h.z, wo.dot(h), ns) as f64
                        * (4.0 * PI as f64 / (2 * n * n) as f64);
                }
            }
            assert!((sum - 1.0).abs() < 0.02, "ns {ns}: {sum}");
        }
    }

    #[test]
    fn streams_are_uniform_and_distinct() {
        let mut s = SampleStream::new(7, 123, 4);
        let n = 20000;
        let mean: f32 = (0..n).map(|_| s.next()).sum::<f32>() / n as f32;
        assert!((mean - 0.5).abs() < 0.01);
        let a = SampleStream::new(7, 123, 4).next();
        let b = SampleStream::new(7, 124, 4).next();
        let c = SampleStream::new(8, 123, 4).next();
        assert!(a != b && a != c);
    }

    /// The 16 eye samples of a pixel, in any dimension pair, form a (0, 4, 2)-net: one point
    /// in each cell of every 1×16, 2×8, 4×4, 8×2, 16×1 grid. So do the 4 light samples of
    /// those 16 eye samples (64 points, a (0, 6, 2)-net) — what makes them stratified.
    #[test]
    fn a_pixels_samples_are_stratified_in_every_dimension_pair() {
        fn is_net(points: &[(f32, f32)]) -> bool {
            let m = points.len().trailing_zeros();
            (0..=m).all(|a| {
                let (nx, ny) = (1usize << a, 1usize << (m - a));
                let mut seen = vec![false; points.len()];
                points.iter().all(|&(x, y)| {
                    let cell = (x * nx as f32) as usize * ny + (y * ny as f32) as usize;
                    !std::mem::replace(&mut seen[cell], true)
                })
            })
        }
        for (seed, pixel) in [(0u64, 0u64), (7, 123), (99, 1 << 40)] {
            for dim in 0..5 {
                let eye: Vec<(f32, f32)> = (0..16)
                    .map(|s| {
                        let mut st = SampleStream::new(seed, pixel, s);
                        (0..dim).for_each(|_| {
                            st.next2();
                        });
                        st.next2()
                    })
                    .collect();
                assert!(is_net(&eye), "seed {seed} pixel {pixel} dim {dim}: {eye:?}");
            }
            let light: Vec<(f32, f32)> = (0..16)
                .flat_map(|s| {
                    let mut st = SampleStream::new(seed, pixel, s);
                    st.next2();
                    let base = st.branch();
                    (0..4).map(move |j| base.child(j, 4).next2())
                })
                .collect();
            assert!(is_net(&light), "seed {seed} pixel {pixel}: {light:?}");
        }
    }

    /// Different dimension pairs are decorrelated (the index is shuffled per pair): the
    /// correlation of x across two pairs over many pixels is ≈ 0, as is that of a pixel's
    /// sample with the same sample of the next pixel.
    #[test]
    fn dimensions_and_pixels_are_uncorrelated() {
        let n = 20_000u64;
        let corr = |f: &dyn Fn(u64) -> (f32, f32)| {
            let (mut sa, mut sb, mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for i in 0..n {
                let (a, b) = f(i);
                let (a, b) = (a as f64, b as f64);
                sa += a;
                sb += b;
                sab += a * b;
                saa += a * a;
                sbb += b * b;
            }
            let nf = n as f64;
            let cov = sab / nf - sa / nf * sb / nf;
            cov / ((saa / nf - (sa / nf).powi(2)) * (sbb / nf - (sb / nf).powi(2))).sqrt()
        };
        let across_dims = corr(&|i| {
            let mut s = SampleStream::new(3, i, (i % 16) as u32);
            (s.next(), s.next())
        });
        let across_pixels = corr(&|i| {
            (
                SampleStream::new(3, 2 * i, 5).next(),
                SampleStream::new(3, 2 * i + 1, 5).next(),
            )
        });
        assert!(across_dims.abs() < 0.03, "{across_dims}");
        assert!(across_pixels.abs() < 0.03, "{across_pixels}");
    }
}

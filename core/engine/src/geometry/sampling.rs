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

/// Counter-based random numbers: value `i` of the stream for (seed, pixel, sample) is a hash
/// of the four, so every pixel draws the same numbers whatever the tiling and thread count.
#[derive(Clone, Copy, Debug)]
pub struct SampleStream {
    key: u64,
    next: u32,
}

impl SampleStream {
    /// The stream of eye sample `sample` of pixel `pixel` for bake seed `seed`.
    pub fn new(seed: u64, pixel: u64, sample: u32) -> Self {
        let key = mix64(
            seed ^ mix64(
                pixel.wrapping_mul(0x9E3779B97F4A7C15) ^ ((sample as u64) << 32 | 0x5bd1e995),
            ),
        );
        SampleStream { key, next: 0 }
    }
    /// The next uniform number in [0, 1).
    #[allow(clippy::should_implement_trait)]
    #[inline]
    pub fn next(&mut self) -> f32 {
        let h = mix64(self.key ^ (self.next as u64).wrapping_mul(0xD1B54A32D192ED03));
        self.next += 1;
        (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
    /// Two numbers.
    #[inline]
    pub fn next2(&mut self) -> (f32, f32) {
        (self.next(), self.next())
    }
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
}

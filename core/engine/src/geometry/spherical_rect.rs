//! Uniform sampling of the solid angle a rectangle subtends (Ureña, Fajardo & King, "An
//! Area-Preserving Parametrization for Spherical Rectangles", EGSR 2013).
//!
//! Sampling an area light uniformly by area gives each sample the weight
//! `L·A·cos θ_light / d²`, which swings with distance and angle across a large or close
//! light (the corners of the Cornell ceiling lamp seen from the wall beside it); sampling
//! its solid angle uniformly gives every sample the same weight `L·Ω`, so the only variance
//! left is that of the receiver's `cos θ · BRDF` and of visibility. The parametrization is
//! computed in f64: it subtracts angles near 2π to get Ω, which in f32 would lose every
//! digit of a 10⁻⁶ sr light.

use glam::{DVec3, Vec3};

/// A rectangle as seen from one shading point, ready to be sampled by solid angle.
#[derive(Clone, Copy, Debug)]
pub struct SphericalRect {
    origin: DVec3,
    x: DVec3,
    y: DVec3,
    z: DVec3,
    z0: f64,
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    b0: f64,
    b1: f64,
    k: f64,
    /// The solid angle, sr.
    pub solid_angle: f64,
}

impl SphericalRect {
    /// The rectangle with corner `corner` and edges `ex`, `ey` (orthogonal), seen from `p`.
    /// `None` when `p` lies in the rectangle's plane (it subtends nothing) or the rectangle
    /// is degenerate.
    pub fn new(corner: Vec3, ex: Vec3, ey: Vec3, p: Vec3) -> Option<SphericalRect> {
        let (corner, ex, ey, o) = (
            corner.as_dvec3(),
            ex.as_dvec3(),
            ey.as_dvec3(),
            p.as_dvec3(),
        );
        let (exl, eyl) = (ex.length(), ey.length());
        if !(exl > 0.0 && eyl > 0.0) {
            return None;
        }
        let x = ex / exl;
        let y = ey / eyl;
        let mut z = x.cross(y);
        let d = corner - o;
        let mut z0 = d.dot(z);
        if z0 > 0.0 {
            z = -z;
            z0 = -z0;
        }
        if !(z0 < 0.0) || !z0.is_finite() {
            return None;
        }
        let x0 = d.dot(x);
        let y0 = d.dot(y);
        let x1 = x0 + exl;
        let y1 = y0 + eyl;
        // Normals of the four planes through `o` and an edge (pointing inwards).
        let n0 = DVec3::new(0.0, z0, -y0).normalize();
        let n1 = DVec3::new(-z0, 0.0, x1).normalize();
        let n2 = DVec3::new(0.0, -z0, y1).normalize();
        let n3 = DVec3::new(z0, 0.0, -x0).normalize();
        let angle = |a: DVec3, b: DVec3| (-a.dot(b)).clamp(-1.0, 1.0).acos();
        let g0 = angle(n0, n1);
        let g1 = angle(n1, n2);
        let g2 = angle(n2, n3);
        let g3 = angle(n3, n0);
        let k = 2.0 * std::f64::consts::PI - g2 - g3;
        let solid_angle = g0 + g1 - k;
        if !(solid_angle > 0.0) || !solid_angle.is_finite() {
            return None;
        }
        Some(SphericalRect {
            origin: o,
            x,
            y,
            z,
            z0,
            x0,
            x1,
            y0,
            y1,
            b0: n0.z,
            b1: n2.z,
            k,
            solid_angle,
        })
    }

    /// The point on the rectangle for uniforms `(u, v)` ∈ [0, 1)²; the density of its
    /// direction from the shading point is `1 / solid_angle` everywhere.
    pub fn sample(&self, u: f32, v: f32) -> Vec3 {
        let (u, v) = (u as f64, v as f64);
        let au = u * self.solid_angle + self.k;
        let (sin_au, cos_au) = au.sin_cos();
        let fu = (cos_au * self.b0 - self.b1) / sin_au;
        let cu = if fu.is_finite() {
            (1.0 / (fu * fu + self.b0 * self.b0).sqrt()).copysign(fu)
        } else {
            // sin(au) = 0: the edge at x0 or x1, depending on the sign of the numerator.
            (cos_au * self.b0 - self.b1).signum()
        }
        .clamp(-1.0, 1.0);
        let xu = if cu * cu < 1.0 {
            (-(cu * self.z0) / (1.0 - cu * cu).sqrt()).clamp(self.x0, self.x1)
        } else if cu > 0.0 {
            self.x0
        } else {
            self.x1
        };
        let d = (xu * xu + self.z0 * self.z0).sqrt();
        let h0 = self.y0 / (d * d + self.y0 * self.y0).sqrt();
        let h1 = self.y1 / (d * d + self.y1 * self.y1).sqrt();
        let hv = h0 + v * (h1 - h0);
        let hv2 = hv * hv;
        let yv = if hv2 < 1.0 - 1e-12 {
            (hv * d / (1.0 - hv2).sqrt()).clamp(self.y0, self.y1)
        } else {
            self.y1
        };
        (self.origin + self.x * xu + self.y * yv + self.z * self.z0).as_vec3()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Solid angle of a rectangle by brute force: area integral of cos/d² on a fine grid.
    fn brute_solid_angle(corner: Vec3, ex: Vec3, ey: Vec3, p: Vec3) -> f64 {
        let n = 800;
        let normal = ex.cross(ey).normalize().as_dvec3();
        let cell = (ex.length() * ey.length()) as f64 / (n * n) as f64;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let q = corner.as_dvec3()
                    + ex.as_dvec3() * ((i as f64 + 0.5) / n as f64)
                    + ey.as_dvec3() * ((j as f64 + 0.5) / n as f64);
                let d = q - p.as_dvec3();
                let d2 = d.length_squared();
                sum += (d.dot(normal).abs() / d2.sqrt()) / d2 * cell;
            }
        }
        sum
    }

    #[test]
    fn solid_angle_matches_brute_force_and_closed_forms() {
        // A unit square seen from 1 above its centre: Ω = 4·asin(1/3)... closed form for a
        // square of side a at height h over its centre: 4·atan(a²/(4h·sqrt(a²/2 + h²))).
        let (a, h) = (1.0f64, 1.0f64);
        let exact = 4.0 * (a * a / (4.0 * h * (a * a / 2.0 + h * h).sqrt())).atan();
        let r = SphericalRect::new(
            Vec3::new(-0.5, -0.5, 0.0),
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.0, 0.0, 1.0),
        )
        .unwrap();
        assert!(
            (r.solid_angle - exact).abs() < 1e-9,
            "{} vs {exact}",
            r.solid_angle
        );
        // Off-centre, below the plane, long and thin.
        for (corner, ex, ey, p) in [
            (
                Vec3::new(0.3, -2.0, 1.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(0.0, 0.5, 0.0),
                Vec3::ZERO,
            ),
            (
                Vec3::new(-1.0, 0.0, -0.2),
                Vec3::new(0.0, 3.0, 0.0),
                Vec3::new(0.0, 0.0, 0.1),
                Vec3::new(0.5, 1.0, 0.0),
            ),
        ] {
            let r = SphericalRect::new(corner, ex, ey, p).unwrap();
            let b = brute_solid_angle(corner, ex, ey, p);
            assert!(
                (r.solid_angle - b).abs() < 2e-4 * b,
                "{} vs {b}",
                r.solid_angle
            );
        }
    }

    #[test]
    fn samples_are_on_the_rectangle_and_uniform_in_solid_angle() {
        let corner = Vec3::new(-0.3, 0.2, 0.4);
        let (ex, ey) = (Vec3::new(1.2, 0.0, 0.0), Vec3::new(0.0, 0.7, 0.0));
        let p = Vec3::new(0.1, -0.1, 0.0);
        let r = SphericalRect::new(corner, ex, ey, p).unwrap();
        // Split the rectangle into 4×4 cells; each cell's share of the samples must equal
        // its share of the solid angle.
        let cells = 4;
        let mut counts = vec![0u32; cells * cells];
        let n = 200_000;
        let mut state = 12345u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for _ in 0..n {
            let q = r.sample(next(), next());
            let local = q - corner;
            assert!(local.z.abs() < 1e-5, "off the plane: {q}");
            let (fx, fy) = (local.x / ex.x, local.y / ey.y);
            assert!((-1e-5..=1.0 + 1e-5).contains(&fx) && (-1e-5..=1.0 + 1e-5).contains(&fy));
            let (i, j) = (
                ((fx * cells as f32) as usize).min(cells - 1),
                ((fy * cells as f32) as usize).min(cells - 1),
            );
            counts[i * cells + j] += 1;
        }
        for i in 0..cells {
            for j in 0..cells {
                let c0 = corner + ex * (i as f32 / cells as f32) + ey * (j as f32 / cells as f32);
                let cell = SphericalRect::new(c0, ex / cells as f32, ey / cells as f32, p).unwrap();
                let expected = cell.solid_angle / r.solid_angle;
                let got = counts[i * cells + j] as f64 / n as f64;
                let sigma = (expected * (1.0 - expected) / n as f64).sqrt();
                assert!(
                    (got - expected).abs() < 5.0 * sigma + 1e-4,
                    "cell {i},{j}: {got} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn tiny_and_grazing_rectangles_stay_finite() {
        // 1 mm light 10 m away: Ω ≈ 1e-8 sr, still resolved in f64.
        let r = SphericalRect::new(
            Vec3::new(-0.0005, -0.0005, 10.0),
            Vec3::X * 0.001,
            Vec3::Y * 0.001,
            Vec3::ZERO,
        )
        .unwrap();
        assert!((r.solid_angle - 1e-8).abs() < 1e-11, "{}", r.solid_angle);
        let q = r.sample(0.3, 0.9);
        assert!(q.is_finite() && (q.z - 10.0).abs() < 1e-4);
        // In the plane: nothing.
        assert!(
            SphericalRect::new(Vec3::new(1.0, 0.0, 0.0), Vec3::X, Vec3::Y, Vec3::ZERO).is_none()
        );
        // Just above the plane, beside the light.
        let r = SphericalRect::new(
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.0, 0.0, 1e-6),
        )
        .unwrap();
        for (u, v) in [(0.0, 0.0), (0.999_999, 0.999_999), (0.5, 0.5)] {
            assert!(r.sample(u, v).is_finite());
        }
    }
}

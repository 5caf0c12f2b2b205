//! Surface samples of a translucent region: points spread uniformly by area, and the light
//! entering the surface at each (`E′`, irradiance times the Fresnel transmittance).
//!
//! Sampling is stratified over the region's area (sample i takes the stratum
//! `[i + ξ, i + 1 + ξ)/N` of the cumulative area, one random shift ξ for all, and a rank-1
//! lattice point of the triangle there), so the points cover the surface evenly and every point stands for the same area `A/N` — the
//! disc of radius `ρ = √(A/(πN))` the dipole kernel is averaged over.

use glam::Vec3;

use crate::geometry::sampling::SampleStream;
use crate::scene::Scene;

/// Points on a region's surface, each standing for `area_each` of it.
#[derive(Clone, Debug, Default)]
pub struct SurfacePoints {
    pub positions: Vec<Vec3>,
    /// Outward normals (interpolated shading normals where the mesh has them).
    pub normals: Vec<Vec3>,
    /// Geometric normals, on the side of `normals` (for ray offsets and the horizon test).
    pub geometric_normals: Vec<Vec3>,
    /// Area per point: the region's area over the point count.
    pub area_each: f64,
    pub total_area: f64,
    /// Bounding-box diagonal of the region: the largest distance two points can have.
    pub diameter: f64,
}

impl SurfacePoints {
    /// Radius of the disc each point stands for: `√(area_each/π)`.
    pub fn rho(&self) -> f64 {
        (self.area_each / std::f64::consts::PI).sqrt()
    }
}

/// Area and bounding-box diagonal of scene region `region` (0 area: no triangle).
pub fn region_extent(scene: &Scene, region: u32) -> (f64, f64) {
    let mut area = 0.0f64;
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for mesh in &scene.meshes {
        for (t, idx) in mesh.indices.iter().enumerate() {
            if mesh.region_of(t) != region {
                continue;
            }
            let p = idx.map(|i| Vec3::from(mesh.positions[i as usize]));
            area += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64;
            for q in p {
                lo = lo.min(q);
                hi = hi.max(q);
            }
        }
    }
    let diameter = if area > 0.0 {
        (hi - lo).length() as f64
    } else {
        0.0
    };
    (area, diameter)
}

/// `count` points uniformly by area on the triangles of scene region `region`, from the
/// random stream of `seed` (deterministic). Empty when the region has no area.
pub fn sample_region(scene: &Scene, region: u32, count: usize, seed: u64) -> SurfacePoints {
    struct Tri {
        p: [Vec3; 3],
        n: Option<[Vec3; 3]>,
        area: f64,
    }
    let mut tris = Vec::new();
    for mesh in &scene.meshes {
        for (t, idx) in mesh.indices.iter().enumerate() {
            if mesh.region_of(t) != region {
                continue;
            }
            let p = idx.map(|i| Vec3::from(mesh.positions[i as usize]));
            let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64;
            if !(area > 0.0) {
                continue;
            }
            let n = mesh
                .normals
                .as_ref()
                .map(|n| idx.map(|i| Vec3::from(n[i as usize])));
            tris.push(Tri { p, n, area });
        }
    }
    let (total_area, diameter) = region_extent(scene, region);
    if tris.is_empty() || count == 0 {
        return SurfacePoints::default();
    }
    let mut cdf = Vec::with_capacity(tris.len());
    let mut acc = 0.0f64;
    for t in &tris {
        acc += t.area;
        cdf.push(acc);
    }
    let mut out = SurfacePoints {
        positions: Vec::with_capacity(count),
        normals: Vec::with_capacity(count),
        geometric_normals: Vec::with_capacity(count),
        area_each: acc / count as f64,
        total_area,
        diameter,
    };
    let mut s = SampleStream::new(seed ^ 0x5355_4253_5552_4641, region as u64, 0);
    let (jitter, jitter2) = (s.next() as f64, s.next() as f64);
    for i in 0..count {
        let target = (i as f64 + jitter) / count as f64 * acc;
        let k = cdf.partition_point(|c| *c < target).min(tris.len() - 1);
        let t = &tris[k];
        // A rank-1 lattice inside the triangle: u1 from the stratum (uniform in the triangle's
        // share of the CDF), u2 from the golden ratio sequence. Independent random (u1, u2)
        // clump like a Poisson process, which shows as blotches in the light gathered over a
        // blur; the lattice spreads the samples evenly.
        let before = if k == 0 { 0.0 } else { cdf[k - 1] };
        let u1 = (((target - before) / t.area) as f32).clamp(0.0, 1.0 - f32::EPSILON);
        let u2 = ((i as f64 * 0.618_033_988_749_894_9 + jitter2) % 1.0) as f32;
        let su = u1.sqrt();
        let (b0, b1) = (1.0 - su, u2 * su);
        let b2 = 1.0 - b0 - b1;
        let pos = t.p[0] * b0 + t.p[1] * b1 + t.p[2] * b2;
        let ng = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).normalize_or_zero();
        let n = match t.n {
            Some(n) => {
                let v = (n[0] * b0 + n[1] * b1 + n[2] * b2).normalize_or_zero();
                if v == Vec3::ZERO || !v.is_finite() {
                    ng
                } else {
                    v
                }
            }
            None => ng,
        };
        out.positions.push(pos);
        out.normals.push(n);
        out.geometric_normals
            .push(if ng.dot(n) < 0.0 { -ng } else { ng });
    }
    out
}

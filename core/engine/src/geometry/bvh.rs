//! Scene geometry behind an obvhs CWBVH: closest hit and occlusion, and the surface data of
//! a hit (position, normals, UV, region).

use glam::{Vec2, Vec3};
use obvhs::{
    cwbvh::{builder::build_cwbvh_from_tris, CwBvh},
    ray::{Ray, RayHit},
    triangle::Triangle,
    BvhBuildParams,
};

use crate::scene::{validate::is_degenerate, Scene};

/// Per-triangle shading data, in BVH order.
#[derive(Clone, Copy, Debug)]
struct TriShading {
    normals: [Vec3; 3],
    uvs: [Vec2; 3],
    region: u32,
}

/// Triangles of the scene (degenerate ones skipped) in a CWBVH.
pub struct SceneGeometry {
    bvh: CwBvh,
    /// Triangles in BVH primitive order, so traversal indexes them directly.
    tris: Vec<Triangle>,
    shading: Vec<TriShading>,
    /// Largest coordinate magnitude of the scene: sets the ray offset scale.
    extent: f32,
}

/// A surface hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub t: f32,
    pub position: Vec3,
    /// Geometric normal, facing the incoming ray.
    pub geometric_normal: Vec3,
    /// Interpolated shading normal, on the same side as the geometric normal.
    pub shading_normal: Vec3,
    pub uv: Vec2,
    pub region: u32,
}

/// Barycentric weights of `p` (on the triangle's plane) for v0, v1, v2, clamped to the
/// triangle. Computed here because obvhs 0.4's `compute_barycentric` divides by the
/// *normalised* normal, which scales the result by twice the triangle's area.
pub fn barycentric(tri: &Triangle, p: Vec3) -> [f32; 3] {
    let (v0, v1, v2) = (Vec3::from(tri.v0), Vec3::from(tri.v1), Vec3::from(tri.v2));
    let (e1, e2, vp) = (v1 - v0, v2 - v0, p - v0);
    let (d00, d01, d11) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d20, d21) = (vp.dot(e1), vp.dot(e2));
    let denom = d00 * d11 - d01 * d01;
    if !(denom > 0.0) {
        return [1.0, 0.0, 0.0];
    }
    let b1 = ((d11 * d20 - d01 * d21) / denom).clamp(0.0, 1.0);
    let b2 = ((d00 * d21 - d01 * d20) / denom).clamp(0.0, 1.0 - b1);
    [1.0 - b1 - b2, b1, b2]
}

/// Raw BVH hit (for throughput measurements): distance and primitive.
#[derive(Clone, Copy, Debug)]
pub struct RawHit {
    pub t: f32,
    pub primitive: u32,
}

impl SceneGeometry {
    /// Builds the BVH over every non-degenerate triangle of `scene` (validated beforehand).
    pub fn build(scene: &Scene) -> SceneGeometry {
        let mut tris = Vec::with_capacity(scene.triangle_count());
        let mut shading = Vec::with_capacity(scene.triangle_count());
        let mut extent = 0.0f32;
        for mesh in &scene.meshes {
            for (t, idx) in mesh.indices.iter().enumerate() {
                let p = idx.map(|i| Vec3::from(mesh.positions[i as usize]));
                if is_degenerate(p[0], p[1], p[2]) {
                    continue;
                }
                for q in p {
                    extent = extent.max(q.abs().max_element());
                }
                let geo_n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
                let normals = match &mesh.normals {
                    Some(n) => idx.map(|i| {
                        let v = Vec3::from(n[i as usize]);
                        let l = v.length();
                        if l > 0.0 && l.is_finite() {
                            v / l
                        } else {
                            geo_n
                        }
                    }),
                    None => [geo_n; 3],
                };
                let uvs = match &mesh.uvs {
                    Some(uv) => idx.map(|i| Vec2::from(uv[i as usize])),
                    None => [Vec2::ZERO; 3],
                };
                tris.push(Triangle {
                    v0: p[0].into(),
                    v1: p[1].into(),
                    v2: p[2].into(),
                });
                shading.push(TriShading {
                    normals,
                    uvs,
                    region: mesh.region_of(t),
                });
            }
        }
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Default::default(),
        );
        let tris_ordered: Vec<Triangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        let shading_ordered = bvh
            .primitive_indices
            .iter()
            .map(|&i| shading[i as usize])
            .collect();
        SceneGeometry {
            bvh,
            tris: tris_ordered,
            shading: shading_ordered,
            extent: extent.max(1e-30),
        }
    }

    /// Number of triangles in the BVH.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Largest coordinate magnitude.
    pub fn extent(&self) -> f32 {
        self.extent
    }

    /// Closest hit along the ray in (tmin, tmax), raw.
    #[inline]
    pub fn intersect_raw(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<RawHit> {
        let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
        let mut hit = RayHit::none();
        if self
            .bvh
            .ray_traverse(ray, &mut hit, |r, id| self.tris[id].intersect(r))
        {
            Some(RawHit {
                t: hit.t,
                primitive: hit.primitive_id,
            })
        } else {
            None
        }
    }

    /// Closest hit with its surface data.
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<SurfaceHit> {
        let raw = self.intersect_raw(origin, dir, tmin, tmax)?;
        let tri = &self.tris[raw.primitive as usize];
        let position = origin + dir * raw.t;
        let [b0, b1, b2] = barycentric(tri, position);
        let sh = &self.shading[raw.primitive as usize];
        let mut ng: Vec3 = Vec3::from(tri.compute_normal());
        if ng.dot(dir) > 0.0 {
            ng = -ng;
        }
        let mut ns =
            (sh.normals[0] * b0 + sh.normals[1] * b1 + sh.normals[2] * b2).normalize_or_zero();
        if ns == Vec3::ZERO {
            ns = ng;
        }
        if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        Some(SurfaceHit {
            t: raw.t,
            position,
            geometric_normal: ng,
            shading_normal: ns,
            uv: sh.uvs[0] * b0 + sh.uvs[1] * b1 + sh.uvs[2] * b2,
            region: sh.region,
        })
    }

    /// Whether anything blocks the segment from `origin` along `dir` up to `tmax`.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let ray = Ray::new(origin.into(), dir.into(), 0.0, tmax);
        !self
            .bvh
            .ray_traverse_miss(ray, |r, id| self.tris[id].intersect(r))
    }

    /// Ray origin just off the surface at `p` on the side of `n`: the offset scales with the
    /// coordinate magnitude (1e-5 relative, ~170 f32 ulps) plus 1e-7 of the scene extent,
    /// so it holds from millimetre scenes to kilometre ones.
    #[inline]
    pub fn offset(&self, p: Vec3, n: Vec3) -> Vec3 {
        let eps = 1e-5 * p.abs().max_element() + 1e-7 * self.extent;
        p + n * eps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentrics_interpolate_uv_and_normals() {
        // A large triangle (area 50): obvhs' own barycentrics would be off by a factor 100.
        let tri = Triangle {
            v0: Vec3::new(0.0, 0.0, 0.0).into(),
            v1: Vec3::new(10.0, 0.0, 0.0).into(),
            v2: Vec3::new(0.0, 10.0, 0.0).into(),
        };
        let b = barycentric(&tri, Vec3::new(2.0, 3.0, 0.0));
        assert!(
            (b[0] - 0.5).abs() < 1e-6 && (b[1] - 0.2).abs() < 1e-6 && (b[2] - 0.3).abs() < 1e-6,
            "{b:?}"
        );
        let b = barycentric(&tri, Vec3::new(20.0, 20.0, 0.0));
        assert!(
            b.iter().all(|w| (0.0..=1.0).contains(w)) && (b.iter().sum::<f32>() - 1.0).abs() < 1e-6
        );
    }
}

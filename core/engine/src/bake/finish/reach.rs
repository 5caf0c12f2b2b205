//! How far a pixel's indirect light stays alike: the harmonic mean distance from its surface
//! to the surfaces its hemisphere sees — the radius Ward, Rubinstein and Clear's irradiance
//! cache (1988) lets one irradiance value stand for its neighbours, since indirect light at
//! a point can change over about that distance and no faster.
//!
//! The linear denoiser ([`super::denoise`]) limits how far it averages with it. Its other
//! edge-stops (region, normal, tangent plane) see where the *geometry* changes; this one sees
//! where the *light* can change on one plane: the floor at a box's foot, a wall at a corner,
//! a ceiling beside the room's walls. It depends on the geometry alone — never on materials
//! or the layers' values — so the filter stays one linear operator for every layer.
//!
//! The directions are one fixed stratified cosine pattern in the surface's frame, the same
//! at every pixel: the value then varies smoothly over a plane instead of carrying Monte
//! Carlo noise that would make the filter stop at random.

use glam::Vec3;

use crate::geometry::bvh::SceneGeometry;
use crate::geometry::sampling::{cosine_hemisphere, frame};

/// Columns and rows of the stratified pattern: 16 rays a filtered pixel, a small share of a
/// bake's rays (a preview bake traces hundreds a pixel).
const COLUMNS: usize = 4;
const ROWS: usize = 4;

/// The harmonic mean distance from `x` (unit normal `n`, facing the side that was seen) to
/// what the cosine-weighted hemisphere around `n` sees; rays that escape count as infinitely
/// far, so an open plane's reach is infinite. `footprint` (the world size of a pixel there)
/// is the smallest distance counted and the offset of the rays' origin, so a pixel's own
/// surface, which its mean position may sit a hair behind, is never what it sees.
pub fn harmonic_distance(geometry: &SceneGeometry, x: Vec3, n: Vec3, footprint: f32) -> f32 {
    let origin = x + n * footprint;
    let (t, b) = frame(n);
    let mut inverse_sum = 0.0f32;
    for k in 0..COLUMNS * ROWS {
        let u1 = ((k % COLUMNS) as f32 + 0.5) / COLUMNS as f32;
        let u2 = ((k / COLUMNS) as f32 + 0.5) / ROWS as f32;
        let l = cosine_hemisphere(u1, u2);
        let dir = t * l.x + b * l.y + n * l.z;
        if let Some(hit) = geometry.intersect_raw(origin, dir, 0.0, f32::INFINITY) {
            inverse_sum += 1.0 / hit.t.max(footprint);
        }
    }
    if inverse_sum > 0.0 {
        (COLUMNS * ROWS) as f32 / inverse_sum
    } else {
        f32::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{file::load_scene, Mesh};

    /// The geometry of `quads` (four corners each, counter-clockwise), in the asset scene's
    /// frame (its regions, camera and lights are unused here).
    fn geometry(quads: &[[[f32; 3]; 4]]) -> SceneGeometry {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../assets/cornell.scene.json");
        let mut scene = load_scene(&path).unwrap();
        scene.meshes = quads
            .iter()
            .map(|q| Mesh {
                name: String::new(),
                positions: q.to_vec(),
                normals: None,
                uvs: None,
                indices: vec![[0, 1, 2], [0, 2, 3]],
                region: 0,
                triangle_regions: None,
            })
            .collect();
        SceneGeometry::build(&scene)
    }

    /// A 10 × 10 floor at z = 0 around the origin, facing up.
    const FLOOR: [[f32; 3]; 4] = [
        [-5.0, -5.0, 0.0],
        [5.0, -5.0, 0.0],
        [5.0, 5.0, 0.0],
        [-5.0, 5.0, 0.0],
    ];

    /// A closed cube of half-size `h` around the origin.
    fn cube(h: f32) -> Vec<[[f32; 3]; 4]> {
        let mut faces = Vec::new();
        for axis in 0..3 {
            for sign in [-h, h] {
                let corner = |a: f32, b: f32| {
                    let mut p = [0.0; 3];
                    p[axis] = sign;
                    p[(axis + 1) % 3] = a;
                    p[(axis + 2) % 3] = b;
                    p
                };
                faces.push([corner(-h, -h), corner(h, -h), corner(h, h), corner(-h, h)]);
            }
        }
        faces
    }

    #[test]
    fn an_open_plane_reaches_forever() {
        let g = geometry(&[FLOOR]);
        let r = harmonic_distance(&g, Vec3::ZERO, Vec3::Z, 1e-3);
        assert_eq!(r, f32::INFINITY);
    }

    #[test]
    fn inside_a_box_the_reach_is_the_harmonic_mean_distance_and_scales_with_the_room() {
        // A point on the floor of a cube of side 2h, a little off its centre (0.1 h, 0.05 h),
        // facing up: the cosine-weighted harmonic mean distance to the walls and ceiling,
        // integrated numerically, is 1.544 h. The fixed pattern's estimate of it is within
        // a few per cent.
        let (h, fp) = (1.0, 1e-3);
        let x = Vec3::new(0.1 * h, 0.05 * h, -h + 1e-4);
        let r = harmonic_distance(&geometry(&cube(h)), x, Vec3::Z, fp);
        assert!((r / (1.544 * h) - 1.0).abs() < 0.06, "{r}");
        // A length: the same room ten times larger reaches ten times farther.
        let r10 = harmonic_distance(&geometry(&cube(10.0 * h)), x * 10.0, Vec3::Z, 10.0 * fp);
        assert!((r10 / r - 10.0).abs() < 1e-2, "{r10} vs {r}");
    }

    #[test]
    fn the_floor_at_a_walls_foot_reaches_less_far_than_away_from_it() {
        let wall = [
            [0.0, -5.0, 0.0],
            [0.0, 5.0, 0.0],
            [0.0, 5.0, 5.0],
            [0.0, -5.0, 5.0],
        ];
        let g = geometry(&[FLOOR, wall]);
        let at = |d: f32| harmonic_distance(&g, Vec3::new(-d, 0.0, 0.0), Vec3::Z, 1e-3);
        let (near, mid, far) = (at(0.05), at(0.5), at(2.0));
        assert!(near < mid && mid < far, "{near} {mid} {far}");
        // Half the cosine-weighted hemisphere leans towards the wall, so the reach grows
        // about in proportion to the distance from it.
        assert!(mid / near > 5.0 && far / mid > 2.0, "{near} {mid} {far}");
    }
}

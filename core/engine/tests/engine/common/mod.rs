//! Shared by the engine's integration tests. Here: small scenes built in code for the
//! physics tests (the assets/ scenes are for demos and benchmarks; these stay tiny so
//! debug-build tests run in seconds). `stack_header`: the one hand-made `StackHeader`;
//! `synthetic_stack`: random stacks and a naive reference for the relight tests.
#![allow(dead_code)]

pub mod stack_header;
pub mod synthetic_stack;

use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::scene::*;
use relume_engine::stack::bases::StackBases;
use relume_engine::stack::{StackHeader, TransferStack};
use relume_engine::Rgb;

pub fn bp(kd: f32, ks: f32, ns: f32) -> MaterialSpec {
    MaterialSpec::BlinnPhong(BlinnPhong {
        kd: [kd; 3],
        ks: [ks; 3],
        ns,
    })
}

pub fn bp_rgb(kd: [f32; 3], ks: [f32; 3], ns: f32) -> MaterialSpec {
    MaterialSpec::BlinnPhong(BlinnPhong { kd, ks, ns })
}

pub fn region(name: &str, editable: bool, material: MaterialSpec) -> Region {
    Region {
        name: name.into(),
        editable,
        material,
        albedo_texture: None,
        ns_range: None,
        subsurface: None,
    }
}

/// A quad (two triangles) with corners a, b, c, d counter-clockwise seen from its front.
pub fn quad(name: &str, a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3], region: u32) -> Mesh {
    Mesh {
        name: name.into(),
        positions: vec![a, b, c, d],
        normals: None,
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
        region,
        triangle_regions: None,
    }
}

/// A UV sphere with smooth normals.
pub fn sphere(
    name: &str,
    centre: [f32; 3],
    radius: f32,
    rings: u32,
    segments: u32,
    region: u32,
) -> Mesh {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..=segments {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            let n = [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ];
            positions.push([
                centre[0] + radius * n[0],
                centre[1] + radius * n[1],
                centre[2] + radius * n[2],
            ]);
            normals.push(n);
        }
    }
    let mut indices = Vec::new();
    let w = segments + 1;
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (
                i * w + j,
                i * w + j + 1,
                (i + 1) * w + j + 1,
                (i + 1) * w + j,
            );
            if i != 0 {
                indices.push([a, d, b]);
            }
            if i != rings - 1 {
                indices.push([b, d, c]);
            }
        }
    }
    Mesh {
        name: name.into(),
        positions,
        normals: Some(normals),
        uvs: None,
        indices,
        region,
        triangle_regions: None,
    }
}

/// A camera at `eye` looking at `target` (Z up), Blender conventions.
pub fn look_at(eye: [f32; 3], target: [f32; 3], lens_mm: f32) -> Camera {
    let e = glam::Vec3::from(eye);
    let f = (glam::Vec3::from(target) - e).normalize();
    let up = if f.cross(glam::Vec3::Z).length() < 1e-4 {
        glam::Vec3::Y
    } else {
        glam::Vec3::Z
    };
    let x = f.cross(up).normalize();
    let y = x.cross(f);
    let z = -f;
    Camera {
        projection: Projection::Perspective,
        matrix_world: [
            [x.x, y.x, z.x, e.x],
            [x.y, y.y, z.y, e.y],
            [x.z, y.z, z.z, e.z],
            [0.0, 0.0, 0.0, 1.0],
        ],
        lens_mm,
        sensor_width_mm: 36.0,
        sensor_height_mm: 24.0,
        sensor_fit: SensorFit::Auto,
        shift_x: 0.0,
        shift_y: 0.0,
        ortho_scale: 6.0,
        clip_start: 1e-3,
        clip_end: 1e6,
    }
}

/// A closed sphere of radius 1 (one region, diffuse albedo `a`), a point light at its
/// centre, the camera inside: every bounce after the first is uniform, bounce k brings aᵏ
/// times the direct light.
pub fn closed_sphere(a: f32, editable: bool, size: u32) -> Scene {
    Scene {
        meshes: vec![sphere("shell", [0.0; 3], 1.0, 48, 96, 0)],
        regions: vec![region("Shell", editable, bp(a, 0.0, 1.0))],
        lights: vec![Light::Point {
            position: [0.0; 3],
            power: 100.0,
            color: [1.0; 3],
            radius: 0.0,
        }],
        world: World::Color {
            color: [0.0; 3],
            strength: 1.0,
        },
        camera: look_at([0.0, -0.3, 0.1], [0.0, 1.0, -0.2], 30.0),
        resolution: Resolution {
            width: size,
            height: size,
        },
        light_groups: Vec::new(),
    }
}

/// Edits of [`cornell`]'s two editable regions (walls, sphere) across the editable range,
/// the first the bake-time materials (walls Kd 0.3 Ks 0.3 ns 5, sphere Kd 0.2 Ks 0.4
/// ns 5): albedo, colour, lobe-shape and two-region edits, the grid docs/bounces.md
/// reports.
pub fn cornell_edits() -> Vec<(&'static str, [BlinnPhong; 2])> {
    let m = |kd: f32, ks: f32, ns: f32| BlinnPhong {
        kd: [kd; 3],
        ks: [ks; 3],
        ns,
    };
    vec![
        ("bake-time", [m(0.3, 0.3, 5.0), m(0.2, 0.4, 5.0)]),
        ("glossy ns 180", [m(0.3, 0.3, 180.0), m(0.2, 0.4, 180.0)]),
        ("Kd 1 / Ks 1", [m(1.0, 0.0, 1.0), m(0.0, 1.0, 1.0)]),
        (
            "Ks 1 ns 200 / Kd 1",
            [m(0.0, 1.0, 200.0), m(1.0, 0.0, 200.0)],
        ),
        ("Kd 0.9 walls", [m(0.9, 0.0, 1.0), m(0.2, 0.4, 5.0)]),
        ("black walls", [m(0.0, 0.0, 1.0), m(0.5, 0.5, 60.0)]),
        ("Kd .5 Ks .5 ns 60", [m(0.5, 0.5, 60.0), m(0.0, 1.0, 30.0)]),
        (
            "coloured",
            [
                BlinnPhong {
                    kd: [0.7, 0.2, 0.1],
                    ks: [0.1, 0.3, 0.5],
                    ns: 12.0,
                },
                m(0.4, 0.6, 100.0),
            ],
        ),
    ]
}

/// A Cornell-like box, open towards −Y, with an area light under the ceiling: regions
/// 0 "White walls" (editable), 1 "Object" (editable sphere), 2 "Red" and 3 "Green" (fixed).
pub fn cornell(size: u32) -> Scene {
    let s = 1.0;
    let meshes = vec![
        quad(
            "floor",
            [-s, -s, -s],
            [s, -s, -s],
            [s, s, -s],
            [-s, s, -s],
            0,
        ),
        quad("ceiling", [-s, -s, s], [-s, s, s], [s, s, s], [s, -s, s], 0),
        quad("back", [-s, s, -s], [s, s, -s], [s, s, s], [-s, s, s], 0),
        quad(
            "left",
            [-s, -s, -s],
            [-s, s, -s],
            [-s, s, s],
            [-s, -s, s],
            2,
        ),
        quad("right", [s, -s, -s], [s, -s, s], [s, s, s], [s, s, -s], 3),
        sphere("object", [0.0, 0.2, -0.55], 0.45, 16, 32, 1),
    ];
    Scene {
        meshes,
        regions: vec![
            region("White walls", true, bp(0.3, 0.3, 5.0)),
            region("Object", true, bp(0.2, 0.4, 5.0)),
            region("Red", false, bp_rgb([0.6, 0.05, 0.05], [0.0; 3], 1.0)),
            region("Green", false, bp_rgb([0.05, 0.5, 0.05], [0.0; 3], 1.0)),
        ],
        lights: vec![Light::Area {
            position: [0.0, 0.0, 0.98],
            axis_u: [1.0, 0.0, 0.0],
            axis_v: [0.0, 1.0, 0.0],
            shape: AreaShape::Square,
            size_x: 0.5,
            size_y: None,
            power: 40.0,
            color: [1.0, 1.0, 1.0],
            visible_camera: false,
        }],
        world: World::Color {
            color: [0.0; 3],
            strength: 1.0,
        },
        camera: look_at([0.0, -3.9, 0.0], [0.0, 0.0, 0.0], 35.0),
        resolution: Resolution {
            width: size,
            height: size,
        },
        light_groups: Vec::new(),
    }
}

/// Pixel indices (row-major) well inside the silhouette of [`furnace`]'s sphere: the unit
/// sphere at distance 4 with a 50 mm lens covers the central ~40 % of the frame.
pub fn inside_furnace_sphere(size: u32) -> Vec<usize> {
    let c = size as f32 / 2.0;
    let r = 0.2 * size as f32;
    let mut v = Vec::new();
    for y in 0..size {
        for x in 0..size {
            let (dx, dy) = (x as f32 + 0.5 - c, y as f32 + 0.5 - c);
            if dx * dx + dy * dy < r * r {
                v.push((y * size + x) as usize);
            }
        }
    }
    v
}

/// A smooth sphere alone in a uniform white world (a white furnace).
pub fn furnace(material: MaterialSpec, editable: bool, size: u32) -> Scene {
    Scene {
        meshes: vec![sphere("ball", [0.0, 0.0, 0.0], 1.0, 48, 96, 0)],
        regions: vec![region("Ball", editable, material)],
        lights: vec![],
        world: World::Color {
            color: [1.0; 3],
            strength: 1.0,
        },
        camera: look_at([0.0, -4.0, 0.0], [0.0, 0.0, 0.0], 50.0),
        resolution: Resolution {
            width: size,
            height: size,
        },
        light_groups: Vec::new(),
    }
}

/// The Cornell box with a second (coloured point) light and a dim world, at `size`².
pub fn cornell_two_lights(size: u32) -> Scene {
    let mut scene = cornell(size);
    if let Light::Area { color, .. } = &mut scene.lights[0] {
        *color = [1.0, 0.9, 0.7];
    }
    scene.lights.push(Light::Point {
        position: [0.5, -0.5, 0.3],
        power: 8.0,
        color: [0.3, 0.5, 1.0],
        radius: 0.05,
    });
    scene.world = World::Color {
        color: [0.02, 0.02, 0.03],
        strength: 1.0,
    };
    scene
}

/// The relight coefficients of `scene`'s editable regions at their bake-time materials, on
/// the bases `header` records.
pub fn bake_material_coefs(header: &StackHeader, scene: &Scene) -> Vec<Vec<Rgb>> {
    let bases = StackBases::from_header(header).unwrap();
    let materials: Vec<_> = scene
        .regions
        .iter()
        .filter(|r| r.editable)
        .map(|r| r.material.clone())
        .collect();
    bases.coefficients(&materials).unwrap()
}

/// `stack` relit on the CPU with the bake-time materials of `scene`'s editable regions.
pub fn relight_at_bake_materials(stack: &TransferStack, scene: &Scene) -> Vec<f32> {
    let coefs = bake_material_coefs(&stack.header, scene);
    relume_engine::relight::CpuRelighter::new(std::sync::Arc::new(stack.clone()))
        .unwrap()
        .relight(&coefs)
        .unwrap()
        .to_vec()
}

/// [`cornell`] at `size` scaled by `s` in length (walls, light, camera position and clip
/// start) with the light's power scaled by s², so the image stays the same.
pub fn cornell_scaled(size: u32, s: f32) -> Scene {
    let mut scene = cornell(size);
    for mesh in &mut scene.meshes {
        for p in &mut mesh.positions {
            p.iter_mut().for_each(|c| *c *= s);
        }
    }
    for light in &mut scene.lights {
        if let Light::Area {
            position,
            size_x,
            power,
            ..
        } = light
        {
            position.iter_mut().for_each(|c| *c *= s);
            *size_x *= s;
            *power *= s * s;
        }
    }
    for row in &mut scene.camera.matrix_world[..3] {
        row[3] *= s;
    }
    scene.camera.clip_start *= s;
    scene
}

"""A row of Principled spheres on a grey floor before a light wall, lit by one area light:
the scene on which materials are compared with Cycles one by one (test_principled_fit.py,
bench_editable_spheres.py). Each sphere is an object of its own with a material of its own,
so a material-ID render (`support.cycles.material_ids`) tells their pixels apart."""

from __future__ import annotations

import bpy

from support import cycles as cy
from support.scenes import add_camera_and_black_world, principled_material, quad

#: Where the area light stands: "front" above the camera (light and view close: the
#: highlights face the camera), "side" to the right at the spheres' height (light and view
#: about 90° apart, highlights near the silhouettes).
LIGHTS = {"front": (0.5, -2.0, 3.0), "side": (3.0, 0.3, 1.2)}


def per_material(image, ids, names: list[str]) -> dict[str, float]:
    """Per material (object) of a material-ID image (`support.cycles.material_ids`) the sum
    of `image` over its pure pixels: its mean brightness times its pixel count."""
    return {name: float(image[ids == k].sum()) for k, name in enumerate(names) if (ids == k).sum() > 0}


def sphere(name, centre, radius, material, segments=48, rings=24):
    """A smooth-shaded UV sphere object `name` with `material`."""
    verts, faces = cy.uv_sphere(centre, radius, segments=segments, rings=rings)
    return cy.mesh_object(name, verts, faces, material, smooth=True)


def build_scene(light_at: str, spheres, resolution: int, editable_spheres: bool = False):
    """`spheres` — (name, base colour, metallic, roughness) each — in a row (radius 0.3,
    0.7 m apart, centred) on a grey floor before a light wall, one area light at
    `LIGHTS[light_at]` aimed at the row's centre, a square `resolution`² camera. The floor is
    editable (diffuse, roughness window 0.9–1) so every scene has an editable region; the
    spheres are editable when `editable_spheres` is set, with the add-on's default window."""
    scene = bpy.context.scene
    floor = cy.diffuse_material("Floor", (0.5, 0.5, 0.5), editable=True)
    floor.relume.use_roughness_range = True
    floor.relume.roughness_min = 0.9
    floor.relume.roughness_max = 1.0
    wall = cy.diffuse_material("Wall", (0.6, 0.55, 0.5))
    s = 4.0
    quad("Floor", [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], floor)
    quad("Wall", [(-s, 1.2, 0), (s, 1.2, 0), (s, 1.2, 3.0), (-s, 1.2, 3.0)], wall)
    first = -0.35 * (len(spheres) - 1)
    for k, (name, colour, metallic, roughness) in enumerate(spheres):
        material = principled_material(name, colour, roughness=roughness, metallic=metallic,
                                       editable=editable_spheres)
        sphere(name, (first + 0.7 * k, 0.0, 0.3), 0.3, material)
    add_camera_and_black_world(scene, resolution, 35, (0.0, -4.2, 1.6), (75, 0, 0))
    data = bpy.data.lights.new("Area", "AREA")
    data.energy = 400.0
    data.shape = "RECTANGLE"
    data.size = 2.0
    data.size_y = 1.0
    light = bpy.data.objects.new("Area", data)
    light.location = LIGHTS[light_at]
    cy.aim_at(light, (0.0, 0.0, 0.3))
    scene.collection.objects.link(light)
    bpy.context.view_layer.update()
    return scene

"""Small test scenes built with bpy: a closed box with a sphere, lit by an area light."""

from __future__ import annotations

import math

import bpy


def clear_scene() -> None:
    """Remove every object and the datablocks tests create, keeping the scene itself."""
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights,
                 bpy.data.cameras, bpy.data.images, bpy.data.worlds):
        for item in list(coll):
            coll.remove(item)


def principled_material(name: str, color, roughness=0.5, metallic=0.0, editable=False):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    node = mat.node_tree.nodes["Principled BSDF"]
    node.inputs["Base Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = roughness
    node.inputs["Metallic"].default_value = metallic
    if editable:
        mat.relume.editable = True
    return mat


def quad(name, corners, material):
    """A one-sided quad object `name` with `corners` (counter-clockwise seen from its front)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def box_scene(resolution: int = 48, light_power: float = 60.0):
    """A 2 m box open to the camera, a sphere on the floor (editable "Ball"), an editable
    "Floor", fixed coloured walls, a square area light under the ceiling."""
    scene = bpy.context.scene
    floor = principled_material("Floor", (0.7, 0.7, 0.7), roughness=0.6, editable=True)
    walls = principled_material("Walls", (0.75, 0.75, 0.75), roughness=1.0)
    red = principled_material("Red", (0.7, 0.1, 0.1), roughness=1.0)
    green = principled_material("Green", (0.1, 0.6, 0.1), roughness=1.0)
    ball = principled_material("Ball", (0.2, 0.3, 0.8), roughness=0.4, editable=True)
    s = 1.0
    quad("FloorQuad", [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], floor)
    quad("Ceiling", [(-s, -s, 2), (-s, s, 2), (s, s, 2), (s, -s, 2)], walls)
    quad("Back", [(-s, s, 0), (s, s, 0), (s, s, 2), (-s, s, 2)], walls)
    quad("Left", [(-s, -s, 0), (-s, s, 0), (-s, s, 2), (-s, -s, 2)], red)
    quad("Right", [(s, -s, 0), (s, -s, 2), (s, s, 2), (s, s, 0)], green)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(0.2, 0.2, 0.4), segments=24, ring_count=12)
    sphere = bpy.context.active_object
    sphere.name = "Sphere"
    sphere.data.materials.append(ball)
    bpy.ops.object.shade_smooth()
    light_data = bpy.data.lights.new("Key", "AREA")
    light_data.energy = light_power
    light_data.size = 0.5
    light = bpy.data.objects.new("Key", light_data)
    light.location = (0.0, 0.0, 1.95)
    scene.collection.objects.link(light)
    add_camera_and_black_world(scene, resolution, 30, (0.0, -3.6, 1.0), (90, 0, 0))
    return scene


def two_light_box(resolution: int = 32):
    """`box_scene` with a second light: a bluish point light "Fill" low in the front left,
    so the two lights' images differ in colour and in where they fall."""
    scene = box_scene(resolution=resolution, light_power=40.0)
    data = bpy.data.lights.new("Fill", "POINT")
    data.energy = 30.0
    data.color = (0.4, 0.6, 1.0)
    data.shadow_soft_size = 0.05
    fill = bpy.data.objects.new("Fill", data)
    fill.location = (-0.6, -0.5, 0.6)
    scene.collection.objects.link(fill)
    bpy.context.view_layer.update()
    return scene


def save_and_reopen(addon) -> dict:
    """Saves the .blend, drops the add-on's loaded stack and opens the file again, as a user
    reopening their file would; returns the add-on's status afterwards."""
    bpy.ops.wm.save_mainfile()
    path = bpy.data.filepath
    addon.runtime.RUNTIME.live.unload()
    bpy.ops.wm.open_mainfile(filepath=path)
    return addon.api.status()


def add_camera_and_black_world(scene, resolution: int, lens: float, location, rotation_deg):
    """A camera "Cam" (focal length `lens` mm, at `location`, Euler XYZ `rotation_deg` in
    degrees) made the scene's camera, a square `resolution`² render, and a black world: the
    framing every test scene here shares."""
    cam_data = bpy.data.cameras.new("Cam")
    cam_data.lens = lens
    cam = bpy.data.objects.new("Cam", cam_data)
    cam.location = location
    cam.rotation_euler = tuple(math.radians(a) for a in rotation_deg)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x = resolution
    scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    scene.world = world
    bpy.context.view_layer.update()

"""Build a Blender scene from a Relume scene file (assets/*.scene.json), for the tests.

The assets scenes are written in Relume's own format; these tests need them as Blender
scenes (bake from the add-on, render with Cycles). Regions become materials: a Blinn–Phong
region with Ks = 0 is a Diffuse BSDF (which the exporter maps exactly back to Kd), any other
region a Principled BSDF with the closest roughness plus the add-on's Blinn–Phong override
holding its exact Kd, Ks and ns (so an editable region relights with the file's values).
Lights, world colour, camera and resolution carry over with the same conventions (Z up,
W and W/m², the lamp's −Z as its direction).
"""

from __future__ import annotations

import json
import math
import pathlib

import bpy
import mathutils


def _matrix_from_axes(position, x_axis, y_axis) -> mathutils.Matrix:
    x = mathutils.Vector(x_axis).normalized()
    y = mathutils.Vector(y_axis).normalized()
    z = x.cross(y).normalized()
    m = mathutils.Matrix.Identity(4)
    for row in range(3):
        m[row][0], m[row][1], m[row][2], m[row][3] = x[row], y[row], z[row], position[row]
    return m


def _matrix_pointing(position, direction) -> mathutils.Matrix:
    """A lamp matrix whose local −Z is `direction`."""
    d = mathutils.Vector(direction).normalized()
    rot = (-d).to_track_quat("Z", "Y").to_matrix().to_4x4()
    rot.translation = mathutils.Vector(position)
    return rot


def diffuse_version(m: dict) -> dict:
    """The material made diffuse with the same total albedo: Blinn–Phong Kd + Ks (clamped to
    1), Principled its base colour; Ks = 0."""
    if m["model"] != "blinn_phong":
        return {"model": "blinn_phong", "kd": list(m["base_color"]), "ks": [0.0, 0.0, 0.0], "ns": 1.0}
    kd = [min(1.0, a + b) for a, b in zip(m["kd"], m["ks"], strict=True)]
    return {"model": "blinn_phong", "kd": kd, "ks": [0.0, 0.0, 0.0], "ns": 1.0}


def _material(region: dict, diffuse_only: bool = False) -> bpy.types.Material:
    mat = bpy.data.materials.new(region["name"])
    mat.use_nodes = True
    tree = mat.node_tree
    m = diffuse_version(region["material"]) if diffuse_only else region["material"]
    out = tree.nodes["Material Output"]
    if diffuse_only and region.get("editable", False):
        # Relume relights an editable region with the override (Kd, Ks = 0); the node tree
        # below (a Diffuse BSDF of the same Kd) is what Cycles renders and what the bake saw.
        mat.relume.kd = m["kd"]
        mat.relume.ks = (0.0, 0.0, 0.0)
        mat.relume.ns = 1.0
        mat.relume.override = True
    if m["model"] == "blinn_phong" and max(m["ks"]) == 0.0:
        tree.nodes.remove(tree.nodes["Principled BSDF"])
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (*m["kd"], 1.0)
        diffuse.inputs["Roughness"].default_value = 0.0
        tree.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
    elif m["model"] == "blinn_phong":
        node = tree.nodes["Principled BSDF"]
        node.inputs["Base Color"].default_value = (*m["kd"], 1.0)
        alpha = math.sqrt(2.0 / (float(m["ns"]) + 2.0))  # ns = 2/α² − 2 inverted
        node.inputs["Roughness"].default_value = math.sqrt(alpha)
        mat.relume.kd = m["kd"]
        mat.relume.ks = m["ks"]
        mat.relume.ns = float(m["ns"])
        mat.relume.override = True
    else:
        node = tree.nodes["Principled BSDF"]
        node.inputs["Base Color"].default_value = (*m["base_color"], 1.0)
        node.inputs["Metallic"].default_value = m.get("metallic", 0.0)
        node.inputs["Roughness"].default_value = m.get("roughness", 0.5)
        node.inputs["IOR"].default_value = m.get("ior", 1.5)
        node.inputs["Specular IOR Level"].default_value = m.get("specular_ior_level", 0.5)
    mat.relume.editable = bool(region.get("editable", False))
    return mat


def _light(i: int, light: dict) -> None:
    kind = light["type"]
    colour = light.get("color", [1.0, 1.0, 1.0])
    if kind == "area":
        data = bpy.data.lights.new(f"Light {i}", "AREA")
        data.shape = light["shape"].upper()
        data.size = light["size_x"]
        data.size_y = light.get("size_y", light["size_x"])
        data.energy = light["power"]
        matrix = _matrix_from_axes(light["position"], light["axis_u"], light["axis_v"])
    elif kind in ("point", "spot"):
        data = bpy.data.lights.new(f"Light {i}", kind.upper())
        data.energy = light["power"]
        data.shadow_soft_size = light.get("radius", 0.0)
        if kind == "spot":
            data.spot_size = light["spot_size"]
            data.spot_blend = light.get("spot_blend", 0.0)
            matrix = _matrix_pointing(light["position"], light["direction"])
        else:
            matrix = mathutils.Matrix.Translation(light["position"])
    elif kind == "sun":
        data = bpy.data.lights.new(f"Light {i}", "SUN")
        data.energy = light["strength"]
        data.angle = light.get("angle", 0.0)
        matrix = _matrix_pointing((0.0, 0.0, 10.0), light["direction"])
    else:
        raise ValueError(f"light type {kind!r} is not imported by the tests")
    data.color = colour
    obj = bpy.data.objects.new(f"Light {i}", data)
    obj.matrix_world = matrix
    bpy.context.scene.collection.objects.link(obj)


def _equirect_image(image: dict, base: pathlib.Path) -> bpy.types.Image:
    """A float Blender image (scene linear) from a scene file's Image (inline or path)."""
    import numpy as np

    if "rgb" in image:
        w, h = int(image["width"]), int(image["height"])
        rgb = np.asarray(image["rgb"], dtype=np.float32).reshape(h, w, 3)
    else:
        import relume

        path = pathlib.Path(image["path"])
        rgba = np.asarray(relume.read_exr(str(path if path.is_absolute() else base / path)))
        h, w = rgba.shape[:2]
        rgb = rgba[..., :3].astype(np.float32)
    img = bpy.data.images.new("Relume test sky", w, h, alpha=False, float_buffer=True)
    img.colorspace_settings.name = "Linear Rec.709"
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb[::-1]  # the file is top row first, Blender bottom row first
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    return img


def set_world(data_world: dict, base: pathlib.Path = pathlib.Path(".")) -> bpy.types.World:
    """The scene's world: a Background colour, or an Environment Texture (equirectangular,
    Blender's default mapping, linear interpolation) for an `equirect` world."""
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    w = data_world
    kind = w.get("type", "color")
    if kind == "color":
        bg.inputs["Color"].default_value = (*w["color"], 1.0)
    elif kind == "equirect":
        env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
        env.image = _equirect_image(w["image"], base)
        env.interpolation = "Linear"
        env.projection = "EQUIRECTANGULAR"
        world.node_tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    else:
        raise ValueError(f"world type {kind!r} is not imported by the tests")
    bg.inputs["Strength"].default_value = w.get("strength", 1.0)
    bpy.context.scene.world = world
    return world


def import_scene(path: str | pathlib.Path, resolution: tuple[int, int] | None = None,
                 diffuse_only: bool = False):
    """Add the scene file's meshes, materials, lights, world and camera to the current scene.

    `diffuse_only`: every region becomes diffuse with its total albedo (`diffuse_version`):
    a Diffuse BSDF in Blender, and editable regions also get the add-on's override with that
    Kd and Ks = 0 (so Relume relights them diffuse too)."""
    data = json.loads(pathlib.Path(path).read_text())
    scene = bpy.context.scene
    materials = [_material(r, diffuse_only) for r in data["regions"]]
    for mesh_data in data["meshes"]:
        mesh = bpy.data.meshes.new(mesh_data["name"])
        mesh.from_pydata([tuple(p) for p in mesh_data["positions"]], [],
                         [tuple(t) for t in mesh_data["indices"]])
        regions = mesh_data.get("triangle_regions")
        used = sorted(set(regions)) if regions else [mesh_data.get("region", 0)]
        for r in used:
            mesh.materials.append(materials[r])
        if regions:
            slot = {r: k for k, r in enumerate(used)}
            mesh.polygons.foreach_set("material_index", [slot[r] for r in regions])
        if mesh_data.get("normals"):
            mesh.shade_smooth()
        mesh.update()
        obj = bpy.data.objects.new(mesh_data["name"], mesh)
        scene.collection.objects.link(obj)
    for i, light in enumerate(data.get("lights", [])):
        _light(i, light)
    set_world(data.get("world", {"type": "color", "color": [0, 0, 0]}), pathlib.Path(path).parent)
    c = data["camera"]
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = "PERSP" if c["projection"] == "perspective" else "ORTHO"
    cam_data.lens = c.get("lens_mm", 50.0)
    cam_data.sensor_width = c.get("sensor_width_mm", 36.0)
    cam_data.sensor_height = c.get("sensor_height_mm", 24.0)
    cam_data.sensor_fit = c.get("sensor_fit", "auto").upper()
    cam_data.shift_x = c.get("shift_x", 0.0)
    cam_data.shift_y = c.get("shift_y", 0.0)
    cam_data.ortho_scale = c.get("ortho_scale", 6.0)
    cam_data.clip_start = c.get("clip_start", 0.1)
    cam_data.clip_end = c.get("clip_end", 100.0)
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.matrix_world = mathutils.Matrix(c["matrix_world"])
    scene.collection.objects.link(cam)
    scene.camera = cam
    w, h = resolution or (data["resolution"]["width"], data["resolution"]["height"])
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    bpy.context.view_layer.update()
    return scene

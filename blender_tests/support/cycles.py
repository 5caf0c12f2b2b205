"""Cycles as the reference for Relume's one-bounce images (the "Cycles agreement" tests).

What "the same image" means on both sides:

- **Light transport.** Relume bakes direct light at the eye hit plus one indirect bounce,
  with next-event estimation at the secondary hit. In Cycles that is `max_bounces = 1`:
  the camera hit is bounce 0 and gets direct light (NEE, MIS with the BSDF ray); the BSDF
  ray is bounce 1 and its hit gets NEE too; the path ends there (Blender's manual:
  "0 bounces: direct lighting only"). The per-type limits are set to the same value
  (a `diffuse_bounces` of 4 and `max_bounces` of 1 is the same thing, but saying it keeps
  the settings readable). `min_light_bounces` 0, no light path guiding.
- **Nothing biased.** Clamping off (Cycles defaults `sample_clamp_indirect` to 10), "Filter
  Glossy" (`blur_glossy`) 0, light-sampling threshold 0 and no light tree (a plain,
  unbiased light selection), adaptive sampling off (every pixel gets exactly `samples`),
  no denoising. Reflective caustics stay **on**: with diffuse materials they cannot occur,
  and with glossy ones Relume does keep diffuse → glossy paths (its secondary hit evaluates
  every basis, specular ones included), so turning them off in Cycles would remove light
  Relume has.
- **Pixel filter.** Relume's camera samples are uniform over the pixel square
  (`core/engine/src/geometry/camera.rs`, `ray(x + sx, y + sy)`): a box of one pixel. Cycles
  gets `pixel_filter_type = 'BOX'`, `filter_width = 1.0` (its default, Blackman–Harris of
  1.5 px, would blur edges by about half a pixel and show up as edge differences).
- **Lights.** Invisible to camera rays (`visible_camera = False`), as Relume's lights are;
  `use_soft_falloff` off (Cycles 4.x+ otherwise softens point/spot/area lights with a radius
  near surfaces); area spread 180° (the default, Lambertian).
- **Colour.** The render is written as a 32-bit float OpenEXR, which Blender writes in scene
  linear (the view transform applies to display and 8-bit files only; it is set to
  Standard anyway), and read back with `relume.read_exr` — no colour management on either
  side.
"""

from __future__ import annotations

import math
import pathlib
import time

import bpy
import numpy as np

from support.scenes import add_camera_and_black_world

#: Light-path limits `configure_cycles(bounces=None)` leaves at Blender's defaults.
BOUNCE_SETTINGS = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                   "volume_bounces", "transparent_max_bounces")


def configure_cycles(scene, samples: int, seed: int, bounces: int | None = 1,
                     threads: int = 2) -> None:
    """Cycles on the CPU, `bounces` indirect bounces (None: Blender's default light paths,
    12 in total and 4 diffuse / 4 glossy), unbiased, box filter, no denoising."""
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = int(samples)
    c.seed = int(seed)
    c.use_animated_seed = False
    c.use_adaptive_sampling = False
    c.use_denoising = False
    if bounces is None:
        rna = type(c).bl_rna.properties
        for k in BOUNCE_SETTINGS:
            setattr(c, k, rna[k].default)
    else:
        c.max_bounces = bounces
        c.diffuse_bounces = bounces
        c.glossy_bounces = bounces
        c.transmission_bounces = bounces
        c.volume_bounces = 0
        c.transparent_max_bounces = 8
    c.min_light_bounces = 0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.blur_glossy = 0.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.use_light_tree = False
    c.light_sampling_threshold = 0.0
    c.use_guiding = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    scene.render.film_transparent = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGBA"
    settings.exr_codec = "ZIP"
    for obj in scene.objects:
        if obj.type == "LIGHT":
            obj.visible_camera = False
            if hasattr(obj.data, "use_soft_falloff"):
                obj.data.use_soft_falloff = False


def render_cycles(scene, path: str | pathlib.Path, samples: int, seed: int,
                  bounces: int | None = 1):
    """Render with Cycles to a linear float EXR; returns (RGB image top row first, seconds)."""
    import relume

    configure_cycles(scene, samples, seed, bounces)
    scene.render.filepath = str(path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - t0
    image = relume.read_exr(str(path))
    return np.asarray(image, dtype=np.float64)[..., :3], seconds


def render_cycles_pair(scene, folder: str | pathlib.Path, name: str, samples: int,
                       bounces: int | None = 1):
    """Two independent Cycles renders of `samples` / 2 each (seeds 1 and 2): their mean is the
    reference, their difference its noise (`noise_of_mean`). Returns (first, second, seconds)."""
    folder = pathlib.Path(folder)
    c1, t1 = render_cycles(scene, folder / f"{name}_c1.exr", samples // 2, seed=1, bounces=bounces)
    c2, t2 = render_cycles(scene, folder / f"{name}_c2.exr", samples // 2, seed=2, bounces=bounces)
    return c1, c2, t1 + t2


def block_mean(image: np.ndarray, block: int) -> np.ndarray:
    """Means over `block` × `block` pixel tiles (the image's size must be a multiple)."""
    h, w, c = image.shape
    return image.reshape(h // block, block, w // block, block, c).mean(axis=(1, 3))


def at_size_of(image: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """`image` at the size `shape` (height, width first): a preset that bakes at a fraction of
    the render's resolution (draft: half) is compared, as it is shown, with each of its
    pixels repeated."""
    factor = shape[0] // image.shape[0]
    if factor > 1:
        image = np.repeat(np.repeat(image, factor, axis=0), factor, axis=1)
    assert image.shape[:2] == tuple(shape[:2]), (image.shape, shape)
    return image


def rel_l2(a: np.ndarray, reference: np.ndarray) -> float:
    """‖a − ref‖ / ‖ref‖ over every pixel and channel."""
    return float(np.linalg.norm(a - reference) / np.linalg.norm(reference))


def noise_of_mean(a: np.ndarray, b: np.ndarray) -> float:
    """Relative L2 noise of the mean of two independent renders a, b of equal sample count:
    Var(a − b) = 2σ² and the mean has σ²/2, so its noise is ‖a − b‖/2 over ‖mean‖."""
    m = 0.5 * (a + b)
    return float(np.linalg.norm(a - b) / 2.0 / np.linalg.norm(m))


def noise_of_one(a: np.ndarray, b: np.ndarray) -> float:
    """Relative L2 noise of one of two independent renders: ‖a − b‖/√2 over ‖mean‖."""
    m = 0.5 * (a + b)
    return float(np.linalg.norm(a - b) / math.sqrt(2.0) / np.linalg.norm(m))


# --- a small open scene for one light at a time ----------------------------------------------

def diffuse_material(name: str, color, editable: bool = False) -> bpy.types.Material:
    """A Diffuse BSDF (roughness 0: Lambertian); an editable one also gets the add-on's
    override with the same Kd and Ks = 0."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = 0.0
    tree.links.new(node.outputs["BSDF"], tree.nodes["Material Output"].inputs["Surface"])
    if editable:
        mat.relume.editable = True
        mat.relume.kd = color
        mat.relume.ks = (0.0, 0.0, 0.0)
        mat.relume.ns = 1.0
        mat.relume.override = True
    return mat


def mesh_object(name, verts, faces, material, smooth=False):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.materials.append(material)
    if smooth:
        mesh.shade_smooth()
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def uv_sphere(centre, radius, segments=32, rings=16):
    cx, cy, cz = centre
    verts = [(cx, cy, cz + radius)]
    for i in range(1, rings):
        t = math.pi * i / rings
        for j in range(segments):
            p = 2.0 * math.pi * j / segments
            verts.append((cx + radius * math.sin(t) * math.cos(p), cy + radius * math.sin(t) * math.sin(p),
                          cz + radius * math.cos(t)))
    verts.append((cx, cy, cz - radius))
    faces = []
    for j in range(segments):
        faces.append((0, 1 + j, 1 + (j + 1) % segments))
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        for j in range(segments):
            k = (j + 1) % segments
            faces.append((a + j, b + j, b + k, a + k))
    last = len(verts) - 1
    base = 1 + (rings - 2) * segments
    for j in range(segments):
        faces.append((base + j, last, base + (j + 1) % segments))
    return verts, faces


def open_scene(resolution: int) -> bpy.types.Scene:
    """A grey floor (6 m), a blue back wall, an orange sphere (editable, overridden diffuse)
    of radius 0.5 on the floor; camera from the front and above; no light, black world."""
    scene = bpy.context.scene
    floor = diffuse_material("Floor", (0.5, 0.5, 0.5))
    wall = diffuse_material("Wall", (0.2, 0.4, 0.7))
    ball = diffuse_material("Ball", (0.8, 0.5, 0.2), editable=True)
    s = 3.0
    mesh_object("Floor", [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [(0, 1, 2, 3)], floor)
    mesh_object("Wall", [(-s, 1.5, 0), (s, 1.5, 0), (s, 1.5, 2.5), (-s, 1.5, 2.5)], [(0, 1, 2, 3)], wall)
    verts, faces = uv_sphere((0.0, 0.0, 0.5), 0.5)
    mesh_object("Sphere", verts, faces, ball, smooth=True)
    add_camera_and_black_world(scene, resolution, 35, (0.0, -4.5, 2.2), (68, 0, 0))
    return scene


def aim_at(obj, target):
    """Turns `obj` (a light) so that it shines along its −Z axis towards `target`."""
    import mathutils

    d = mathutils.Vector(target) - obj.location
    obj.rotation_euler = (-d).to_track_quat("Z", "Y").to_euler()


def add_light(kind: str):
    """One light of `kind` for `open_scene`, with its parameters in the docstring's table:

    point  300 W at (1.2, −1.0, 2.6), radius 0.1 m (a sphere light in Cycles)
    spot   800 W at (−1.5, −1.5, 3.0) aimed at the sphere, size 50°, blend 0.3
    sun    4 W/m² travelling along (0.45, 0.35, −0.82), angle 2°
    area   250 W, 1.0 × 0.5 m rectangle at (0.3, −0.8, 2.4) aimed at the sphere
    """
    scene = bpy.context.scene
    if kind == "point":
        data = bpy.data.lights.new("Point", "POINT")
        data.energy = 300.0
        data.shadow_soft_size = 0.1
        obj = bpy.data.objects.new("Point", data)
        obj.location = (1.2, -1.0, 2.6)
    elif kind == "spot":
        data = bpy.data.lights.new("Spot", "SPOT")
        data.energy = 800.0
        data.shadow_soft_size = 0.0
        data.spot_size = math.radians(50.0)
        data.spot_blend = 0.3
        obj = bpy.data.objects.new("Spot", data)
        obj.location = (-1.5, -1.5, 3.0)
        aim_at(obj, (0.0, 0.0, 0.5))
    elif kind == "sun":
        data = bpy.data.lights.new("Sun", "SUN")
        data.energy = 4.0
        data.angle = math.radians(2.0)
        obj = bpy.data.objects.new("Sun", data)
        obj.location = (0.0, 0.0, 5.0)
        import mathutils

        d = mathutils.Vector((0.45, 0.35, -0.82)).normalized()
        obj.rotation_euler = (-d).to_track_quat("Z", "Y").to_euler()
    elif kind == "area":
        data = bpy.data.lights.new("Area", "AREA")
        data.energy = 250.0
        data.shape = "RECTANGLE"
        data.size = 1.0
        data.size_y = 0.5
        obj = bpy.data.objects.new("Area", data)
        obj.location = (0.3, -0.8, 2.4)
        aim_at(obj, (0.0, 0.0, 0.5))
    else:
        raise ValueError(kind)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return obj


def sky_image(width: int = 64, height: int = 32) -> dict:
    """A smooth equirectangular sky as a scene-file Image (inline, top row first): a blue
    gradient, a darker ground, and a broad warm "sun" blob (Gaussian, about 12° wide) low in
    the south-east, bright enough to cast a visible shadow."""
    import numpy as np

    rows = []
    sun = np.array([math.cos(math.radians(35)) * math.cos(math.radians(-40)),
                    math.cos(math.radians(35)) * math.sin(math.radians(-40)), math.sin(math.radians(35))])
    for j in range(height):
        v = 1.0 - (j + 0.5) / height
        theta = math.pi * (1.0 - v)  # from the zenith
        for i in range(width):
            u = (i + 0.5) / width
            phi = 2.0 * math.pi * (0.5 - u)  # atan2(y, x), Blender's mapping
            d = np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])
            z = d[2]
            if z >= 0:
                base = np.array([0.25, 0.45, 0.9]) * (0.4 + 0.6 * z) + np.array([0.5, 0.5, 0.45]) * (1 - z) ** 4
            else:
                base = np.array([0.12, 0.1, 0.08])
            ang = math.acos(max(-1.0, min(1.0, float(d @ sun))))
            blob = 40.0 * math.exp(-(ang / math.radians(6.0)) ** 2)
            rows.extend((base + blob * np.array([1.0, 0.85, 0.6])).tolist())
    return {"width": width, "height": height, "rgb": rows}


def material_ids(scene, path) -> tuple[np.ndarray, list[str]]:
    """Per pixel the index of the object it shows (-1: background or mixed), from a Cycles
    render with every object's material an Emission of value (index + 1)/64."""
    names = [o.name for o in scene.objects if o.type == "MESH"]
    saved = {}
    for k, name in enumerate(names):
        obj = bpy.data.objects[name]
        mat = bpy.data.materials.new(f"id {name}")
        mat.use_nodes = True
        tree = mat.node_tree
        tree.nodes.remove(tree.nodes["Principled BSDF"])
        em = tree.nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = ((k + 1) / 64.0, 0.0, 0.0, 1.0)
        em.inputs["Strength"].default_value = 1.0
        tree.links.new(em.outputs["Emission"], tree.nodes["Material Output"].inputs["Surface"])
        saved[name] = obj.data.materials[0]
        obj.data.materials[0] = mat
    try:
        image, _ = render_cycles(scene, path, 16, seed=1, bounces=0)
    finally:
        for name, mat in saved.items():
            bpy.data.objects[name].data.materials[0] = mat
        bpy.context.view_layer.update()
    value = image[..., 0] * 64.0 - 1.0
    ids = np.rint(value).astype(int)
    pure = (np.abs(value - ids) < 1e-3) & (image[..., 1] == 0.0) & (ids >= 0)
    ids[~pure] = -1
    # Keep pixels whose four neighbours show the same object.
    padded = np.pad(ids, 1, constant_values=-1)
    same = np.ones_like(pure)
    for dy, dx in ((0, 1), (2, 1), (1, 0), (1, 2)):
        same &= padded[dy:dy + ids.shape[0], dx:dx + ids.shape[1]] == ids
    ids[~same] = -1
    return ids, names

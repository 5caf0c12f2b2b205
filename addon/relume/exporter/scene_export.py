"""Blender scene → Relume scene: the one entry point of the exporter.

Regions are the materials the exported meshes use, sorted by name so the editable order —
which is the editable index in the stack's layer keys — is stable between exports. Objects
without a material share a "Relume Default" region (Blender's default grey). Images (Base
Color textures, environment maps) are written as OpenEXR files into `texture_dir` and
referenced by path; the core reads them back and hashes their pixels with the scene.

Blender's light groups (a light object's and the world's `lightgroup`) are written as the
scene file's `light_groups` whatever the Light Groups preference, so the scene — and its
hash — does not depend on how the next bake groups the lights; only a bake with "scene"
grouping keeps them apart (logic/light_groups.py says what happens to lights in none).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field

import numpy as np

from ..logic.camera_map import BlenderCamera, CameraError, map_camera
from ..logic.export_warnings import ExportWarning, WarningList
from ..logic.light_groups import scene_light_groups
from ..logic.lights_map import map_light
from ..logic.material_map import FALLBACK_PRINCIPLED, emission_of, map_material
from .geometry import collect_meshes
from .lights import read_light
from .nodes import active_output, image_rgb_linear, read_surface

DEFAULT_REGION = "Relume Default"


class ExportError(ValueError):
    """The scene cannot be exported (no camera, nothing to render...)."""


@dataclass
class ExportOptions:
    #: Fraction of the render resolution (× its percentage) the bake uses: 0.5 halves both sides.
    resolution_scale: float = 1.0
    #: Folder for textures written out of Blender images.
    texture_dir: str = ""
    #: [ns_min, ns_max] from a material's roughness range, by material name.
    ns_ranges: dict = field(default_factory=dict)


@dataclass
class ExportResult:
    scene: object  # relume.Scene
    scene_dict: dict  # the JSON part (meshes excluded), for inspection and the scene file
    warnings: list[ExportWarning]
    region_names: list[str]
    editable: list[str]
    material_of_region: dict  # region name → bpy material (None for the default region)
    triangle_count: int
    light_names: list[str] = field(default_factory=list)  # exported lights, in scene order
    #: The bounce cap Cycles renders this scene with (see `cycles_bounce_cap`).
    max_bounces: int = 12


def _sanitize(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name) or "image"


#: path → (digest of the pixels, size, mtime) of each image this session wrote: every export
#: (a bake, each stale check, each batch render's check) would otherwise write the same
#: images again, the largest share of its time after the meshes.
_WRITTEN: dict[str, tuple[bytes, int, int]] = {}


def _write_image(rgb: np.ndarray, texture_dir: str, stem: str) -> str:
    """Write `rgb` as `texture_dir/stem.exr`, unless this session wrote those very pixels
    there and the file is as it left it (same size and modification time)."""
    import relume

    os.makedirs(texture_dir, exist_ok=True)
    path = os.path.join(texture_dir, _sanitize(stem) + ".exr")
    pixels = np.ascontiguousarray(rgb)
    digest = hashlib.blake2b(pixels.view(np.uint8).reshape(-1), digest_size=16)
    digest.update(repr((pixels.shape, pixels.dtype.str)).encode())
    key = digest.digest()
    try:
        st = os.stat(path)
        if _WRITTEN.get(path) == (key, st.st_size, st.st_mtime_ns):
            return path
    except OSError:
        pass
    relume.write_exr(path, pixels)
    st = os.stat(path)
    _WRITTEN[path] = (key, st.st_size, st.st_mtime_ns)
    return path


def _world(scene, warnings: WarningList, texture_dir: str) -> dict | None:
    world = scene.world
    if world is None:
        return None
    subject = f"World '{world.name}'"
    tree = world.node_tree if getattr(world, "use_nodes", True) else None
    if tree is None:
        return {"type": "color", "color": [max(0.0, c) for c in world.color], "strength": 1.0}
    out = active_output(tree, "ShaderNodeOutputWorld")
    if out is None or not out.inputs["Surface"].is_linked:
        return None
    bg = out.inputs["Surface"].links[0].from_node
    if bg.bl_idname != "ShaderNodeBackground":
        warnings.add(subject, f"surface {bg.bl_idname}", "a black world")
        return None
    strength_sock = bg.inputs["Strength"]
    if strength_sock.is_linked:
        warnings.add(subject, "Strength linked", "strength 1")
    strength = 1.0 if strength_sock.is_linked else max(0.0, float(strength_sock.default_value))
    color_sock = bg.inputs["Color"]
    if color_sock.is_linked:
        src = color_sock.links[0].from_node
        if src.bl_idname == "ShaderNodeTexEnvironment" and src.image is not None:
            if src.inputs["Vector"].is_linked:
                warnings.add(subject, "a Mapping/vector input on the Environment Texture",
                             "Blender's default orientation (bake the rotation into the image)")
            if src.projection != "EQUIRECTANGULAR":
                warnings.add(subject, f"{src.projection} projection", "read as equirectangular")
            rgb, why = image_rgb_linear(src.image)
            if rgb is not None:
                if why:
                    warnings.add(subject, why, "used as is")
                path = _write_image(rgb, texture_dir, f"world_{world.name}")
                return {"type": "equirect", "image": {"path": path}, "strength": strength}
            warnings.add(subject, why, "the Background colour")
        else:
            warnings.add(subject, f"Color linked to {src.bl_idname}", "the Background socket's colour")
    colour = [max(0.0, float(c)) for c in list(color_sock.default_value)[:3]]
    return {"type": "color", "color": colour, "strength": strength}


def _camera(scene, warnings: WarningList) -> dict:
    cam_obj = scene.camera
    if cam_obj is None:
        raise ExportError("the scene has no active camera (Scene properties → Camera)")
    c = cam_obj.data
    return map_camera(BlenderCamera(
        name=cam_obj.name, type=c.type, matrix_world=[list(r) for r in cam_obj.matrix_world],
        lens=c.lens, sensor_width=c.sensor_width, sensor_height=c.sensor_height,
        sensor_fit=c.sensor_fit, shift_x=c.shift_x, shift_y=c.shift_y, ortho_scale=c.ortho_scale,
        clip_start=c.clip_start, clip_end=c.clip_end, use_dof=bool(c.dof.use_dof)), warnings)


#: Highest bounce count the core bakes (`relume_engine::bake::settings::MAX_BOUNCES`).
MAX_BOUNCES = 128


def cycles_light_paths(scene) -> tuple[int, int, int]:
    """(cap, diffuse, glossy): the scene's Cycles light path limits as Relume bakes them. The
    cap is Max Bounces, and no more than a path can take within both the Diffuse and the
    Glossy limit (their sum; Blender's defaults, 12 / 4 / 4, give 8), at most `MAX_BOUNCES`;
    the bake then counts each kind against its own limit as Cycles does (the core's
    `diffuse_bounces`, `glossy_bounces`), so a path that meets only diffuse surfaces still
    stops at 4. Blender's defaults when the scene has no Cycles settings."""
    c = getattr(scene, "cycles", None)
    total = int(getattr(c, "max_bounces", 12))
    diffuse = max(0, min(int(getattr(c, "diffuse_bounces", 4)), MAX_BOUNCES))
    glossy = max(0, min(int(getattr(c, "glossy_bounces", 4)), MAX_BOUNCES))
    return max(0, min(total, diffuse + glossy, MAX_BOUNCES)), diffuse, glossy


def cycles_bounce_cap(scene) -> int:
    """The bounce cap of `cycles_light_paths`."""
    return cycles_light_paths(scene)[0]


def bake_resolution(scene, scale: float) -> tuple[int, int]:
    r = scene.render
    f = r.resolution_percentage / 100.0 * scale
    return max(1, int(round(r.resolution_x * f))), max(1, int(round(r.resolution_y * f)))


def export_scene(context, options: ExportOptions) -> ExportResult:
    """Export the context's scene (evaluated depsgraph) to a `relume.Scene`."""
    import relume

    scene = context.scene
    depsgraph = context.evaluated_depsgraph_get()
    warnings = WarningList()
    try:
        camera = _camera(scene, warnings)
    except CameraError as e:
        raise ExportError(str(e)) from None

    # Regions: collect materials first (names sorted for a stable editable order).
    materials: dict[str, object] = {}
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type in ("MESH", "CURVE", "SURFACE", "META", "FONT") and not obj.original.hide_render:
            slots = [s.material for s in obj.material_slots]
            if not slots or any(m is None for m in slots):
                materials.setdefault(DEFAULT_REGION, None)
            for m in slots:
                if m is not None:
                    materials.setdefault(m.original.name, m.original)
    if not materials:
        raise ExportError("nothing to bake: no visible mesh object in the scene")
    names = sorted(n for n in materials if n != DEFAULT_REGION)
    if DEFAULT_REGION in materials:
        names.append(DEFAULT_REGION)
    index = {n: i for i, n in enumerate(names)}

    def region_of(mat) -> int:
        return index[mat.original.name] if mat is not None else index[DEFAULT_REGION]

    regions = []
    textured_regions = set()
    emissive = []  # (region index, material name, (colour, strength))
    for n in names:
        mat = materials[n]
        if mat is None:
            regions.append({"name": n, "editable": False, "material": dict(FALLBACK_PRINCIPLED)})
            continue
        surface = read_surface(mat)
        material, textured = map_material(surface, warnings)
        props = getattr(mat, "relume", None)
        editable = bool(props.editable) if props is not None else False
        region = {"name": n, "editable": editable, "material": material}
        if textured:
            rgb, why = image_rgb_linear(surface.base_color_image)
            if rgb is None:
                warnings.add(f"Material '{n}'", why, "the Base Color socket's colour")
                region["material"]["base_color"] = [max(0.0, float(c)) for c in
                                                     list(surface.values.get("Base Color", (0.8, 0.8, 0.8)))[:3]]
            else:
                if why:
                    warnings.add(f"Material '{n}'", why, "used as is")
                path = _write_image(rgb, options.texture_dir, f"material_{n}")
                region["albedo_texture"] = {"path": path}
                textured_regions.add(index[n])
        if not editable and material.get("subsurface_weight", 0.0) > 0.0:
            warnings.add(f"Material '{n}'", "subsurface scattering on a material that is not Editable",
                         "an opaque surface (tick Editable to bake its translucency)")
            for k in ("subsurface_weight", "subsurface_radius", "subsurface_scale"):
                region["material"].pop(k, None)
        if editable and n in options.ns_ranges:
            region["ns_range"] = list(options.ns_ranges[n])
        emission = emission_of(surface, warnings)
        if emission is not None:
            emissive.append((index[n], n, emission))
        regions.append(region)

    meshes = collect_meshes(depsgraph, region_of, warnings)
    if not meshes:
        raise ExportError("nothing to bake: the visible objects have no faces")

    lights, light_names, light_groups = [], [], []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "LIGHT" and not obj.original.hide_render:
            blender_light = read_light(obj.original, inst.matrix_world)
            mapped = map_light(blender_light, warnings)
            if mapped is not None:
                lights.append(mapped)
                light_names.append(blender_light.name)
                light_groups.append(blender_light.lightgroup)
    # Emissive materials are lights of their region's triangles, seen by the camera as Cycles
    # shows them (per material: an object's own camera visibility and light group are not
    # read for emission; they go to the default group).
    for region_index, n, (colour, strength) in emissive:
        lights.append({"type": "emissive", "region": region_index, "strength": strength,
                       "color": colour, "visible_camera": True})
        light_names.append(f"{n} (emission)")
        light_groups.append("")

    if abs(scene.render.pixel_aspect_x - scene.render.pixel_aspect_y) > 1e-6:
        warnings.add(f"Scene '{scene.name}'", "non-square pixel aspect", "square pixels")
    width, height = bake_resolution(scene, options.resolution_scale)
    scene_dict = {
        "format": "relume-scene", "meshes": [], "regions": regions,
        "lights": lights, "camera": camera, "resolution": {"width": width, "height": height},
    }
    # Version 2 adds translucency; a scene without it stays a version-1 file (older cores
    # read it).
    translucent = any("subsurface_weight" in r["material"] for r in regions)
    # Version 3 adds emitters the camera sees and emissive surfaces.
    emitters = any(li.get("type") == "emissive" or li.get("visible_camera") for li in lights)
    scene_dict["version"] = 3 if emitters else 2 if translucent else 1
    world = _world(scene, warnings, options.texture_dir)
    if world is not None:
        scene_dict["world"] = world
    world_group = str(getattr(scene.world, "lightgroup", "")) if world is not None else None
    groups = scene_light_groups(light_groups, world_group)
    if groups:  # none: the key is left out, as older add-ons wrote it (same scene hash)
        scene_dict["light_groups"] = groups
    if not lights and (world is None or _world_is_black(world)):
        warnings.add(f"Scene '{scene.name}'", "no light and a black world", "a black image")

    rs = relume.Scene.from_json(json.dumps(scene_dict), options.texture_dir or ".")
    triangles = 0
    for m in meshes:
        uvs = m.uvs
        if uvs is None and np.isin(m.triangle_regions, list(textured_regions)).any():
            warnings.add(f"Object '{m.name}'", "a textured material but no UV map",
                         "UV (0, 0) everywhere (the texture's corner colour)")
            uvs = np.zeros((len(m.positions), 2), np.float32)
        rs.add_mesh(m.name, m.positions, m.indices, normals=m.normals, uvs=uvs,
                    triangle_regions=m.triangle_regions)
        triangles += len(m.indices)
    rs.validate()
    return ExportResult(
        scene=rs, scene_dict=scene_dict, warnings=warnings.items(), region_names=names,
        editable=[r["name"] for r in regions if r["editable"]],
        material_of_region={n: materials[n] for n in names}, triangle_count=triangles,
        light_names=light_names, max_bounces=cycles_bounce_cap(scene))


def _world_is_black(world: dict) -> bool:
    return world.get("type") == "color" and (max(world["color"]) <= 0 or world.get("strength", 1) <= 0)



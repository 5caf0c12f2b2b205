"""The exporter against Blender's own data: geometry, regions, camera, lights, warnings."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from support.scenes import box_scene


def _world_triangles():
    """Blender's own world-space triangles (through loop_triangles), as a sorted array."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    tris = []
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH":
            continue
        ev = obj.evaluated_get(depsgraph)
        mesh = ev.to_mesh()
        mesh.calc_loop_triangles()
        m = np.array(obj.matrix_world)
        for t in mesh.loop_triangles:
            pts = [m[:3, :3] @ np.array(mesh.vertices[v].co) + m[:3, 3] for v in t.vertices]
            tris.append(np.concatenate(sorted(pts, key=lambda p: tuple(np.round(p, 5)))))
        ev.to_mesh_clear()
    return np.array(sorted(tris, key=lambda r: tuple(np.round(r, 5))))


def test_geometry_regions_camera_lights_match_blender(addon, prefs, blend_dir):
    box_scene(resolution=40)
    result = addon.api.export()
    scene = result.scene
    blender_tris = _world_triangles()
    assert scene.triangle_count == len(blender_tris) == result.triangle_count

    # Regions: one per material, sorted by name, editable flags from the material panel.
    assert result.region_names == ["Ball", "Floor", "Green", "Red", "Walls"]
    assert result.editable == ["Ball", "Floor"]
    assert scene.editable_regions == ["Ball", "Floor"]

    # Positions: the exported meshes hold exactly Blender's world-space triangles.
    exported = []
    depsgraph = bpy.context.evaluated_depsgraph_get()
    meshes = addon.exporter.geometry.collect_meshes(depsgraph, lambda m: 0, addon.logic.export_warnings.WarningList())
    for m in meshes:
        for tri in m.indices:
            pts = [m.positions[i].astype(np.float64) for i in tri]
            exported.append(np.concatenate(sorted(pts, key=lambda p: tuple(np.round(p, 5)))))
            # Shading normals are unit and on the triangle's front side.
            n = m.normals[tri]
            assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    exported = np.array(sorted(exported, key=lambda r: tuple(np.round(r, 5))))
    assert exported.shape == blender_tris.shape
    assert np.abs(exported - blender_tris).max() < 1e-5

    # Camera: Blender's matrix (no scale here), lens and sensor.
    cam = bpy.context.scene.camera
    exported_cam = result.scene_dict["camera"]
    assert np.allclose(np.array(exported_cam["matrix_world"]), np.array(cam.matrix_world), atol=1e-6)
    assert exported_cam["lens_mm"] == pytest.approx(cam.data.lens)
    assert exported_cam["sensor_width_mm"] == pytest.approx(cam.data.sensor_width)
    assert result.scene_dict["resolution"] == {"width": 40, "height": 40}

    # Light: Cycles units carried over as they are (W), axes from the object's matrix.
    (light,) = result.scene_dict["lights"]
    key = bpy.data.objects["Key"]
    assert light["type"] == "area" and light["shape"] == "square"
    assert light["power"] == pytest.approx(key.data.energy)
    assert light["size_x"] == pytest.approx(key.data.size)
    assert np.allclose(light["position"], list(key.matrix_world.translation))
    emit = -np.cross(light["axis_u"], light["axis_v"])
    assert np.allclose(emit, -np.array(key.matrix_world.col[2][:3]), atol=1e-6)  # local −Z


def test_scaled_rotated_light_and_camera_scale(addon, prefs, blend_dir):
    box_scene(resolution=32)
    key = bpy.data.objects["Key"]
    key.scale = (2.0, 3.0, 1.0)
    key.data.shape = "RECTANGLE"
    key.data.size, key.data.size_y = 0.2, 0.1
    key.data.exposure = 1.0
    cam = bpy.context.scene.camera
    cam.scale = (2.0, 2.0, 2.0)
    bpy.context.view_layer.update()
    result = addon.api.export()
    (light,) = result.scene_dict["lights"]
    assert light["size_x"] == pytest.approx(0.4, rel=1e-6)
    assert light["size_y"] == pytest.approx(0.3, rel=1e-6)
    assert light["power"] == pytest.approx(2.0 * key.data.energy)  # exposure 1 = ×2
    rot = np.array(result.scene_dict["camera"]["matrix_world"])[:3, :3]
    assert np.allclose(rot.T @ rot, np.eye(3), atol=1e-6)  # scale normalised away


def test_point_spot_sun_units(addon, prefs, blend_dir):
    box_scene(resolution=16)
    for kind, energy in (("POINT", 100.0), ("SPOT", 50.0), ("SUN", 3.0)):
        data = bpy.data.lights.new(kind.lower(), kind)
        data.energy = energy
        data.color = (1.0, 0.5, 0.25)
        obj = bpy.data.objects.new(kind.lower(), data)
        obj.location = (0.1, -0.2, 1.5)
        obj.rotation_euler = (math.radians(30), 0, 0)
        bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    lights = {light["type"]: light for light in addon.api.export().scene_dict["lights"]}
    assert lights["point"]["power"] == pytest.approx(100.0)
    assert lights["point"]["color"] == pytest.approx([1.0, 0.5, 0.25])
    assert lights["spot"]["spot_size"] == pytest.approx(bpy.data.lights["spot"].spot_size)
    assert lights["sun"]["strength"] == pytest.approx(3.0)
    down = -np.array(bpy.data.objects["sun"].matrix_world.col[2][:3])
    assert np.allclose(lights["sun"]["direction"], down / np.linalg.norm(down), atol=1e-6)


def test_unsupported_nodes_warn_by_name(addon, prefs, blend_dir):
    box_scene(resolution=16)
    glass = bpy.data.materials.new("GlassThing")
    glass.use_nodes = True
    nodes = glass.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    g = nodes.new("ShaderNodeBsdfGlass")
    glass.node_tree.links.new(g.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    bpy.data.objects["Sphere"].data.materials[0] = glass
    wall = bpy.data.materials["Walls"].node_tree.nodes["Principled BSDF"]
    wall.inputs["Transmission Weight"].default_value = 0.5
    wall.inputs["Emission Strength"].default_value = 2.0
    wall.inputs["Emission Color"].default_value = (1, 1, 1, 1)
    bpy.context.view_layer.update()
    result = addon.api.export()
    text = [str(w) for w in result.warnings]
    assert any("Material 'GlassThing'" in t and "ShaderNodeBsdfGlass" in t and "grey" in t for t in text), text
    assert any("Material 'Walls'" in t and "Transmission Weight" in t for t in text), text
    # Emission is exported as a light of the region (scene format 3), not dropped.
    assert not any("Material 'Walls'" in t and "emission" in t.lower() for t in text), text
    walls = result.region_names.index("Walls")
    emissive = [li for li in result.scene_dict["lights"] if li["type"] == "emissive"]
    assert emissive == [{"type": "emissive", "region": walls, "strength": 2.0, "color": [1.0, 1.0, 1.0],
                         "visible_camera": True}], emissive
    assert result.scene_dict["version"] == 3
    # The fallback is what the warning says: Blender's default grey Principled.
    region = next(r for r in result.scene_dict["regions"] if r["name"] == "GlassThing")
    assert region["material"]["base_color"] == [0.8, 0.8, 0.8]


def test_no_camera_is_a_clear_error(addon, prefs, blend_dir):
    box_scene(resolution=16)
    bpy.context.scene.camera = None
    with pytest.raises(addon.exporter.scene_export.ExportError, match="no active camera"):
        addon.api.export()
    with pytest.raises(RuntimeError, match="no active camera"):  # the operator's error report
        bpy.ops.relume.export_scene(filepath=str(blend_dir / "x.scene.json"))
    assert not (blend_dir / "x.scene.json").exists()


def test_scene_file_written_for_the_command_line(addon, prefs, blend_dir):
    import relume

    box_scene(resolution=16)
    path = blend_dir / "box.scene.json"
    assert bpy.ops.relume.export_scene(filepath=str(path)) == {"FINISHED"}
    loaded = relume.Scene.load(str(path))
    assert loaded.hash() == addon.api.export().scene.hash()


def test_split_vertices_number_as_np_unique_does(addon, blend_dir):
    """The exporter's split of vertices by (vertex, normal, uv) numbers them exactly as
    `np.unique(axis=0)` did, so stacks baked before it still match their scene's hash:
    on Blender's own corners (a shaded sphere with flat faces and UV seams) and on keys with
    many ties and a negative zero."""
    from importlib import import_module

    split_vertices = import_module(addon.__name__ + ".exporter.geometry").split_vertices
    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12)
    obj = bpy.context.active_object
    for i, poly in enumerate(obj.data.polygons):
        poly.use_smooth = i % 3 != 0
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    mesh.calc_loop_triangles()
    nt, nl = len(mesh.loop_triangles), len(mesh.loops)
    tv = np.empty(nt * 3, np.int64)
    mesh.loop_triangles.foreach_get("vertices", tv)
    tl = np.empty(nt * 3, np.int64)
    mesh.loop_triangles.foreach_get("loops", tl)
    cn = np.empty(nl * 3, np.float32)
    mesh.corner_normals.foreach_get("vector", cn)
    uv = np.empty(nl * 2, np.float32)
    mesh.uv_layers.active.data.foreach_get("uv", uv)
    keys = np.hstack([tv[:, None].astype(np.float64), cn.reshape(nl, 3)[tl].astype(np.float64),
                      uv.reshape(nl, 2)[tl].astype(np.float64)])
    rng = np.random.default_rng(7)
    ties = rng.integers(0, 4, size=(5000, 6)).astype(np.float64)
    ties[::5, 3] = -0.0
    for k in (keys, ties):
        _, first, inverse = np.unique(k, axis=0, return_index=True, return_inverse=True)
        got_first, got_inverse = split_vertices(k)
        assert np.array_equal(got_first, first)
        assert np.array_equal(got_inverse, inverse.reshape(-1))
    assert len(np.unique(keys, axis=0)) > len(mesh.vertices)  # the sphere's corners do split
    first, inverse = split_vertices(np.zeros((0, 6)))
    assert len(first) == len(inverse) == 0


def test_world_image_written_once_per_content(addon, prefs, blend_dir):
    """Each export (a bake, every stale check) writes the world's environment image only when
    its pixels or the file changed: the same pixels leave the file untouched, new pixels or a
    deleted file write it again, and the scene's hash follows the pixels."""
    import os
    import time

    box_scene(resolution=16)
    image = bpy.data.images.new("sky", 32, 16, float_buffer=True)
    image.pixels.foreach_set(np.full(32 * 16 * 4, 0.5, np.float32))
    world = bpy.context.scene.world or bpy.data.worlds.new("World")
    bpy.context.scene.world = world
    world.use_nodes = True
    nodes = world.node_tree.nodes
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    world.node_tree.links.new(env.outputs["Color"], nodes["Background"].inputs["Color"])

    first = addon.api.export().scene.hash()
    paths = [p for p in (blend_dir / "relume").rglob("*.exr")]
    assert len(paths) == 1, paths
    stamp = os.stat(paths[0]).st_mtime_ns
    time.sleep(0.05)  # past the file system's clock tick: a rewrite would change the mtime
    assert addon.api.export().scene.hash() == first
    assert os.stat(paths[0]).st_mtime_ns == stamp, "unchanged pixels were written again"
    # A file touched since (another program, a copy) is written again.
    touched = stamp - 10**9
    os.utime(paths[0], ns=(touched, touched))
    assert addon.api.export().scene.hash() == first
    stamp = os.stat(paths[0]).st_mtime_ns
    assert stamp != touched, "a file changed since it was written was not written again"

    image.pixels.foreach_set(np.full(32 * 16 * 4, 0.25, np.float32))
    changed = addon.api.export().scene.hash()
    assert changed != first
    assert os.stat(paths[0]).st_mtime_ns != stamp

    paths[0].unlink()
    assert addon.api.export().scene.hash() == changed
    assert paths[0].exists()

"""Material and world node trees → plain values for `..logic.material_map`.

Only the node linked to the active output's Surface socket is read (what Cycles renders);
reroutes are followed. Image pixels are converted to scene-linear RGB here because only
bpy knows an image's colour space.
"""

from __future__ import annotations

import numpy as np

from ..logic.material_map import SurfaceNodes


def _follow(link):
    """The node at the far end of a link, through reroutes (None if dangling)."""
    node = link.from_node
    seen = 0
    while node is not None and node.bl_idname == "NodeReroute" and seen < 64:
        if not node.inputs[0].is_linked:
            return None
        node = node.inputs[0].links[0].from_node
        seen += 1
    return node


def active_output(tree, idname: str):
    outputs = [n for n in tree.nodes if n.bl_idname == idname]
    for n in outputs:
        if getattr(n, "is_active_output", False):
            return n
    return outputs[0] if outputs else None


def _socket_value(sock):
    v = getattr(sock, "default_value", None)
    if v is None:
        return None
    try:
        return tuple(v)
    except TypeError:
        return float(v)


def read_surface(material) -> SurfaceNodes:
    """What the material's surface is made of (see `SurfaceNodes`)."""
    name = material.name
    tree = material.node_tree if getattr(material, "use_nodes", True) else None
    if tree is None:
        return SurfaceNodes(material_name=name, shader="", uses_nodes=False, viewport={
            "diffuse_color": tuple(material.diffuse_color), "roughness": material.roughness,
            "metallic": material.metallic})
    out = active_output(tree, "ShaderNodeOutputMaterial")
    if out is None:
        return SurfaceNodes(material_name=name, shader="")
    surface = out.inputs["Surface"]
    shader_node = _follow(surface.links[0]) if surface.is_linked else None
    desc = SurfaceNodes(
        material_name=name,
        shader=shader_node.bl_idname if shader_node is not None else "",
        has_volume=out.inputs["Volume"].is_linked,
        has_displacement=out.inputs["Displacement"].is_linked,
    )
    if shader_node is None:
        return desc
    for sock in shader_node.inputs:
        if sock.is_linked:
            far = _follow(sock.links[0])
            desc.links[sock.name] = far.bl_idname if far is not None else "nothing"
            if sock.name == "Base Color" and far is not None and far.bl_idname == "ShaderNodeTexImage":
                desc.base_color_image = far.image
        else:
            value = _socket_value(sock)
            if value is not None:
                desc.values[sock.name] = value
    return desc


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def image_rgb_linear(image) -> tuple[np.ndarray | None, str]:
    """The image as (h, w, 3) float32 scene-linear, top row first; or (None, why not)."""
    if image is None:
        return None, "no image"
    w, h = image.size[0], image.size[1]
    if w == 0 or h == 0:
        return None, f"image '{image.name}' has no pixels (missing file?)"
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, image.channels)
    rgb = px[:, :, :3] if image.channels >= 3 else np.repeat(px[:, :, :1], 3, axis=2)
    space = image.colorspace_settings.name
    if space in ("sRGB",) and not image.is_float:
        rgb = srgb_to_linear(rgb.astype(np.float64)).astype(np.float32)
    elif space not in ("Linear Rec.709", "Linear", "Non-Color", "sRGB", "Linear CIE-XYZ E"):
        return (np.ascontiguousarray(np.nan_to_num(rgb[::-1], nan=0.0, posinf=0.0).clip(0, None)),
                f"colour space '{space}' read as linear Rec.709")
    rgb = np.nan_to_num(rgb[::-1], nan=0.0, posinf=0.0).clip(0, None)  # Blender is bottom row first
    return np.ascontiguousarray(rgb, dtype=np.float32), ""

"""UI: the Image Editor's "Relume" tab and the material properties' Relume panel."""

from __future__ import annotations

import bpy

from ..logic.light_groups import cost_text, group_label
from ..logic.region_params import PrincipledParams
from ..relight_values import region_params
from ..runtime import RUNTIME
from ..services.export import roughness_range
from .bake_controls import draw_bake_controls


class RELUME_PT_image(bpy.types.Panel):
    bl_label = "Relume"
    bl_space_type = "IMAGE_EDITOR"
    bl_region_type = "UI"
    bl_category = "Relume"

    def draw(self, context):
        layout = self.layout
        live = RUNTIME.live
        draw_bake_controls(layout, context)
        layout.label(text=f"Device: {live.device_text}")
        if live.last_denoise is not None:
            layout.label(text=f"Shown: {live.last_denoise['summary']}"[:140])
        refine_line = live.refine_status()
        if refine_line is not None:
            layout.label(text=refine_line)
        if live.relight_error:
            layout.label(text=live.relight_error[:140], icon="ERROR")
        for w in live.range_warnings:
            box = layout.box()
            for i in range(0, min(len(w), 360), 120):
                box.label(text=w[i:i + 120], icon="ERROR" if i == 0 else "BLANK1")
        if live.last_latency_ms is not None:
            layout.label(text=f"Last relight: {live.last_latency_ms:.1f} ms")
        if RUNTIME.warnings:
            box = layout.box()
            box.label(text=f"{len(RUNTIME.warnings)} export warning(s)", icon="ERROR")
            for w in RUNTIME.warnings[:8]:
                box.label(text=str(w)[:140])
        if live.stack is None:
            return
        import relume

        _draw_light_groups(layout, context)
        for name in live.stack.editable_regions:
            mat = bpy.data.materials.get(name)
            box = layout.box()
            if mat is None:
                box.label(text=f"{name}: material missing", icon="ERROR")
                continue
            box.label(text=name, icon="MATERIAL")
            _draw_region(box, mat, relume)


def _draw_light_groups(layout, context) -> None:
    """One box per light group of the loaded stack: its Strength and Color, relit live.

    The entries are created when the stack loads (`live.sync_light_groups`); a draw may not
    write data, so a missing one is only reported (Reload Stack creates it).
    """
    groups = RUNTIME.live.light_groups
    if not groups:
        return
    layout.label(text=cost_text(len(groups)), icon="LIGHT")
    stored = context.scene.relume_light_groups
    for name in groups:
        box = layout.box()
        box.label(text=group_label(name, RUNTIME.light_names), icon="OUTLINER_OB_LIGHT")
        entry = stored.get(name)
        if entry is None:
            box.label(text="No gain stored: Reload Stack", icon="ERROR")
            box.operator("relume.reload")
            continue
        row = box.row()
        row.prop(entry, "strength")
        row.prop(entry, "color", text="")


def _principled(mat):
    tree = mat.node_tree
    if tree is None:
        return None
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeBsdfPrincipled":
            return node
    return None


def _draw_region(layout, mat, relume) -> None:
    props = mat.relume
    layout.prop(props, "override")
    if props.override:
        layout.prop(props, "kd")
        layout.prop(props, "ks")
        layout.prop(props, "ns")
        return
    node = _principled(mat)
    if node is None:
        layout.label(text="No Principled BSDF: use the override")
        return
    for name in ("Base Color", "Metallic", "Roughness", "IOR", "Specular IOR Level",
                 "Subsurface Weight", "Subsurface Radius", "Subsurface Scale"):
        sock = node.inputs[name]
        if not sock.is_linked:
            layout.prop(sock, "default_value", text=name)
    p = region_params(mat)
    if isinstance(p, PrincipledParams):
        bp = relume.principled_to_blinn_phong(p.base_color, p.metallic, p.roughness, p.ior,
                                              p.specular_ior_level)
        if p.subsurface_weight > 0:
            mean_free_path = ", ".join(f"{r * p.subsurface_scale:.3g}" for r in p.subsurface_radius)
            layout.label(text=f"Subsurface: weight {p.subsurface_weight:.2f}, mean free path "
                              f"({mean_free_path}) m")
        kd = ", ".join(f"{c:.2f}" for c in bp["kd"])
        ks = ", ".join(f"{c:.2f}" for c in bp["ks"])
        layout.label(text=f"Blinn–Phong: Kd ({kd})  Ks ({ks})  ns {bp['ns']:.3g}")


class RELUME_PT_material(bpy.types.Panel):
    bl_label = "Relume"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return context.material is not None

    def draw(self, context):
        props = context.material.relume
        layout = self.layout
        layout.prop(props, "editable")
        if props.editable:
            row = layout.row()
            row.prop(props, "use_roughness_range")
            sub = row.row()
            sub.enabled = props.use_roughness_range
            sub.prop(props, "roughness_min")
            sub.prop(props, "roughness_max")
            lo, hi = roughness_range(context.material)
            layout.label(text=f"Basis baked for roughness {lo:.2f}–{hi:.2f}; outside it the relight "
                              f"uses the range's edge and the Relume tab says so", icon="INFO")
            layout.prop(props, "override")
            if props.override:
                layout.prop(props, "kd")
                layout.prop(props, "ks")
                layout.prop(props, "ns")


CLASSES = (RELUME_PT_image, RELUME_PT_material)

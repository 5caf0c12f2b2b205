"""Add-on preferences: bake settings and the Bake button (docs/design.md §4)."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from .bake_controls import draw_bake_controls

# The add-on's package (this module is in its `ui` subpackage): the preferences' key.
ADDON_ID = __package__.rpartition(".")[0]

PRESET_ITEMS = [
    ("draft", "Draft", "Fastest bake: few samples, coarse basis, half resolution"),
    ("preview", "Preview", "A usable image in seconds to a minute"),
    ("final", "Final", "Converged image for final frames"),
    ("custom", "Custom", "The sample counts and tolerance below"),
]

_GROUP_COST = "storage and relight time grow by the number of groups (at most 16)"

LIGHT_GROUP_ITEMS = [
    ("none", "None", "All lights share one set of layers: the lights are fixed after the bake"),
    ("per_light", "Per Light", "Each light (and an emitting world) in layers of its own, its "
                               "strength and colour live after the bake; " + _GROUP_COST),
    ("scene", "Blender Light Groups", "Each of Blender's light groups (Object → Shading → "
                                      "Light Group, and the World's) in layers of its own; "
                                      "lights and world without one share a 'default' group; "
                                      + _GROUP_COST),
]


class RelumePreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_ID

    preset: EnumProperty(name="Preset", items=PRESET_ITEMS, default="preview",
                         description="Quality preset; docs/measurements.md lists each one's measured error and time")
    spp: IntProperty(name="Eye Samples", min=1, max=65536, default=16,
                     description="Samples per pixel (custom preset)")
    light_samples: IntProperty(name="Light Samples", min=1, max=1024, default=4)
    indirect_samples: IntProperty(name="Indirect Samples", min=1, max=1024, default=1)
    bounces_from_scene: BoolProperty(
        name="Bounces from Cycles", default=True,
        description="Bake with the scene's Cycles light paths: Max Bounces, each path's "
                    "diffuse and glossy bounces counted against their own limits (4 and 4 "
                    "at Blender's defaults); the preset bakes as many as the scene needs")
    bounces: IntProperty(name="Bounces", min=0, max=128, default=12,
                         description="Bounce cap when not taken from Cycles. 0: direct light "
                                     "only; 1: one bounce, exact under edits; more: later "
                                     "bounces keep their bake-time materials (frozen tail)")
    basis_tolerance: FloatProperty(name="Basis Tolerance", min=1e-4, max=0.5, default=0.028,
                                   description="Largest relative L2 error of the BRDF basis "
                                               "(sets the number of basis BRDFs; the default is "
                                               "the preview preset's)")
    memory_budget_mb: FloatProperty(
        name="Memory Budget (MiB)", min=0.0, default=0.0,
        description="Memory a bake may plan to use at its peak; a bake whose estimate exceeds it is refused "
                    "before it starts. 0: 80 % of the memory available when the bake starts")
    passes: IntProperty(name="Passes", min=1, max=16, default=1,
                        description="Progressive passes: a complete stack after each, so the "
                                    "image appears early and cleans up")
    resolution_scale: FloatProperty(name="Resolution Scale", min=0.05, max=1.0, default=1.0,
                                    subtype="FACTOR",
                                    description="Fraction of the render resolution the bake uses")
    device: EnumProperty(name="Relight Device", default="auto", items=[
        ("auto", "Auto", "A real GPU through wgpu when there is one, else the CPU"),
        ("gpu", "GPU", "The GPU (an error if none is usable)"),
        ("cpu", "CPU", "The CPU (multi-threaded)"),
    ])
    material_lobes: EnumProperty(name="Editable Materials", default="principled", items=[
        ("principled", "Principled Basis",
         "Cycles' Principled lobes for opaque, untextured Principled materials, with each "
         "material's bake-time lobe as a slot of its own: the unedited image and colour edits "
         "as Cycles renders them, roughness and metallic edits as far as the preset's basis "
         "carries them; more layers than the Blinn–Phong basis at the preview and final presets, "
         "and a basis build of seconds the first time on a machine (textured and translucent "
         "materials keep Blinn–Phong)"),
        ("blinn-phong", "Blinn–Phong Basis",
         "The paper's basis: a Principled material is relit as the Blinn–Phong fitted to "
         "Cycles' Principled BSDF (glossy reflections of smooth materials are lost)"),
    ])
    light_groups: EnumProperty(name="Light Groups", items=LIGHT_GROUP_ITEMS, default="none",
                               description="Keep lights apart so their strength and colour can "
                                           "change live after the bake; " + _GROUP_COST)
    denoise: BoolProperty(
        name="Denoise Shown Image", default=True,
        description="Show the relit image through OpenImageDenoise (Blender's own) with albedo "
                    "and normal features once an edit settles; while a slider moves, and with "
                    "this off, the raw relit image (the exact sum of the stack) is shown")
    refine: BoolProperty(
        name="Refine After Edits", default=True,
        description="Once an edit settles, trace the bounces past the second again with the "
                    "edited materials in the background and add what the relight misses there "
                    "(roughness and mirror edits, several materials edited together), the image "
                    "improving pass by pass; the next edit stops it. Stacks with one bounce "
                    "need none")
    stack_folder: StringProperty(name="Stack Folder", subtype="DIR_PATH", default="",
                                 description="Where stacks are stored: empty = a 'relume' folder "
                                             "beside the .blend; '//' paths are relative to it")

    def draw(self, context):
        layout = self.layout
        col = layout.column()
        col.prop(self, "preset")
        sub = col.column()
        sub.enabled = self.preset == "custom"
        sub.prop(self, "spp")
        sub.prop(self, "light_samples")
        sub.prop(self, "indirect_samples")
        sub.prop(self, "basis_tolerance")
        col.prop(self, "bounces_from_scene")
        row = col.row()
        row.enabled = not self.bounces_from_scene
        row.prop(self, "bounces")
        col.prop(self, "passes")
        col.prop(self, "memory_budget_mb")
        col.prop(self, "resolution_scale")
        col.prop(self, "device")
        col.prop(self, "denoise")
        col.prop(self, "refine")
        col.prop(self, "material_lobes")
        col.prop(self, "light_groups")
        if self.light_groups != "none":
            col.label(text="Stack size and relight time grow by the number of groups", icon="INFO")
        col.prop(self, "stack_folder")
        draw_bake_controls(layout, context)


class _Defaults:
    """The preferences' defaults, for when the add-on runs without being enabled as such."""

    def __getattr__(self, name):
        prop = RelumePreferences.__annotations__[name]
        return prop.keywords.get("default")


def get_prefs(context=None):
    context = context or bpy.context
    addon = context.preferences.addons.get(ADDON_ID)
    return addon.preferences if addon is not None else _Defaults()


CLASSES = (RelumePreferences,)

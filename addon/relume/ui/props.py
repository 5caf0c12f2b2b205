"""Relume settings stored in the .blend: per material, and the scene's light group gains."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, CollectionProperty, FloatProperty, FloatVectorProperty, PointerProperty

from ..live import request_stale_check
from ..live_image import request_relight
from ..runtime import RUNTIME


# Changing a registered property of a material does not tag the material for the depsgraph,
# so the depsgraph handler never sees these edits: they call the live relight (or the stale
# check) themselves.
def _relight_on_change(self, context) -> None:
    request_relight()


def _stale_check_on_change(self, context) -> None:
    if RUNTIME.live.stack is not None:
        request_stale_check()


class RelumeMaterialSettings(bpy.types.PropertyGroup):
    """Whether a material stays editable after the bake, and its optional direct values.

    Editable materials keep their BRDF free: the bake stores their contribution per basis
    BRDF (more layers, so more storage and relight time) and the Principled sliders relight
    the image live. An override replaces the Principled mapping by explicit Blinn–Phong
    values (the paper's Kd, Ks, ns).
    """

    editable: BoolProperty(
        name="Editable", default=False, update=_stale_check_on_change,
        description="Keep this material editable after the Relume bake (relit live); "
                    "changing this needs a rebake")
    override: BoolProperty(
        name="Override", default=False, update=_relight_on_change,
        description="Use the Blinn–Phong values below instead of the Principled BSDF's")
    kd: FloatVectorProperty(name="Kd", subtype="COLOR", size=3, min=0.0, max=1.0,
                            default=(0.5, 0.5, 0.5), description="Diffuse albedo",
                            update=_relight_on_change)
    ks: FloatVectorProperty(name="Ks", subtype="COLOR", size=3, min=0.0, max=1.0,
                            default=(0.04, 0.04, 0.04), description="Specular albedo (Kd + Ks ≤ 1)",
                            update=_relight_on_change)
    ns: FloatProperty(name="ns", min=1e-3, max=1e6, default=30.0, soft_min=1.0, soft_max=1000.0,
                      description="Blinn–Phong exponent (Relume maps Principled roughness 0.5 to ≈ 57)",
                      update=_relight_on_change)
    use_roughness_range: BoolProperty(
        name="Roughness Range", default=False, update=_stale_check_on_change,
        description="Set the roughness range this material's basis is baked for. Off: the "
                    "Principled range down to roughness 0.1. A narrower "
                    "range needs fewer basis BRDFs (smaller stack, faster relight); a roughness "
                    "outside the baked range is relit at the range's edge and flagged in the panel")
    roughness_min: FloatProperty(name="Min", min=0.0, max=1.0, default=0.1,
                                 update=_stale_check_on_change)
    roughness_max: FloatProperty(name="Max", min=0.0, max=1.0, default=1.0,
                                 update=_stale_check_on_change)


class RelumeLightGroup(bpy.types.PropertyGroup):
    """The live gain of one light group of the stack, keyed by the group's name (`name`).

    Kept on the scene rather than in the session so the gains persist in the .blend and are
    re-applied when the stack is reloaded; entries are added when a stack with new groups
    loads and never removed, so a gain survives a rebake with other grouping.
    """

    strength: FloatProperty(name="Strength", min=0.0, soft_max=10.0, default=1.0,
                            update=_relight_on_change,
                            description="Multiplies this light group's light (relit live)")
    color: FloatVectorProperty(name="Color", subtype="COLOR", size=3, min=0.0, soft_max=1.0,
                               default=(1.0, 1.0, 1.0), update=_relight_on_change,
                               description="Tints this light group's light (relit live)")


CLASSES = (RelumeMaterialSettings, RelumeLightGroup)


def register() -> None:
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Material.relume = PointerProperty(type=RelumeMaterialSettings)
    bpy.types.Scene.relume_light_groups = CollectionProperty(type=RelumeLightGroup)


def unregister() -> None:
    del bpy.types.Scene.relume_light_groups
    del bpy.types.Material.relume
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)

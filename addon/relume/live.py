"""Live relight: material edits → relit pixels in the "Relume" image.

A depsgraph handler notices material changes and asks for a (throttled) relight of the
regions that changed (`live_image`). Anything else that changes what the bake saw (objects,
lights, camera, world, fixed materials, editability) triggers a stale check instead: the
stack is then shown as stale and no longer relit from, never silently misused. Opening a
.blend loads its stack.
"""

from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from .live_image import request_relight
from .runtime import RUNTIME
from .services.stack import check_stale, load_stack


def _deferred_stale_check():
    check_stale()
    return None


def request_stale_check() -> None:
    if bpy.app.background:
        check_stale()
    elif not RUNTIME.stale_check_pending:
        RUNTIME.stale_check_pending = True
        bpy.app.timers.register(_deferred_stale_check, first_interval=0.5)


def _affects_bake(update, editable: set[str]) -> bool:
    """Whether one depsgraph update may change what the bake saw.

    An edit of an editable material also tags the objects and meshes that use it, for
    shading only: those updates carry no transform or geometry change and are not a reason
    for a stale check (a full export), which would otherwise run on every slider step.
    Objects, meshes and curves count when they moved or their geometry changed (vertices,
    modifiers, material slots); collections when their members or visibility changed.
    """
    idt = update.id
    if isinstance(idt, bpy.types.Material):
        return not (idt.name in editable and idt.relume.editable)
    if isinstance(idt, (bpy.types.Object, bpy.types.Mesh, bpy.types.Curve, bpy.types.Collection)):
        return update.is_updated_transform or update.is_updated_geometry
    return isinstance(idt, (bpy.types.Light, bpy.types.Camera, bpy.types.World))


@persistent
def on_depsgraph_update(scene, depsgraph) -> None:
    live = RUNTIME.live
    if live.stack is None:
        return
    editable = set(live.stack.editable_regions)
    material_changed = False
    stale_suspect = False
    for update in depsgraph.updates:
        idt = update.id
        if isinstance(idt, bpy.types.Image):
            continue
        if isinstance(idt, (bpy.types.Material, bpy.types.ShaderNodeTree)):
            material_changed = True
        if not stale_suspect and _affects_bake(update, editable):
            stale_suspect = True
    if stale_suspect:
        request_stale_check()
    if material_changed and live.ready:
        request_relight()


@persistent
def on_load_post(*_args) -> None:
    RUNTIME.live.unload()
    RUNTIME.live.stale_reason = None
    try:
        load_stack()
    except Exception as e:  # never let a handler raise into Blender's file loading
        RUNTIME.live.load_error = str(e)


def register() -> None:
    bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)
    bpy.app.handlers.load_post.append(on_load_post)


def unregister() -> None:
    for lst, fn in ((bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
                    (bpy.app.handlers.load_post, on_load_post)):
        while fn in lst:
            lst.remove(fn)

"""Blender light objects → `..logic.lights_map.BlenderLight` values."""

from __future__ import annotations

from ..logic.lights_map import BlenderLight


def read_light(obj, matrix_world) -> BlenderLight:
    data = obj.data
    temperature = None
    if getattr(data, "use_temperature", False):
        temperature = tuple(data.temperature_color)
    linking = getattr(obj, "light_linking", None)
    linked = bool(linking is not None and (linking.receiver_collection or linking.blocker_collection))
    cycles = getattr(data, "cycles", None)
    return BlenderLight(
        name=obj.name,
        type=data.type,
        matrix_world=[list(r) for r in matrix_world],
        energy=float(data.energy),
        color=tuple(data.color),
        exposure=float(getattr(data, "exposure", 0.0)),
        temperature_rgb=temperature,
        radius=float(getattr(data, "shadow_soft_size", 0.0)),
        spot_size=float(getattr(data, "spot_size", 0.785)),
        spot_blend=float(getattr(data, "spot_blend", 0.15)),
        angle=float(getattr(data, "angle", 0.0)),
        shape=str(getattr(data, "shape", "SQUARE")),
        size=float(getattr(data, "size", 1.0)),
        size_y=float(getattr(data, "size_y", 1.0)),
        spread=float(getattr(data, "spread", 3.14159265)),
        normalize=bool(getattr(data, "normalize", True)),
        cast_shadow=bool(getattr(cycles, "cast_shadow", True)) if cycles is not None else True,
        light_linked=linked,
        visible_camera=bool(getattr(obj, "visible_camera", True)),
        lightgroup=str(getattr(obj, "lightgroup", "")),
    )

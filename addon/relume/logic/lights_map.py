"""Blender light values → Relume scene lights (docs/scene-format.md, "Lights").

Units follow Cycles, so no scaling happens for the common case: point, spot and area power
in W, sun strength in W/m². Blender's extras are folded in where they are exact (exposure
multiplies the power by 2^exposure; a blackbody temperature tints the colour; object scale
stretches an area light) and warned about where they are not (area spread, light linking,
shadowless lights, non-uniformly scaled spots).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .export_warnings import WarningList

Matrix = list[list[float]]


@dataclass
class BlenderLight:
    """What the exporter reads off one light object (plain values, world space)."""

    name: str
    type: str  # 'POINT', 'SPOT', 'SUN', 'AREA'
    matrix_world: Matrix  # rows of the object's 4×4 world matrix
    energy: float
    color: tuple[float, float, float]
    exposure: float = 0.0
    temperature_rgb: tuple[float, float, float] | None = None  # None: not used
    radius: float = 0.0  # shadow_soft_size
    spot_size: float = math.radians(45.0)
    spot_blend: float = 0.15
    angle: float = 0.0  # sun
    shape: str = "SQUARE"
    size: float = 1.0
    size_y: float = 1.0
    spread: float = math.pi
    normalize: bool = True
    cast_shadow: bool = True
    light_linked: bool = False
    visible_camera: bool = True  # the object's Ray Visibility → Camera
    lightgroup: str = ""  # Blender's light group ("" for none): see light_groups.py
    extra: dict = field(default_factory=dict)


def _column(m: Matrix, j: int) -> list[float]:
    return [m[0][j], m[1][j], m[2][j]]


def _length(v: list[float]) -> float:
    return math.sqrt(sum(c * c for c in v))


def _unit(v: list[float], what: str) -> list[float]:
    n = _length(v)
    if not (n > 1e-20 and math.isfinite(n)):
        raise ValueError(f"{what}: degenerate transform (zero or non-finite axis)")
    return [c / n for c in v]


def _area_of(shape: str, sx: float, sy: float) -> float:
    if shape in ("square", "rectangle"):
        return sx * sy
    return math.pi * sx * sy / 4.0


def map_light(light: BlenderLight, warnings: WarningList) -> dict | None:
    """The scene-file dict for `light`, or None when it emits nothing (and says why)."""
    subject = f"Light '{light.name}'"
    m = light.matrix_world
    position = _column(m, 3)
    power = float(light.energy) * (2.0 ** float(light.exposure))
    color = list(light.color)
    if light.temperature_rgb is not None:
        color = [c * t for c, t in zip(color, light.temperature_rgb, strict=True)]
    if not all(math.isfinite(v) for v in position + color + [power]):
        raise ValueError(f"{subject}: non-finite position, colour or power")
    if power <= 0.0 or max(color) <= 0.0:
        warnings.add(subject, "zero power or black colour", "left out of the bake")
        return None
    if not light.cast_shadow:
        warnings.add(subject, "shadows off", "Relume always casts shadows")
    if light.light_linked:
        warnings.add(subject, "light linking", "the light reaches every object")
    color = [max(0.0, c) for c in color]
    kind = light.type
    if kind == "POINT":
        return {"type": "point", "position": position, "power": power, "color": color,
                "radius": max(0.0, float(light.radius))}
    if kind == "SPOT":
        sx, sy = _length(_column(m, 0)), _length(_column(m, 1))
        if abs(sx - sy) > 1e-4 * max(sx, sy):
            warnings.add(subject, "non-uniform X/Y scale (elliptical cone)",
                         "a round cone of the light's Spot Size")
        direction = [-c for c in _unit(_column(m, 2), subject)]
        return {"type": "spot", "position": position, "direction": direction, "power": power,
                "spot_size": min(math.pi, max(1e-4, float(light.spot_size))),
                "spot_blend": min(1.0, max(0.0, float(light.spot_blend))),
                "color": color, "radius": max(0.0, float(light.radius))}
    if kind == "SUN":
        direction = [-c for c in _unit(_column(m, 2), subject)]
        return {"type": "sun", "direction": direction, "strength": power,
                "angle": min(math.pi, max(0.0, float(light.angle))), "color": color}
    if kind == "AREA":
        u_col, v_col = _column(m, 0), _column(m, 1)
        shape = light.shape.lower()
        sx = float(light.size) * _length(u_col)
        sy = (float(light.size_y) if shape in ("rectangle", "ellipse") else float(light.size)) * _length(v_col)
        if not (sx > 0 and sy > 0):
            warnings.add(subject, "zero size", "left out of the bake")
            return None
        if light.spread < math.pi - 1e-4:
            warnings.add(subject, f"Spread {math.degrees(light.spread):.0f}°",
                         "emits over the full hemisphere (Lambertian)")
        if not light.normalize:
            # Cycles then treats Power as the emission of a 1 m² light: total power × area.
            power *= _area_of(shape, sx, sy)
        axis_u = _unit(u_col, subject)
        axis_v = _unit(v_col, subject)
        # Orthogonalise v against u (shear in the object's matrix) so the file validates.
        d = sum(a * b for a, b in zip(axis_u, axis_v, strict=True))
        axis_v = _unit([b - d * a for a, b in zip(axis_u, axis_v, strict=True)], subject)
        out = {"type": "area", "position": position, "axis_u": axis_u, "axis_v": axis_v,
               "shape": shape, "size_x": sx, "power": power, "color": color}
        if shape in ("rectangle", "ellipse"):
            out["size_y"] = sy
        if light.visible_camera:
            # Cycles shows the front face with radiance P/(π·A) (scene format 3).
            out["visible_camera"] = True
        return out
    warnings.add(subject, f"light type {kind}", "left out of the bake")
    return None

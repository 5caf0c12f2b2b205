"""Blender camera values → the Relume scene camera (docs/scene-format.md, "Camera").

The scene format wants a pure rotation in `matrix_world`, so object scale is normalised away
(Blender ignores it for rays too). Panoramic cameras cannot be mapped and are an error:
the stack would be of a different image. Depth of field becomes a warning (pinhole).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .export_warnings import WarningList


class CameraError(ValueError):
    """The scene's camera cannot be used for a bake (none, or a panoramic one)."""


@dataclass
class BlenderCamera:
    name: str
    type: str  # 'PERSP', 'ORTHO', 'PANO'
    matrix_world: list[list[float]]
    lens: float = 50.0
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: str = "AUTO"
    shift_x: float = 0.0
    shift_y: float = 0.0
    ortho_scale: float = 6.0
    clip_start: float = 0.1
    clip_end: float = 100.0
    use_dof: bool = False


def _normalised_rotation(m: list[list[float]], subject: str) -> list[list[float]]:
    cols = []
    for j in range(3):
        c = [m[0][j], m[1][j], m[2][j]]
        n = math.sqrt(sum(v * v for v in c))
        if not (n > 1e-20 and math.isfinite(n)):
            raise CameraError(f"{subject}: degenerate transform (zero scale)")
        cols.append([v / n for v in c])
    x, y, z = cols
    det = (x[0] * (y[1] * z[2] - y[2] * z[1]) - x[1] * (y[0] * z[2] - y[2] * z[0])
           + x[2] * (y[0] * z[1] - y[1] * z[0]))
    if det < 0:
        raise CameraError(f"{subject}: mirrored transform (negative scale) cannot be a camera")
    return [[x[i], y[i], z[i], m[i][3]] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def map_camera(cam: BlenderCamera, warnings: WarningList) -> dict:
    subject = f"Camera '{cam.name}'"
    if cam.type == "PANO":
        raise CameraError(f"{subject}: panoramic cameras are not supported (perspective or orthographic only)")
    if cam.use_dof:
        warnings.add(subject, "depth of field", "a pinhole camera (everything in focus)")
    return {
        "projection": "orthographic" if cam.type == "ORTHO" else "perspective",
        "matrix_world": _normalised_rotation(cam.matrix_world, subject),
        "lens_mm": float(cam.lens),
        "sensor_width_mm": float(cam.sensor_width),
        "sensor_height_mm": float(cam.sensor_height),
        "sensor_fit": cam.sensor_fit.lower(),
        "shift_x": float(cam.shift_x),
        "shift_y": float(cam.shift_y),
        "ortho_scale": float(cam.ortho_scale),
        "clip_start": float(cam.clip_start),
        "clip_end": float(cam.clip_end),
    }

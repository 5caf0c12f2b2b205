"""The relit image with the current materials: as pixels, and written to a file."""

from __future__ import annotations

import os

import bpy
import numpy as np

from ..live_image import denoise_mode, write_image
from ..relight_values import current_gains, current_params
from ..runtime import RUNTIME
from . import stack as stack_service
from .errors import BakeError


def _relit_top_first(context=None, denoise: str | None = None, refine: float = 0.0):
    """Relight with the current material values, write the "Relume" image, and return the
    shown (h, w, 4) image with its rows top first (the relighter's order). `denoise`:
    "oidn" or "none"; None follows the preference (`last_denoise` says what ran). `refine`:
    seconds of refinement first (the bounces past the second traced with these materials;
    `api.status()["refine"]` reports the passes)."""
    if not (refine >= 0.0 and refine != float("inf")):
        raise ValueError(f"refine must be finite seconds >= 0, got {refine}")
    live = RUNTIME.live
    if live.stack is None and not stack_service.load_stack(context):
        raise BakeError(f"no usable Relume stack: {live.load_error or 'not baked yet'}")
    if live.stale_reason is not None:
        raise BakeError(f"the Relume stack is stale: {live.stale_reason}")
    mode = denoise or denoise_mode(context)
    outcome = live.relight(current_params(), force=True, gains=current_gains(), denoise=mode)
    if refine > 0.0:
        live.refine(refine)
        outcome = live.shown(denoise=mode, refined=True)
    write_image(outcome.image)
    return outcome.image


def relight(context=None, denoise: str = "none", refine: float = 0.0):
    """Relight with the current material values; returns the (h, w, 4) image (bottom row
    first): the exact relit image, or with `denoise="oidn"` the shown one (see `render`),
    refined for `refine` seconds first."""
    return np.ascontiguousarray(_relit_top_first(context, denoise, refine)[::-1])


def render(filepath: str, context=None, check_stale: bool = True, denoise: str | None = None,
           refine: float = 0.0) -> str:
    """Write the shown image to `filepath` (.exr: linear float; .png: sRGB 8-bit): the relit
    image through OpenImageDenoise when the preference (or `denoise="oidn"`) asks for it,
    else (`denoise="none"`) the exact relit image. `api.status()["denoise"]` says which ran.
    `refine`: seconds of refinement first — the bounces past the second traced again with
    these materials (what a lobe-shape edit, or several materials edited together, leaves
    out of the relight there); a batch render can afford what the live image cannot."""
    import relume

    if check_stale and RUNTIME.live.stack is not None and stack_service.check_stale(context) is not None:
        raise BakeError(f"the Relume stack is stale: {RUNTIME.live.stale_reason}")
    top_first = _relit_top_first(context, denoise, refine)
    path = bpy.path.abspath(filepath)
    folder = os.path.dirname(path)
    if folder:
        os.makedirs(folder, exist_ok=True)
    if path.lower().endswith(".png"):
        relume.write_png(path, top_first)
    elif path.lower().endswith(".exr"):
        relume.write_exr(path, top_first)
    else:
        raise ValueError(f"unsupported output format '{os.path.splitext(path)[1]}': use .exr or .png")
    return path

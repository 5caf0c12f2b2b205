"""A material's shader nodes (read by the exporter) → a Relume region material.

Relume's surface model is the Principled BSDF mapped to Blinn–Phong by the core
(`relume.principled_to_blinn_phong`): Base Color (or an Image Texture linked straight to it,
which multiplies the diffuse albedo), Metallic, Roughness, IOR, Specular IOR Level. Every other
input that changes the look, and every other surface shader, is named in a warning with the
fallback used — never ignored silently. A Diffuse BSDF maps exactly (Principled with no
specular), so it is not a fallback.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from .export_warnings import WarningList

PRINCIPLED = "ShaderNodeBsdfPrincipled"
DIFFUSE = "ShaderNodeBsdfDiffuse"
IMAGE_TEXTURE = "ShaderNodeTexImage"
EMISSION = "ShaderNodeEmission"

#: What a material without a usable surface shader becomes: Blender's default grey.
FALLBACK_PRINCIPLED = {"model": "principled", "base_color": [0.8, 0.8, 0.8], "metallic": 0.0,
                       "roughness": 0.5, "ior": 1.5, "specular_ior_level": 0.5}

#: The Principled inputs Relume maps, with Blender's defaults.
MAPPED_INPUTS = {"Base Color": (0.8, 0.8, 0.8, 1.0), "Metallic": 0.0, "Roughness": 0.5,
                 "IOR": 1.5, "Specular IOR Level": 0.5, "Subsurface Weight": 0.0,
                 "Subsurface Radius": (1.0, 0.2, 0.1), "Subsurface Scale": 0.05}

#: Inputs that change the look but that Relume does not model: (input, value that is
#: neutral, what the warning says is used instead).
UNMODELLED_INPUTS = [
    ("Alpha", 1.0, "opaque"),
    ("Transmission Weight", 0.0, "opaque (no transmission)"),
    ("Coat Weight", 0.0, "no coat layer"),
    ("Sheen Weight", 0.0, "no sheen"),
    ("Anisotropic", 0.0, "isotropic highlight"),
    ("Diffuse Roughness", 0.0, "Lambertian diffuse"),
    ("Thin Film Thickness", 0.0, "no thin film"),
]


@dataclass
class SurfaceNodes:
    """What the exporter read off a material's node tree (plain values)."""

    material_name: str
    shader: str  # bl_idname of the node linked to the output's Surface; "" when none
    values: dict[str, Any] = field(default_factory=dict)  # unlinked inputs' default values
    links: dict[str, str] = field(default_factory=dict)  # linked inputs → linked node's bl_idname
    base_color_image: Any = None  # exporter's handle to the image linked to Base Color
    has_volume: bool = False
    has_displacement: bool = False
    uses_nodes: bool = True
    viewport: dict[str, Any] = field(default_factory=dict)  # diffuse_color/roughness/metallic


def _rgb(value: Any) -> list[float]:
    v = list(value)[:3]
    return [max(0.0, float(c)) if math.isfinite(float(c)) else 0.0 for c in v]


def _scalar(value: Any, default: float) -> float:
    try:
        f = float(value)
    except (TypeError, ValueError):
        return default
    return f if math.isfinite(f) else default


def map_material(nodes: SurfaceNodes, warnings: WarningList) -> tuple[dict, bool]:
    """The region's `material` dict, and whether Base Color comes from `base_color_image`."""
    subject = f"Material '{nodes.material_name}'"
    if not nodes.uses_nodes:
        vp = nodes.viewport
        return ({"model": "principled", "base_color": _rgb(vp.get("diffuse_color", (0.8, 0.8, 0.8))),
                 "metallic": _clamp01(_scalar(vp.get("metallic", 0.0), 0.0)),
                 "roughness": _clamp01(_scalar(vp.get("roughness", 0.5), 0.5)),
                 "ior": 1.5, "specular_ior_level": 0.5}, False)
    if nodes.has_volume:
        warnings.add(subject, "volume shader", "the volume is ignored (surface only)")
    if nodes.has_displacement:
        warnings.add(subject, "displacement", "the undisplaced surface")
    if nodes.shader == DIFFUSE:
        if "Color" in nodes.links:
            warnings.add(subject, f"Diffuse Color linked to {nodes.links['Color']}",
                         "the socket's own colour")
        colour = _rgb(nodes.values.get("Color", (0.8, 0.8, 0.8)))
        if any(c > 1.0 for c in colour):
            # Blender allows a colour above 1; the core refuses Kd > 1 (more light out than in).
            warnings.add(subject, "Diffuse Color above 1", "the colour clamped to 1 per channel")
            colour = [min(1.0, c) for c in colour]
        return ({"model": "blinn_phong", "kd": colour, "ks": [0.0, 0.0, 0.0], "ns": 1.0}, False)
    if nodes.shader == EMISSION:
        # A pure emitter reflects nothing; its light is exported by `emission_of`.
        return ({"model": "blinn_phong", "kd": [0.0, 0.0, 0.0], "ks": [0.0, 0.0, 0.0], "ns": 1.0}, False)
    if nodes.shader != PRINCIPLED:
        what = f"surface shader {nodes.shader}" if nodes.shader else "no surface shader"
        warnings.add(subject, what, "Blender's default grey Principled BSDF (0.8, roughness 0.5)")
        return (dict(FALLBACK_PRINCIPLED), False)

    textured = False
    base_color = _rgb(nodes.values.get("Base Color", MAPPED_INPUTS["Base Color"]))
    if "Base Color" in nodes.links:
        if nodes.links["Base Color"] == IMAGE_TEXTURE and nodes.base_color_image is not None:
            textured = True
            base_color = [1.0, 1.0, 1.0]
        else:
            warnings.add(subject, f"Base Color linked to {nodes.links['Base Color']}",
                         "the socket's own colour")
    for name in ("Metallic", "Roughness", "IOR", "Specular IOR Level"):
        if name in nodes.links:
            warnings.add(subject, f"{name} linked to {nodes.links[name]}", "the socket's own value")
    for name, neutral, fallback in UNMODELLED_INPUTS:
        value = _scalar(nodes.values.get(name, neutral), neutral)
        if name in nodes.links or abs(value - neutral) > 1e-6:
            shown = f"linked to {nodes.links[name]}" if name in nodes.links else f"{value:g}"
            warnings.add(subject, f"{name} {shown}", fallback)
    if "Normal" in nodes.links:
        warnings.add(subject, f"Normal linked to {nodes.links['Normal']}", "the mesh's shading normals")
    tint = nodes.values.get("Specular Tint", (1.0, 1.0, 1.0, 1.0))
    if "Specular Tint" in nodes.links or any(abs(float(c) - 1.0) > 1e-6 for c in list(tint)[:3]):
        warnings.add(subject, "Specular Tint", "untinted dielectric specular")
    metallic = _clamp01(_scalar(nodes.values.get("Metallic", 0.0), 0.0))
    if textured and metallic > 0:
        warnings.add(subject, "metallic with a Base Color texture",
                     "white metallic specular (the texture tints the diffuse part only)")
    material = {"model": "principled", "base_color": base_color, "metallic": metallic,
                "roughness": _clamp01(_scalar(nodes.values.get("Roughness", 0.5), 0.5)),
                "ior": max(1.0, _scalar(nodes.values.get("IOR", 1.5), 1.5)),
                "specular_ior_level": _clamp01(_scalar(nodes.values.get("Specular IOR Level", 0.5), 0.5))}
    material.update(subsurface_fields(nodes, warnings, subject))
    return material, textured


def emission_of(nodes: SurfaceNodes, warnings: WarningList) -> tuple[list[float], float] | None:
    """The surface's emission as (colour, strength) — Principled Emission Color × Strength or
    an Emission shader's Color × Strength — or None when it emits nothing. Cycles renders
    such a surface with radiance colour × strength (strength 1 of white shows as 1.0) from
    both faces; the exporter writes it as an `emissive` light of the region (scene format 3).
    A linked colour or strength is read as its socket's own value, and said so."""
    if not nodes.uses_nodes:
        return None
    if nodes.shader == PRINCIPLED:
        colour_name, strength_name = "Emission Color", "Emission Strength"
        default_colour, default_strength = (0.0, 0.0, 0.0), 0.0
    elif nodes.shader == EMISSION:
        colour_name, strength_name = "Color", "Strength"
        default_colour, default_strength = (1.0, 1.0, 1.0), 1.0
    else:
        return None
    subject = f"Material '{nodes.material_name}'"
    for name in (colour_name, strength_name):
        if name in nodes.links:
            warnings.add(subject, f"{name} linked to {nodes.links[name]}", "the socket's own value")
    strength = _scalar(nodes.values.get(strength_name, default_strength), default_strength)
    colour = _rgb(nodes.values.get(colour_name, default_colour))
    if not (strength > 0 and max(colour) > 0):
        return None
    return colour, strength


def subsurface_fields(nodes: SurfaceNodes, warnings: WarningList, subject: str) -> dict:
    """The Principled subsurface inputs as the core's `subsurface_*` fields (scene format 2):
    Weight, Radius (RGB, in units of Scale) and Scale (scene units); empty when the weight is
    0. The core's dipole takes the IOR input as its η; Subsurface IOR and Anisotropy (used by
    Cycles' random walk) have no counterpart in the dipole model and are named when set."""
    for name in ("Subsurface Weight", "Subsurface Radius", "Subsurface Scale"):
        if name in nodes.links:
            warnings.add(subject, f"{name} linked to {nodes.links[name]}", "the socket's own value")
    weight = _clamp01(_scalar(nodes.values.get("Subsurface Weight", 0.0), 0.0))
    if weight <= 0.0:
        return {}
    radius = _rgb(nodes.values.get("Subsurface Radius", MAPPED_INPUTS["Subsurface Radius"]))
    scale = max(0.0, _scalar(nodes.values.get("Subsurface Scale", 0.05), 0.05))
    aniso = _scalar(nodes.values.get("Subsurface Anisotropy", 0.0), 0.0)
    if abs(aniso) > 1e-6:
        warnings.add(subject, f"Subsurface Anisotropy {aniso:g}", "isotropic scattering (the dipole's g = 0)")
    return {"subsurface_weight": weight, "subsurface_radius": radius, "subsurface_scale": scale}


def _clamp01(x: float) -> float:
    return min(1.0, max(0.0, x))

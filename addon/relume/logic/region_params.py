"""The material of one editable region, as the live relight sends it to the relighter.

Read from bpy by the add-on (`relight_values.region_params`) and compared with what was last
sent, so that only regions whose values changed are relit: frozen dataclasses compare by
value, and a region that switches between the two kinds never compares equal.
"""

from __future__ import annotations

from dataclasses import dataclass

Rgb = tuple[float, float, float]


@dataclass(frozen=True)
class OverrideParams:
    """Explicit Blinn–Phong values (the paper's Kd, Ks, ns): the material's override, or a
    material whose nodes map to Blinn–Phong directly."""

    kd: Rgb
    ks: Rgb
    ns: float

    def send(self, relighter, region: str) -> None:
        relighter.set_material(region, self.kd, self.ks, self.ns)


@dataclass(frozen=True)
class PrincipledParams:
    """The Principled BSDF inputs the relighter maps onto the region's basis."""

    base_color: Rgb
    metallic: float
    roughness: float
    ior: float
    specular_ior_level: float
    subsurface_weight: float
    subsurface_radius: Rgb
    subsurface_scale: float

    def send(self, relighter, region: str) -> None:
        relighter.set_principled(region, self.base_color, self.metallic, self.roughness, self.ior,
                                 self.specular_ior_level,
                                 subsurface_weight=self.subsurface_weight,
                                 subsurface_radius=self.subsurface_radius,
                                 subsurface_scale=self.subsurface_scale)


RegionParams = OverrideParams | PrincipledParams

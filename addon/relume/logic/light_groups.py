"""Light groups: Blender's light groups → the scene file's `light_groups`, and their gains.

A stack baked with light groups keeps each group's light in layers of its own, so a group's
strength and colour can change at relight time (radiance is linear in each light's
emission). The cost is that storage and relight time grow by the number of groups.

The core's "scene" grouping (`LightGrouping::Scene`, core/engine/src/geometry/lights/groups.rs)
puts the lights the scene file's `light_groups` do not list — and the world, unless a group
says `"world": true` — into one more group named "default", which every such stack has (even
when it holds nothing). A Blender light group literally named "default" is therefore the
same group as "no light group": it is not written as a group of its own (and the core, for
any scene file that does list one, uses it as the default group rather than adding a second
group of that name).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: The core's group for lights in no light group (and the world, unless it has one).
DEFAULT_GROUP = "default"

#: Preference value → `relume.BakeSettings.light_grouping`.
GROUPING_OF_PREF = {"none": "all", "per_light": "per-light", "scene": "scene"}


def scene_light_groups(light_groups: list[str], world_group: str | None) -> list[dict]:
    """The scene file's `light_groups` entries.

    `light_groups[i]` is the Blender light group of the scene's light `i` ("" for none);
    `world_group` is the world's (None when the scene has no world). Groups are sorted by
    name so the list — which the scene hash covers — does not depend on object order.
    """
    members: dict[str, dict] = {}

    def group(name: str) -> dict:
        return members.setdefault(name, {"name": name, "lights": [], "world": False})

    for i, name in enumerate(light_groups):
        if name and name != DEFAULT_GROUP:
            group(name)["lights"].append(i)
    if world_group and world_group != DEFAULT_GROUP:
        group(world_group)["world"] = True
    return [members[n] for n in sorted(members)]


@dataclass(frozen=True)
class Gain:
    """One light group's live gain: a strength and an RGB colour, both ≥ 0."""

    strength: float = 1.0
    color: tuple = (1.0, 1.0, 1.0)

    def checked(self, group: str) -> Gain:
        """This gain as plain floats; ValueError naming `group` when a value is negative,
        not finite, or the colour does not have three components."""
        color = tuple(float(c) for c in self.color)
        values = (float(self.strength),) + color
        if len(color) != 3:
            raise ValueError(f"light group '{group}': color needs 3 components (R, G, B), "
                             f"got {len(color)}")
        if not all(math.isfinite(v) and v >= 0.0 for v in values):
            raise ValueError(f"light group '{group}': strength and color must be finite and "
                             f"≥ 0, got strength {self.strength}, color {self.color}")
        return Gain(float(self.strength), color)


def unknown_group_message(name: str, groups: list[str]) -> str:
    """Why `name` cannot be set on a stack whose groups are `groups`."""
    if not groups:
        return (f"light group '{name}': the loaded stack has no light groups (set Light Groups "
                f"to Per Light or Blender Light Groups in the Relume preferences and rebake)")
    return f"light group '{name}' is not in the loaded stack (its groups: {', '.join(groups)})"


def group_label(group: str, light_names: list[str]) -> str:
    """The panel's name for `group`: the core names per-light groups "light <i>" after the
    scene's light order, which the user knows by the Blender light's name."""
    if group.startswith("light "):
        index = group[len("light "):]
        if index.isdigit() and int(index) < len(light_names):
            return f"{group} ({light_names[int(index)]})"
    if group == DEFAULT_GROUP:
        return f"{group} (lights and world without a light group)"
    return group


def cost_text(count: int) -> str:
    """The panel's reminder of what the groups cost."""
    return f"{count} light group{'s' if count != 1 else ''}: stack and relight cost ×{count}"

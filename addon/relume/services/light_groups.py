"""Setting a baked light group's live gain from a script."""

from __future__ import annotations

import bpy

from ..logic.light_groups import Gain, unknown_group_message
from ..runtime import RUNTIME
from .errors import BakeError
from .stack import load_stack


def set_light_group(name: str, strength: float = 1.0, color=(1.0, 1.0, 1.0), context=None) -> None:
    """Set a light group's live strength and colour (a stack baked with light groups).

    Stored on the scene like the Relume tab's sliders — saved with the .blend, re-applied when
    the stack reloads — and relit through the same live path; `render()` uses it. Raises
    `BakeError` when there is no stack, `ValueError` for a group the loaded stack does not
    have (its groups are listed) or a negative or non-finite value.
    """
    context = context or bpy.context
    live = RUNTIME.live
    if live.stack is None and not load_stack(context):
        raise BakeError(f"no usable Relume stack: {live.load_error or 'not baked yet'}")
    groups = live.light_groups
    if name not in groups:
        raise ValueError(unknown_group_message(name, groups))
    gain = Gain(strength, tuple(color)).checked(name)
    stored = context.scene.relume_light_groups
    entry = stored.get(name)
    if entry is None:
        entry = stored.add()
        entry.name = name
    entry.strength = gain.strength  # each assignment relights through the update callback
    entry.color = gain.color

"""The stack file of the current scene (bpy side of `logic.stack_paths`)."""

from __future__ import annotations

import os
import tempfile

import bpy

from .logic.stack_paths import stack_file_name, stack_folder
from .ui.prefs import get_prefs


def stack_location(context=None) -> tuple[str, str, bool]:
    """(stack path, texture folder, whether the folder is temporary)."""
    context = context or bpy.context
    prefs = get_prefs(context)
    temp_root = bpy.app.tempdir or tempfile.gettempdir()
    folder, temporary = stack_folder(bpy.data.filepath, prefs.stack_folder, temp_root)
    path = os.path.join(folder, stack_file_name(bpy.data.filepath, context.scene.name))
    return path, os.path.join(folder, "textures"), temporary

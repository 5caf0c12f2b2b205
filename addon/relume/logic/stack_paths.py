"""Where a scene's stack file lives.

Stacks sit beside the .blend by default, in a `relume/` folder, one file per Blender scene:
`<blend name>.<scene name>.relume.exr`. An absolute folder in the preferences overrides the
place (a cache disk, a farm share); a relative one is relative to the .blend, as Blender's
own `//` paths are. An unsaved file has no folder of its own, so its stacks go to the
temporary directory and the panel says so (they would otherwise be lost silently).
"""

from __future__ import annotations

import os
import re

STACK_SUFFIX = ".relume.exr"


def _safe(name: str) -> str:
    """A file-name-safe form of a Blender name (Blender allows '/', ':' and the like)."""
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")
    return cleaned or "scene"


def stack_folder(blend_path: str, folder_setting: str, temp_dir: str) -> tuple[str, bool]:
    """The folder for stacks, and whether it is a temporary one (unsaved .blend).

    `folder_setting` is the preference: "" (beside the .blend), a path starting with "//"
    or relative (relative to the .blend), or absolute.
    """
    setting = folder_setting.strip()
    if setting and os.path.isabs(setting) and not setting.startswith("//"):
        return os.path.normpath(setting), False
    if not blend_path:
        return os.path.join(temp_dir, "relume"), True
    base = os.path.dirname(os.path.abspath(blend_path))
    rel = setting[2:] if setting.startswith("//") else setting
    return os.path.normpath(os.path.join(base, rel or "relume")), False


def stack_file_name(blend_path: str, scene_name: str) -> str:
    """`<blend>.<scene>.relume.exr` (just `<scene>` for an unsaved file)."""
    stem = os.path.splitext(os.path.basename(blend_path))[0] if blend_path else "untitled"
    return f"{_safe(stem)}.{_safe(scene_name)}{STACK_SUFFIX}"

"""Where Blender keeps its OpenImageDenoise, for the relighter's search.

Every Blender ships OIDN: on Linux and Windows in the folder of its binary (`lib/`, and
`blender.shared/` on Windows), on macOS in `Contents/Resources/lib`; the `bpy` wheel keeps it
in `bpy/lib`. Using Blender's own copy means the library (and the TBB it starts) is the one
Blender has already loaded.
"""

from __future__ import annotations

import os


def blender_lib_dirs(binary_path: str, bpy_module_file: str | None) -> list[str]:
    """The existing folders that may hold Blender's OIDN, most likely first."""
    candidates = []
    if binary_path:
        base = os.path.dirname(os.path.abspath(binary_path))
        candidates += [os.path.join(base, "lib"), os.path.join(base, "blender.shared"),
                       os.path.normpath(os.path.join(base, "..", "Resources", "lib"))]
    if bpy_module_file:
        candidates.append(os.path.join(os.path.dirname(os.path.abspath(bpy_module_file)), "lib"))
    seen, out = set(), []
    for d in candidates:
        if d not in seen and os.path.isdir(d):
            seen.add(d)
            out.append(d)
    return out

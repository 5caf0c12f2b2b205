"""Where Blender keeps its OpenImageDenoise, for the relighter's search.

Every Blender ships OIDN: on Linux in the `lib` folder beside its binary, on Windows in
`blender.shared`, on macOS in `Contents/Resources/lib`; the `bpy` wheel keeps it in
`bpy/lib`. Those folders sit beside the binary and a few levels above the `bpy` package's
scripts (`<root>/<version>/scripts/modules/bpy/`, `<root>` being the install folder,
`Contents/Resources` or the wheel's `bpy`). Using Blender's own copy means the library (and
the TBB it starts) is the one Blender has already loaded.
"""

from __future__ import annotations

import os

_FOLDERS = ("lib", "blender.shared")
#: How far above the bpy package's file to look (bpy, modules, scripts, version, root).
_LEVELS = 5


def _holds_oidn(folder: str) -> bool:
    try:
        return any("OpenImageDenoise" in name for name in os.listdir(folder))
    except OSError:
        return False


def blender_lib_dirs(binary_path: str, bpy_module_file: str | None) -> list[str]:
    """The folders that hold an OpenImageDenoise library, the binary's first."""
    bases = []
    if binary_path:
        base = os.path.dirname(os.path.abspath(binary_path))
        bases += [base, os.path.normpath(os.path.join(base, "..", "Resources"))]
    if bpy_module_file:
        d = os.path.dirname(os.path.abspath(bpy_module_file))
        for _ in range(_LEVELS):
            bases.append(d)
            d = os.path.dirname(d)
    out = []
    for base in bases:
        for name in _FOLDERS:
            folder = os.path.join(base, name)
            if folder not in out and _holds_oidn(folder):
                out.append(folder)
    return out

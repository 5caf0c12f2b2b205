"""Relume: bake a scene's global illumination into a transfer stack once, then relight it
for any material in milliseconds. The classes and functions come from the Rust core
(``relume._core``); see core/py/README.md for the API."""

from ._core import (
    __version__,
    # exceptions
    RelumeError,
    SceneError,
    StackError,
    StaleStackError,
    TruncatedStackError,
    ForeignStackError,
    StackVersionError,
    CancelledError,
    MaterialsError,
    BasisError,
    DeviceError,
    RelumeIOError,
    InternalError,
    # scene, bake, stack, relight
    Scene,
    BakeSettings,
    BakeJob,
    bake,
    Stack,
    Relighter,
    principled_to_blinn_phong,
    # images
    write_exr,
    write_png,
    read_exr,
    _debug_panic,
)

__all__ = [
    "__version__",
    "RelumeError",
    "SceneError",
    "StackError",
    "StaleStackError",
    "TruncatedStackError",
    "ForeignStackError",
    "StackVersionError",
    "CancelledError",
    "MaterialsError",
    "BasisError",
    "DeviceError",
    "RelumeIOError",
    "InternalError",
    "Scene",
    "BakeSettings",
    "BakeJob",
    "bake",
    "Stack",
    "Relighter",
    "principled_to_blinn_phong",
    "write_exr",
    "write_png",
    "read_exr",
]

"""pytest setup for the suites that drive real Blender (the `bpy` module, headless).

Blender's user folders are pointed at a temporary directory before `bpy` is imported, so
installing the extension never touches the developer's own Blender. The add-on is installed
once per session from the zip that `scripts/build_addon.sh` builds, through Blender's own
extension installer, exactly as a user's "Install from Disk" does.
"""

from __future__ import annotations

import importlib
import json
import os
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
_USER = tempfile.mkdtemp(prefix="relume-blender-user-")
os.environ.setdefault("BLENDER_USER_RESOURCES", _USER)  # must precede `import bpy`

import bpy  # noqa: E402
import pytest  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))


def addon_zip() -> pathlib.Path:
    """The built extension zip (built now if `dist/` has none)."""
    zips = sorted((ROOT / "dist").glob("relume-*.zip"))
    if not zips:
        subprocess.run(["bash", str(ROOT / "scripts" / "build_addon.sh")], check=True)
        zips = sorted((ROOT / "dist").glob("relume-*.zip"))
    assert zips, "scripts/build_addon.sh made no dist/relume-*.zip"
    return zips[-1]


def install_addon():
    """Installs the built extension zip with Blender's extension installer and enables it, as
    a user does; returns the add-on's module (`bl_ext.user_default.relume`) and its
    preferences. The tests' `addon` fixture and the benchmarks share it."""
    result = bpy.ops.extensions.package_install_files(
        filepath=str(addon_zip()), repo="user_default", enable_on_install=True)
    assert result == {"FINISHED"}, result
    module = importlib.import_module("bl_ext.user_default.relume")
    assert "bl_ext.user_default.relume" in bpy.context.preferences.addons
    return module, bpy.context.preferences.addons["bl_ext.user_default.relume"].preferences


@pytest.fixture(scope="session")
def addon():
    """The installed and enabled add-on's module (`bl_ext.user_default.relume`)."""
    module, _ = install_addon()
    return module


@pytest.fixture(scope="module")
def results_file(request, tmp_path_factory):
    """For the suites that measure against Cycles: when the module's tests have run, its
    `_RESULTS` (figures by test) are written as JSON to pytest's basetemp under the module's
    `RESULTS_NAME`, so a run's figures can be read without its output."""
    module = request.module
    path = tmp_path_factory.getbasetemp() / module.RESULTS_NAME
    yield path
    path.write_text(json.dumps(module._RESULTS, indent=2))
    print(f"\nFigures of {module.__name__}: {path}")


@pytest.fixture
def prefs(addon):
    p = bpy.context.preferences.addons["bl_ext.user_default.relume"].preferences
    saved = {k: getattr(p, k) for k in ("preset", "spp", "light_samples", "indirect_samples",
                                        "bounces", "basis_tolerance", "passes", "resolution_scale",
                                        "device", "stack_folder", "light_groups",
                                        "bounces_from_scene", "material_lobes")}
    p.preset = "custom"
    p.spp = 2
    p.light_samples = 1
    p.indirect_samples = 1
    p.bounces = 1
    p.bounces_from_scene = False
    p.basis_tolerance = 0.05
    p.passes = 1
    p.resolution_scale = 1.0
    p.device = "cpu"
    p.stack_folder = ""
    p.light_groups = "none"
    p.material_lobes = "blinn-phong"
    yield p
    for k, v in saved.items():
        setattr(p, k, v)


@pytest.fixture
def blend_dir(addon, tmp_path):
    """An empty scene saved as tmp_path/test.blend (so stacks go to tmp_path/relume/)."""
    from support.scenes import clear_scene

    clear_scene()
    bpy.context.scene.relume_light_groups.clear()
    addon.runtime.RUNTIME.live.unload()
    addon.runtime.RUNTIME.session = None
    addon.runtime.RUNTIME.warnings = []
    path = tmp_path / "test.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return tmp_path

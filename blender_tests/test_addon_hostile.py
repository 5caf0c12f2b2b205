"""Never crash, never lose work, inside Blender: a hostile, truncated or foreign stack file
beside a .blend shows its error in the panel's status when the file opens, and Blender (this
bpy process) lives on; a bake whose memory estimate exceeds the budget is refused before it
traces, with the estimate in the message, and the previous stack stays as it was."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from support.scenes import box_scene, save_and_reopen

ROOT = __import__("pathlib").Path(__file__).resolve().parent.parent


def _hostile():
    spec = importlib.util.spec_from_file_location("hostile_stack", ROOT / "scripts" / "hostile_stack.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("kind", ["huge claims", "truncated", "foreign"])
def test_a_hostile_stack_beside_the_blend_is_an_error_in_the_panel(addon, prefs, blend_dir, kind):
    import relume

    box_scene(resolution=24)
    addon.api.bake()
    path = addon.api.status()["stack_path"]
    with open(path, "rb") as f:
        good = f.read()
    if kind == "huge claims":
        bad = _hostile().with_claimed_size(good, 16384, 16384)
        expected = "claims 16384×16384 pixels"
    elif kind == "truncated":
        bad = good[: len(good) // 3]
        expected = "truncated"
    else:
        scratch = blend_dir / "plain.exr"
        relume.write_exr(str(scratch), np.ones((4, 4, 3), np.float32))
        bad = scratch.read_bytes()
        expected = "not a Relume transfer stack"
    with open(path, "wb") as f:
        f.write(bad)
    status = save_and_reopen(addon)
    assert not status["loaded"], status
    assert expected in (status["load_error"] or ""), status
    # Blender lives on and the add-on still works: a rebake replaces the bad file.
    addon.api.bake()
    status = addon.api.status()
    assert status["loaded"] and status["load_error"] is None, status


def test_a_bake_over_the_memory_budget_is_refused_with_the_estimate(addon, prefs, blend_dir):
    import relume

    box_scene(resolution=24)
    addon.api.bake()
    path = addon.api.status()["stack_path"]
    with open(path, "rb") as f:
        before = f.read()
    settings = addon.api.bake_settings()
    settings.memory_budget_mb = 0.25
    with pytest.raises(addon.api.BakeError, match="not enough memory for this bake") as info:
        addon.api.bake(settings=settings)
    assert "layers reached by a probe" in str(info.value)
    with open(path, "rb") as f:
        assert f.read() == before, "the refused bake touched the previous stack"
    assert addon.api.status()["loaded"]
    del relume

"""The README's batch example, run as a user runs it: a separate process on the bpy module."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import bpy
import numpy as np
from support.scenes import box_scene

ROOT = pathlib.Path(__file__).resolve().parent.parent


def test_batch_sweep_example(addon, prefs, blend_dir):
    import relume

    box_scene(resolution=24)
    bpy.ops.wm.save_mainfile()
    out = blend_dir / "sweep"
    env = dict(os.environ)  # same BLENDER_USER_RESOURCES: the installed extension
    proc = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "batch_sweep.py"), "--blend", bpy.data.filepath,
         "--material", "Floor", "--input", "Roughness", "--values", "0.2,0.9", "--out", str(out),
         "--png"],
        env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "baking" in proc.stdout  # no stack yet: the example bakes first
    exrs = sorted(out.glob("*.exr"))
    pngs = sorted(out.glob("*.png"))
    assert len(exrs) == 2 and len(pngs) == 2, os.listdir(out)
    a, b = (relume.read_exr(str(p)) for p in exrs)
    assert a.shape == b.shape == (24, 24, 3)
    assert np.isfinite(a).all() and np.isfinite(b).all()
    assert np.abs(a - b).max() > 1e-4, "the sweep's frames are identical"
    # The stack the example baked sits beside the .blend, where the add-on finds it.
    assert list((blend_dir / "relume").glob("*.relume.exr"))

"""pytest setup for the bindings' tests: they run against the installed `relume` wheel
(scripts/test.sh builds and installs it), not against a source tree, as a user's import does."""

from __future__ import annotations

import json
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]


@pytest.fixture
def small_cornell(tmp_path):
    """The assets Cornell scene at 32², as a relume.Scene (2 editable regions)."""
    import relume

    data = json.loads((ROOT / "assets" / "cornell.scene.json").read_text())
    data["resolution"] = {"width": 32, "height": 32}
    return relume.Scene.from_json(json.dumps(data), str(ROOT / "assets"))

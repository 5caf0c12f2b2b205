"""Every bake setting the core declares reaches each front: the add-on's mapping table
(addon/relume/logic/bake_settings_map.py) and the Python type stubs. The settings are read
from their one definition (core/engine/src/bake/fields.rs) and the bindings' own `passes`."""

from __future__ import annotations

import ast
import pathlib
import re
from types import SimpleNamespace

from test_addon_logic import bake_settings_map as m

ROOT = pathlib.Path(__file__).resolve().parent.parent
FIELDS_RS = ROOT / "core" / "engine" / "src" / "bake" / "fields.rs"
STUBS = ROOT / "core" / "py" / "python" / "relume" / "_core.pyi"


def core_settings() -> set[str]:
    """The keys of `bake_fields!` in fields.rs, and `passes` (the bindings' progressive bake)."""
    text = FIELDS_RS.read_text()
    block = text[text.index("bake_fields! {"):]
    block = block[:block.index("\n}\n")]
    keys = set(re.findall(r"^    ([a-z_]+): ", block, re.MULTILINE))
    assert "spp" in keys and "compression_tolerance" in keys, "fields.rs changed shape"
    return keys | {"passes"}


def test_the_addon_says_what_it_does_with_every_bake_setting():
    mapped, left = set(m.PREFERENCE_OF), set(m.NOT_A_PREFERENCE)
    assert not mapped & left, sorted(mapped & left)
    assert mapped | left == core_settings(), (sorted(core_settings() - mapped - left),
                                              sorted(mapped | left - core_settings()))
    assert mapped >= m.CUSTOM_ONLY


def test_the_preferences_become_keywords_by_the_table():
    prefs = SimpleNamespace(preset="custom", spp=2, light_samples=3, indirect_samples=1,
                            basis_tolerance=0.05, bounces=5, material_lobes="blinn-phong",
                            light_groups="per_light", memory_budget_mb=0.0, passes=2)
    preset, kw = m.settings_keywords(prefs, bounces=4)
    assert preset is None
    assert kw == {"spp": 2, "light_samples": 3, "indirect_samples": 1, "basis_tolerance": 0.05,
                  "bounces": 4, "lobe": "blinn-phong", "light_grouping": "per-light", "passes": 2}
    prefs.preset, prefs.memory_budget_mb = "final", 512.0
    preset, kw = m.settings_keywords(prefs, bounces=4)
    assert preset == "final" and not m.CUSTOM_ONLY & set(kw)
    assert kw["memory_budget_mb"] == 512.0
    # Bounces from Cycles: its Diffuse and Glossy limits go with the cap.
    preset, kw = m.settings_keywords(prefs, bounces=8, kinds=(4, 3))
    assert (kw["bounces"], kw["diffuse_bounces"], kw["glossy_bounces"]) == (8, 4, 3)


def test_the_stubs_declare_every_bake_setting():
    tree = ast.parse(STUBS.read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "BakeSettings")
    declared = {n.target.id for n in cls.body if isinstance(n, ast.AnnAssign)}
    assert declared == core_settings(), (sorted(core_settings() - declared), sorted(declared - core_settings()))

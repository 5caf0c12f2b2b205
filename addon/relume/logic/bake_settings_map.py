"""The add-on's preferences → the core's bake settings (`relume.BakeSettings` keywords).

Every bake setting is in exactly one of two tables: `PREFERENCE_OF` names the preference
that sets it, `NOT_A_PREFERENCE` says why the add-on leaves it to the preset or the core's
default. A test compares their keys with the settings the core declares, so a setting added
to the core fails it until this file says what the add-on does with it.
"""

from __future__ import annotations

from .light_groups import GROUPING_OF_PREF

#: Bake setting → the preference (`ui.prefs.RelumePreferences`) that sets it.
PREFERENCE_OF = {
    "spp": "spp",
    "light_samples": "light_samples",
    "indirect_samples": "indirect_samples",
    "basis_tolerance": "basis_tolerance",
    "bounces": "bounces",
    "lobe": "material_lobes",
    "light_grouping": "light_groups",
    "memory_budget_mb": "memory_budget_mb",
    "passes": "passes",
}

#: The settings a preset chooses: the preferences set them only with the custom preset.
CUSTOM_ONLY = frozenset({"spp", "light_samples", "indirect_samples", "basis_tolerance"})

#: Bake setting → why no preference sets it.
NOT_A_PREFERENCE = {
    "bounce_budget": "the preset's: the bake measures the bounces the scene needs",
    "sampling": "the preset's",
    "bounce_light_samples": "the preset's (custom: as many as Light Samples)",
    "diffuse_bounces": "the scene's Cycles Diffuse limit with Bounces from Cycles (else none)",
    "glossy_bounces": "the scene's Cycles Glossy limit with Bounces from Cycles (else none)",
    "seed": "the core's default: a bake is reproducible; scripts set it",
    "resolution": "the render resolution, exported with the scene",
    "resolution_scale": "applied to the render resolution when the scene is exported",
    "precision": "the core's default (f16)",
    "bases": "the basis tolerance picks the count",
    "principled_bases": "the preset's",
    "ns_min": "each editable material's roughness range (Material Properties → Relume)",
    "ns_max": "each editable material's roughness range (Material Properties → Relume)",
    "threads": "every core",
    "drop_budget": "the core's default: every layer a path reached is kept",
    "subsurface_samples": "the core's default, or the material's own",
    "subsurface_theta": "the core's default",
    "denoise_direct": "the preset's",
    "denoise_bounce": "the preset's",
    "compression_step": "the preset's",
    "compression_tolerance": "the preset's",
    "adaptive_threshold": "the core's default (off): no preset adopts it yet; scripts set it",
    "adaptive_min_spp": "the core's default (automatic); scripts set it",
}

def settings_keywords(prefs, bounces: int, kinds: tuple[int, int] | None = None) -> tuple[str | None, dict]:
    """(preset name or None for custom, keywords) for `relume.BakeSettings` from `prefs`
    (any object with the preferences' attributes), the bounce cap to bake with and, when the
    bounces come from Cycles' light paths, its (Diffuse, Glossy) limits."""
    custom = prefs.preset == "custom"
    keywords = {}
    for setting, pref in PREFERENCE_OF.items():
        if setting in CUSTOM_ONLY and not custom:
            continue
        keywords[setting] = getattr(prefs, pref)
    keywords["bounces"] = bounces
    if kinds is not None:
        keywords["diffuse_bounces"], keywords["glossy_bounces"] = kinds
    keywords["light_grouping"] = GROUPING_OF_PREF[keywords["light_grouping"]]
    # 0 MiB is the preference's "no budget of my own": the core's default.
    if not keywords["memory_budget_mb"] or keywords["memory_budget_mb"] <= 0.0:
        del keywords["memory_budget_mb"]
    return (None if custom else prefs.preset), keywords

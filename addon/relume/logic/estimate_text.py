"""The bake estimate (`relume.estimate_bake`) as short lines of text, for the panel and the
Estimate operator's reports."""

from __future__ import annotations


def estimate_lines(est: dict | None) -> list[str]:
    """The estimate as the panel shows it, one short line each."""
    if not est:
        return []
    mb = 1e6
    lines = [f"Estimate: {est['layers_reached']} of {est['layers_possible']} layers, "
             f"peak {est['peak_bytes'] / mb:.0f} MB, stack {est['stack_bytes'] / mb:.0f} MB"]
    for r in est.get("editable", []):
        lo, hi = r["roughness_range"]
        lines.append(f"{r['region']}: roughness {lo:.2f}–{hi:.2f} (ns ≤ {r['ns_range'][1]:.0f}) → "
                     f"{r['bases']} bases, {r['slots']} slots")
    return lines

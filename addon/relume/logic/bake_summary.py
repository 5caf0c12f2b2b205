"""One line that says what a finished bake made, for the panel's status and the operator's
report: what a user needs to judge the stack (layers stored of those possible, its size in
memory against full frames, and what the bounce compression cost), not just the time."""

from __future__ import annotations


def bake_summary(result: dict) -> str:
    """`result` is `relume.BakeJob.result()`'s dict; its `report` is the core's BakeReport."""
    parts = [f"baked in {float(result.get('seconds', 0.0)):.1f} s"]
    report = result.get("report") or {}
    if "layers_possible" in report:
        stored = int(report.get("layers_grey", 0)) + int(report.get("layers_rgb", 0))
        parts.append(f"{stored} of {report['layers_possible']} layers")
    stored_bytes = report.get("stored_bytes")
    if stored_bytes:
        dense = report.get("dense_bytes") or stored_bytes
        parts.append(f"{stored_bytes / 1e6:.0f} MB ({dense / 1e6:.0f} MB as full frames)")
    error = report.get("compression_error")
    if error:
        parts.append(f"compression error {100 * float(error):.2f} %")
    kept_out = sum(int(v) for v in (report.get("non_finite") or {}).values())
    if kept_out:
        parts.append(f"{kept_out} non-finite values kept out (see warnings)")
    return " · ".join(parts)

"""Named warnings for what the exporter cannot map, and the fallback it used instead.

A Blender scene can hold anything; Relume models Principled BSDF surfaces, the four light
types, a world colour or equirectangular image and one camera. Whatever else it meets is
never dropped silently: each case becomes one `ExportWarning` naming the datablock, what was
not mapped and what was used in its place. The add-on shows them in the panel and through
`operator.report({'WARNING'}, ...)`; scripts get them from `ExportResult.warnings`.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ExportWarning:
    """One thing the exporter could not map.

    `subject` names the Blender datablock ("Material 'Glass'", "Light 'Key'"), `what` the
    feature it met ("Transmission Weight 1.0"), `fallback` what Relume used instead.
    """

    subject: str
    what: str
    fallback: str

    def __str__(self) -> str:
        return f"{self.subject}: {self.what} is not supported; {self.fallback}"


class WarningList:
    """Collects warnings without repeating the same one (one per subject and feature)."""

    def __init__(self) -> None:
        self._items: list[ExportWarning] = []
        self._seen: set[tuple[str, str]] = set()

    def add(self, subject: str, what: str, fallback: str) -> None:
        key = (subject, what)
        if key not in self._seen:
            self._seen.add(key)
            self._items.append(ExportWarning(subject, what, fallback))

    def items(self) -> list[ExportWarning]:
        return list(self._items)

    def __len__(self) -> int:
        return len(self._items)

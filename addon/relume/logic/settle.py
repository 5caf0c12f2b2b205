"""When the live image is denoised: once the edits have settled.

While a slider moves, each relight shows the raw relit image (milliseconds); OpenImageDenoise
takes far longer (a few hundred ms at 512² on a CPU), so it runs only when no edit has come
for `delay` seconds, and the denoised image then replaces the raw one. Every edit pushes
that moment back.
"""

from __future__ import annotations

import time
from collections.abc import Callable

#: Seconds without an edit before the shown image is denoised: long enough that a slider
#: dragged at a steady pace does not pause on it, short enough to feel immediate on release.
SETTLE_DELAY_S = 0.3


class Settle:
    """Tracks the last edit; `remaining()` says how long until the image may be denoised."""

    def __init__(self, delay: float = SETTLE_DELAY_S, clock: Callable[[], float] = time.perf_counter):
        if not delay >= 0.0:
            raise ValueError(f"settle delay must be >= 0, got {delay}")
        self.delay = delay
        self._clock = clock
        self._last_edit: float | None = None
        #: Counts the edits: a denoised image of an earlier generation is out of date.
        self.generation = 0

    def touch(self) -> None:
        """An edit was shown raw: the denoised image is due `delay` seconds from now."""
        self._last_edit = self._clock()
        self.generation += 1

    @property
    def pending(self) -> bool:
        return self._last_edit is not None

    def remaining(self) -> float:
        """Seconds until the denoised image is due (0: now); 0 when nothing is pending."""
        if self._last_edit is None:
            return 0.0
        return max(0.0, self._last_edit + self.delay - self._clock())

    def take(self) -> bool:
        """True (and nothing pending afterwards) when the denoised image is due now."""
        if self._last_edit is None or self.remaining() > 0.0:
            return False
        self._last_edit = None
        return True

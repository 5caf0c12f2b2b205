"""Rate limiting for the live relight.

A slider drag in Blender fires a depsgraph update for every mouse move (often > 100 per
second). Relighting each one would queue work behind the user's hand, so the handler lets
one relight through per interval and leaves the last change pending; a timer picks it up
when the interval has passed, so the final slider position is always shown.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class Throttle:
    """At most one action per `interval` seconds; later requests become pending.

    The default 1/60 s keeps the image at display rate while a 512² CPU relight (a few ms)
    leaves the UI thread mostly free.
    """

    def __init__(self, interval: float = 1.0 / 60.0, clock: Callable[[], float] = time.perf_counter):
        if not interval >= 0.0:
            raise ValueError(f"throttle interval must be >= 0, got {interval}")
        self.interval = interval
        self._clock = clock
        self._last = -float("inf")
        self.pending = False

    def remaining(self) -> float:
        """Seconds until the next action may run (0 when it may run now)."""
        return max(0.0, self._last + self.interval - self._clock())

    def request(self) -> bool:
        """True when the caller may act now (and records it); False marks it pending."""
        if self.remaining() <= 0.0:
            self._last = self._clock()
            self.pending = False
            return True
        self.pending = True
        return False

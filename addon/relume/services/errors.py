"""The errors the services raise for a bake or a relight that cannot be done."""

from __future__ import annotations


class BakeError(RuntimeError):
    """A bake that did not complete (cancelled or failed); the message says which and why."""


class BakeCancelled(BakeError):
    """The bake was cancelled (Esc, the Cancel button, `cancel_bake()`); nothing was lost."""

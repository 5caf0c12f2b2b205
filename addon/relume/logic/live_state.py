"""The live relight's state: the loaded stack, its relighter, and what was last applied.

Material values arrive as `RegionParams` (read from bpy by the add-on); only regions whose
values changed since the last relight are sent to the relighter, which then re-sums only the
layers whose signature holds those regions (the core's incremental path). A stack that does
not match the current scene is kept but marked stale and never relit from.

Light group gains (stacks baked with light groups) follow the same rule: only changed gains
are sent, and a changed gain alone is reason enough to relight.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

from .region_params import RegionParams


@dataclass
class RelightOutcome:
    image: object  # numpy (h, w, 4) float32, rows top first unless `bottom_first`
    changed: list
    relight_ms: float
    bottom_first: bool = False  # rows in Blender's order (the live image's)
    #: The relighter's report of what was done to the image shown (`last_denoise`).
    denoise: dict | None = None


class LiveState:
    def __init__(self) -> None:
        self.stack = None
        self.relighter = None
        self.stack_path = ""
        self.stale_reason: str | None = None
        self.load_error: str | None = None
        #: Why the last live relight failed (a refused material value), for the panel.
        self.relight_error: str | None = None
        self.applied: dict[str, RegionParams] = {}
        #: Light group → (strength, (r, g, b)) last sent to the relighter.
        self.applied_gains: dict[str, tuple] = {}
        #: Timings of the last live relight (`live_image.relight_now`), for the panel and
        #: the edit-latency benchmark: the whole call, the relight alone (as Python sees
        #: it) and the copy of its pixels into the Blender image.
        self.last_latency_ms: float | None = None
        self.last_relight_ms: float | None = None
        self.last_upload_ms: float | None = None
        #: Folders that may hold Blender's OpenImageDenoise (`logic.oidn_dirs`), set by the
        #: add-on; and the report of the last image shown (which denoiser ran, and why).
        self.oidn_dirs: list[str] = []
        self.last_denoise: dict | None = None
        #: The report of the last `refine` (passes so far for the current edit), and whether
        #: the relighter was given the scene a refinement traces.
        self.last_refine: dict | None = None
        self.refinable = False

    @property
    def ready(self) -> bool:
        return self.relighter is not None and self.stale_reason is None

    @property
    def range_warnings(self) -> list[str]:
        """One sentence per editable material whose roughness (exponent) lies outside the
        range its basis was baked for: it is relit at the range's edge, and this says so."""
        if self.relighter is None:
            return []
        return [w["message"] for w in self.relighter.warnings]

    @property
    def device_text(self) -> str:
        if self.relighter is None:
            return "no stack loaded"
        return f"{self.relighter.device.upper()}: {self.relighter.device_reason}"

    def unload(self) -> None:
        self.stack = None
        self.relighter = None
        self.last_refine = None
        self.refinable = False
        self.applied = {}
        self.applied_gains = {}

    def load(self, stack_path: str, scene=None, device: str = "auto") -> bool:
        """Load the stack at `stack_path`; with `scene`, check that it was baked from it.

        Returns whether a usable (loaded and not stale) stack is there. Errors are kept in
        `load_error` for the panel rather than raised: a missing or broken stack is a state
        the user fixes by baking, not a crash.
        """
        import relume

        self.unload()
        self.stack_path = stack_path
        self.stale_reason = None
        self.load_error = None
        if not os.path.exists(stack_path):
            self.load_error = "not baked yet"
            return False
        try:
            self.stack = relume.Stack.load(stack_path)
            if scene is not None:
                self.check(scene)
            # The scene gives the denoiser its pixel features; a stale one is not the stack's.
            features_from = scene if scene is not None and self.stale_reason is None else None
            self.relighter = relume.Relighter(self.stack, device, scene=features_from)
            # The refinement traces the scene: without it there is none to run.
            self.refinable = features_from is not None
        except relume.RelumeError as e:
            self.load_error = f"{type(e).__name__}: {e}"
            self.unload()
            return False
        return self.stale_reason is None

    def check(self, scene) -> bool:
        """Mark the stack stale when `scene` (a fresh export) is not what it was baked from."""
        import relume

        if self.stack is None:
            return False
        try:
            self.stack.check_scene(scene)
            self.stale_reason = None
        except relume.StaleStackError as e:
            self.stale_reason = str(e)
        return self.stale_reason is None

    def apply(self, params: dict[str, RegionParams], force: bool = False) -> list[str]:
        """Send changed regions' materials to the relighter; returns the regions changed."""
        changed = []
        for region, p in params.items():
            if not force and self.applied.get(region) == p:
                continue
            p.send(self.relighter, region)
            self.applied[region] = p
            changed.append(region)
        return changed

    @property
    def light_groups(self) -> list[str]:
        """The loaded stack's light groups ([] without a stack or when baked without)."""
        return list(self.stack.light_groups) if self.stack is not None else []

    def apply_gains(self, gains: dict[str, tuple], force: bool = False) -> list[str]:
        """Send changed light group gains, (strength, (r, g, b)) by group name, to the
        relighter; groups the stack does not have are skipped (gains stored for another
        bake's groups). Returns the groups changed."""
        groups = set(self.light_groups)
        changed = []
        for name, (strength, color) in gains.items():
            if name not in groups or (not force and self.applied_gains.get(name) == (strength, color)):
                continue
            self.relighter.set_light_group(name, strength, color)
            self.applied_gains[name] = (strength, color)
            changed.append(name)
        return changed

    def relight(self, params: dict[str, RegionParams], force: bool = False,
                gains: dict[str, tuple] | None = None,
                bottom_first: bool = False, denoise: str = "none",
                refined: bool = False) -> RelightOutcome | None:
        """Apply `params` (and light group `gains`) and relight; None when nothing changed
        (and not forced). `bottom_first`: the image's rows in Blender's order, for the live
        image. `denoise`: "none" (the raw relit image) or "oidn" (the shown image, the
        linear one when OIDN cannot run: `last_denoise` says which). `refined`: with what
        `refine` traced for these very values added (nothing for other values)."""
        if not self.ready:
            return None
        changed = self.apply(params, force)
        changed += self.apply_gains(gains or {}, force)
        if not changed and not force:
            return None
        t0 = time.perf_counter()
        # The relighter copies its image out either way (its own buffer stays for the next
        # incremental sum); asking it for Blender's row order makes that copy the flip, so
        # the live image is written from it directly, with no second frame-sized copy.
        image = self.relighter.relight(flip_y=bottom_first, denoise=denoise,
                                       oidn_dirs=self.oidn_dirs, refined=refined)
        self.last_relight_ms = (time.perf_counter() - t0) * 1e3
        self.last_denoise = self.relighter.last_denoise
        return RelightOutcome(image=image, changed=changed, relight_ms=self.last_relight_ms,
                              bottom_first=bottom_first, denoise=self.last_denoise)

    def refine(self, seconds: float, max_passes: int | None = None) -> dict | None:
        """Refine the current edit for about `seconds` (the relighter's `refine`: what the
        relight misses past the second bounce, traced with the edited materials and kept
        for `refined` images); its report, or None without a usable stack."""
        if not self.ready:
            return None
        self.last_refine = self.relighter.refine(seconds=seconds, max_passes=max_passes)
        return self.last_refine

    def refine_status(self) -> str | None:
        """One line for the panel about the last refinement; None when there is none."""
        r = self.last_refine
        if not r or not r["needed"]:
            return None
        done = r["passes"] >= r["bake_samples"]
        return (f"Refined: {r['passes']} passes" if done else
                f"Refining: {r['passes']} of {r['bake_samples']} passes")

    def shown(self, bottom_first: bool = False, denoise: str = "oidn",
              refined: bool = False) -> RelightOutcome | None:
        """The current image as shown (`denoise`: "oidn" at the live image's quality, or
        "none"), with the refinement of these values added when `refined`; nothing
        re-summed. None without a usable stack."""
        if denoise == "oidn":
            return self.denoised(bottom_first=bottom_first, refined=refined)
        if not self.ready:
            return None
        t0 = time.perf_counter()
        image = self.relighter.relight(flip_y=bottom_first, denoise="none", refined=refined)
        self.last_denoise = self.relighter.last_denoise
        return RelightOutcome(image=image, changed=[], relight_ms=(time.perf_counter() - t0) * 1e3,
                              bottom_first=bottom_first, denoise=self.last_denoise)

    def denoised(self, bottom_first: bool = False, quality: str = "balanced",
                 refined: bool = False) -> RelightOutcome | None:
        """The current image through OpenImageDenoise, nothing re-summed (the edits are
        already in the relighter's image); None without a usable stack. `quality`: OIDN's
        "balanced" for the live image (its advice for interactive use, about a third of
        the time of "high" on a CPU, docs/denoise.md), "high" for renders."""
        if not self.ready:
            return None
        t0 = time.perf_counter()
        image = self.relighter.relight(flip_y=bottom_first, denoise="oidn", oidn_dirs=self.oidn_dirs,
                                       oidn_quality=quality, refined=refined)
        self.last_denoise = self.relighter.last_denoise
        return RelightOutcome(image=image, changed=[], relight_ms=(time.perf_counter() - t0) * 1e3,
                              bottom_first=bottom_first, denoise=self.last_denoise)

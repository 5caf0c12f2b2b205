"""The "Relume" image: relit from the scene's current values and written with `foreach_set`.

Relights are throttled: `request_relight` relights now when the throttle allows it, else once
its interval has passed (a timer; in background mode, at once, as there is no event loop).
Light group gains (the scene's `relume_light_groups`, the Relume tab's sliders) take the
same throttled path.

Each live relight shows the raw relit image; when the edits settle (`logic.settle`: no edit
for a short delay) and the preference *Denoise Shown Image* is on, the image is replaced by
the same relight through OpenImageDenoise. OIDN takes up to seconds, so it runs on a worker
thread (the relighter releases the GIL, and its raw relights do not wait for it) and a timer
writes its image on Blender's thread unless an edit came meanwhile. Then, with the
preference *Refine After Edits* on, the same worker refines the edit (the relighter's
`refine`: bounces past the second traced again with the edited materials) about a second at a
time and each refined image replaces the last, until the refinement has covered the bake's
own samples; the next edit cancels it. Headless there is no event loop and so no timer: the
live image stays raw, and scripts get the shown image from `api.render` (its `refine` seconds
refine it first), or call `show_settled`, the same denoise step done at once.
"""

from __future__ import annotations

import contextlib
import threading
import time

import bpy
import numpy as np

from .logic.oidn_dirs import blender_lib_dirs
from .relight_values import current_gains, current_params, sync_light_groups
from .runtime import RUNTIME
from .ui.prefs import get_prefs

IMAGE_NAME = "Relume"

#: Seconds of refinement between two refined images: long enough for a pass at 512² on two
#: cores, short enough that the image visibly improves.
REFINE_STEP_S = 1.0


def _bottom_first(pixels: np.ndarray) -> np.ndarray:
    """`pixels` with its rows reversed (Blender's order), as the contiguous float32 array
    `foreach_set` copies from at memory speed. Written into one buffer kept for the session
    (`RUNTIME.upload_buffer`), so such a write allocates nothing the size of the frame. The
    live relight does not come here: it asks the relighter for Blender's order directly."""
    buf = RUNTIME.upload_buffer
    if buf is None or buf.shape != pixels.shape:
        buf = RUNTIME.upload_buffer = np.empty(pixels.shape, np.float32)
    np.copyto(buf, pixels[::-1])
    return buf


def write_image(pixels: np.ndarray, bottom_first: bool = False) -> bpy.types.Image:
    """Put an (h, w, 4) float image into the "Relume" image: rows top first (the relighter's
    default order, flipped here), or already bottom first (Blender's order, written as is)."""
    h, w = pixels.shape[0], pixels.shape[1]
    img = bpy.data.images.get(IMAGE_NAME)
    if img is not None and (img.size[0] != w or img.size[1] != h or not img.is_float):
        bpy.data.images.remove(img)
        img = None
    if img is None:
        img = bpy.data.images.new(IMAGE_NAME, width=w, height=h, alpha=True, float_buffer=True)
        # Older colour-management configs name it "Linear"; float images default to it.
        with contextlib.suppress(TypeError):
            img.colorspace_settings.name = "Linear Rec.709"
    rows = pixels if bottom_first else _bottom_first(pixels)
    img.pixels.foreach_set(rows.ravel())
    img.update()
    return img


def relight_now(force: bool = False) -> bool:
    """Relight from the current material values; True when the image was updated."""
    import relume

    t0 = time.perf_counter()
    try:
        outcome = RUNTIME.live.relight(current_params(), force=force, gains=current_gains(),
                                       bottom_first=True)
    except relume.RelumeError as e:
        # A value the relighter refuses (an override with Kd + Ks > 1, say) or a failure in
        # the relight: shown in the panel, never raised into Blender's handlers.
        RUNTIME.live.relight_error = f"{type(e).__name__}: {e}"
        _redraw_image_editors()
        return False
    RUNTIME.live.relight_error = None
    if outcome is None:
        return False
    t_upload = time.perf_counter()
    write_image(outcome.image, bottom_first=outcome.bottom_first)
    t_end = time.perf_counter()
    RUNTIME.live.last_upload_ms = (t_end - t_upload) * 1e3
    RUNTIME.live.last_latency_ms = (t_end - t0) * 1e3
    _redraw_image_editors()
    _schedule_settled()
    return True


def denoise_mode(context=None) -> str:
    """"oidn" when the preference asks for the denoised image, else "none"."""
    return "oidn" if get_prefs(context).denoise else "none"


def refine_enabled(context=None) -> bool:
    """Whether the preference asks for the background refinement after an edit."""
    return bool(getattr(get_prefs(context), "refine", False))


def set_oidn_dirs() -> None:
    """Point the relighter's OpenImageDenoise search at Blender's own copy."""
    RUNTIME.live.oidn_dirs = blender_lib_dirs(bpy.app.binary_path, getattr(bpy, "__file__", None))


def show_settled() -> bool:
    """Replace the Relume image by the current relight through OpenImageDenoise (the
    linear image, with the reason in `last_denoise`, where OIDN cannot run). True when
    the image was written."""
    import relume

    if denoise_mode() != "oidn":
        return False
    try:
        outcome = RUNTIME.live.denoised(bottom_first=True)
    except relume.RelumeError as e:
        RUNTIME.live.relight_error = f"{type(e).__name__}: {e}"
        _redraw_image_editors()
        return False
    if outcome is None:
        return False
    write_image(outcome.image, bottom_first=True)
    _redraw_image_editors()
    return True


def _settle_timer():
    remaining = RUNTIME.settle.remaining()
    if remaining > 0.0:
        return remaining + 1e-3
    RUNTIME.settle_timer_registered = False
    if RUNTIME.settle.take() and (denoise_mode() == "oidn" or refine_enabled()):
        _start_settled_worker()
    return None


def _start_settled_worker() -> None:
    """OIDN, then the refinement, on a worker thread; `_poll_settled` writes each image it
    posts on Blender's thread."""
    import relume

    generation, relighter = RUNTIME.settle.generation, RUNTIME.live.relighter
    live = RUNTIME.live
    mode, refine = denoise_mode(), refine_enabled() and live.refinable

    def current() -> bool:
        return generation == RUNTIME.settle.generation and relighter is live.relighter

    def post(outcome, error=None) -> None:
        RUNTIME.settled_result = (generation, relighter, outcome, error)

    def work():
        try:
            if mode == "oidn":
                post(live.denoised(bottom_first=True))
            while refine and current():
                report = live.refine(REFINE_STEP_S)
                if report is None or not report["needed"] or not current():
                    break
                post(live.shown(bottom_first=True, denoise=mode, refined=True))
                if report["passes"] >= report["bake_samples"]:
                    break
        except relume.RelumeError as e:
            post(None, f"{type(e).__name__}: {e}")

    RUNTIME.settled_result = None
    RUNTIME.settled_worker = threading.Thread(target=work, name="relume-settled", daemon=True)
    RUNTIME.settled_worker.start()
    bpy.app.timers.register(_poll_settled, first_interval=0.05)


def _poll_settled():
    result = RUNTIME.settled_result
    worker = RUNTIME.settled_worker
    running = worker is not None and worker.is_alive()
    if result is None:
        return 0.05 if running else None
    RUNTIME.settled_result = None
    generation, relighter, outcome, error = result
    # An edit since (a newer raw image is shown, a newer denoise is due) or another stack:
    # this image is out of date.
    if generation != RUNTIME.settle.generation or relighter is not RUNTIME.live.relighter:
        return 0.05 if running else None
    if error is not None:
        RUNTIME.live.relight_error = error
    elif outcome is not None:
        write_image(outcome.image, bottom_first=True)
    _redraw_image_editors()
    return 0.05 if running or RUNTIME.settled_result is not None else None


def _schedule_settled() -> None:
    """After a raw live relight: any refinement under way stops, and the denoised (and
    refined) image follows once the edits settle (not headless: no timers run there)."""
    relighter = RUNTIME.live.relighter
    if relighter is not None:
        relighter.cancel_refine()
    if bpy.app.background or (denoise_mode() != "oidn" and not refine_enabled()):
        return
    RUNTIME.settle.touch()
    if not RUNTIME.settle_timer_registered:
        RUNTIME.settle_timer_registered = True
        bpy.app.timers.register(_settle_timer, first_interval=RUNTIME.settle.remaining() + 1e-3)


def on_stack_loaded() -> None:
    """After a (re)load: the scene's light group entries, then a full relight with its gains."""
    sync_light_groups()
    relight_now(force=True)


def _redraw_image_editors() -> None:
    wm = getattr(bpy.context, "window_manager", None)
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type in ("IMAGE_EDITOR", "PREFERENCES", "PROPERTIES"):
                area.tag_redraw()


def _pending_relight():
    RUNTIME.relight_timer_registered = False
    if RUNTIME.throttle.pending and RUNTIME.throttle.request():
        relight_now()
    return None


def request_relight() -> None:
    """Relight now if the throttle allows it, else once the interval has passed."""
    if RUNTIME.throttle.request():
        relight_now()
    elif not bpy.app.background and not RUNTIME.relight_timer_registered:
        RUNTIME.relight_timer_registered = True
        bpy.app.timers.register(_pending_relight, first_interval=RUNTIME.throttle.remaining() + 1e-3)
    elif bpy.app.background:
        # No timers without an event loop: a script's edit must still land, so run it.
        RUNTIME.throttle.pending = False
        relight_now()

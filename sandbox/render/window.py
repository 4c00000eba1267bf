"""The interactive window (Taichi GGUI), drawing through the same Renderer as headless video.

Keys: space pause/resume, s single step while paused, r reset, Esc or q quit. The full sandbox (tools, panels,
readouts) grows here; headless runs never import GGUI.
"""

from __future__ import annotations

import os

import taichi as ti

from ..errors import SandboxError
from .raster import Renderer


def window_unavailable_reason() -> str | None:
    """Why no window can be opened here (no display), or None when one may be tried."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display"
    return None


def run_window(sim, frames: int | None = None, screenshot: str | None = None, substeps: int | None = None) -> int:
    """Show the simulation in a GGUI window until closed (or for `frames` frames); returns frames shown.

    Raises SandboxError with one line when no window can be opened (e.g. no Vulkan driver).
    """
    cfg = sim.scene.render
    renderer = Renderer(sim, cfg.width, cfg.height, cfg)
    try:
        window = ti.ui.Window(f"sandbox: {sim.scene.name}", (cfg.width, cfg.height), vsync=True)
    except Exception as exc:  # GGUI raises RuntimeError without Vulkan; keep the message to one line
        first_line = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SandboxError(f"cannot open a window: {first_line}") from None
    canvas = window.get_canvas()
    paused = False
    shown = 0
    while window.running:
        single = False
        for event in window.get_events(ti.ui.PRESS):
            if event.key in (ti.ui.ESCAPE, "q"):
                window.running = False
            elif event.key == ti.ui.SPACE:
                paused = not paused
            elif event.key == "s":
                single = True
            elif event.key == "r":
                sim.reset()
        if not window.running:
            break
        renderer.begin_frame()
        if not paused:
            sim.advance_frame(substeps)
        elif single:
            sim.step(1)
        sim.stats()  # the guard: a non-finite state stops with a named error instead of drawing garbage
        renderer.render()
        canvas.set_image(renderer.image)
        shown += 1
        last = frames is not None and shown >= frames
        if last and screenshot:
            window.save_image(screenshot)
        window.show()
        if last:
            break
    window.destroy()
    return shown

"""The interactive window (Taichi GGUI), drawing through the same Renderer as headless video.

Keys (also listed by the help overlay, h): space pause/resume, s single step, r reset, Tab next tool (heat, cool,
drag, attract, repel, impulse, erase, spawn), Up and Down brush radius, Right and Left substeps per frame, g gravity
on/off, i next integrator, m next spawn material, p screenshot, z undo the last tool stroke, w save the state, o
load it back, x full screen, q or Esc quit (GGUI reports letters and named keys only: no digits, brackets or F keys).
The left mouse button applies the tool at the cursor (2D scenes); in 3D the mouse orbits (left), zooms (right) and
pans (middle). The side panel shows only the controls the scene uses (no heat tools without heat).
Everything the keys do goes through WindowState.handle_key, which needs no screen, so it is tested directly.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import taichi as ti

from ..core import runtime, taichi_compat
from ..errors import SandboxError
from ..render.raster import Renderer
from .controller import Controller
from .pacing import FramePacer
from .probe import particle_at, probe
from .window_panel import PANEL_WIDTH, draw_panel
from .window_parts import FRAME_PARTS, FrameClock, OrbitCamera, Recorder, ResizeWatch, screen_size
from .window_state import apply_requests, make_state, quick_save_path, view_config

__all__ = ["FRAME_PARTS", "WindowRun", "WindowUnavailable", "run_window", "window_unavailable_reason"]


class WindowUnavailable(SandboxError):
    """No window can be opened here (no display, no Vulkan driver): the CLI runs headless instead."""


def window_unavailable_reason() -> str | None:
    """Why no window can be opened here (no display), or None when one may be tried."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display"
    return None


def open_window(name: str, shape: tuple[int, int], show: bool = True, pos: tuple[int, int] = (100, 100)):
    """A GGUI window titled for scene `name`, `shape` (width, height) pixels, its top-left corner at `pos`; a
    WindowUnavailable with one line where none can be opened (no Vulkan driver)."""
    try:
        return ti.ui.Window(f"sandbox: {name}", tuple(shape), vsync=True, show_window=show, pos=tuple(pos))
    except Exception as exc:  # GGUI raises RuntimeError without Vulkan; keep the message to one line
        first_line = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise WindowUnavailable(f"cannot open a window: {first_line}") from None


def window_output(canvas) -> str:
    """The renderer output a window shows: GGUI's packed RGBA on the CPU backend, where this Taichi's canvas takes
    it as it is (its set_image would convert a float image over every pixel each frame), else the float image."""
    if not taichi_compat.has_field_info():  # what Renderer.show_on calls
        return "image"
    return "rgba" if runtime.running_arch() == "cpu" and hasattr(canvas, "canvas") else "image"


def run_window(
    sim,
    frames: int | None = None,
    screenshot: str | None = None,
    substeps: int | None = None,
    show: bool = True,
    record: str | None = None,
    timings: dict[str, list[float]] | None = None,
    steady: bool = True,
    size: tuple[int, int] | None = None,
) -> WindowRun:
    """Show the simulation in a GGUI window until closed (or for `frames` frames); returns the frames shown and the
    scene the user picked to switch to, if any (the caller opens it: open_scene, then run_window again). `record`:
    write the frames to this video from the start (the v key starts and stops recordings to out/SCENE_N.mp4).
    `timings`: append each frame's seconds by part (FRAME_PARTS, and "frame" for the whole loop) to these lists
    (the benchmark; it waits for each part's kernels to finish). `steady`: pace the substeps to hold the frame rate
    (FramePacer); False runs the wanted substeps every frame whatever they cost. `size`: the window's (width,
    height) in pixels (default: render.width and render.height); the window can be resized, and the picture is
    drawn again at its new size (text, charts and framing follow).

    Raises SandboxError with one line when no window can be opened (e.g. no Vulkan driver).
    """
    loop = WindowLoop(sim, substeps, show, record, timings, size)
    try:
        while loop.window.running:
            last = frames is not None and loop.shown + 1 >= frames
            if loop.frame(steady, screenshot if last else None) or last:
                break
    finally:
        message = loop.recorder.update(False, loop.renderer)
        if message:
            print(message)
        loop.window.destroy()
    return WindowRun(loop.shown, loop.state.switch_to or None, loop.shape)


class WindowLoop:
    """One window's loop over its simulation's controller: events in (keys through WindowState, the mouse as
    strokes and camera moves), a frame advanced and drawn, the panel and the picture shown (run_window drives it)."""

    def __init__(self, sim, substeps, show: bool, record, timings, size) -> None:
        cfg = sim.scene.render
        self.sim, self.cfg, self.show, self.timings = sim, cfg, show, timings
        self.shape = self.windowed = tuple(size or (cfg.width, cfg.height))
        self.window = open_window(sim.scene.name, self.shape, show)
        self.full_screen = False
        self.canvas, self.gui = self.window.get_canvas(), self.window.get_gui()
        self.output = window_output(self.canvas)
        self.state = make_state(sim, substeps)
        self.view = view_config(cfg, self.state)  # the renderer's configuration; toggles rebuild it when they differ
        self.size = picture_size(sim, *self.shape)  # what the renderer draws; GGUI stretches it to the window
        self.renderer = self.new_renderer()
        self.control = Controller(sim)
        self.state.recording = record is not None
        self.recorder = Recorder(sim.scene.name, *self.size, cfg.fps, record)
        self.chart_series = tuple(cfg.chart)
        self.potential_shown = (False, 1.0, 1.0)
        painter = self.renderer.painter
        self.orbit = OrbitCamera(painter.eye_np, painter.target_np) if sim.dim == 3 else None
        self.last_cursor = None
        if sim.hood is not None and sim.hood.order is not None:
            # sort the storage now: the sort's kernel loads before the first frame, not as a pause of a tenth of a
            # second or more at its first use mid-interaction
            sim.hood.order.apply()
        self.save_path = quick_save_path(sim)
        self.shown, self.fps, self.last = 0, 0.0, time.perf_counter()
        self.clock = FrameClock(timings)
        self.pacer = FramePacer()
        self.resize = ResizeWatch(self.shape)

    def new_renderer(self) -> Renderer:
        """A renderer at the picture size with the view's settings; its motion-blur tails move with the particles."""
        renderer = Renderer(
            self.sim.model, self.sim.state, *self.size, self.view, self.output, panel=PANEL_WIDTH, room_for_charts=True
        )
        self.sim.state.carry(renderer.tails)
        return renderer

    def frame(self, steady: bool, save_as: str | None = None) -> bool:
        """One frame of the loop (its picture saved to `save_as` as well, if given); True when the user asked to
        quit."""
        state = self.state
        self.clock.start()
        frame_start = time.perf_counter()
        if self.show:  # a hidden window (show_window=False, for tests) has no events or cursor
            for event in self.window.get_events(ti.ui.PRESS):
                state.handle_key(event.key)
        if state.quit:
            return True
        apply_requests(self.control, state, self.save_path)
        self.follow_window_and_view()
        u, v = self.window.get_cursor_pos() if self.show else (0.5, 0.5)
        self.mouse(u, v)
        self.clock.lap("events")
        self.renderer.begin_frame()
        state.frame_substeps = self.pacer.choose(state.substeps) if steady else state.substeps
        if self.timings is not None:  # what the pacing chose, for `sandbox bench --window`
            self.timings.setdefault("substeps", []).append(state.frame_substeps)
            self.timings.setdefault("wanted_substeps", []).append(state.substeps)
        sim_start = time.perf_counter()
        self.control.advance(state.frame_substeps, self.renderer.mid_frame)
        ti.sync()
        sim_end = time.perf_counter()
        self.clock.lap("simulation")
        stats = self.readouts(u, v)
        self.clock.lap("readouts")
        self.draw(u, v, stats)
        if not self.control.paused:
            rest = (sim_start - frame_start) + (time.perf_counter() - sim_end)  # the frame's work besides stepping
            self.pacer.record(state.frame_substeps, sim_end - sim_start, rest)
        self.shown += 1
        if state.screenshot or save_as:
            self.window.save_image(save_as or f"screenshot_{self.shown:05d}.png")
            state.screenshot = False
        if self.show:  # a hidden window renders on save_image; show() is for real windows only
            self.window.show()
        self.clock.lap("display")
        self.clock.stop()
        return False

    def follow_window_and_view(self) -> None:
        """The window's size and full-screen state, the view toggles, the pair-force panel and the charts as the
        keys and panel last set them: a renderer rebuilt where its kernels are specialised to them."""
        state, sim, renderer = self.state, self.sim, self.renderer
        resized = self.resize.settled(self.window.get_window_shape() if self.show else self.shape, state.recording)
        if state.full_screen != self.full_screen:  # x: the window opened again at the screen's size, or back
            resized = self.toggle_full_screen() or resized
        if resized:  # the user resized the window: draw at its new size from now on
            self.shape, self.size = resized, picture_size(sim, *resized)
            state.log.append(f"window {self.shape[0]} x {self.shape[1]}")
        if view_config(self.cfg, state) != self.view or resized:
            self.view = view_config(self.cfg, state)
            sim.state.drop(renderer.tails)
            old, renderer = renderer, self.new_renderer()
            renderer.adopt_plots(old)  # the scene's charts keep their history
            self.renderer = renderer
            if self.orbit is not None:
                renderer.set_camera(self.orbit.eye(), self.orbit.target, renderer.painter.fov)
            self.chart_series = tuple(self.cfg.chart)  # what the new renderer shows; the energy plot is restored below
            self.potential_shown = (False, 1.0, 1.0)  # ... and the pair-force panel
            if not resized:
                state.log.append(f"view: {state.color_by}, blur {'on' if state.motion_blur else 'off'}")
        if sim.terms.pair is not None:
            shown_law = (state.potential, *sim.terms.pair.scale)
            if shown_law != self.potential_shown:
                r, force = sim.terms.pair.curve()
                renderer.set_potential(force if state.potential else None, (float(r[0]), float(r[-1])))
                self.potential_shown = shown_law
        wanted = ENERGY_SERIES if state.energy_plot else tuple(self.cfg.chart)
        if wanted != self.chart_series:
            renderer.set_chart(wanted)
            self.chart_series = wanted

    def toggle_full_screen(self) -> tuple[int, int] | None:
        """Open the window again at the screen's size (or back at its windowed size); the new size, or None where
        the screen's size is not known."""
        state = self.state
        screen = screen_size() if state.full_screen else None
        if state.full_screen and screen is None:
            state.full_screen = False
            state.log.append("full screen: the screen's size is not known here (pip install screeninfo)")
            return None
        self.window.destroy()
        target, place = (screen[2:], screen[:2]) if screen else (self.windowed, (100, 100))
        self.window = open_window(self.sim.scene.name, target, self.show, place)
        self.canvas, self.gui, self.full_screen = self.window.get_canvas(), self.window.get_gui(), state.full_screen
        self.resize = ResizeWatch(target)
        return tuple(target)

    def mouse(self, u: float, v: float) -> None:
        """The mouse at window point (u, v): in 2D the held button is the tool; in 3D left drag orbits, right drag
        zooms, middle drag pans, and shift with the left button is the tool at the particle under the cursor."""
        window, state = self.window, self.state
        held = self.show and bool(state.tool) and window.is_pressed(ti.ui.LMB)
        if self.orbit is not None and self.show:
            buttons = [window.is_pressed(b) for b in (ti.ui.LMB, ti.ui.RMB, ti.ui.MMB)]
            shifted = buttons[0] and window.is_pressed(ti.ui.SHIFT)
            buttons[0] = buttons[0] and not shifted
            if self.last_cursor is not None and any(buttons):
                self.orbit.drag(buttons, u - self.last_cursor[0], v - self.last_cursor[1])
                self.renderer.set_camera(self.orbit.eye(), self.orbit.target, self.renderer.painter.fov)
            self.last_cursor = (u, v)
            centre = self.renderer.pick(u, v) if held and shifted else None
        else:
            centre = self.renderer.world_point(u, v) if held else None
        if centre is not None:  # the tool acts where the cursor is, for as long as the button is held
            self.control.press(state.tool, centre, state.radius, state.material or None)
        else:
            self.control.release()

    def readouts(self, u: float, v: float):
        """The frame's Stats (the blow-up guard's check among them) recorded for the charts, the springs' stable
        step now and then, and the probe under the cursor; the pair energy's neighbour scan only every 10th frame
        unless the energy plot is on."""
        sim, state = self.sim, self.state
        stats = sim.stats(pair_energy=state.energy_plot or self.shown % 10 == 0)
        self.renderer.record(stats)
        if sim.state.springs is not None and self.shown % STABLE_DT_EVERY == 0:  # it copies every spring to the host
            state.stable_dt = sim.stable_dt()
        state.probe = probe_under(sim, self.renderer, u, v) if self.show else ""
        return stats

    def draw(self, u: float, v: float, stats) -> None:
        """The picture (with the brush outlined at the cursor in 2D), the recording, the frame rate and the panel."""
        state, renderer = self.state, self.renderer
        if state.tool and self.sim.dim == 2:
            renderer.set_brush((u * renderer.width, v * renderer.height), state.radius * renderer.painter.px_per_unit)
        else:
            renderer.set_brush(None)
        renderer.render()
        self.clock.lap("drawing")
        renderer.show_on(self.canvas)
        message = self.recorder.update(state.recording, renderer)
        if message:
            state.log.append(message)
        now = time.perf_counter()
        self.fps = 0.9 * self.fps + 0.1 / max(now - self.last, 1e-6)
        self.last = now
        state.pace = (
            0.0 if self.control.paused else self.fps * state.frame_substeps * self.sim.dt
        )  # simulated s / wall s
        draw_panel(self.gui, self.control, state, stats, self.fps, self.shape[0])


WINDOW_3D_SCALE = 0.5  # the window draws 3D scenes at this fraction of its size: shading every pixel of 1280 x 720


def picture_size(sim, width: int, height: int) -> tuple[int, int]:
    """The size the window's renderer draws at for a `width` x `height` window: the full size in 2D; in 3D
    WINDOW_3D_SCALE of it (spheres are shaded per pixel; at full size the 3D block drew 12-18 fps on two cores)."""
    if sim.dim == 3:
        return max(64, int(width * WINDOW_3D_SCALE)), max(36, int(height * WINDOW_3D_SCALE))
    return width, height


@dataclass(frozen=True)
class WindowRun:
    """How a window ended: the frames it showed, and the shipped scene picked in its panel to open next (or None)."""

    frames: int
    next_scene: str | None = None
    size: tuple[int, int] | None = None  # the window's last (width, height): the next scene opens at it


ENERGY_SERIES = ("kinetic_energy", "potential_energy", "total_energy")
STABLE_DT_EVERY = 30  # frames between refreshes of the panel's stable-step readout


def probe_under(sim, renderer, u: float, v: float) -> str:
    """The probe's line for the particle under the window point (u, v), or "" where there is none."""
    i = particle_at(sim, renderer.world_point(u, v)) if sim.dim == 2 else renderer.pick_index(u, v)
    return "" if i is None else probe(sim, i).text()

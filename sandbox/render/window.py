"""The interactive window (Taichi GGUI), drawing through the same Renderer as headless video.

Keys (also listed by the help overlay, h or F1): space pause/resume, s single step, r reset, 1-8 choose a tool
(heat, cool, drag, attract, repel, impulse, erase, spawn), [ and ] brush radius, + and - substeps per frame, g
gravity on/off, i next integrator, m next spawn material, p screenshot, q or Esc quit. The left mouse button applies
the tool at the cursor (2D scenes); in 3D the mouse orbits (left), zooms (right) and pans (middle). The side panel
shows only the controls the scene uses (no heat tools without heat).
Everything the keys do goes through WindowState.handle_key, which needs no screen, so it is tested directly.
"""

from __future__ import annotations

import functools
import math
import os
import textwrap
import time
from dataclasses import dataclass, field

import numpy as np
import taichi as ti

from .. import runtime
from ..errors import SandboxError
from ..integrators import REGISTRY
from ..tools import TOOLS, Tools
from .raster import Renderer

TOOL_KEYS = {str(k + 1): name for k, name in enumerate(TOOLS)}
HELP = [
    "space  pause / resume",
    "s      single step (paused)",
    "r      reset to the start",
    "1-8    tool: " + ", ".join(f"{k} {v}" for k, v in TOOL_KEYS.items()),
    "[ ]    brush radius",
    "+ -    substeps per frame",
    "g      gravity on / off",
    "i      next integrator",
    "p      screenshot",
    "m      next material for the spawn tool",
    "v      start / stop recording an MP4 (out/SCENE_N.mp4)",
    "e      live energy plot on / off",
    "f      pair-force panel on / off (with attraction and repulsion sliders)",
    "c      next colour map (temperature, phase, speed, material)",
    "b      motion blur on / off",
    "k      springs drawn on / off (2D)",
    "l      the scene's lesson on / off",
    "h, F1  this help",
    "q, Esc quit",
    "left mouse: apply the tool at the cursor (2D)",
    "3D: left drag orbit, right drag zoom, middle drag pan",
]


class WindowUnavailable(SandboxError):
    """No window can be opened here (no display, no Vulkan driver): the CLI runs headless instead."""


def window_unavailable_reason() -> str | None:
    """Why no window can be opened here (no display), or None when one may be tried."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display"
    return None


@dataclass
class WindowState:
    """What the window's keys control; handle_key is the single place keys change it."""

    tools_available: list[str]
    integrators: list[str]
    integrator: str
    substeps: int
    tool: str = ""
    radius: float = 3.0
    paused: bool = False
    single_step: bool = False
    reset: bool = False
    quit: bool = False
    show_help: bool = False
    gravity_on: bool = True
    screenshot: bool = False
    materials: list[str] = field(default_factory=list)  # what the spawn tool can make
    material: str = ""
    recording: bool = False  # v: writing the window's frames to an MP4
    energy_plot: bool = False  # e: a live plot of kinetic, potential and total energy
    gravity_angle: float = 0.0  # degrees from straight down (2D), set by the panel's slider
    potential: bool = False  # f: show the pair-force law against distance, with attraction/repulsion sliders
    attraction: float = 1.0  # scale of every pair's alpha (the panel's slider)
    repulsion: float = 1.0  # scale of every pair's beta
    dt_scale: float = 1.0  # the time step as a multiple of the scene's (the panel's slider)
    stable_dt: float = float("inf")  # the springs' stable step, refreshed every STABLE_DT_EVERY frames
    color_modes: list[str] = field(default_factory=list)  # c cycles the colour map through these
    color_by: str = ""
    motion_blur: bool = False  # b
    draw_springs: bool = False  # k
    show_lesson: bool = True  # l: the scene's lesson at the top of the panel
    log: list[str] = field(default_factory=list)

    def __post_init__(self):
        if not self.tool and self.tools_available:
            self.tool = self.tools_available[0]
        if not self.material and self.materials:
            self.material = self.materials[0]

    def handle_key(self, key: str) -> None:
        """Apply one key press (GGUI key names: single characters, 'Escape', ' ', 'F1')."""
        if key in ("q", "Escape"):
            self.quit = True
        elif key == " ":
            self.paused = not self.paused
        elif key == "s":
            self.single_step = True
        elif key == "r":
            self.reset = True
        elif key in TOOL_KEYS:
            if TOOL_KEYS[key] in self.tools_available:
                self.tool = TOOL_KEYS[key]
            else:
                self.log.append(f"{TOOL_KEYS[key]} is not available in this scene")
        elif key == "[":
            self.radius = max(0.5, self.radius / 1.25)
        elif key == "]":
            self.radius = min(100.0, self.radius * 1.25)
        elif key in ("+", "="):
            self.substeps = min(1000, self.substeps + 1)
        elif key == "-":
            self.substeps = max(1, self.substeps - 1)
        elif key == "g":
            self.gravity_on = not self.gravity_on
        elif key == "i":
            k = self.integrators.index(self.integrator)
            self.integrator = self.integrators[(k + 1) % len(self.integrators)]
        elif key in ("h", "F1"):
            self.show_help = not self.show_help
        elif key == "p":
            self.screenshot = True
        elif key == "v":
            self.recording = not self.recording
        elif key == "e":
            self.energy_plot = not self.energy_plot
        elif key == "f":
            self.potential = not self.potential
        elif key == "c" and self.color_modes:
            self.color_by = self.color_modes[(self.color_modes.index(self.color_by) + 1) % len(self.color_modes)]
        elif key == "b":
            self.motion_blur = not self.motion_blur
        elif key == "k":
            self.draw_springs = not self.draw_springs
        elif key == "l":
            self.show_lesson = not self.show_lesson
        elif key == "m" and self.materials:
            self.material = self.materials[(self.materials.index(self.material) + 1) % len(self.materials)]


def tools_for(sim) -> list[str]:
    """The tools that make sense in this scene: no heat tools without heat (in 3D they act with shift held, at the
    depth of the particle under the cursor)."""
    return [t for t in TOOLS if sim.heat is not None or t not in ("heat", "cool")]


def make_state(sim, substeps: int | None) -> WindowState:
    world = sim.scene.world
    fixed = substeps or (world.substeps if world.substeps != "auto" else 8)
    cfg = sim.scene.render
    modes = ["temperature", "phase"] if sim.heat is not None else []
    modes += ["speed", "material"]
    tools = tools_for(sim)
    empty = sim.built.count == 0 and not sim.scene.emitters  # nothing to heat or push: start by spawning
    return WindowState(
        tools,
        list(REGISTRY),
        sim.integrator.name,
        int(fixed),
        materials=sim.material_names,
        color_modes=modes,
        color_by=cfg.color_by if cfg.color_by in modes else modes[0],
        motion_blur=cfg.motion_blur,
        draw_springs=cfg.draw_springs,
        tool="spawn" if empty and "spawn" in tools else "",
    )


def reading(value: float, unit: str = "", digits: int = 1) -> str:
    """A readout: the value with its unit, or "-" where there is nothing to measure (the mean temperature of no
    particles). ASCII: the window's font has no en dash."""
    return f"{value:.{digits}f}{' ' + unit if unit else ''}" if math.isfinite(value) else "-"


def view_config(cfg, state: WindowState):
    """The scene's [render] table with the window's view toggles applied (colour map, motion blur, springs)."""
    import dataclasses

    return dataclasses.replace(
        cfg, color_by=state.color_by, motion_blur=state.motion_blur, draw_springs=state.draw_springs
    )


def window_output(canvas) -> str:
    """The renderer output a window shows: GGUI's packed RGBA on the CPU backend, where this Taichi's canvas takes
    it as it is (its set_image would convert a float image over every pixel each frame), else the float image."""
    try:
        from taichi.ui.utils import get_field_info  # noqa: F401  (what Renderer.show_on calls)
    except ImportError:
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
) -> int:
    """Show the simulation in a GGUI window until closed (or for `frames` frames); returns frames shown. `record`:
    write the frames to this video from the start (the v key starts and stops recordings to out/SCENE_N.mp4).
    `timings`: append each frame's seconds by part (FRAME_PARTS, and "frame" for the whole loop) to these lists
    (the benchmark; it waits for each part's kernels to finish).

    Raises SandboxError with one line when no window can be opened (e.g. no Vulkan driver).
    """
    cfg = sim.scene.render
    try:
        window = ti.ui.Window(f"sandbox: {sim.scene.name}", (cfg.width, cfg.height), vsync=True, show_window=show)
    except Exception as exc:  # GGUI raises RuntimeError without Vulkan; keep the message to one line
        first_line = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise WindowUnavailable(f"cannot open a window: {first_line}") from None
    canvas = window.get_canvas()
    output = window_output(canvas)
    renderer = Renderer(sim, cfg.width, cfg.height, cfg, output)
    gui = window.get_gui()
    tools = Tools(sim)
    state = make_state(sim, substeps)
    state.recording = record is not None
    recorder = Recorder(sim.scene.name, cfg.width, cfg.height, cfg.fps, record)
    chart_series = tuple(cfg.chart)
    potential_shown = (False, 1.0, 1.0)
    view = cfg  # the renderer's configuration; the window's toggles rebuild it when they differ
    orbit = OrbitCamera(renderer.eye_np, renderer.target_np) if sim.dim == 3 else None
    last_cursor = None
    base_dt = sim.dt
    gravity = np.asarray(sim.scene.world.gravity, dtype=float)
    g_norm = float(np.linalg.norm(gravity))
    if sim.reorder is not None:  # sort the storage now: the sort's kernel loads before the first frame, not as a
        sim.reorder.apply()  # pause of a tenth of a second or more at its first use mid-interaction
    shown, fps, last = 0, 0.0, time.perf_counter()
    clock = _FrameClock(timings)
    while window.running:
        clock.start()
        if show:  # a hidden window (show_window=False, for tests) has no events or cursor
            for event in window.get_events(ti.ui.PRESS):
                state.handle_key(event.key)
        if state.quit:
            break
        if state.reset:
            sim.reset()
            state.reset = False
        if state.integrator != sim.integrator.name:
            sim.set_integrator(state.integrator)
        if sim.dim == 2 and g_norm > 0 and state.gravity_angle:  # the panel's slider turns gravity
            a = np.radians(state.gravity_angle)
            sim.gravity[None] = g_norm * np.array([np.sin(a), -np.cos(a)]) * state.gravity_on
        else:
            sim.gravity[None] = gravity if state.gravity_on else 0 * gravity
        if view_config(cfg, state) != view:  # a view toggle: a renderer built for it (its kernels are specialised)
            view = view_config(cfg, state)
            renderer.detach()
            renderer = Renderer(sim, cfg.width, cfg.height, view, output)
            if orbit is not None:
                renderer.set_camera(orbit.eye(), orbit.target, renderer.fov)
            chart_series = tuple(cfg.chart)  # what the new renderer shows; the energy plot is restored below
            potential_shown = (False, 1.0, 1.0)  # ... and the pair-force panel
            state.log.append(f"view: {state.color_by}, blur {'on' if state.motion_blur else 'off'}")
        if sim.scene.world.substeps != "auto":
            sim.dt = base_dt * state.dt_scale
        if sim.pair is not None:
            shown_law = (state.potential, state.attraction, state.repulsion)
            if shown_law != potential_shown:
                sim.pair.set_scale(state.attraction, state.repulsion)
                renderer.set_potential(sim.pair.curve()[1] if state.potential else None)
                potential_shown = shown_law
        wanted = ENERGY_SERIES if state.energy_plot else tuple(cfg.chart)
        if wanted != chart_series:
            renderer.set_chart(wanted)
            chart_series = wanted
        u, v = window.get_cursor_pos() if show else (0.5, 0.5)
        if orbit is not None and show:  # left drag orbits, right drag zooms, middle drag pans
            buttons = [window.is_pressed(b) for b in (ti.ui.LMB, ti.ui.RMB, ti.ui.MMB)]
            if buttons[0] and window.is_pressed(ti.ui.SHIFT):  # shift: the tool, not the camera
                buttons[0] = False
                centre = renderer.pick(u, v)
                if state.tool and centre is not None:
                    tools.apply(
                        state.tool, centre, state.radius, sim.dt * state.substeps, material=state.material or None
                    )
            if last_cursor is not None and any(buttons):
                du, dv = u - last_cursor[0], v - last_cursor[1]
                if buttons[0]:
                    orbit.orbit(du, dv)
                elif buttons[1]:
                    orbit.zoom(dv)
                else:
                    orbit.pan(du, dv)
                renderer.set_camera(orbit.eye(), orbit.target, renderer.fov)
            last_cursor = (u, v)
        if show and state.tool and window.is_pressed(ti.ui.LMB) and sim.dim == 2:
            pos = (np.array([u * cfg.width, v * cfg.height]) - np.asarray(renderer.offset.to_list())) / (
                renderer.px_per_unit
            )
            tools.apply(state.tool, pos, state.radius, sim.dt * state.substeps, material=state.material or None)
        clock.lap("events")
        renderer.begin_frame()
        if not state.paused:
            sim.advance_frame(state.substeps, renderer.mid_frame)
        elif state.single_step:
            sim.step(1)
        state.single_step = False
        clock.lap("simulation")
        # the guard (a non-finite state stops with a named error instead of drawing garbage) and the readouts; the
        # pair energy's neighbour scan only every 10th frame unless the energy plot is on
        stats = sim.stats(pair_energy=state.energy_plot or shown % 10 == 0)
        renderer.record(stats)
        if sim.springs is not None and shown % STABLE_DT_EVERY == 0:  # it copies every spring to the host
            state.stable_dt = sim.stable_dt()
        clock.lap("readouts")
        if state.tool and sim.dim == 2:  # the brush, outlined at the cursor
            renderer.set_brush((u * cfg.width, v * cfg.height), state.radius * renderer.px_per_unit)
        else:
            renderer.set_brush(None)
        renderer.render()
        clock.lap("drawing")
        renderer.show_on(canvas)
        message = recorder.update(state.recording, renderer)
        if message:
            state.log.append(message)
        now = time.perf_counter()
        fps = 0.9 * fps + 0.1 / max(now - last, 1e-6)
        last = now
        _panel(gui, sim, state, stats, fps)
        shown += 1
        done = frames is not None and shown >= frames
        if state.screenshot or (done and screenshot):
            window.save_image(screenshot if (done and screenshot) else f"screenshot_{shown:05d}.png")
            state.screenshot = False
        if show:  # a hidden window renders on save_image; show() is for real windows only
            window.show()
        clock.lap("display")
        clock.stop()
        if done:
            break
    message = recorder.update(False, renderer)
    if message:
        print(message)
    window.destroy()
    return shown


FRAME_PARTS = ("events", "simulation", "readouts", "drawing", "display")  # the window loop's parts, in order


class _FrameClock:
    """Seconds per part of each window frame, for `run_window(timings=...)`; does nothing without a dict."""

    def __init__(self, timings: dict[str, list[float]] | None):
        self.timings = timings
        if timings is not None:
            for part in (*FRAME_PARTS, "frame"):
                timings.setdefault(part, [])

    def start(self) -> None:
        if self.timings is not None:
            ti.sync()
            self.t0 = self.last = time.perf_counter()

    def lap(self, part: str) -> None:
        """The time since the last lap (or the start) was spent on `part`."""
        if self.timings is not None:
            ti.sync()
            now = time.perf_counter()
            self.timings[part].append(now - self.last)
            self.last = now

    def stop(self) -> None:
        if self.timings is not None:
            self.timings["frame"].append(self.last - self.t0)


ENERGY_SERIES = ("kinetic_energy", "potential_energy", "total_energy")
STABLE_DT_EVERY = 30  # frames between refreshes of the panel's stable-step readout


class OrbitCamera:
    """3D camera for the mouse: orbit about a target (yaw, pitch), zoom (distance) and pan (moves the target).
    Cursor movements are fractions of the window (GGUI's cursor coordinates)."""

    def __init__(self, eye, target):
        self.target = np.asarray(target, dtype=float)
        d = np.asarray(eye, dtype=float) - self.target
        self.distance = float(np.linalg.norm(d))
        self.yaw = float(np.arctan2(d[0], d[2]))
        self.pitch = float(np.arcsin(np.clip(d[1] / self.distance, -1.0, 1.0)))

    def eye(self) -> np.ndarray:
        c = np.cos(self.pitch)
        return self.target + self.distance * np.array([c * np.sin(self.yaw), np.sin(self.pitch), c * np.cos(self.yaw)])

    def orbit(self, du: float, dv: float) -> None:
        """A drag across the whole window turns the view half a turn (and tilts it a quarter, within the poles)."""
        self.yaw -= np.pi * du
        self.pitch = float(np.clip(self.pitch - 0.5 * np.pi * dv, -1.45, 1.45))

    def zoom(self, dv: float) -> None:
        """Dragging up by the window's height moves 7.4x closer (exponential, so it never reaches the target)."""
        self.distance *= float(np.exp(-2.0 * dv))

    def pan(self, du: float, dv: float) -> None:
        """Move the target across the view, by the distance per window width."""
        fwd = self.target - self.eye()
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        right /= max(np.linalg.norm(right), 1e-9)
        up = np.cross(right, fwd)
        self.target = self.target - self.distance * (du * right + dv * up)


class Recorder:
    """Starts, feeds and stops MP4 recordings of the window's pictures through the headless video writer."""

    def __init__(self, scene_name: str, width: int, height: int, fps: float, first_path: str | None = None):
        self.scene_name, self.size, self.fps = scene_name, (width, height), fps
        self.next_path = first_path
        self.writer = None
        self.count = 0

    def update(self, recording: bool, renderer) -> str:
        """Called once per frame after rendering; returns a message when a recording starts or stops."""
        from .video import open_writer

        message = ""
        if recording and self.writer is None:
            self.count += 1
            path = self.next_path or f"out/{self.scene_name}_{self.count}.mp4"
            self.next_path = None
            self.writer = open_writer(path, *self.size, self.fps)
            self.path = path
            message = f"recording {path}"
        if self.writer is not None and recording:
            self.writer.write(renderer.picture())
        if self.writer is not None and not recording:
            self.writer.close()
            message = f"saved {self.path} ({self.writer.frames_written} frames)"
            self.writer = None
        return message


def thermometers(sim) -> list[tuple[str, float]]:
    """(name, mean temperature) of each body and emitter that has particles now, for the panel's readout."""
    if sim.heat is None:
        return []
    n = int(sim.particles.n[None])
    groups = sim.particles.group.to_numpy()[:n]
    temps = sim.particles.T.to_numpy()[:n]
    names = [g.name for g in sim.scene.groups] + ["spawned"]
    sums = np.bincount(groups, weights=temps, minlength=len(names))
    counts = np.bincount(groups, minlength=len(names))
    return [(names[k], float(sums[k] / counts[k])) for k in range(len(names)) if counts[k]]


def tool_label(name: str, selected: str) -> str:
    """A tool button's label: its key and name, marked when it is the selected tool."""
    key = TOOLS.index(name) + 1
    return f"> {key} {name} <" if name == selected else f"  {key} {name}  "


LESSON_WIDTH = 46  # characters per line of the lesson in the panel


@functools.cache  # the panel asks every frame; a lesson (frozen) wraps the same way each time
def lesson_text(lesson) -> tuple[str, ...]:
    """The scene's lesson as the panel's lines: each part labelled and wrapped to LESSON_WIDTH characters."""
    lines = []
    for label, text in lesson.parts():
        lines += textwrap.wrap(f"{label}: {text}", LESSON_WIDTH)
    return tuple(lines)


def _panel(gui, sim, state: WindowState, stats, fps: float) -> None:
    with gui.sub_window(sim.scene.name, 0.0, 0.0, 0.28, 0.6):
        lesson = lesson_text(sim.scene.lesson)
        if lesson:
            state.show_lesson = gui.checkbox("lesson (l)", state.show_lesson)
            if state.show_lesson:
                for line in lesson:
                    gui.text(line)
        gui.text(f"t = {stats.time:.2f} s   {fps:.0f} fps   {'paused' if state.paused else ''}")
        gui.text(
            f"particles {stats.particles}"
            + (f"   broken springs {stats.broken_springs}" if sim.springs is not None else "")
        )
        if sim.heat is not None:
            gui.text(f"mean T {reading(stats.mean_temperature, 'C')}   molten {100 * stats.molten_fraction:.0f}%")
            for name, temperature in thermometers(sim)[:6]:
                gui.text(f"  {name}: {temperature:.1f} C")
            sim.heat.ambient[None] = gui.slider_float("ambient C", float(sim.heat.ambient[None]), -50.0, 300.0)
        gui.text(f"energy: kinetic {stats.kinetic_energy:.4g}  total {stats.total_energy:.4g}")
        per_particle = reading(stats.total_energy_per_particle, digits=3)
        walls = f"   on walls {reading(stats.wall_pressure, digits=3)}" if sim.domain.wall_area else ""
        gui.text(f"pressure {reading(stats.pressure, digits=3)}{walls}   energy per particle {per_particle}")
        gui.text(f"integrator {state.integrator}   substeps {state.substeps}")
        if state.tools_available:
            gui.text(f"tool: {state.tool}   radius {state.radius:.1f}   spawns {state.material} (m)")
            if sim.dim == 3:
                gui.text("3D: Shift + left button uses the tool")
            for name in state.tools_available:
                if gui.button(tool_label(name, state.tool)):
                    state.tool = name
            state.radius = gui.slider_float("radius", state.radius, 0.5, 30.0)
        state.paused = gui.checkbox("paused", state.paused)
        state.energy_plot = gui.checkbox("energy plot (e)", state.energy_plot)
        if sim.scene.world.substeps != "auto":
            state.dt_scale = gui.slider_float("dt x", state.dt_scale, 0.1, 2.0)
            gui.text(f"dt {sim.dt:.4g}  (stable for springs below {state.stable_dt:.3g})" if sim.springs else "")
        state.recording = gui.checkbox("record MP4 (v)", state.recording)
        if sim.pair is not None:
            state.potential = gui.checkbox("pair force (f)", state.potential)
            if state.potential:
                state.attraction = gui.slider_float("attraction x", state.attraction, 0.0, 4.0)
                state.repulsion = gui.slider_float("repulsion x", state.repulsion, 0.25, 4.0)
                r_eq = sim.pair.r_eq_np[0, 0]
                gui.text(f"equilibrium distance {r_eq:.3f} (curve crosses zero)")
        if sim.dim == 2 and any(sim.scene.world.gravity):
            state.gravity_angle = gui.slider_float("gravity angle", state.gravity_angle, -180.0, 180.0)
        if state.log:
            gui.text(state.log[-1])
    if state.show_help:
        with gui.sub_window("keys", 0.3, 0.05, 0.4, 0.5):
            for line in HELP:
                gui.text(line)

"""What the window's keys and panel control, without a screen: WindowState (handle_key is the single place keys
change it, so it is tested directly), the tools a scene offers, and the text of readouts, tool buttons and lessons."""

from __future__ import annotations

import dataclasses
import functools
import textwrap
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..config.arguments import file_stem
from ..errors import SandboxError
from ..integrators import REGISTRY
from . import tool_table


def help_lines() -> list[str]:
    """The help overlay's lines: every key binding's words (the tools as the table holds them now), then the mouse."""
    tools = "Tab    next tool: " + ", ".join(tool_table.names()) + " (or the panel's slider)"
    return [tools if b.help == TOOLS_LINE else b.help for b in KEYS if b.help] + MOUSE_HELP


def _flip(name: str) -> Callable[[WindowState], None]:
    return lambda s: setattr(s, name, not getattr(s, name))


def _ask(name: str) -> Callable[[WindowState], None]:
    return lambda s: setattr(s, name, True)


def _next_tool(s: WindowState) -> None:
    if s.tools_available:
        k = s.tools_available.index(s.tool) if s.tool in s.tools_available else -1
        s.tool = s.tools_available[(k + 1) % len(s.tools_available)]


def _next_of(items: str, name: str) -> Callable[[WindowState], None]:
    """Step the attribute `name` to the next of the list attribute `items` (nothing when the list is empty)."""

    def step(s: WindowState) -> None:
        choices = getattr(s, items)
        if choices:
            setattr(s, name, choices[(choices.index(getattr(s, name)) + 1) % len(choices)])

    return step


def _set(name: str, change: Callable) -> Callable[[WindowState], None]:
    return lambda s: setattr(s, name, change(getattr(s, name)))


@dataclass(frozen=True)
class Binding:
    """A key binding: the GGUI key names that press it, its line in the help ("" where the line before covers it),
    and what it does to the WindowState."""

    keys: tuple[str, ...]
    help: str
    act: Callable[[WindowState], None]


TOOLS_LINE = "Tab"  # the help line of Tab is written from the tool table
# Every key, once: handle_key and the help both read this table. GGUI (Taichi 1.7) reports letters and named keys
# only (Escape, Return, Tab, arrows, space, Shift, ...): digits, brackets, + and - never arrive, so none is bound.
KEYS = (
    Binding((" ",), "space  pause / resume", _ask("toggle_pause")),
    Binding(("s",), "s      single step (paused)", _ask("single_step")),
    Binding(("r",), "r      reset to the start", _ask("reset")),
    Binding(("Tab",), TOOLS_LINE, _next_tool),
    Binding(("Up",), "Up Down     brush radius", _set("radius", lambda r: min(100.0, r * 1.25))),
    Binding(("Down",), "", _set("radius", lambda r: max(0.5, r / 1.25))),
    Binding(("Right",), "Right Left  substeps per frame", _set("substeps", lambda n: min(1000, n + 1))),
    Binding(("Left",), "", _set("substeps", lambda n: max(1, n - 1))),
    Binding(("g",), "g      gravity on / off", _ask("toggle_gravity")),
    Binding(("i",), "i      next integrator", _ask("next_integrator")),
    Binding(("z",), "z      undo the last tool stroke (Ctrl+Z too)", _ask("undo")),
    Binding(("w",), "w      save the state (out/SCENE.state.npz)", _ask("save")),
    Binding(("o",), "o      load the saved state back", _ask("load")),
    Binding(("n",), "n      the scene picker (switch scene) on / off", _flip("picking")),
    Binding(("p",), "p      screenshot", _ask("screenshot")),
    Binding(("m",), "m      next material for the spawn tool", _next_of("materials", "material")),
    Binding(("v",), "v      start / stop recording an MP4 (out/SCENE_N.mp4)", _flip("recording")),
    Binding(("e",), "e      live energy plot on / off", _flip("energy_plot")),
    Binding(("f",), "f      pair-force panel on / off (the law against distance)", _flip("potential")),
    Binding(
        ("c",), "c      next colour map (temperature, phase, speed, material)", _next_of("color_modes", "color_by")
    ),
    Binding(("b",), "b      motion blur on / off", _flip("motion_blur")),
    Binding(("k",), "k      springs drawn on / off (2D)", _flip("draw_springs")),
    Binding(("l",), "l      the scene's lesson on / off", _flip("show_lesson")),
    Binding(("x", "F11"), "x      full screen on / off", _flip("full_screen")),
    Binding(("h", "F1"), "h      this help", _flip("show_help")),
    Binding(("q", "Escape"), "q, Esc  quit", _ask("quit")),
)
BY_KEY = {key: b for b in KEYS for key in b.keys}
MOUSE_HELP = [
    "left mouse: apply the tool at the cursor (2D)",
    "3D: left drag orbit, right drag zoom, middle drag pan",
]


@dataclass
class WindowState:
    """What the window's keys control; handle_key is the single place keys change it. What the controller holds
    (paused, gravity, the integrator, the settings) is not copied here: a key or a panel widget asks for a change
    (toggle_pause, toggle_gravity, next_integrator ...) and apply_requests makes it on the controller, which the
    panel reads every frame."""

    tools_available: list[str]
    integrators: list[str]  # the order `i` steps through
    substeps: int
    tool: str = ""
    radius: float = 3.0
    toggle_pause: bool = False
    single_step: bool = False
    reset: bool = False
    quit: bool = False
    show_help: bool = False
    toggle_gravity: bool = False
    next_integrator: bool = False
    screenshot: bool = False
    materials: list[str] = field(default_factory=list)  # what the spawn tool can make
    material: str = ""
    recording: bool = False  # v: writing the window's frames to an MP4
    energy_plot: bool = False  # e: a live plot of kinetic, potential and total energy
    potential: bool = False  # f: show the pair-force law against distance (its sliders are settings)
    stable_dt: float = float("inf")  # the springs' stable step, refreshed every STABLE_DT_EVERY frames
    color_modes: list[str] = field(default_factory=list)  # c cycles the colour map through these
    color_by: str = ""
    motion_blur: bool = False  # b
    draw_springs: bool = False  # k
    show_lesson: bool = True  # l: the scene's lesson at the top of the panel
    undo: bool = False  # z: put back the state before the last tool stroke
    save: bool = False  # w: write the state to the quick-save file
    load: bool = False  # o: read it back
    probe: str = ""  # what the particle under the cursor is (the panel shows it)
    frame_substeps: int = 0  # what this frame ran: substeps, or fewer when pacing holds the frame rate
    switch_to: str = ""  # a shipped scene picked in the panel: the window closes and opens it
    picking: bool = False  # the panel lists the shipped scenes to switch to
    pace: float = 0.0  # simulated seconds per wall second
    full_screen: bool = False  # F11: the window at the screen's size
    log: list[str] = field(default_factory=list)

    def __post_init__(self):
        if not self.tool and self.tools_available:
            self.tool = self.tools_available[0]
        if not self.material and self.materials:
            self.material = self.materials[0]

    def handle_key(self, key: str) -> None:
        """Apply one key press (GGUI key names: single characters, 'Escape', ' ', 'F1'): its binding in KEYS."""
        binding = BY_KEY.get(key)
        if binding is not None:
            binding.act(self)


def tools_for(sim) -> list[str]:
    """The tools that make sense in this scene: no heat tools without heat (in 3D they act with shift held, at the
    depth of the particle under the cursor; none that changes the particle count in a simulation of worlds)."""
    return tool_table.offered(sim.terms.heat is not None, sim.worlds)


def first_tool(scene) -> str:
    """The tool a scene starts with, in the window and the page alike: spawning in an empty scene (no bodies or
    emitters: nothing to heat or push), else the first tool it offers (the heat tools only with heat)."""
    tools = tool_table.offered(scene.heat is not None)
    empty = not scene.bodies and not scene.emitters
    return "spawn" if empty and "spawn" in tools else (tools[0] if tools else "")


def make_state(sim, substeps: int | None) -> WindowState:
    world = sim.scene.world
    fixed = substeps or (world.substeps if world.substeps != "auto" else 8)
    cfg = sim.scene.render
    modes = ["temperature", "phase"] if sim.terms.heat is not None else []
    modes += ["speed", "material"]
    tools = tools_for(sim)
    return WindowState(
        tools,
        list(REGISTRY),
        int(fixed),
        materials=sim.material_names,
        color_modes=modes,
        color_by=cfg.color_by if cfg.color_by in modes else modes[0],
        motion_blur=cfg.motion_blur,
        draw_springs=cfg.draw_springs,
        tool=first_tool(sim.scene),
    )


def view_config(cfg, state: WindowState):
    """The scene's [render] table with the window's view toggles applied (colour map, motion blur, springs); the
    window always shows the colour bar."""

    return dataclasses.replace(
        cfg, color_by=state.color_by, motion_blur=state.motion_blur, draw_springs=state.draw_springs, legend=True
    )


LESSON_WIDTH = 46  # characters per line of the lesson in the panel of a 1280-pixel window
CHARACTER_PX = 7.5  # the width of one of GGUI's panel characters, pixels (its font is 13 px high)


def lesson_text(lesson, width: int = LESSON_WIDTH) -> tuple[str, ...]:
    """The scene's lesson as the panel's lines: each part labelled and wrapped to `width` characters."""
    return _wrapped(tuple(lesson.parts()), width)


@functools.cache  # the panel asks every frame; a lesson's parts wrap the same way each time
def _wrapped(parts: tuple[tuple[str, str], ...], width: int) -> tuple[str, ...]:
    lines = []
    for label, text in parts:
        lines += textwrap.wrap(f"{label}: {text}", width)
    return tuple(lines)


def pace_text(state: WindowState) -> str:
    """The panel's line on substeps and pace (simulated seconds per wall second): "substeps 20, 1.2 sim s/s", and
    when pacing holds the frame rate with fewer substeps than wanted, "slow motion: 8 of 20 substeps, 0.41 sim s/s"."""
    pace = f"{state.pace:.3g} sim s/s"
    if state.frame_substeps and state.frame_substeps < state.substeps:
        return f"slow motion: {state.frame_substeps} of {state.substeps} substeps, {pace}"
    return f"substeps {state.substeps}, {pace}"


def quick_save_path(sim) -> Path:
    """Where the window's save key writes the state, and its load key reads it: out/SCENE.state.npz."""
    return Path("out") / f"{file_stem(sim.scene.name)}.state.npz"


def apply_requests(control, state: WindowState, path: Path) -> None:
    """Carry out on `control` (a Controller) what the keys and panel asked for this frame: reset, pause and single
    step, the integrator, gravity on or off, the time step's scale, the pair-force sliders, undo, save and load
    (`path`: the quick-save file), each file action leaving a line in the panel's log."""
    if state.reset:
        state.reset = False
        control.reset()
    if state.single_step:
        state.single_step = False
        control.step_once()  # pauses
    if state.toggle_pause:
        state.toggle_pause = False
        control.play() if control.paused else control.pause()
    if state.next_integrator:
        state.next_integrator = False
        names, now = state.integrators, control.sim.integrator.name
        control.set_integrator(names[(names.index(now) + 1) % len(names) if now in names else 0])
    if state.toggle_gravity:
        state.toggle_gravity = False
        control.steer_gravity(on=not control.gravity_on)
    if state.undo:
        state.undo = False
        state.log.append(control.undo().text)
    if state.save:
        state.save = False
        try:
            state.log.append(f"saved {control.save(path)}")
        except (OSError, SandboxError) as exc:
            state.log.append(f"cannot save {path}: {getattr(exc, 'strerror', None) or exc}")
    if state.load:
        state.load = False
        if not path.exists():
            state.log.append(f"no saved state yet ({path}): press w first")
        else:
            try:
                control.load(path)
                state.log.append(f"loaded {path} (t = {control.sim.time:.2f} s)")
            except SandboxError as exc:
                state.log.append(str(exc))


def panel_characters(window_width: int, panel: float) -> int:
    """Characters a line of the panel holds in a window `window_width` pixels wide whose panel is `panel` of it
    (LESSON_WIDTH at 1280 pixels and the window's panel; at least 20)."""
    return max(20, min(LESSON_WIDTH, int(panel * window_width / CHARACTER_PX) - 1))


def pick_scene(state: WindowState, name: str) -> None:
    """The panel's scene picker chose `name`: close this window and open that scene (run_window returns it)."""
    state.switch_to = name
    state.quit = True

"""One simulation's interactive life, whatever shows it: the desktop window (window.py), a classroom tab
(serve_session.py) and scripts drive it through this one object, so a tool, a setting or a run control is written
once.

Events go in as calls (press and release a tool stroke, pause, step, reset, undo, move a slider, save, load, switch
scene); the frame goes out through `advance` (the stroke applied, then the frame's steps); the readouts, settings and
the screen reader's summary come from `readouts`, `settings` and `summary` (panel.py describes them). What a view
decides for itself is only how it shows them: GGUI widgets, or HTML and JPEG pictures.

A call that fails for a reason the user should read returns or raises a `Notice`-worthy one line; nothing here prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config.resources import shipped_scene
from ..config.scene import load_scene
from ..core import runtime
from ..core.controls import owners as controls_owners
from ..errors import SandboxError
from ..files.persist import load_into, save_state
from ..measure.units import shown
from ..simulation import Simulation
from . import panel
from .history import UndoRing
from .tools import Tools
from .window_state import first_tool, tools_for

SUMMARY_EVERY = 2.0  # seconds of simulated time the summary's trend looks back over
# Every slider settings() can offer, by family ("source0" and "source1" are the family "source"), in the order the
# panels show them: the page labels each as its catalogues' s_<family> (app/web/i18n), and a test holds the three
# catalogues to this list.
SETTING_FAMILIES = (
    "air",
    "source",
    "wall",
    "heater",
    "lid",
    "attraction",
    "repulsion",
    "gravity",
    "gravity_angle",
    "dt_scale",
)


def setting_family(key: str) -> str:
    """The family of a setting's key: its key without a trailing index ("source1" -> "source")."""
    return key.rstrip("0123456789")


@dataclass(frozen=True)
class Notice:
    """A line for the user: `key` names it for the page's catalogue, `text` says it in English."""

    key: str
    text: str


@dataclass(frozen=True)
class Stroke:
    """The tool held down now: `tool` (a name in tool_table.py) at `centre` (scene units) over `radius`;
    `material` for spawn."""

    tool: str
    centre: tuple[float, ...]
    radius: float
    material: str | None = None


class Controller:
    """The run controls, tools, undo ring, live settings and readouts of one simulation (module docstring)."""

    def __init__(self, sim, world: int | None = None, tools: Tools | None = None) -> None:
        """The controller of `sim`, or of its world `world` alone (a simulation of many worlds, core/worlds.py: its
        tools, undo, slider settings, reset and state files act in that world; whoever holds the simulation steps
        it, so `advance` applies the held stroke only). `tools`: brushes of `sim` shared with other controllers of
        its worlds (each Tools compiles its own kernels), set to this one's world as they act."""
        self.paused = False
        self.pending_steps = 0  # single steps asked for while paused
        self.world = world
        self.shared_tools = tools
        self.bind(sim)

    def bind(self, sim) -> None:
        """Control `sim` from now on (a new scene): a fresh undo ring, no stroke, gravity as the scene sets it."""
        self.sim = sim
        # what the controls, undo, reset and state files act on: the simulation, or its one world (world_view.py)
        self.target = sim if self.world is None else sim.world(self.world)
        self.tools = self.shared_tools if self.shared_tools is not None else Tools(sim, self.world)
        self.history = UndoRing()
        self.stroke: Stroke | None = None
        self.trend = panel.Trend(SUMMARY_EVERY)
        self.base_dt = sim.dt
        self.dt_scale = 1.0
        scene_gravity = np.asarray(sim.scene.world.gravity, dtype=float)
        self.gravity_strength = float(np.linalg.norm(scene_gravity))
        self.gravity_on = True
        self.gravity_angle = 0.0  # degrees from the scene's direction (2D: turning it, as the window's slider does)

    def move_to(self, world: int) -> None:
        """Control world `world` from now on: the world this controller held was moved there (a world taken out of
        use before it: world_state.remove_world); its undo ring, stroke and settings go with it."""
        self.world = world
        self.target = self.sim.world(world)

    def hold(self, held) -> None:
        """Control `held` (world_view.HeldWorld: this controller's world taken out of its simulation while paused)
        until move_to() puts it back: sliders, undo, reset and state files act on it; no tool does."""
        self.stroke = None
        self.target = held

    @classmethod
    def open(cls, name: str, arch: str = "cpu", restart: bool = True) -> Controller:
        """A controller of a fresh simulation of the shipped scene `name` (open_scene: Taichi restarted unless
        `restart` is False, where other simulations share the runtime)."""
        return cls(open_scene(name, arch, restart))

    def switch(self, name: str, arch: str = "cpu") -> None:
        """Open the shipped scene `name` in place of this one (its fields freed with Taichi's restart)."""
        self.bind(open_scene(name, arch))

    # ------------------------------------------------------------------ what the scene offers
    def tool_names(self) -> list[str]:
        """The tools this scene offers (no heat tools without heat)."""
        return tools_for(self.sim)

    def first_tool(self) -> str:
        """The tool a view starts with (window_state.first_tool)."""
        return first_tool(self.sim.scene)

    # ------------------------------------------------------------------ time
    def pause(self) -> None:
        self.paused = True

    def play(self) -> None:
        self.paused = False

    def step_once(self) -> None:
        """One step, then stay paused."""
        self.paused, self.pending_steps = True, self.pending_steps + 1

    def reset(self) -> None:
        """The scene as it started (the undo ring emptied: its states are of another history)."""
        self.target.reset()
        self.history = UndoRing()
        self.stroke = None
        self.apply_gravity()

    def advance(self, substeps: int | None = None, midway=None) -> int:
        """One frame: the held stroke acts for the frame's time (paused or not: a paused scene can still be heated,
        erased or spawned into), then `substeps` steps (None: the scene's) unless paused, or one pending single step.
        `midway`: called halfway through (the renderer's mid_frame). Returns the steps taken; SimulationError
        (the blow-up guard) propagates: the view decides whether to stop or start again."""
        n = substeps if substeps is not None else self.sim.frame_substeps()[0]
        if self.stroke is not None:
            s = self.stroke
            self.tools.set_world(self.world)
            self.tools.apply(s.tool, s.centre, s.radius, self.sim.dt * n, material=s.material)
        if self.world is not None:  # the simulation's holder steps every world
            return 0
        if not self.paused:
            return self.sim.advance_frame(substeps, midway)
        if self.pending_steps:
            self.pending_steps -= 1
            self.sim.step(1)
            return 1
        return 0

    # ------------------------------------------------------------------ tools
    def press(self, tool: str, centre, radius: float, material: str | None = None) -> None:
        """The tool is held at `centre` (scene units) with `radius`: the first press of a stroke keeps the state
        before it for undo. SandboxError (one line) for a tool or material the scene does not have."""
        if tool not in self.tool_names():
            raise SandboxError(f"this scene has no {tool} tool")
        if material is not None and material not in self.sim.material_names:
            raise SandboxError(f"this scene has no material {material!r}")
        if self.stroke is None:
            self.history.push(self.target)
        self.stroke = Stroke(tool, tuple(float(c) for c in centre), float(radius), material)

    def release(self) -> None:
        """The tool is let go: the stroke ends (the next press starts a new one, undone on its own)."""
        self.stroke = None

    def undo(self) -> Notice:
        """Put back the state before the last stroke."""
        self.stroke = None
        if self.history.undo(self.target):
            return Notice("undone", "undone")
        return Notice("nothing_to_undo", "nothing to undo")

    # ------------------------------------------------------------------ live settings
    def settings(self) -> list[panel.Setting]:
        """The sliders a lesson asks students to move: each term's own (physics/term.py's `sliders()`, over its live
        controls: the air, the heat sources, the walls, the heater, the lid, the pair law), then the controller's
        (gravity's strength and, in 2D, direction; the time step's scale). The window, the page and the teacher's
        broadcast all offer these; a new one is a declaration in its term and its words in the catalogues."""
        values = self.target.controls.values()
        out = [
            self._from_slider(f"{space}.{s.control}", values, s)
            for space, owner in controls_owners(self.sim.model, self.sim.terms)
            for s in owner.sliders()
        ]
        out += self._own_settings()
        undeclared = [s.key for s in out if setting_family(s.key) not in SETTING_FAMILIES]
        if undeclared:  # a new slider needs its family here and its words in the catalogues
            raise ValueError(f"settings {undeclared} are not in SETTING_FAMILIES; expected them declared")
        return sorted(out, key=lambda s: SETTING_FAMILIES.index(setting_family(s.key)))  # the panels' order

    def _from_slider(self, control: str, values: dict, s) -> panel.Setting:
        """The panel's slider of a term's declaration `s` over the live control `control` (an entry of it where
        `s.index` is set), shown in the scene's units."""
        now = values[control]

        def apply(value: float) -> None:
            if s.index is None:
                self.target.controls.set({control: value})
            else:
                vector = list(self.target.controls.values()[control])
                vector[s.index] = value
                self.target.controls.set({control: vector})

        value = now if s.index is None else now[s.index]
        return self._shown(s.key, s.words, float(value), s.lo, s.hi, s.kind, s.step, apply)

    def _own_settings(self) -> list[panel.Setting]:
        """Gravity's strength and (2D) direction, over the one gravity vector; the time step as a multiple of the
        scene's (scenes with fixed substeps)."""
        out = []
        if any(self.sim.scene.world.gravity):
            top = 4.0 * float(np.linalg.norm(self.sim.scene.world.gravity))
            strength = lambda value: self.steer_gravity(strength=value)  # noqa: E731
            out.append(
                self._shown("gravity", "gravity", self.gravity_strength, 0.0, top, "acceleration", top / 100, strength)
            )
            if self.sim.dim == 2:
                angle = lambda value: self.steer_gravity(angle=value)  # noqa: E731
                out.append(
                    panel.Setting(
                        "gravity_angle", "gravity angle", self.gravity_angle, -180.0, 180.0, "deg", 1.0, angle
                    )
                )
        if self.sim.scene.world.substeps != "auto" and self.world is None:  # one step size for all worlds
            out.append(panel.Setting("dt_scale", "time step", self.dt_scale, 0.1, 2.0, "x", 0.05, self.set_dt_scale))
        return out

    def _shown(self, key, words, value, lo, hi, kind: str, step, apply) -> panel.Setting:
        """A slider over a computed value of unit kind `kind`, shown and moved in the scene's units (a real
        substance's scene: its own, measure/units.py)."""
        scale, unit = shown(kind, self.sim.material_names, self.sim.dim)
        return panel.Setting(key, words, value * scale, lo * scale, hi * scale, unit, step * scale,
                             lambda v: apply(v / scale))  # fmt: skip

    def set(self, key: str, value: float) -> None:
        """Move the slider `key` to `value`, clamped to its range; ValueError for a key the scene does not offer."""
        offered = {s.key: s for s in self.settings()}
        if key not in offered:
            raise ValueError(f"this scene has no setting {key!r} (it has: {', '.join(offered) or 'none'})")
        s = offered[key]
        s.apply(min(max(float(value), s.lo), s.hi))

    def steer_gravity(self, on: bool | None = None, angle: float | None = None, strength: float | None = None) -> None:
        """Gravity on or off, (2D) turned `angle` degrees from straight down, at `strength` (length / s^2); what is
        not given stays."""
        if on is not None:
            self.gravity_on = bool(on)
        if angle is not None:
            self.gravity_angle = float(angle)
        if strength is not None:
            self.gravity_strength = float(strength)
        self.apply_gravity()

    def apply_gravity(self) -> None:
        """Gravity as the controls say: the scene's direction (2D: turned by gravity_angle), at gravity_strength,
        or none while it is off."""
        scene_gravity = np.asarray(self.sim.scene.world.gravity, dtype=float)
        norm = float(np.linalg.norm(scene_gravity))
        if self.sim.dim == 2 and norm > 0 and self.gravity_angle:
            a = math.radians(self.gravity_angle)
            g = self.gravity_strength * np.array([math.sin(a), -math.cos(a)])
            g[np.abs(g) < 1e-9 * self.gravity_strength] = 0.0  # cos(90 deg)'s round-off is no pull
        else:
            g = scene_gravity * (self.gravity_strength / norm) if norm > 0 else scene_gravity
        self.target.controls.set({"world.gravity": [float(c) for c in (g if self.gravity_on else 0.0 * g)]})

    def set_dt_scale(self, scale: float) -> None:
        """The time step as `scale` times the scene's (scenes with fixed substeps; "auto" picks its own)."""
        self.dt_scale = float(scale)
        if self.sim.scene.world.substeps != "auto":
            self.sim.dt = self.base_dt * self.dt_scale

    def set_integrator(self, name: str) -> None:
        """Switch the time integrator, keeping the state."""
        self.sim.set_integrator(name)

    def set_pair_scale(self, attraction: float, repulsion: float) -> None:
        """Scale every pair's attraction and repulsion from the materials' values (scenes with a pair force)."""
        if self.sim.terms.pair is not None:
            self.target.controls.set({"pair.scale": [float(attraction), float(repulsion)]})

    # ------------------------------------------------------------------ readouts
    def readouts(self, stats, fps: float | None = None) -> list[panel.Readout]:
        """The panel's measurements now (`stats`: the simulation's Stats; `fps`: frames a wall second, if shown)."""
        return panel.readouts(self.sim, stats, fps, self.world)

    def summary(self, stats) -> dict:
        """What the scene is doing, for a screen reader (panel.summary), with its temperature's trend."""
        molecular = self.sim.terms.structure is not None  # the atoms' temperature is their motion's
        previous = self.trend.add(self.sim.time, stats.motion_temperature if molecular else stats.mean_temperature)
        return panel.summary(self.sim, stats, previous)

    # ------------------------------------------------------------------ state files
    def save(self, path: Path) -> Path:
        """Write the state (the world's, for a world's controller) to `path`; returns the path written
        (OutputError, SimulationError: one line)."""
        return save_state(self.sim, path) if self.world is None else self.target.save(path)

    def load(self, path: Path) -> None:
        """Put back a state file of this scene (checked before anything changes; SandboxError with one line); the
        gravity controls follow the file's gravity."""
        if self.world is None:
            load_into(self.sim, path)
        else:
            self.target.load(path)
        self.stroke = None
        g = np.asarray(self.target.controls.values()["world.gravity"], dtype=float)
        if np.any(g):
            self.gravity_on, self.gravity_strength = True, float(np.linalg.norm(g))
            self.gravity_angle = self._angle_of(g)
        if self.sim.scene.world.substeps != "auto":
            self.dt_scale = self.sim.dt / self.base_dt

    def _angle_of(self, g: np.ndarray) -> float:
        """The gravity slider's angle (degrees) that gives the direction of `g`: 0 along the scene's own direction
        (and in 3D, where there is no angle), else turned from straight down as apply_gravity turns it."""
        scene = np.asarray(self.sim.scene.world.gravity, dtype=float)
        if self.sim.dim != 2 or np.allclose(g / np.linalg.norm(g), scene / np.linalg.norm(scene), atol=1e-9):
            return 0.0
        return math.degrees(math.atan2(g[0], -g[1]))


def open_scene(name: str, arch: str = "cpu", restart: bool = True):
    """A fresh Simulation of the shipped scene `name` (the window's scene picker, a classroom tab's scene): Taichi
    is restarted first, so the last scene's fields and compiled kernels are freed (a runtime holds at most ~512
    field trees, so switching without it would run out), and started again at the new scene's precision.
    `restart=False` keeps the running runtime and what lives in it (a classroom host's other sessions: each adds
    a few trees, and its scene's precision is theirs)."""
    path = shipped_scene(name)
    if path is None:
        raise SandboxError(f"no shipped scene {name!r}")
    scene = load_scene(path)
    if restart:
        runtime.reset()
    runtime.require(arch, scene.world.precision)
    return Simulation(scene, arch=arch)

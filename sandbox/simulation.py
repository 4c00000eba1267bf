"""The Simulation: a facade over a scene's model, state, terms, rates, stepping plan, integrator and measurements.

    assembly.py           scene -> Model (what it fixes), State (what a step changes), terms, neighbourhood
    step/rates.py         the terms' forces and heat rates; integrators/ step the State through them
    step/plan.py          the host passes around each step and how steps are launched (long way, fused, team)
    measure/              the terms' measurements (Stats) and the blow-up guard
    files/persist.py      the State to and from a file; scripting.py: run, movie, picture, readouts

Per step the plan runs the terms' host passes, then the integrator's stages: each evaluates the rates (per-stage
passes, neighbour lists refreshed, one fused kernel for every pair, bond and particle term) and updates every
particle, the last stage ending with each particle's end-of-step work (walls, the heat update).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import taichi as ti

from . import caching, scripting
from .assembly import assemble
from .config.arguments import MAX_SUBSTEPS
from .config.scene_tables import Scene
from .core import controls as live_controls
from .core import runtime
from .errors import SandboxError, SimulationError
from .files.persist import save_state
from .integrators import make_integrator
from .measure.diagnostics import Diagnostics
from .measure.guard import BlowupGuard, explain_blowup, scene_limits
from .measure.stats import STAT_COLUMNS, Stats  # noqa: F401 - re-exported
from .physics import TermList
from .physics.springs import Springs
from .step.plan import StepPlan
from .step.rates import Rates
from .world_state import add_world, live_worlds, world_controls
from .world_view import WorldView


class ParticleView:
    """`sim.particles`: the particle fields by attribute (x, v, T, n, ...) and, called, the particle table. The
    facade makes it, so the core's particle record never calls back up into the simulation."""

    __slots__ = ("_fields", "_table")

    def __init__(self, fields, table: Callable[[], dict]):
        self._fields, self._table = fields, table

    def __getattr__(self, name: str):
        return getattr(self._fields, name)

    def __call__(self) -> dict:
        return self._table()


class Simulation:
    """A running scene: its model, state and terms, stepped by a plan, measured by its diagnostics."""

    def __init__(
        self,
        scene: Scene,
        arch: str = "cpu",
        half_lists: bool | None = None,
        worlds: int = 1,
        starts: list[Scene] | None = None,
        alone_threads: int | None = None,
    ):
        """Build what `scene` names on Taichi backend `arch`. `half_lists`: apply each neighbour pair once to both
        particles from a half list (None: on the CPU backend, where it halves the pair work; a GPU gathers from
        full lists instead, which needs no write conflicts). `worlds`: copies of the scene held and stepped together
        (core/worlds.py; each is `world(k)`); `starts`: instead, one scene per world, each the scene but for what a
        world may hold of its own (world_view.WORLD_KEYS: its bodies' temperatures and velocities, its gravity,
        drag, air, heat sources, thermal walls, heater and lid), so that each world is that scene run alone (on
        `alone_threads` CPU threads: a run's forces are summed in chunks of its threads; default, this
        simulation's)."""
        worlds = len(starts) if starts else worlds
        built = assemble(scene, arch, half_lists, worlds, starts, alone_threads)
        self.model, self.state, self.hood = built.model, built.state, built.hood
        self.terms = TermList(built.terms)
        self.runtime_generation = runtime.generation()
        self.rates = Rates(self.model, self.state, list(self.terms), self.hood)
        self.integrator = make_integrator(scene.world.integrator, self.rates, self.state)
        self.plan = StepPlan(self.model, self.state, list(self.terms), self.rates, self.integrator)
        self.diagnostics = Diagnostics(self.model, self.state, list(self.terms), self.hood)
        self.guard = BlowupGuard(scene_limits(scene, self.model.built, self.terms.pair))
        self.broken: str | None = None  # the guard's message once it stopped the run, until a restore
        self.parts = list(self.terms) + ([self.hood] if self.hood is not None else [])  # what a restore refreshes
        for term in self.terms:
            term.start(self.state)
        for k, start in enumerate(starts or []):
            self.world(k).controls.set(world_controls(start, self.controls.values()))
        self.mark_initial()

    # ------------------------------------------------------------------ what it is
    scene = property(lambda self: self.model.scene)
    dim = property(lambda self: self.model.dim)
    arch = property(lambda self: self.model.arch)
    capacity = property(lambda self: self.model.capacity)
    material_names = property(lambda self: self.model.material_names)
    worlds = property(lambda self: self.model.worlds, doc="copies of the scene held (core/worlds.py)")

    live_worlds = property(lambda self: live_worlds(self), doc="worlds in use: the first ones (add_world adds one)")

    def world(self, k: int) -> WorldView:
        """World k of the worlds in use: its readouts, particles, controls, state and files (world_view.py)."""
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < self.live_worlds:
            raise SandboxError(f"world {k!r}: expected a whole number from 0 to {self.live_worlds - 1}")
        return WorldView(self, k)

    def add_world(self) -> WorldView:
        """Take one more of the worlds this simulation holds into use, started as the scene starts (world_state.py);
        the worlds in use step on untouched. SandboxError where all are in use."""
        return WorldView(self, add_world(self))

    particles = property(
        lambda self: ParticleView(self.state.particles, lambda: scripting.particle_table(self)),
        doc="the particle fields (sim.particles.x, ...); calling it, sim.particles(): scripting.particle_table",
    )
    time = property(lambda self: self.state.time, doc="simulated time")
    step_count = property(lambda self: self.state.step, doc="steps taken")
    frames_done = property(lambda self: self.state.frames, doc="frames advanced")

    @property
    def frame_seconds(self) -> float:
        """The simulated seconds one frame spans: the scene's substeps of dt, or its frame time with auto substeps."""
        world = self.scene.world
        return float(world.frame_time if world.substeps == "auto" else int(world.substeps) * self.dt)

    dt = property(
        lambda self: self.state.dt,
        lambda self, value: setattr(self.state, "dt", float(value)),
        doc='the step size (world.dt, or the last frame\'s with substeps = "auto")',
    )

    def check_alive(self) -> None:
        """SandboxError when Taichi was restarted since this simulation was built (another precision or backend
        was asked for, or runtime.reset()): its fields are gone, and using them would crash."""
        if self.runtime_generation != runtime.generation():
            raise SandboxError(
                f"this {self.scene.name} simulation was built before Taichi was restarted (a later simulation asked "
                f"for another precision or backend, or runtime.reset()); build it again"
            )

    def set_integrator(self, name: str) -> None:
        """Switch the time integrator by name, keeping the state (live, e.g. from the window)."""
        if name != self.integrator.name:
            self.state.forget("integrator")
            self.integrator = self.plan.integrator = make_integrator(name, self.rates, self.state)

    # ------------------------------------------------------------------ stepping
    def step(self, n: int = 1) -> None:
        """Advance n steps of dt."""
        self.check_alive()
        self.plan.step(n)

    def steps_to_every_pass(self) -> int:
        """Steps from now until every pass that runs between steps (refreezing) has run once: what a warm-up steps
        to compile every kernel a run launches."""
        return self.plan.steps_to_every_pass()

    def frame_substeps(self) -> tuple[int, float]:
        """(steps, step size) for the next frame: the scene's fixed substeps at dt, or under "auto" the fewest equal
        steps of at most auto_step() that span world.frame_time."""
        world = self.scene.world
        if world.substeps != "auto":
            return int(world.substeps), self.state.dt
        n = max(1, math.ceil(world.frame_time / self.auto_step() - 1e-9))
        if n > 10 * MAX_SUBSTEPS:
            raise SimulationError(
                f'substeps = "auto" needs {n:,} steps for one frame at t = {self.time:.4g}: the stable step has fallen '
                f"to {world.frame_time / n:.3g} (a spring stiffened, or a particle moves too fast)"
            )
        return n, world.frame_time / n

    def advance_frame(self, substeps: int | None = None, midway: Callable[[], None] | None = None) -> int:
        """Advance one frame (the scene's substeps, or `substeps` steps of dt); returns the steps taken. `midway` is
        called after half of them, rounded down (the renderer's mid_frame: the bend of curved motion-blur streaks);
        not for a single step, which has no middle. The walls' and the lid's gauges (stats().wall_pressure,
        lid_pressure) restart with it."""
        self.check_alive()
        if substeps is None:
            substeps, self.state.dt = self.frame_substeps()
        for term in self.terms:  # the walls' and the lid's pressure gauges
            if hasattr(term, "restart_gauge"):
                term.restart_gauge(self.time)
        if midway is None or substeps < 2:
            self.step(substeps)
        else:
            self.step(substeps // 2)
            midway()
            self.step(substeps - substeps // 2)
        self.state.frames += 1
        return substeps

    def stable_dt(self) -> float:
        """The largest stable step now: the least of the terms' bounds (the springs' for this integrator, explicit
        heat's); inf without any."""
        return min([term.stable_dt(self.integrator) for term in self.terms], default=math.inf)

    def auto_step(self) -> float:
        """The step substeps = "auto" takes now: the least of world.dt, the terms' auto steps (the springs' auto h w
        over omega_max, half the explicit heat limit) and half the time the fastest particle takes to cross the
        smallest radius."""
        limits = [self.scene.world.dt] + [term.auto_dt(self.integrator) for term in self.terms]
        n = self.state.live_count()
        if n:
            v = np.linalg.norm(self.velocities(), axis=1).max()
            r = self.particles.radius.to_numpy()[:n].min()
            if v > 0:
                limits.append(0.5 * r / v)
        return min(limits)

    controls = property(
        lambda self: live_controls.Controls(self.model, self.terms),
        doc="the live controls by namespaced name: controls.values(), controls.set({...}) (core/controls.py)",
    )

    # ------------------------------------------------------------------ measuring
    def stats(self, pair_energy: bool = True, world: int = 0) -> Stats:
        """Energies, temperatures and counts now (of world `world`, where the simulation holds several). Raises
        SimulationError when the blow-up guard finds the state broken. pair_energy=False skips the pair energy's
        neighbour scan (the costliest part) and reports the last one measured: the window does so on most frames."""
        self.check_alive()
        m = self.diagnostics.measure(pair_energy, world)
        heat = self.terms.heat is not None
        problem = self.guard.problem(m, m["bad"], self.state.dt, heat)
        if problem:
            self.broken = explain_blowup(self.state, self.terms, self.integrator, *problem)
            raise SimulationError(self.broken)
        box = self.scene.world
        volume = float(np.prod(np.subtract(box.hi, box.lo)))  # the pressure's V (area in 2D)
        walls = self.terms.walls.pressure(m["impulse"], self.time)
        now = self.state.world_times()[world]  # a world's own clock: since it (re)started
        return Stats.from_sums(m, now, self.dim, volume, walls, heat, self.state.springs is not None)

    # ------------------------------------------------------------------ the state
    def snapshot(self) -> dict:
        """Copies of the physical state (particles, springs, clock, the terms' own), for restore() and reset()."""
        self.check_alive()
        return self.state.snapshot()

    def restore(self, snap: dict) -> None:
        """Put the state back exactly as snapshot() saw it."""
        self.state.restore(snap)
        self.broken = None
        for part in self.parts:
            part.after_restore(self.state)

    def mark_initial(self) -> None:
        """Make the current state the one reset() returns to."""
        self._initial = self.snapshot()
        if self.terms.springs is not None:
            self.terms.springs.omega0 = Springs.omega_of(self._initial)

    def reset(self) -> None:
        """Back to the scene's initial state."""
        self.restore(self._initial)

    def set_temperatures(self, temperatures: np.ndarray) -> None:
        """Set the live particles' temperatures (degrees, (N,)); enthalpies and liquid flags follow."""
        n = self.state.live_count()
        full = self.particles.T.to_numpy()
        full[:n] = temperatures
        self.particles.T.from_numpy(full)
        self.terms.heat.sync_temperatures()

    def save(self, path: str | Path) -> Path:
        """Write the whole state to `path` (.npz) so that sandbox.resume(path) continues bit for bit; atomic (a
        crash while writing leaves any earlier file of that name whole). Returns the path written. A state the
        blow-up guard stopped, or one that would not load back, is not saved (SimulationError)."""
        if self.broken:
            raise SimulationError(f"{path}: not saved: the state is past a blow-up ({self.broken})")
        if self.worlds > 1:
            raise SandboxError(f"{path}: not saved: a state file holds one world; this simulation has {self.worlds}")
        return save_state(self, path)

    # ------------------------------------------------------------------ for scripts (scripting.py)
    def run(self, frames: int, progress: bool = False):
        """Advance `frames` frames and return their measurements (a FrameTable, one row per frame; of world 0 where
        the simulation holds several: sim.world(k).stats() reads another's). Raises SimulationError when the blow-up
        guard stops the run (the frames before it have been run)."""
        return scripting.run_frames(self, frames, progress)

    def movie(self, frames: int, width: int = 480, height: int = 270, every: int = 1, progress: bool = False):
        """Run `frames` frames drawing every `every`-th (a notebook Movie: plays inline, .save(path), .table)."""
        return scripting.movie(self, frames, width, height, every, progress)

    def picture(self, width: int | None = None, height: int | None = None, **render) -> np.ndarray:
        """The scene drawn now as a new (height, width, 3) uint8 RGB array (see scripting.picture)."""
        return scripting.picture(self, width, height, **render)

    def write_extxyz(self, path: str | Path, append: bool = True, bonds: bool = False) -> None:
        """Write the particles as one extended-XYZ frame (ASE, OVITO) to `path` (see scripting.write_extxyz)."""
        scripting.write_extxyz(self, path, append, bonds)

    def write_cache(
        self, path: str | Path, frames: int, every: int = 1, surface: bool = False, fps: float = 30.0
    ) -> Path:
        """Run `frames` frames into a particle cache for Blender, Houdini or ParaView (PATH.usd, .vtp or .ply; see
        caching.write_cache and docs/export.md): the state now and after every `every`-th frame; `surface`: a
        surface mesh of the bodies and melts with each. Returns the path to open."""
        return caching.write_cache(self, path, frames, every, surface, fps)

    def _repr_html_(self) -> str:
        return scripting.html(self)

    def positions(self) -> np.ndarray:
        """Live positions, (N, D) NumPy copy (with worlds, every world's in turn: sim.world(k) for one's)."""
        return self.particles.x.to_numpy()[self.state.live_rows()]

    def velocities(self) -> np.ndarray:
        return self.particles.v.to_numpy()[self.state.live_rows()]

    def temperatures(self) -> np.ndarray:
        return self.particles.T.to_numpy()[self.state.live_rows()]

    def forces(self) -> np.ndarray:
        """Forces of the last evaluation, (N, D)."""
        return self.rates.force.to_numpy()[self.state.live_rows()]

    def melt_fractions(self) -> np.ndarray:
        """Melt fraction in [0, 1] of the live particles, (N,) (0 without heat)."""
        return scripting.melt_fractions(self)

    def pipeline(self) -> list[str]:
        """The passes a step runs, in order, in words: the stepping plan's own lists (step/plan.py)."""
        return self.plan.lines()

    def memory_bytes(self) -> dict[str, int]:
        """Bytes of field memory by part."""
        return scripting.memory_bytes(self)


def timed_steps(sim: Simulation, n: int) -> float:
    """Run n steps and return the wall seconds, synchronised with the device."""
    ti.sync()
    t0 = time.perf_counter()
    sim.step(n)
    ti.sync()
    return time.perf_counter() - t0

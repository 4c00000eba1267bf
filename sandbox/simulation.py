"""The Simulation: builds only the passes a scene needs, steps them, measures them and guards against blow-ups.

The facade over its rooms: the passes (physics/), the rates of a step over them (step/rates.py), the three ways of
running steps (step/long_way.py, step/fused.py, step/team.py, chosen by step/plan.py), the measurements
(diagnostics.py), the stability bounds (stability.py), state access (state.py) and its self-description
(description.py). Per step, the integrator calls eval_rates() (neighbour grid rebuild -> spring update -> one fused
kernel for pair force, heat flow, springs and the body forces) and then its own update kernel, which ends with
finish_particle() (walls and the heat update) for each particle.
"""

import math
import time
from collections.abc import Callable

import numpy as np
import taichi as ti

from .config.arguments import MAX_SUBSTEPS
from .config.budget import emitter_population
from .config.build import build_particles
from .config.scene_tables import COUPLINGS, Scene
from .core import runtime, taichi_compat, transfer
from .core.loops import LoopPolicy
from .core.model import MaterialTable, ParticleFields, material_column
from .core.oriented import data_oriented
from .description import Description
from .diagnostics import STAT_COLUMNS, Measurements, Stats  # noqa: F401 - STAT_COLUMNS, Stats re-exported
from .errors import SandboxError, SimulationError
from .guard import BlowupGuard, scene_limits
from .integrators import make_integrator
from .physics.body_forces import build_body_forces
from .physics.boundary import Domain
from .physics.emitters import Emitters
from .physics.fields import VelocityField
from .physics.grid import CellGrid
from .physics.heat import Heat, lattice_correction
from .physics.heat_implicit import ImplicitHeat
from .physics.neighbours import NeighbourList, no_lists
from .physics.pair import PairForce
from .physics.phase import Phase, Refreezer
from .physics.reorder import CellOrder
from .physics.smoke import SmokeGrid
from .physics.springs import Springs
from .scripting import Scripting
from .stability import StabilityBounds
from .state import StateAccess
from .step.fused import FusedStepping
from .step.long_way import LongWay
from .step.plan import StepPlan, can_step_as_a_team
from .step.rates import Rates
from .step.team import Team

CHUNKS_PER_THREAD = 2  # half-list pass: blocks of particles per CPU thread, each with its own buffer row


@data_oriented
class Simulation(Rates, LongWay, FusedStepping, Measurements, StabilityBounds, StateAccess, Description, Scripting):
    """A running scene: fields, passes, integrator, clock."""

    def __init__(self, scene: Scene, arch: str = "cpu", half_lists: bool | None = None):
        """Build what `scene` names on Taichi backend `arch`. `half_lists`: apply each neighbour pair once to both
        particles from a half list (None: on the CPU backend, where it halves the pair work; a GPU gathers from
        full lists instead, which needs no write conflicts)."""
        self.scene = scene
        self.arch = runtime.init(arch, scene.world.precision)
        self.runtime_generation = runtime.generation()
        built = build_particles(scene)
        self.built = built
        world = scene.world
        self.dim = scene.dim
        self.dt = world.dt
        # room to spawn particles: half as many again (at least 1,024), plus what the emitters keep alive at once,
        # unless the scene sets world.capacity
        self.capacity = world.capacity if world.capacity else built.count + max(1024, built.count // 2)
        if not world.capacity:
            self.capacity += sum(emitter_population(e) for e in scene.emitters)
        self.capacity = max(self.capacity, built.count)
        pair_only = not (scene.heat or built.spring_count)
        threads = taichi_compat.cpu_threads() if self.arch == "cpu" else 1
        self.loops = LoopPolicy(self.arch, self.capacity, pair_only, threads, can_step_as_a_team(scene))
        self.material_names = scene.used_materials()
        materials = [scene.materials[name] for name in self.material_names]
        # The tables and particles built here are copied to their fields in one kernel at the block's end (a copy
        # kernel each was a tenth of a second of compiling at start-up); nothing here reads them back.
        with transfer.batched():
            self.materials = MaterialTable(materials)
            self.phase = Phase(self.materials) if scene.heat else None
            heat = scene.heat
            self.can_refreeze = bool(heat and heat.refreeze and any(m.melts for m in materials))
            self.has_lifetimes = any(e.lifetime > 0 for e in scene.emitters)
            self.particles = ParticleFields(
                self.dim, self.capacity, heat=heat is not None, refreeze=self.can_refreeze, lifetimes=self.has_lifetimes
            )
            self.particles.load(built, self.materials.colors, materials)
            self.particles.table_of = self.particle_table
            self.smoke = (
                SmokeGrid(self.dim, world.lo, world.hi, scene.smoke, world.gravity, self.arch == "cpu")
                if scene.smoke
                else None
            )
            self.fields = VelocityField(self.dim, scene.fields, self.smoke) if (scene.fields or scene.smoke) else None
            groups = scene.groups
            couplings = [g.field if self.fields is not None else "none" for g in groups]
            self.has_kinematic = "kinematic" in couplings
            self.has_field_drag = "drag" in couplings
            # per group (every body, every emitter, then the spawn tool's particles):
            self.g_coupling = ti.field(ti.i32, shape=len(groups) + 1)  # index into COUPLINGS
            self.g_drag = ti.field(float, shape=len(groups) + 1)  # field = drag: relaxation rate (1/time)
            transfer.upload(
                [
                    (self.g_coupling, np.array([COUPLINGS.index(c) for c in couplings], np.int32)),
                    (self.g_drag, np.array([g.field_drag for g in groups], float)),
                ]
            )
            self.gravity = ti.Vector.field(self.dim, float, shape=())  # acceleration (length / time^2)
            self.drag = ti.field(float, shape=())  # linear drag rate (1 / time)
            transfer.upload([(self.gravity, np.asarray(world.gravity, float)), (self.drag, world.drag)])
            if self.has_kinematic or self.has_field_drag:
                self.v_field = ti.Vector.field(self.dim, float, shape=self.capacity)  # v(x, t) at coupled particles
            if self.has_kinematic:
                self.x_start = ti.Vector.field(self.dim, float, shape=self.capacity)  # kinematic: x at the step start
                self.v_start = ti.Vector.field(self.dim, float, shape=self.capacity)
            self.domain = Domain(world.lo, world.hi, world.periodic, world.restitution, world.friction)
            p = self.particles
            self.pair = (
                PairForce(
                    self.dim,
                    materials,
                    scene.pair.a,
                    scene.pair.b,
                    scene.pair.cutoff,
                    scene.pair.core,
                    p.mass,
                    p.material,
                    p.v,
                    scene.pair.shift,
                )
                if scene.pair
                else None
            )
            self.heat = None
            if scene.heat:
                density = material_column(materials, built.material, "density")
                correction = lattice_correction(built.x, built.mass / density, scene.heat_radius)
                self.heat = Heat(self.dim, scene.heat, scene.heat_radius, p, self.materials, self.phase, correction)
            self.springs = None
            if built.spring_count or self.can_refreeze:
                bonds = (heat.refreeze_max_bonds or (8 if self.dim == 2 else 12)) if self.can_refreeze else 0
                spare = self.capacity * bonds // 2  # room for every particle to refreeze with its full bond count
                self.springs = Springs(
                    built, self.capacity, p, self.materials, self.phase, self.domain.separation, spare, bonds
                )
        reach = max(scene.pair.cutoff if scene.pair else 0.0, scene.heat_radius)
        skin = world.skin if world.neighbor_list else 0.0
        self.grid = (
            CellGrid(p.x, p.n, world.lo, world.hi, reach + skin, world.periodic, self.capacity, self.loops)
            if reach > 0
            else None
        )
        implicit_heat = bool(scene.heat) and scene.heat.stepper != "explicit"  # its solve reads full lists
        if half_lists is None:
            half_lists = self.arch == "cpu"
        self.half_pairs = bool(half_lists) and world.neighbor_list and reach > 0 and not implicit_heat
        self.neighbours = (
            NeighbourList(
                self.grid,
                self.domain,
                p.x,
                p.n,
                reach,
                skin,
                self.capacity,
                half=self.half_pairs,
                springs=self.springs if self.pair is not None else None,
                loops=self.loops,
            )
            if self.grid is not None and world.neighbor_list
            else None
        )
        self.no_lists = no_lists()  # what the step's kernels take for the lists when it does not use them
        if self.half_pairs:
            # Each worker thread takes a contiguous block of particles and writes what its pairs give to the other
            # particle into its own buffer row (no atomics, no write conflicts); the per-particle pass sums the rows.
            self.n_chunks = CHUNKS_PER_THREAD * max(1, taichi_compat.cpu_threads())
            self.n_pair_rows = 1 if self.loops.serial_pairs else self.n_chunks  # rows the pair pass writes
            self.pair_f = ti.Vector.field(self.dim, float, shape=(self.n_pair_rows, self.capacity))
            if scene.heat:
                self.pair_q = ti.field(float, shape=(self.n_pair_rows, self.capacity))
        every = world.reorder if world.reorder != "auto" else (20 if built.count >= 5000 else 0)
        self.reorder = CellOrder(self, every) if every and self.neighbours is not None else None
        self.refreezer = Refreezer(self, scene.refreeze_radius) if self.can_refreeze else None
        self.emitters = Emitters(self, scene.emitters, len(scene.bodies)) if scene.emitters else None
        self._warned_overflow = False
        self.has_neighbours = self.neighbours is not None
        self.marks_bonds = self.has_neighbours and self.neighbours.marks_bonds  # the half pass skips bonded pairs
        self.has_grid, self.has_pair = self.grid is not None, self.pair is not None
        self.has_heat, self.has_springs = self.heat is not None, self.springs is not None
        self.has_power = self.has_heat and self.heat.has_power
        self.has_fixed = self.has_heat and self.heat.has_fixed
        # With the implicit heat stepper the rates kernel skips heat; the solve runs after each step.
        self.has_explicit_heat = self.has_heat and scene.heat.stepper == "explicit"
        self.implicit_heat = None
        if self.has_heat and not self.has_explicit_heat:
            self.implicit_heat = ImplicitHeat(self)
        self.body_forces = build_body_forces(self)  # summed per particle by the rates pass
        self._build_measurements()
        self.integrator = make_integrator(world.integrator, self)
        self.team = Team(self, threads) if self.loops.team and self.half_pairs else None  # it steps half lists
        self.fuses_steps = self._fusable_scene()
        self.plan = StepPlan(self)  # the host's passes around each step, in order; pipeline() prints it
        self.fused_batches = 0  # launches of _fused_steps (or of the team) so far
        self.stopped_stage = ti.field(ti.i32, shape=())  # where a fused launch stopped inside a step (overflow)
        self.pending_stage = 0  # the stage the current step goes on from (0: at a step boundary)
        if self.emitters is not None:
            self.emitters.emit_initial()
        self.time = 0.0
        self.step_count = 0
        self.frames_done = 0  # frames advanced (advance_frame)
        self.guard = BlowupGuard(scene_limits(scene, built, self.pair))
        self._last_pair_energy: tuple[float, float] | None = (
            None  # pair energy and virial, for stats(pair_energy=False)
        )
        self._heat_limit = self.heat_dt_limit() if self.has_explicit_heat else math.inf
        self._initial = self.snapshot()
        self._spring_omega0 = self._snapshot_omega_max(self._initial)

    def set_integrator(self, name: str) -> None:
        """Switch the time integrator by name, keeping the state (live, e.g. from the window)."""
        if name != self.integrator.name:
            self.integrator = make_integrator(name, self)

    # ------------------------------------------------------------------ stepping
    def check_alive(self) -> None:
        """SandboxError when Taichi was restarted since this simulation was built (another precision or backend
        was asked for, or runtime.reset()): its fields are gone, and using them would crash."""
        if self.runtime_generation != runtime.generation():
            raise SandboxError(
                f"this {self.scene.name} simulation was built before Taichi was restarted (a later simulation asked "
                f"for another precision or backend, or runtime.reset()); build it again"
            )

    def step(self, n: int = 1) -> None:
        """Advance n steps of dt."""
        self.check_alive()
        if n <= 0:
            return
        self.integrator.begin(self.dt)
        while n > 0:
            if self.reorder is not None and self.fuses_steps and self.reorder.due() and not self.pending_stage:
                self.reorder.apply()  # between fused batches (the long way sorts at the start of its step)
            batch = self._fused_batch(n)
            done = self._run_fused(batch) if batch else 0
            if done < batch and self.neighbours is not None and self.neighbours.forced:
                pass  # a list build overflowed and the lists were widened: the next batch builds them again
            elif done < max(batch, 1):  # not fusable now, or the lists cannot be widened: one step the long way
                self._step_once()
                done += 1
            n -= done
        if self.has_lifetimes:
            self.emitters.retire()
        self.integrator.end(self.dt)

    def _count_steps(self, done: int) -> None:
        """Advance the clock by `done` steps and run what is due at a step boundary (refreezing)."""
        for _ in range(done):
            self.time += self.dt  # added one step at a time: the same clock as stepping one by one
        before = self.step_count
        self.step_count += done
        if self.refreezer is not None:
            interval = self.scene.heat.refreeze_interval
            if self.step_count // interval > before // interval:  # a fused batch ends at the refreeze step
                if self.refreezer.run() and self.marks_bonds:
                    self.neighbours.invalidate()  # the list marks bonded pairs: new springs must be marked

    def frame_substeps(self) -> tuple[int, float]:
        """(steps, step size) for the next frame: the scene's fixed substeps at world.dt, or under "auto" the
        fewest equal steps of at most auto_step() that span world.frame_time."""
        world = self.scene.world
        if world.substeps != "auto":
            return int(world.substeps), self.dt
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
        not for a single step, which has no middle. The wall gauge (stats().wall_pressure) restarts with the frame."""
        self.check_alive()
        if substeps is None:
            substeps, self.dt = self.frame_substeps()
        self.restart_wall_gauge()  # stats().wall_pressure: this frame's average
        if midway is None or substeps < 2:
            self.step(substeps)
        else:
            self.step(substeps // 2)
            midway()
            self.step(substeps - substeps // 2)
        self.frames_done += 1
        return substeps


def timed_steps(sim: Simulation, n: int) -> float:
    """Run n steps and return the wall seconds, synchronised with the device."""
    ti.sync()
    t0 = time.perf_counter()
    sim.step(n)
    ti.sync()
    return time.perf_counter() - t0

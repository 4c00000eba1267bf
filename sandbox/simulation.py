"""The Simulation: builds only the passes a scene needs, steps them, measures them and guards against blow-ups.

Per step, the integrator calls eval_rates() (neighbour grid rebuild -> spring update -> one fused kernel for pair
force, heat flow, springs, gravity and drag) and then its own update kernel, which ends with finish_particle()
(walls and the heat update) for each particle.
"""

import math
import time
import warnings
from collections.abc import Callable

import taichi as ti

from . import runtime, taichi_compat, transfer
from .arguments import MAX_SUBSTEPS
from .budget import emitter_population
from .build import build_particles
from .description import Description
from .diagnostics import STAT_COLUMNS, Measurements, Stats  # noqa: F401 - STAT_COLUMNS, Stats re-exported
from .errors import SandboxError, SimulationError
from .guard import BlowupGuard, scene_limits
from .integrators import make_integrator
from .loops import SPREAD_STRIDE, LoopPolicy, spread_item
from .model import MaterialTable, ParticleFields, material_column
from .oriented import data_oriented
from .physics.boundary import Domain
from .physics.emitters import NEVER_BONDS, Emitters
from .physics.fields import VelocityField
from .physics.grid import CellGrid
from .physics.heat import Heat, lattice_correction
from .physics.heat_implicit import ImplicitHeat
from .physics.neighbours import LIST_ARRAY, NeighbourList, no_lists
from .physics.pair import PairForce
from .physics.phase import LIQUID, Phase, Refreezer
from .physics.reorder import CellOrder
from .physics.smoke import SmokeGrid
from .physics.springs import Springs
from .scene_tables import COUPLINGS, Scene
from .scripting import Scripting
from .stability import StabilityBounds
from .state import StateAccess
from .step_plan import can_step_as_a_team, host_work_between_steps
from .team import Team

NO_COUPLING, KINEMATIC, DRAG = (COUPLINGS.index(c) for c in ("none", "kinematic", "drag"))
REORDER_BATCH = 20  # most steps per fused launch when the storage is sorted into cell order between launches
CHUNKS_PER_THREAD = 2  # half-list pass: blocks of particles per CPU thread, each with its own buffer row


@data_oriented
class Simulation(Measurements, StabilityBounds, StateAccess, Description, Scripting):
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
            for k, g in enumerate(groups):
                self.g_coupling[k] = COUPLINGS.index(couplings[k])
                self.g_drag[k] = g.field_drag
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
        self.gravity = ti.Vector.field(self.dim, float, shape=())  # acceleration (length / time^2)
        self.gravity[None] = world.gravity
        self.drag = ti.field(float, shape=())  # linear drag rate (1 / time)
        self.drag[None] = world.drag
        self._build_measurements()
        self.integrator = make_integrator(world.integrator, self)
        self.team = Team(self, threads) if self.loops.team and self.half_pairs else None  # it steps half lists
        self.fuses_steps = self._fusable_scene()
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

    def _step_once(self) -> None:
        """One step of dt, each pass launched from here (any scene, any integrator); or the rest of a step whose
        first stages a fused launch ran (self.pending_stage: only fusable scenes, which have no host work)."""
        if self.pending_stage:
            self.integrator.step(self.dt, self.pending_stage)
            self.pending_stage = 0
            self._count_steps(1)
            return
        if self.reorder is not None and self.reorder.due():
            self.reorder.apply()
        if self.heat is not None and self.heat.scheduled:
            self.heat.set_time(self.time)
        if self.emitters is not None:
            self.emitters.emit_due(self.time, self.dt)
            if self.emitters.refills:
                self.emitters.refill(self.time)
        if self.smoke is not None and self.step_count % self.scene.smoke.interval == 0:
            self.smoke.step(self.dt * self.scene.smoke.interval)
        if self.has_kinematic:
            self._kinematic_begin()
        if self.has_field_drag:
            self._sample_field(self.time)  # the drag force's target, held through the step
        self.integrator.step(self.dt)
        if self.implicit_heat is not None:
            use_list = self.neighbours is not None and self.neighbours.ensure_fresh()
            if not use_list and self.grid is not None:
                self.grid.rebuild()
            self.implicit_heat.step(self.dt, use_list, self._lists(use_list))
            self.implicit_heat.apply()
        if self.has_kinematic:
            self._advect_kinematic(self.dt, self.time)
        if self.has_lifetimes:
            self._age(self.dt)
        self._count_steps(1)

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

    # ------------------------------------------------------------------ the fused step
    def _fusable_scene(self) -> bool:
        """Whether this scene's steps can run many to a launch: in _fused_steps when every loop of a step runs on
        one thread (a small scene on the CPU: a parallel loop inside a kernel's step loop would not be parallel), or
        as a team of threads (self.team); and the step has no work that the host does between steps (emitters,
        scheduled sources, smoke, velocity fields, lifetimes, the implicit heat solve). Sorting the storage into
        cell order runs between batches, which are at most REORDER_BATCH steps long when the scene sorts."""
        return (self.loops.serial_pairs and self.loops.serial_light or self.team is not None) and self._no_host_work()

    def _no_host_work(self) -> bool:
        """No work that the host does between steps (see _fusable_scene)."""
        return not host_work_between_steps(self.scene)

    def _lists(self, use: bool):
        """The neighbour lists to hand a kernel: the lists when the step uses them, else the 1 x 1 stand-in."""
        return self.neighbours.ids if use else self.no_lists

    def _fused_batch(self, n: int) -> int:
        """How many of the next n steps to run in one _fused_steps launch (0: step the long way)."""
        if not (self.fuses_steps and self.integrator.stages):
            return 0
        if self.neighbours is not None and not (self.neighbours.usable or self.neighbours.forced):
            return 0  # lists too wide to allocate: the long way scans the grid
        if self.refreezer is not None:  # end the batch at the next refreeze step
            interval = self.scene.heat.refreeze_interval
            n = min(n, interval - self.step_count % interval)
        if self.reorder is not None:
            n = min(n, REORDER_BATCH)
        return n

    def _run_fused(self, batch: int) -> int:
        """Run up to `batch` steps in one launch (the first from self.pending_stage on); returns the steps done: fewer
        when a list build overflowed, which leaves self.pending_stage at the stage it stopped before."""
        nb = self.neighbours
        forced = 0
        if nb is not None:
            forced = int(nb.forced)
            nb.forced, nb.fused = False, True
        ids = self._lists(nb is not None)
        with runtime.without_cfg_pass():  # a whole step in one kernel: see the function
            if self.team is not None:
                done = self.team.run(batch, forced, self.pending_stage, self.integrator, ids, self.dt)
            else:
                done = int(self._fused_steps(batch, forced, self.pending_stage, self.integrator, ids, self.dt))
        if done < 0:  # the team's thread pool did not start every worker: nothing ran; step the long way from now on
            nb.forced = bool(forced)
            self.team, self.fuses_steps = None, False
            return 0
        self.fused_batches += 1
        self.pending_stage = int(self.stopped_stage[None]) if done < batch else 0
        if nb is not None:
            if done < batch:  # the build of step `done` overflowed: widen the lists (the next batch rebuilds them)
                if nb.grow():
                    nb.invalidate()
                else:
                    nb.usable = False  # too wide to allocate: the long way scans the grid
            else:
                nb.usable = True  # every build in the batch fitted (an overflow stops the batch)
        self._count_steps(done)
        return done

    @ti.kernel
    def _fused_steps(
        self, steps: ti.i32, forced: ti.i32, first_stage: ti.i32, integrator: ti.template(), ids: LIST_ARRAY, dt: float
    ) -> ti.i32:
        """Up to `steps` whole steps of a staged integrator in a single launch, the first from `first_stage` on: per
        stage the per-step passes, the neighbour-list check and rebuild decided here on the device, forces and heat
        rates, and the update. A launch costs 30-50 us of host time, as much as a whole step of a 1,000-particle
        scene. Stops before the forces of a stage whose list build overflowed (returns the steps done and leaves
        the stage in stopped_stage; the host grows the list and goes on from there)."""
        done = 0
        rebuild = forced
        stage = first_stage
        stopped = 0
        while done < steps and not stopped:
            while stage < ti.static(integrator.stages) and not stopped:
                self._prestep_loops()
                if ti.static(self.has_neighbours):
                    if rebuild or self.neighbours.stale[None]:
                        self.grid.rebuild_loops()
                        self.neighbours.fill_loops(ids)
                        self.neighbours.fused_builds[None] += 1
                        if self.neighbours.overflow[None]:
                            stopped = 1
                            self.stopped_stage[None] = stage
                elif ti.static(self.has_grid):
                    self.grid.rebuild_loops()
                if not stopped:
                    rebuild = 0
                    merged = ti.static(self._updates_in_gather(self.has_neighbours))
                    self._rate_loops(self.has_neighbours, ids, integrator, dt, stage, merged)
                    if ti.static(not merged):
                        for i in range(self.particles.n[None]):
                            integrator.update_particle(i, dt, stage)
                    stage += 1
            if not stopped:
                done += 1
                stage = 0
        return done

    @ti.kernel
    def _kinematic_begin(self):
        """Kinematic particles: remember x and v at the step start (the integrator's updates are undone)."""
        p = self.particles
        self.loops.light()
        for i in range(p.n[None]):
            if self.g_coupling[p.group[i]] == KINEMATIC:
                self.x_start[i] = p.x[i]
                self.v_start[i] = p.v[i]

    def _advect_kinematic(self, dt: float, t: float) -> None:
        """x += dt v(x, t) from the step's start (forward Euler), or dt v(x + dt/2 v, t + dt/2) (midpoint). The field
        is sampled by one kernel at the current positions, so its code (curl noise is long) compiles once."""
        self._sample_field(t)
        if self.scene.world.advection == "midpoint":
            self._kinematic_move(0.5 * dt, False)
            self._sample_field(t + 0.5 * dt)
        self._kinematic_move(dt, True)

    @ti.kernel
    def _sample_field(self, t: float):
        p = self.particles
        for i in range(p.n[None]):
            if self.g_coupling[p.group[i]] != NO_COUPLING:
                self.v_field[i] = self.fields.velocity(p.x[i], t)

    @ti.kernel
    def _kinematic_move(self, dt: float, final: ti.template()):
        p = self.particles
        self.loops.light()
        for i in range(p.n[None]):
            if self.g_coupling[p.group[i]] == KINEMATIC:
                x = self.x_start[i] + dt * self.v_field[i]
                if ti.static(final):
                    p.x[i], p.v[i] = self.domain.enforce(x, self.v_field[i], p.radius[i], 0.0)
                else:
                    p.x[i] = x

    @ti.kernel
    def _age(self, dt: float):
        self.loops.light()
        for i in range(self.particles.n[None]):
            self.particles.age[i] += dt

    def eval_rates(self, then_update: float | None = None, stage: int = 0) -> None:
        """Forces (p.f) and heat rates (p.dhdt) at the current state. `then_update`: a step dt for the integrator's
        per-particle update of `stage` (`update_particle`), run in the same kernel launch as the forces (one launch
        less per step: a launch costs about 30 us on the CPU backend)."""
        use_list = False
        moved = bool(self._prestep()) if (self.has_neighbours or self.has_springs or self.has_power) else False
        if self.neighbours is not None:
            use_list = self.neighbours.ensure_fresh(moved)
            if not use_list:
                self.grid.rebuild()  # the fallback scans the grid, which must match the current positions
            if not use_list and not self._warned_overflow:
                self._warned_overflow = True
                warnings.warn(
                    "neighbour list overflow: some particle has more than "
                    f"{self.neighbours.width} neighbours; scanning the cell grid instead (slower)",
                    stacklevel=2,
                )
        elif self.grid is not None:
            self.grid.rebuild()
        ids = self._lists(use_list)
        if then_update is None:
            self._rates(use_list, ids)
        else:
            self._rates_update(use_list, ids, self.integrator, then_update, stage)

    @ti.kernel
    def _prestep(self) -> ti.i32:
        """One launch for the cheap per-step passes (see _prestep_loops); returns 1 when some particle has moved half
        the neighbour skin."""
        self._prestep_loops()
        moved = 0
        if ti.static(self.has_neighbours):
            moved = self.neighbours.stale[None]
        return moved

    @ti.func
    def _prestep_loops(self):
        """Has any particle moved half the neighbour skin (sets neighbours.stale), the springs' thermoelastic update
        and breaking, and the mass inside each power source."""
        if ti.static(self.has_power):
            for k in range(self.heat.n_sources):
                self.heat.src_mass[k] = 0.0
            self.loops.light()
            for i in range(self.particles.n[None]):
                self.heat.add_source_mass(i)
        if ti.static(self.has_neighbours):
            self.neighbours.stale[None] = 0
            self.neighbours.check_count()
            self.loops.light()
            for i in range(self.particles.n[None]):
                self.neighbours.check_one(i)
        if ti.static(self.has_springs):
            # each spring's update reads two phase states: heavier than a light loop, so parallel with the pair loops
            self.loops.pairs()
            for s in range(self.springs.span[None]):
                self.springs.update_one(s)

    @ti.func
    def _pair_terms(self, i, j, d, r2, f_scaled, f_visc, q):
        """Add the pair force (scaled by 1/m_i), the viscous force and the heat flow of neighbour j to i."""
        if ti.static(self.has_pair):
            if r2 < self.pair.cutoff**2:
                f_scaled += self.pair.scaled_force(i, j, d, r2)
                f_visc += self.pair.viscous_force(i, j, d, r2)
        if ti.static(self.has_explicit_heat):
            if r2 < self.heat.support**2:
                q += self.heat.flow(i, j, r2)
        return f_scaled, f_visc, q

    @ti.func
    def half_rows_of_chunk(self, t, n, ids: ti.template()):
        """The half-list rows of chunk t of the n particles (a contiguous block of ids), into buffer row t."""
        for i in range(t * n // self.n_chunks, (t + 1) * n // self.n_chunks):
            self._half_row(t, i, ids)

    @ti.func
    def _half_row(self, t, i, ids: ti.template()):
        """The pairs (i, j) of i's half list: i's share kept, j's (equal and opposite) written to chunk t's buffer
        row. Row t belongs to this chunk alone, so it is updated by a plain load and store: `+=` on a field would be
        an atomic compare-and-swap loop on the CPU (1.4x slower pass). Forces and heat flows are evaluated for every
        listed pair and masked beyond their range rather than branched around: a listed pair lies within reach +
        skin, where both laws are finite, and a branch taken for 80% of pairs mispredicts often."""
        p = self.particles
        xi = p.x[i]
        m_i = p.mass[i]
        fi = ti.Vector.zero(float, self.dim)
        qi = 0.0
        shared = ti.Vector.zero(float, 5)
        if ti.static(self.has_pair):
            shared = self.pair.shared_coefficients()
        t_i, c_i, mat_i = 0.0, 0.0, 0
        if ti.static(self.has_explicit_heat):
            t_i, c_i, mat_i = self.heat.own_terms(i)
        for k in range(self.neighbours.count[i]):
            j = ids[i, k]
            bonded = False  # joined by a live spring: no pair force (heat still flows)
            if ti.static(self.marks_bonds):
                if j < 0:
                    s = -j - 1
                    j = self.springs.other_end(i, s)
                    bonded = self.springs.alive[s] != 0
            d = self.domain.separation(xi, p.x[j])
            r2 = d.dot(d)
            if ti.static(self.has_pair):
                fij = self.pair.force_with(self.pair.pair_coefficients(shared, i, j), m_i, i, j, d, r2)
                fij *= ti.select((r2 < self.pair.cutoff**2) and not bonded, 1.0, 0.0)
                fi += fij
                self.pair_f[t, j] = self.pair_f[t, j] - fij
            if ti.static(self.has_explicit_heat):
                qij = ti.select(r2 < self.heat.support**2, 1.0, 0.0) * self.heat.flow_with(t_i, c_i, mat_i, j, r2)
                qi += qij
                self.pair_q[t, j] = self.pair_q[t, j] - qij
        self.pair_f[t, i] = self.pair_f[t, i] + fi
        if ti.static(self.has_explicit_heat):
            self.pair_q[t, i] = self.pair_q[t, i] + qi

    @ti.kernel
    def _rates(self, use_list: ti.template(), ids: LIST_ARRAY):
        self._rate_loops(use_list, ids, None, 0.0, 0, False)

    @ti.kernel
    def _rates_update(
        self, use_list: ti.template(), ids: LIST_ARRAY, integrator: ti.template(), dt: float, stage: ti.i32
    ):
        merged = ti.static(self._updates_in_gather(use_list))
        self._rate_loops(use_list, ids, integrator, dt, stage, merged)
        if ti.static(not merged):
            self.loops.light()
            for i in range(self.particles.n[None]):
                integrator.update_particle(i, dt, stage)

    def _updates_in_gather(self, use_list: bool) -> bool:
        """Whether the per-particle pass of _rate_loops may update each particle as soon as its force is summed (one
        pass over the particles less): when that pass reads nothing of other particles, i.e. the pair terms come
        from the half-list rows or there are none, and there are no springs (their force reads the other end) and
        no kinematic particles."""
        pairs_precomputed = not self.has_grid or (use_list and self.half_pairs)
        return pairs_precomputed and not self.has_springs and not self.has_kinematic

    @ti.func
    def _rate_loops(
        self,
        use_list: ti.template(),
        ids: ti.template(),
        integrator: ti.template(),
        dt,
        stage,
        update_here: ti.template(),
    ):
        """The loops of a force and heat-rate evaluation (see eval_rates); each runs in parallel unless self.loops
        serializes it. `update_here` (allowed when _updates_in_gather): the per-particle pass also updates each
        particle by `dt` with `integrator`'s `stage` once its rates are in."""
        p = self.particles
        if ti.static(use_list and self.half_pairs):
            n = p.n[None]
            if ti.static(self.loops.serial_pairs):
                ti.loop_config(serialize=True)
                for i in range(n):
                    self._half_row(0, i, ids)
            else:
                for u in range(self.n_chunks * SPREAD_STRIDE):  # a loop over the chunks alone runs on one thread
                    t = spread_item(u)
                    if t >= 0:
                        self.half_rows_of_chunk(t, n, ids)
        if ti.static(self.has_springs):
            self.loops.pairs()  # each particle visits its bonds too: as much work per item as a pair loop
        else:
            self.loops.light()
        for ks in range(p.n[None]):
            i = ks
            if ti.static(self.has_grid):
                i = self.grid.sorted_ids[ks]  # visit particles cell by cell: neighbours stay in cache
            self._gather_particle(i, use_list, ids, integrator, dt, stage, update_here)

    @ti.func
    def _gather_particle(
        self,
        i,
        use_list: ti.template(),
        ids: ti.template(),
        integrator: ti.template(),
        dt,
        stage,
        update_here: ti.template(),
    ):
        """Particle i's force (p.f) and heat rate (p.dhdt): gravity, drag, its pair terms (summed from the half-list
        rows, or gathered from its list or the grid), its springs; then, with `update_here`, its update by `dt`
        (the integrator's `stage`)."""
        p = self.particles
        xi = p.x[i]
        f = p.mass[i] * (self.gravity[None] - self.drag[None] * p.v[i])
        if ti.static(self.has_field_drag):
            if self.g_coupling[p.group[i]] == DRAG:
                f += p.mass[i] * self.g_drag[p.group[i]] * (self.v_field[i] - p.v[i])
        q = 0.0
        if ti.static(self.has_grid):
            f_scaled = ti.Vector.zero(float, self.dim)  # pair-law forces / m_i
            f_visc = ti.Vector.zero(float, self.dim)
            if ti.static(use_list and self.half_pairs):
                for t in range(self.n_pair_rows):  # what the pair pass left for i, read and cleared
                    f_visc += self.pair_f[t, i]
                    self.pair_f[t, i] = ti.Vector.zero(float, self.dim)
                    if ti.static(self.has_explicit_heat):
                        q += self.pair_q[t, i]
                        self.pair_q[t, i] = 0.0
            elif ti.static(use_list):
                for k in range(self.neighbours.count[i]):
                    j = ids[i, k]
                    d = self.domain.separation(xi, p.x[j])
                    f_scaled, f_visc, q = self._pair_terms(i, j, d, d.dot(d), f_scaled, f_visc, q)
            else:
                c = self.grid.cell_of(xi)
                for o in range(self.grid.n_offsets):
                    nc, shift = self.grid.neighbour_cell(c, self.grid.offset(o))
                    if nc >= 0:
                        start = self.grid.cell_start[nc]
                        xs = xi - shift
                        for k in range(start, start + self.grid.cell_count[nc]):
                            j = self.grid.sorted_ids[k]
                            if j != i:
                                d = self.grid.x_sorted[k] - xs
                                f_scaled, f_visc, q = self._pair_terms(i, j, d, d.dot(d), f_scaled, f_visc, q)
            f += p.mass[i] * f_scaled + f_visc
        if ti.static(self.has_springs):
            for k in range(self.springs.max_bonds):
                s = self.springs.bonds[i, k]
                if s < 0:
                    break
                if self.springs.alive[s]:
                    j = self.springs.other_end(i, s)
                    d = self.domain.separation(xi, p.x[j])
                    f += self.springs.force(i, j, s, d)
                    if ti.static(self.has_pair and not (use_list and self.half_pairs and self.marks_bonds)):
                        r2 = d.dot(d)
                        if r2 < self.pair.cutoff**2:  # bonded pairs feel the spring, not the pair force
                            f -= self.pair.force(i, j, d, r2)
        if ti.static(self.has_kinematic):
            if self.g_coupling[p.group[i]] == KINEMATIC:
                f = ti.Vector.zero(float, self.dim)  # moved by the field alone (_advect_kinematic)
        p.f[i] = f
        if ti.static(self.has_explicit_heat):
            q += self.heat.source_flow(i)
            p.dhdt[i] = q / p.mass[i]
        if ti.static(update_here):
            integrator.update_particle(i, dt, stage)

    @ti.func
    def finish_particle(self, i, dt):
        """Walls (or periodic wrap) and the explicit heat update for particle i, at the end of a step."""
        p = self.particles
        p.x[i], p.v[i] = self.domain.enforce(p.x[i], p.v[i], p.radius[i], p.mass[i])
        if ti.static(self.has_kinematic):
            if self.g_coupling[p.group[i]] == KINEMATIC:  # the integrator does not move them: _advect_kinematic does
                p.x[i], p.v[i] = self.x_start[i], self.v_start[i]
        if ti.static(self.has_explicit_heat):
            self.set_enthalpy(i, p.h[i] + dt * p.dhdt[i])

    @ti.func
    def set_enthalpy(self, i, h):
        """Give particle i specific enthalpy h (held by fixed sources), and its temperature and liquid flag."""
        p = self.particles
        if ti.static(self.has_fixed):
            h = self.heat.held(i, h)
        p.h[i] = h
        t, phi = self.phase.state(h, p.material[i])
        p.T[i] = t
        if ti.static(self.can_refreeze):
            if phi >= self.materials.break_fraction[p.material[i]] and p.liquid[i] != NEVER_BONDS:
                p.liquid[i] = LIQUID

    @ti.kernel
    def sync_temperatures(self):
        """Recompute every particle's enthalpy from its temperature (after the temperature was set directly)."""
        for i in range(self.particles.n[None]):
            self.particles.h[i] = self.phase.enthalpy(self.particles.T[i], self.particles.material[i])
            self.set_enthalpy(i, self.particles.h[i])

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

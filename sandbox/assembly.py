"""Build what a scene names: its Model (what it fixes), its State (what a step changes), the neighbourhood its pair
terms are evaluated over, and its term list (only the terms the scene has: physics/term.py's registry).

Everything is allocated by capacity, and the tables and initial particles built here are copied to their fields in
one kernel when the batched block ends (a copy kernel each was a tenth of a second of compiling at start-up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config.budget import emitter_population
from .config.build import build_particles
from .config.scene_tables import Scene
from .core import runtime, taichi_compat, transfer
from .core.domain import Domain
from .core.loops import LoopPolicy
from .core.model import MaterialTable, Model
from .core.particles import Particles, SpringState
from .core.state import State
from .errors import SandboxError
from .physics import TERMS, Parts
from .physics.grid import CellGrid
from .physics.neighbourhood import Neighbourhood
from .physics.neighbours import NeighbourList
from .physics.phase import Phase, initial_enthalpy
from .physics.reorder import CellOrder
from .physics.term import hook_order
from .step.plan import can_step_as_a_team


@dataclass
class Assembly:
    """A scene built: its model, state, neighbourhood (None without pair terms) and terms (in their order)."""

    model: Model
    state: State
    hood: Neighbourhood | None
    terms: list


def assemble(
    scene: Scene,
    arch: str = "cpu",
    half_lists: bool | None = None,
    worlds: int = 1,
    starts: list | None = None,
    alone_threads: int | None = None,
) -> Assembly:
    """Build `scene` on Taichi backend `arch` (see Simulation for `half_lists`), `worlds` copies of it side by side
    (core/worlds.py; SandboxError where the scene has a part that cannot yet run as worlds); `starts`: the scene of
    each world where they start from other particles (their temperatures and velocities: Simulation);
    `alone_threads`: the CPU threads of the lone run each world is to equal (default: this simulation's)."""
    running = runtime.init(arch, scene.world.precision)
    built = build_particles(scene)
    world = scene.world
    # room to spawn particles: half as many again (at least 1,024), plus what the emitters keep alive at once,
    # unless the scene sets world.capacity
    capacity = world.capacity if world.capacity else built.count + max(1024, built.count // 2)
    if not world.capacity:
        capacity += sum(emitter_population(e) for e in scene.emitters)
    capacity = max(capacity, built.count) * worlds
    threads = taichi_compat.cpu_threads() if running == "cpu" else 1
    pair_only, team_ok = not (scene.heat or built.spring_count), can_step_as_a_team(scene)
    loops = LoopPolicy(running, capacity, pair_only, threads, team_ok)
    # how a lone run of one world would loop: the pair pass sums each world's rows as it would (step/rates.py)
    alone = threads if alone_threads is None or running != "cpu" else alone_threads
    lone_loops = LoopPolicy(running, capacity // worlds, pair_only, alone, can_step_as_a_team(scene))
    materials = [scene.materials[name] for name in scene.used_materials()]
    heat = scene.heat
    can_refreeze = bool(heat and heat.refreeze and any(m.melts for m in materials))
    with transfer.batched():
        table = MaterialTable(materials)
        domain = Domain(world.lo, world.hi, world.periodic, world.restitution, world.friction, worlds)
        phase = Phase(table) if heat else None
        model = Model(scene, running, built, capacity, materials, table, phase, loops, domain, threads, worlds)
        model.lone_loops, model.lone_threads = lone_loops, alone
        lifetimes = any(e.lifetime > 0 for e in scene.emitters)
        particles = Particles(
            scene.dim,
            capacity,
            heat=heat is not None,
            refreeze=can_refreeze,
            lifetimes=lifetimes,
            structure=scene.molecular is not None,
            worlds=worlds,
            gaps=bool(scene.emitters),
        )
        # with gaps (counts that change), world k's particles start at k times a lone run's capacity
        stride = capacity // worlds if particles.gaps else 0
        try:
            builds = [build_particles(s) for s in starts] if starts else [built] * worlds
            every_world = built.side_by_side(builds, stride)
        except ValueError as exc:
            raise SandboxError(f"{scene.name}: {exc}") from None
        _load_particles(particles, every_world, table.colors, materials, built.count)
        springs = None
        if built.spring_count or can_refreeze:
            bonds = (heat.refreeze_max_bonds or (8 if scene.dim == 2 else 12)) if can_refreeze else 0
            spare = capacity * bonds // 2  # room for every particle to refreeze with its full bond count
            springs = SpringState(every_world, capacity, spare, bonds, worlds)
        state = State(particles, springs, world.dt)
        parts = Parts(model, state, None)
        for cls in sorted(TERMS, key=lambda c: hook_order(c, "build")):
            if cls.wanted(parts):
                parts.terms[cls.key] = cls(parts)
    terms = list(parts.terms.values())
    if worlds > 1:
        refuse_worlds(scene, worlds, terms, built.count)
    parts.neighbours = hood = _neighbourhood(scene, model, state, half_lists, any(t.key == "pair" for t in terms))
    for part in ([hood] if hood is not None else []) + terms:
        part.declare(state)
    return Assembly(model, state, hood, terms)


# The terms a simulation of many worlds can hold: their controls, gauges, grids and passes are kept per world (a
# term not named here would keep one for all worlds, and is refused).
WORLD_TERMS = frozenset(
    {
        "smoke",
        "emitters",
        "lifetimes",
        "fields",
        "kinematic",
        "gravity",
        "pair",
        "springs",
        "heat",
        "walls",
        "refreeze",
        "agitation",
        "structure",
        "thermal_walls",
        "lid",
        "heater",
    }
)


def refuse_worlds(scene: Scene, worlds: int, terms: list, particles: int) -> None:
    """SandboxError naming what in `scene` (built as `terms`, with `particles` at the start) cannot yet run as
    `worlds` worlds (core/worlds.py)."""
    if particles == 0 and not scene.emitters:  # a world keeps its scene's particles: none to keep
        raise SandboxError(
            f"{scene.name}: worlds = {worlds} needs a scene with particles or emitters; this one is empty"
        )
    other = sorted(term.key for term in terms if term.key not in WORLD_TERMS)
    if other:
        raise SandboxError(
            f"{scene.name}: worlds = {worlds} is for scenes whose parts are all {', '.join(sorted(WORLD_TERMS))}; "
            f"this one has {', '.join(other)}"
        )
    common = sorted(t.key for t in terms if not getattr(t, "world_controls", False) and t.controls())
    if common:  # a live control of one value for all worlds: a tab's slider would move every tab's
        raise SandboxError(f"{scene.name}: worlds = {worlds} cannot yet hold {', '.join(common)}: one control for all")
    heat = scene.heat
    if heat and heat.stepper != "explicit":  # one conjugate-gradient solve would couple the worlds' iterations
        raise SandboxError(f'{scene.name}: worlds = {worlds} needs heat.stepper = "explicit", not {heat.stepper!r}')
    if scene.world.integrator == "implicit_euler":
        raise SandboxError(f"{scene.name}: worlds = {worlds} needs an explicit integrator, not implicit_euler")
    if scene.world.substeps == "auto":  # one step size for all: a world's own stable step would change the others'
        raise SandboxError(f'{scene.name}: worlds = {worlds} needs whole world.substeps, not "auto"')


def _load_particles(particles: Particles, built, colors: np.ndarray, materials: list, each_built: int) -> None:
    """Copy the built particles in: positions, velocities, ..., and with heat the enthalpy of their temperature
    (`built`: every world's, `each_built` particles a world)."""
    n = built.count
    particles.next_ident = n
    p = particles
    pairs = [
        (p.n, n),
        (p.x, built.x),
        (p.v, built.v),
        (p.mass, built.mass),
        (p.radius, built.radius),
        (p.material, built.material),
        (p.color, colors[built.material]),
        (p.group, built.body),
        (p.ident, np.arange(n, dtype=np.int32)),
    ]
    if p.worlds:  # world k's particles are one world's build (config/build.py's side_by_side), ids as in a lone run
        each = p.world_size = n // p.world_count
        pairs[-1] = (p.ident, np.tile(np.arange(each, dtype=np.int32), p.world_count))
        pairs.append((p.world, np.repeat(np.arange(p.world_count, dtype=np.int32), each)))
        if p.gaps:  # each world's ids go on from its own build's (emitters number theirs per world)
            particles.next_ident = [each_built] * p.world_count
            pairs.append((p.counts, np.full(p.world_count, each_built, dtype=np.int32)))
    if p.heat:
        h, phi = initial_enthalpy(built.temperature, built.material, materials)
        pairs += [(p.h, h), (p.T, built.temperature)]
        if p.refreeze:
            breaks = np.array([min(m.break_melt_fraction, 1e30) for m in materials])[built.material]
            pairs.append((p.liquid, ((phi >= breaks) | ~built.solid).astype(np.int32)))
    transfer.upload(pairs)


def _neighbourhood(scene: Scene, model: Model, state: State, half_lists: bool | None, has_pair: bool):
    """The cell grid within the reach of the pair terms (pair force, heat), its lists and the cell-order sort."""
    world = scene.world
    reach = max(scene.pair.cutoff if scene.pair else 0.0, scene.heat_radius)
    if reach <= 0:
        return None
    skin = world.skin if world.neighbor_list else 0.0
    capacity = model.capacity
    p = state.particles
    grid = CellGrid(p.x, p.n, world.lo, world.hi, reach + skin, world.periodic, capacity, model.loops, particles=p)
    implicit_heat = bool(scene.heat) and scene.heat.stepper != "explicit"  # its solve reads full lists
    if half_lists is None:
        half_lists = model.arch == "cpu"
    half = bool(half_lists) and world.neighbor_list and not implicit_heat
    lists = None
    if world.neighbor_list:
        springs = state.springs if has_pair else None  # half rows mark bonded pairs, which the pair force skips
        lists = NeighbourList(grid, model.domain, state, reach, skin, capacity, half, springs, model.loops)
    every = world.reorder if world.reorder != "auto" else (20 if model.built.count >= 5000 else 0)
    every = every if model.worlds == 1 else 0  # a world owns one block of slots (core/worlds.py): no sort of storage
    order = CellOrder(state, grid, lists, every) if every and lists is not None else None
    return Neighbourhood(grid, lists, order, half)

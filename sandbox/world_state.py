"""One world's state out of a simulation of many worlds, and back into it, while the other worlds run on untouched:
undo in one world, a world started again, a world's state file (`sim.world(k).snapshot()`, `restore()`, `reset()`,
`save()`, `load()`).

A world's state is held as a lone run of its scene holds its own (`sim.snapshot()`'s names and shapes): its block of
particle slots (core/worlds.py: world k's particle i at k N + i) as slots 0 .. N - 1, its springs as a lone run's
(the built block, then the bonds it made by refreezing), each bond list pointing at them, its own row of each
per-world gauge, its own clock. So a world's state file is a lone run's, read by `sandbox.resume` and by any world
of a simulation of the scene, and a lone run's state file loads into a world.

Springs are where the layouts differ: refreezing puts a world's new bonds in any free slot of the shared spring
table (another world's broken built bond's among them). Putting a world back kills every bond its particles hold
now, then places its saved ones: a built bond in its own slot where that slot is free, any other bond (and a built
one whose slot another world has taken) in a free slot. A bond list is packed to its live bonds as it goes in (as
refreezing packs every list before it bonds): a force sums a particle's bonds in its list's order, so the order,
not the slots, is what a step reads, and the world steps on as its lone run would. Its neighbour-list rows are
rebuilt at the next step (their reference positions put far away: only this world is found stale).
"""

from __future__ import annotations

import numpy as np

from .core import controls as live_controls
from .core import transfer
from .core.state import FIELD, NDARRAY, VALUE, WORLDS
from .core.worlds import set_world_entry, world_entry
from .errors import SandboxError
from .physics.heat_sources import scheduled_start, source_value

FAR = 1e30  # a reference position no particle is within half a skin of
SPRING_ROWS = ("i", "j", "rest", "ks", "kd", "factor", "alive")  # the springs' per-slot fields
# what a world's state has none of (the batch's own)
OWN = ("particles.world", "particles.counts", "clock.world_started", "clock.world_steps_started")
IMPULSE = "walls.impulse"  # the walls' momentum gauge (the model's, not the state's): in memory only


def _layout(sim) -> tuple[int, int, int]:
    """(worlds held, slots a world: world k's start at k times it, a lone run's capacity) of `sim`."""
    worlds = sim.worlds
    return worlds, sim.state.particles.world_size, sim.model.capacity // worlds


def _live(sim, whole: dict, k: int) -> int:
    """World k's live particles in `whole` (a snapshot): its block, or with gaps its count."""
    p = sim.state.particles
    return int(whole["particles.counts"][k]) if p.gaps else p.world_size


def world_part(sim, whole: dict, k: int) -> dict:
    """World k's state, as a lone run of the scene holds it (module docstring), out of `whole`: a snapshot of every
    world (Simulation.snapshot()'s names: NumPy arrays and host values)."""
    state = sim.state
    worlds, block, lone_capacity = _layout(sim)
    each = _live(sim, whole, k)
    rows = slice(k * block, k * block + each)
    out = {}
    for e in state.entries(physical_only=True):
        if e.name in OWN or e.name.startswith("springs."):
            continue
        value = whole[e.name]
        if e.rows == "particles":
            out[e.name] = _lone_rows(value[rows], lone_capacity)
        elif e.rows == WORLDS and e.kind == VALUE:  # a host list a world (the emitters' counters)
            out[e.name] = _copy(value[k])
        elif e.rows == WORLDS:
            out[e.name] = np.array(value[k])
        elif e.kind == VALUE:
            out[e.name] = value.copy() if isinstance(value, list) else value
        else:
            out[e.name] = np.array(value)
    out["particles.n"] = np.array(each, dtype=whole["particles.n"].dtype)
    out["clock.time"] = whole["clock.time"] - whole["clock.world_started"][k]
    out["clock.step"] = whole["clock.step"] - whole["clock.world_steps_started"][k]
    if state.particles.gaps:  # ids numbered on per world, by its emitters
        out["particles.next_ident"] = int(whole["particles.next_ident"][k])
    elif "particles.next_ident" in out:  # a world's ids are its lone run's: 0 .. N - 1 (no tool adds to a world)
        out["particles.next_ident"] = each
    if state.springs is not None:
        out.update(_springs_out(sim, whole, k, block, lone_capacity))
    return out


def _copy(value):
    return list(value) if isinstance(value, list) else value


def _lone_rows(block: np.ndarray, capacity: int) -> np.ndarray:
    """A lone run's field of `capacity` rows holding `block` first (the rows past its live ones are zero)."""
    out = np.zeros((capacity, *block.shape[1:]), dtype=block.dtype)
    out[: len(block)] = block
    return out


def _springs_out(sim, whole: dict, k: int, each: int, lone_capacity: int) -> dict:
    """World k's springs in a lone run's slots: its built block where it was built, its other live bonds after it
    (`each`: the particle slots a world, world k's from k each)."""
    springs = sim.state.springs
    built = springs.built_count // sim.worlds
    lone_count = springs.count // sim.worlds
    ends = whole["springs.i"]
    mine = np.flatnonzero((whole["springs.alive"] != 0) & (ends >= k * each) & (ends < (k + 1) * each))
    in_block = (mine >= k * built) & (mine < (k + 1) * built)
    lone_slot = np.empty(len(mine), dtype=np.int64)
    lone_slot[in_block] = mine[in_block] - k * built
    lone_slot[~in_block] = built + np.arange(int((~in_block).sum()))
    if len(mine) and lone_slot.max() >= lone_count:
        raise SandboxError(
            f"world {k} holds {len(mine)} bonds, more than the {lone_count} spring slots of a lone run of its scene"
        )
    out = {f"springs.{name}": np.zeros(lone_count, dtype=whole[f"springs.{name}"].dtype) for name in SPRING_ROWS}
    for name in SPRING_ROWS:
        out[f"springs.{name}"][lone_slot] = whole[f"springs.{name}"][mine]
    for end in ("i", "j"):
        out[f"springs.{end}"][lone_slot] -= k * each
    slot_map = np.full(springs.count, -1, dtype=np.int64)
    slot_map[mine] = lone_slot
    bonds = whole["springs.bonds"][k * each : (k + 1) * each]
    out["springs.bonds"] = _lone_rows(_packed(np.where(bonds >= 0, slot_map[np.maximum(bonds, 0)], -1)), lone_capacity)
    out["springs.created"] = np.array(whole["springs.created"][k])
    out["springs.span"] = np.array(max(built, int(lone_slot.max()) + 1 if len(mine) else 0), dtype=np.int32)
    return out


def _packed(bonds: np.ndarray) -> np.ndarray:
    """Bond lists (rows of slots, -1 for none) with their live entries first, in their order, -1 after."""
    keep = bonds >= 0
    order = np.argsort(~keep, axis=1, kind="stable")
    return np.where(np.take_along_axis(keep, order, axis=1), np.take_along_axis(bonds, order, axis=1), -1).astype(
        np.int32
    )


def world_snapshot(sim, k: int) -> dict:
    """World k's state now (module docstring), with its walls' gauge: for undo in one world."""
    part = world_part(sim, sim.state.snapshot(), k)
    part[IMPULSE] = world_entry(sim.model.domain.impulse, sim.worlds, k)
    return part


def put_world(sim, k: int, part: dict) -> None:
    """Put `part` (world_part's: a world's state as a lone run holds it) into world k of `sim`; the other worlds
    are untouched, bit for bit. SandboxError where it does not fit (another particle count, no free spring slots)."""
    state = sim.state
    p = state.particles
    worlds, each, _ = _layout(sim)
    n = int(part["particles.n"])
    if n > each if p.gaps else n != each:
        room = f"room for {each}" if p.gaps else f"{each}"
        raise SandboxError(f"world {k} holds {room} particles; the state put into it holds {n}")
    for e in state.entries(physical_only=True):
        if e.kind == NDARRAY and e.rows == "particles":  # none is declared so far: say so rather than skip it
            raise SandboxError(f"world {k}: {e.name} is not yet put back per world")
    rows = slice(k * each, (k + 1) * each)
    entries = [e for e in state.entries(physical_only=True) if e.kind == FIELD and e.rows in ("particles", WORLDS)]
    entries = [e for e in entries if e.name not in OWN and e.name != "springs.bonds"]
    now = transfer.download_all([e.get() for e in entries])
    for e, data in zip(entries, now):
        if e.rows == "particles":
            data[rows] = part[e.name][:each]
        else:
            data[k] = part[e.name]
    writes = [(e.get(), data) for e, data in zip(entries, now)]
    if p.gaps:  # its count, its ids' next, its emitters' counters, its particles' world
        writes += _gaps_in(sim, part, k, n)
    if state.springs is not None:
        writes += _springs_in(sim, part, k, each)
    transfer.upload_all(writes)
    hood = sim.hood
    if hood is not None and hood.lists is not None:  # its rows alone rebuilt at the next step
        x_ref = hood.lists.x_ref.to_numpy()
        x_ref[rows] = FAR
        hood.lists.x_ref.from_numpy(x_ref)
    set_world_entry(sim.model.domain.impulse, worlds, k, float(part.get(IMPULSE, 0.0)))
    state.world_started[k] = state.time - float(part["clock.time"])
    state.world_steps_started[k] = state.step - int(part["clock.step"])
    sim.broken = None


def _gaps_in(sim, part: dict, k: int, n: int) -> list:
    """(field, values) writes that give world k (of a simulation with gaps) the part's count, and the host values
    a world keeps for itself set to the part's."""
    p, state = sim.state.particles, sim.state
    counts = p.counts.to_numpy()
    counts[k] = n
    world = p.world.to_numpy()
    world[k * p.world_size : (k + 1) * p.world_size] = k
    p.next_ident[k] = int(part["particles.next_ident"])
    for e in state.entries(physical_only=True):
        if e.kind == VALUE and e.rows == WORLDS:
            e.get()[k] = _copy(part[e.name])
    return [(p.counts, counts), (p.world, world)]


def _springs_in(sim, part: dict, k: int, each: int) -> list:
    """(field, values) writes that kill world k's bonds and place the part's (module docstring)."""
    springs = sim.state.springs
    built = springs.built_count // sim.worlds
    fields = [getattr(springs, name) for name in SPRING_ROWS]
    now = dict(zip(SPRING_ROWS, transfer.download_all(fields)))
    ends = now["i"]
    now["alive"][(ends >= k * each) & (ends < (k + 1) * each)] = 0  # every bond the world holds now
    lone_alive = np.flatnonzero(part["springs.alive"][: int(part["springs.span"])] != 0)
    home = np.where(lone_alive < built, k * built + lone_alive, -1)
    placed = np.where((home >= 0) & (now["alive"][np.maximum(home, 0)] == 0), home, -1)
    free = np.setdiff1d(np.flatnonzero(now["alive"] == 0), placed[placed >= 0], assume_unique=True)
    homeless = np.flatnonzero(placed < 0)
    if len(homeless) > len(free):
        raise SandboxError(f"world {k}: no room for its {len(lone_alive)} bonds among the simulation's spring slots")
    placed[homeless] = free[: len(homeless)]
    for name in SPRING_ROWS:
        now[name][placed] = part[f"springs.{name}"][lone_alive]
    for end in ("i", "j"):
        now[end][placed] += k * each
    slot_map = np.full(len(part["springs.alive"]), -1, dtype=np.int64)
    slot_map[lone_alive] = placed
    lone_bonds = part["springs.bonds"][:each]
    mapped = np.where(lone_bonds >= 0, slot_map[np.maximum(lone_bonds, 0)], -1)
    bonds = springs.bonds.to_numpy()
    bonds[k * each : (k + 1) * each] = _packed(mapped)
    created = springs.created.to_numpy()
    created[k] = int(part["springs.created"])
    span = max(int(springs.span[None]), int(placed.max()) + 1 if len(placed) else 0)
    writes = [(springs.bonds, bonds), (springs.created, created), (springs.span, np.array(span, dtype=np.int32))]
    return [(getattr(springs, name), now[name]) for name in SPRING_ROWS] + writes


def reset_world(sim, k: int) -> None:
    """Put world k back to the scene's initial state, its clock from 0 (`sim.world(k).reset()`): the others run on
    as they were, and the live controls stay as they are, as Simulation.reset leaves them."""
    put_world(sim, k, world_part(sim, sim._initial, k))


def world_controls(scene, controls: dict) -> dict:
    """The live controls (by namespaced name, those among `controls`) that a world started from `scene` takes: its
    gravity, drag, air temperature and heat sources' temperatures (a power source's power), the pair law's scales
    (the materials' own), the thermal walls' temperatures, the molecular heater's power and lid's pressure
    (following their schedules where the scene gives them one)."""
    out = {
        "world.gravity": [float(g) for g in scene.world.gravity],
        "world.drag": float(scene.world.drag),
        "pair.scale": [1.0, 1.0],
    }
    if scene.heat:
        out["heat.ambient"] = float(scene.heat.ambient)
        if scene.heat.sources:
            out["heat.sources"] = [float(source_value(src, 0.0)) for src in scene.heat.sources]
    for name, spec, base in _scheduled(scene):
        out.update({f"{name}.{key}": value for key, value in scheduled_start(spec, base).items()})
    molecular = scene.molecular
    for wall in molecular.walls if molecular else []:
        out[f"thermal_walls.{wall.name}"] = float(wall.temperature)
    return {key: value for key, value in out.items() if key in controls}


def _scheduled(scene) -> list[tuple]:
    """(control namespace, scene table, its base key) of `scene`'s molecular heater and lid, where it has them."""
    molecular = scene.molecular
    tables = [("heater", molecular and molecular.heater, "power"), ("lid", molecular and molecular.lid, "pressure")]
    return [(name, spec, base) for name, spec, base in tables if spec]


def live_worlds(sim) -> int:
    """The worlds of `sim` in use: the first live_count / world_size (the others wait for add_world)."""
    return sim.state.live_count() // sim.state.particles.world_size if sim.worlds > 1 else 1


def add_world(sim) -> int:
    """Take the next world of `sim` into use, started as world 0 started, with the scene's live controls; returns
    its index. The worlds in use step on untouched (the count's change rebuilds no list row of theirs).
    SandboxError where every world the simulation holds is in use."""
    k = live_worlds(sim)
    if sim.worlds == 1:
        raise SandboxError("this simulation holds one world; expected one built with room for more (worlds=K)")
    if k >= sim.worlds:
        raise SandboxError(
            f"all {sim.worlds} worlds of this simulation are in use; expected one built with more "
            "(sandbox.load(scene, worlds=K))"
        )
    _set_live(sim, k + 1)
    start_world(sim, k)
    return k


def start_world(sim, k: int) -> None:
    """World k (in use) as a new world starts: world 0's initial state, its clock from 0, the scene's live
    controls (a classroom tab's world as the tab opens the scene)."""
    put_world(sim, k, world_part(sim, sim._initial, 0))
    controls = live_controls.Controls(sim.model, sim.terms, k)
    controls.set(world_controls(sim.scene, controls.values()))


def remove_world(sim, k: int) -> None:
    """Take world k out of use: the last world in use moves into its place (state, clock and live controls: its
    index becomes k; its neighbour rows are built again, so it steps on within round-off of its own run), and the
    live count drops by a world. SandboxError for the only world in use."""
    last = live_worlds(sim) - 1
    if last == 0:
        raise SandboxError("world 0 is the only world in use; a simulation keeps at least one")
    if k != last:
        moved = live_controls.Controls(sim.model, sim.terms, last).values()
        put_world(sim, k, world_snapshot(sim, last))
        live_controls.Controls(sim.model, sim.terms, k).set(moved)
    springs = sim.state.springs
    if springs is not None:  # the bonds of the world out of use: none acts on slots past the live count
        each = sim.state.particles.world_size
        alive, ends = transfer.download_all([springs.alive, springs.i])
        alive[(ends >= last * each) & (ends < (last + 1) * each)] = 0
        transfer.upload_all([(springs.alive, alive)])
    _set_live(sim, last)


def _set_live(sim, worlds: int) -> None:
    """Make the first `worlds` worlds live: the particle count, and the count the neighbour lists were built for
    (so the change alone rebuilds no row: a world taken into use has its rows rebuilt by put_world)."""
    n = worlds * sim.state.particles.world_size
    sim.state.particles.n[None] = n
    hood = sim.hood
    if hood is not None and hood.lists is not None:
        hood.lists.n_listed[None] = n

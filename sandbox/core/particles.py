"""Particle and spring storage: struct-of-arrays Taichi fields, allocated by capacity and only for what a scene uses.

`Particles` holds what each particle is and does (position, velocity, mass, ..., its enthalpy and temperature with
heat); `SpringState` holds the bonds (ends, rest length, stiffness, how soft they are now, whether they hold) and
each particle's list of bonds. Both belong to the State (core/state.py), which declares them field by field.

Particles move in storage when a scene sorts them into cell order (physics/reorder.py) or retires the dead
(physics/emitters.py): `Mover` does both, for every per-particle field that rides with a particle (the State's own
and any passenger a front-end attached, such as a renderer's motion-blur tails), renumbering spring ends and moving
bond lists with them.
"""

from dataclasses import dataclass

import numpy as np
import taichi as ti

from . import transfer
from .oriented import data_oriented
from .ranges import ANY, COUNT, POSITIVE, Range
from .worlds import per_world


@dataclass(frozen=True)
class PerParticle:
    """One per-particle field: its name, kind ("real", "int", "vector": dim reals, "colour": 3 f32), the Particles
    option that allocates it (None: always), the value a slot holds before a particle is put there or after it
    leaves (what spawning writes where it is given nothing), the values a state file may hold, and its meaning."""

    name: str
    kind: str
    option: str | None
    default: float
    valid: Range
    meaning: str


# Every per-particle field, once: allocation, the order particles move in, spawning's defaults, freed slots and
# the state file's checks all read this table.
PER_PARTICLE = (
    PerParticle("x", "vector", None, 0.0, ANY, "position (length), (C, D)"),
    PerParticle("v", "vector", None, 0.0, ANY, "velocity (length / time), (C, D)"),
    PerParticle("mass", "real", None, 0.0, POSITIVE, "mass, (C,)"),
    PerParticle("radius", "real", None, 0.0, POSITIVE, "radius (length): walls and drawing, (C,)"),
    PerParticle("material", "int", None, 0, Range(lo=0, below="materials"), "index into the scene's materials, (C,)"),
    PerParticle("color", "colour", None, 0.0, Range(lo=0.0, hi=1.0), "base colour, RGB in [0, 1], (C, 3)"),
    PerParticle("group", "int", None, 0, Range(lo=0, below="groups"), "the body or emitter it came from, (C,)"),
    # its id: its index in the built scene, then numbered on as emitters and tools add particles (stable when
    # storage is reordered or compacted; never reused)
    PerParticle("ident", "int", None, 0, Range(lo=0, below="next_ident"), "the particle's id, (C,)"),
    PerParticle("h", "real", "heat", 0.0, ANY, "specific enthalpy (heat / mass): the heat state, (C,)"),
    PerParticle("T", "real", "heat", 0.0, ANY, "temperature (degrees), derived from h (physics/phase.py), (C,)"),
    PerParticle("liquid", "int", "refreeze", 0, Range(lo=0, hi=3), "1 once molten, until it refreezes, (C,)"),
    PerParticle("age", "real", "lifetimes", 0.0, COUNT, "time since birth, (C,)"),
    PerParticle("lifetime", "real", "lifetimes", 0.0, COUNT, "retired when age reaches it; 0: for ever, (C,)"),
    PerParticle("kind", "int", "structure", 0, ANY, "phase from structure: 0 gas, 1 liquid, 2 solid, (C,)"),
    PerParticle("world", "int", "worlds", 0, Range(lo=0, below="worlds"), "the world it belongs to (core/worlds.py)"),
)


@data_oriented
class Particles:
    """Per-particle fields (PER_PARTICLE): capacity C slots, the first n[None] live; D = dim. `sim.particles()`
    (calling this object) returns the live particles as NumPy arrays by id (simulation.py's particle_table)."""

    def __init__(
        self,
        dim: int,
        capacity: int,
        heat: bool,
        refreeze: bool = False,
        lifetimes: bool = False,
        structure: bool = False,
        worlds: int = 1,
        gaps: bool = False,
    ):
        self.dim = dim
        self.world_count = worlds  # worlds held (core/worlds.py); the `world` field only where more than one
        self.worlds = worlds > 1
        self.world_size = 0  # particles a world: world k's are slots k * world_size .. (set as they are loaded)
        # worlds whose particle counts change (emitters, lifetimes): each world a block of world_size slots, its
        # live particles first (`counts`), the slots after them idle until it spawns into them (core/worlds.py)
        self.gaps = gaps and self.worlds
        if self.gaps:
            self.counts = ti.field(ti.i32, shape=worlds)  # each world's live particles
        self.capacity = capacity
        self.heat = heat
        self.refreeze = refreeze
        self.lifetimes = lifetimes
        self.structure = structure
        self.n = ti.field(ti.i32, shape=())  # live particle count
        self.next_ident = 0  # the id the next added particle gets
        for field in self.declared():
            setattr(self, field.name, self._allocate(field.kind))

    def _allocate(self, kind: str):
        if kind == "vector":
            return ti.Vector.field(self.dim, float, shape=self.capacity)
        if kind == "colour":
            return ti.Vector.field(3, ti.f32, shape=self.capacity)
        return ti.field(ti.i32 if kind == "int" else float, shape=self.capacity)

    def declared(self) -> list[PerParticle]:
        """The declarations of the fields this scene allocates, in PER_PARTICLE's order."""
        return [f for f in PER_PARTICLE if f.option is None or getattr(self, f.option)]

    def names(self) -> list[str]:
        """Names of the per-particle fields allocated, in a fixed order (what moves with a particle)."""
        return [f.name for f in self.declared()]

    def fields(self) -> list:
        """The per-particle fields, in names() order."""
        return [getattr(self, name) for name in self.names()]

    def nbytes(self) -> int:
        """Bytes held by these fields."""
        real = 8 if self.x.dtype == ti.f64 else 4
        size = {"vector": self.dim * real, "real": real, "int": 4, "colour": 12}
        return self.capacity * sum(size[f.kind] for f in self.declared())

    @ti.func
    def idle(self, i):
        """Whether slot i (below n) holds no particle: a slot past its world's live ones in worlds with gaps (never
        in a lone run or in worlds of fixed counts, where the first n slots are all live: no load compiled)."""
        if ti.static(self.gaps):
            return i % self.world_size >= self.counts[i // self.world_size]
        else:
            return False

    @ti.func
    def world_slots(self, w):
        """(first, end): the slots of world w's live particles, its block of world_size slots (with gaps: the first
        counts[w] of it). For a simulation of many worlds."""
        first = w * self.world_size
        end = first + self.world_size
        if ti.static(self.gaps):
            end = first + self.counts[w]
        return first, end

    def block(self, world: int | None) -> tuple[int, int]:
        """(first slot, live count) of world `world`'s particles (a host read); every live particle's where
        `world` is None or there is one world."""
        if world is None or not self.worlds:
            return 0, int(self.n[None])
        return world * self.world_size, int(self.counts[world]) if self.gaps else self.world_size

    def put(self, first: int, values: dict[str, np.ndarray]) -> None:
        """Write slots [first, first + m) of every field: `values` (name -> (m,) or (m, k) array) where given, the
        declared default elsewhere, so a new particle never inherits what an earlier one left in its slot."""
        m = len(next(iter(values.values())))
        unknown = set(values) - set(self.names())
        if unknown:
            raise ValueError(f"no per-particle field {', '.join(sorted(unknown))}; expected some of {self.names()}")
        for f in self.declared():
            field = getattr(self, f.name)
            data = field.to_numpy()
            data[first : first + m] = values[f.name] if f.name in values else f.default
            field.from_numpy(data)

    def clear(self, first: int, last: int) -> None:
        """Slots [first, last) back to their declared defaults (the slots the erased or retired left)."""
        if last > first:
            self._clear(first, last, tuple(self.fields()), tuple(f.default for f in self.declared()))

    @ti.kernel
    def _clear(self, first: ti.i32, last: ti.i32, fields: ti.template(), defaults: ti.template()):
        for i in range(first, last):
            self._clear_slot(i, fields, defaults)

    @ti.func
    def _clear_slot(self, i, fields: ti.template(), defaults: ti.template()):
        for k in ti.static(range(len(fields))):
            fields[k][i] = ti.zero(fields[k][i]) + ti.static(defaults[k])

    def clear_freed(self, was) -> None:
        """With gaps: each world's slots from its live count up to was[w] (its count before: a field of a count a
        world) back to their declared defaults, in one launch."""
        self._clear_freed(was, tuple(self.fields()), tuple(f.default for f in self.declared()))

    @ti.kernel
    def _clear_freed(self, was: ti.template(), fields: ti.template(), defaults: ti.template()):
        block = ti.static(self.world_size)
        for i in range(self.n[None]):
            w, r = i // block, i % block
            if self.counts[w] <= r < was[w]:
                self._clear_slot(i, fields, defaults)


def bond_table(
    spring_i: np.ndarray, spring_j: np.ndarray, n_particles: int, max_bonds: int, spring_ids: np.ndarray | None = None
) -> np.ndarray:
    """(n_particles, max_bonds) int32 table of spring ids at each particle, padded with -1. `spring_ids`: the ids of
    the given springs (default 0..S-1)."""
    table = np.full((max(n_particles, 1), max(max_bonds, 1)), -1, dtype=np.int32)
    ends = np.concatenate([spring_i, spring_j])
    ids = np.concatenate([np.arange(len(spring_i)) if spring_ids is None else spring_ids] * 2)
    order = np.argsort(ends, kind="stable")
    ends, ids = ends[order], ids[order]
    first = np.searchsorted(ends, ends, side="left")
    slot = np.arange(len(ends)) - first
    table[ends, slot] = ids
    return table


@data_oriented
class SpringState:
    """The springs: S slots (the built springs, then spare slots that refreezing fills), each particle's bond list.

    Slots [0, span) hold every spring that was ever alive: per-spring loops stop there, not at `count`."""

    def __init__(self, built, capacity: int, spare: int = 0, max_bonds: int = 0, worlds: int = 1):
        """`built`: the scene's particles and springs (config/build.py; every world's, one world after the other);
        `capacity`: particle slots; `spare`: extra spring slots for refreezing; `max_bonds`: bond-list width (at
        least the built one); `worlds`: the worlds they are shared among (`created` is counted per world)."""
        self.built_count = built.spring_count
        self.count = built.spring_count + spare  # spring slots
        self.max_bonds = max(built.max_bonds(), max_bonds, 1)
        s = max(self.count, 1)
        self.i = ti.field(ti.i32, shape=s)  # first end
        self.j = ti.field(ti.i32, shape=s)  # second end
        self.rest = ti.field(float, shape=s)  # rest length l (length)
        self.ks = ti.field(float, shape=s)  # base stiffness k_s (force / length)
        self.kd = ti.field(float, shape=s)  # base damping k_d (force / speed)
        self.factor = ti.field(float, shape=s)  # thermoelastic factor s(T) in [0, 1]
        self.alive = ti.field(ti.i32, shape=s)  # 1 while the spring holds, 0 once broken (for good)
        self.bonds = ti.field(ti.i32, shape=(capacity, self.max_bonds))  # spring ids at each particle, -1 padded
        self.created = per_world(worlds, ti.i32)  # springs ever made (built + refrozen): broken = created - alive
        self.span = ti.field(ti.i32, shape=())
        pad = np.zeros(s - self.built_count)
        table = np.full((capacity, self.max_bonds), -1, dtype=np.int32)
        table[: built.count] = bond_table(built.spring_i, built.spring_j, built.count, self.max_bonds)[: built.count]
        alive = np.zeros(s, dtype=np.int32)
        alive[: self.built_count] = 1
        transfer.upload(  # one copy kernel for all of them
            [
                (self.i, np.concatenate([built.spring_i, pad]).astype(np.int32)),
                (self.j, np.concatenate([built.spring_j, pad]).astype(np.int32)),
                (self.rest, np.concatenate([built.rest_length, pad])),
                (self.ks, np.concatenate([built.stiffness, pad])),
                (self.kd, np.concatenate([built.damping, pad])),
                (self.factor, np.ones(s)),
                (self.alive, alive),
                (self.bonds, table),
                (self.created, self.built_count if worlds == 1 else np.full(worlds, self.built_count // worlds)),
                (self.span, self.built_count),
            ]
        )

    NAMES = ("i", "j", "rest", "ks", "kd", "factor", "alive", "bonds", "created", "span")

    def nbytes(self, real_bytes: int) -> int:
        """Bytes held: per slot two ends, an alive flag and four reals, and the bond lists."""
        return self.count * (3 * 4 + 4 * real_bytes) + self.bonds.shape[0] * self.max_bonds * 4

    def rebuild_bonds(self) -> None:
        """Rebuild every particle's bond list from the live springs (after particles were removed or renumbered)."""
        alive, i, j = transfer.download([self.alive, self.i, self.j], [self.count] * 3)
        alive = np.flatnonzero(alive)
        n = self.bonds.shape[0]
        transfer.upload([(self.bonds, bond_table(i[alive], j[alive], n, self.max_bonds, alive)[:n])])

    @ti.func
    def other_end(self, i, s):
        return self.i[s] + self.j[s] - i


@ti.func
def fold_bonds(springs: ti.template(), i, acc, visit: ti.template(), extra: ti.template()):
    """The one loop over particle i's live bonds: acc = visit(acc, i, j, s, extra) for each live spring s joining i to
    j, in bond-list order; returns acc. `extra`: what the visitor reads besides, a tuple passed as it is (visitors
    take it as a template)."""
    for k in range(springs.max_bonds):
        s = springs.bonds[i, k]
        if s < 0:
            break
        if springs.alive[s]:
            acc = visit(acc, i, springs.other_end(i, s), s, extra)
    return acc


def _like(field, capacity: int):
    n = getattr(field, "n", 0)
    if n:
        return ti.Vector.field(n, field.dtype, shape=capacity)
    return ti.field(field.dtype, shape=capacity)


def _item_bytes(field) -> int:
    size = 8 if field.dtype in (ti.f64, ti.i64) else 4
    return size * max(getattr(field, "n", 0), 1)


@data_oriented
class Mover:
    """Moves particles in storage: every field in `fields` (the per-particle ones and passengers, a tuple passed to
    each launch, so a passenger attached later is moved too), spring ends renumbered and bond lists moved with them.
    Scratch for sorting is allocated on first use."""

    def __init__(self, particles: Particles, springs: SpringState | None):
        self.p = particles
        self.springs = springs
        self.has_springs = springs is not None
        self.capacity = particles.capacity
        self.inverse = None  # sorting: the new index of the particle stored at each old index
        self.scratch: dict[int, object] = {}  # id(field) -> its sorting scratch
        self.bond_scratch = None

    def permute(self, order, n: int, fields: tuple) -> None:
        """Sort the first n particles so that slot k holds the particle that was at order[k] (a field of ids)."""
        if self.inverse is None:
            self.inverse = ti.field(ti.i32, shape=self.capacity)
            if self.has_springs:
                self.bond_scratch = ti.field(ti.i32, shape=self.springs.bonds.shape)
        for field in fields:
            if id(field) not in self.scratch:
                self.scratch[id(field)] = _like(field, self.capacity)
        pairs = tuple((f, self.scratch[id(f)]) for f in fields)
        self._permute(order, pairs)

    @ti.kernel
    def _permute(self, order: ti.template(), pairs: ti.template()):
        n = self.p.n[None]
        for k in range(n):
            self.inverse[order[k]] = k
        # One loop over the particles for all the fields (each top-level loop is a task LLVM compiles on its own,
        # even from the offline cache: a loop per field made the first sort of a run a 0.3 s pause), so each field
        # has its own scratch.
        for k in range(n):
            for pair in ti.static(pairs):
                pair[1][k] = pair[0][order[k]]
        for k in range(n):
            for pair in ti.static(pairs):
                pair[0][k] = pair[1][k]
        if ti.static(self.has_springs):
            s = self.springs
            for q in range(s.span[None]):
                s.i[q] = self.inverse[s.i[q]]
                s.j[q] = self.inverse[s.j[q]]
            for k, b in ti.ndrange(n, s.max_bonds):
                self.bond_scratch[k, b] = s.bonds[order[k], b]
            for k, b in ti.ndrange(n, s.max_bonds):
                s.bonds[k, b] = self.bond_scratch[k, b]

    @ti.kernel
    def fill_holes(self, hole: ti.template(), filler: ti.template(), count: ti.i32, fields: ti.template()):
        """Move the particle at filler[m] into slot hole[m] for m < count (compaction after the dead were found), its
        bonds and spring ends with it."""
        for m in range(count):
            dst, src = hole[m], filler[m]
            for field in ti.static(fields):
                field[dst] = field[src]
            if ti.static(self.has_springs):
                s = self.springs
                for b in range(s.max_bonds):
                    spring = s.bonds[src, b]
                    s.bonds[dst, b] = spring
                    s.bonds[src, b] = -1
                    if spring >= 0:
                        if s.i[spring] == src:
                            s.i[spring] = dst
                        if s.j[spring] == src:
                            s.j[spring] = dst

    def scratch_bytes(self, fields: tuple) -> int:
        """Bytes of scratch that sorting `fields` holds."""
        total = 4 * self.capacity + sum(self.capacity * _item_bytes(f) for f in fields)
        if self.has_springs:
            total += 4 * self.springs.bonds.shape[0] * self.springs.bonds.shape[1]
        return total

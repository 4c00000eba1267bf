"""The State: what a step changes, declared entry by entry.

A state is the particles (core/particles.py), the springs, the clock (time, step count, frames, step size) and
whatever else a part of the simulation carries from one step to the next and declares here when it is built: an
emitter's counters, the smoke grid, the neighbour lists, a leapfrog integrator's synchronised values. Each entry is a
Taichi field, an ndarray held by an attribute (replaced when it is widened) or a host value, under a dotted name
(`particles.x`, `springs.alive`, `neighbours.ids`, `clock.time`).

Entries are physical (the scene's state: what reset and undo put back) or kept only so that a resumed run continues
bit for bit (the neighbour lists fix the order in which forces are summed; a restored snapshot invalidates them
instead). Saving and loading a state file (files/persist.py), snapshots, undo, reset and resume all go through
`entries()`: there is no other list of what the state is.

The `layout` counter moves on whenever particles are added, removed or moved in storage (`particles_moved()`): what
was built over the old layout (neighbour lists) rebuilds. Passengers are per-particle fields that others keep (a
renderer's motion-blur tails) and attach with `carry()`: they move with the particles but are not state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import transfer
from .particles import Mover, Particles, SpringState
from .ranges import ANY, COUNT, STEP, Range

FIELD, NDARRAY, VALUE = "field", "ndarray", "value"
MOVES_KEPT = 64  # moves of the layout whose worlds are remembered (a rebuild between steps reads the last few)
WORLDS = "worlds"  # the rows of a per-world gauge (core/worlds.py): world k's is row k


@dataclass(frozen=True)
class Entry:
    """One declared piece of the state."""

    name: str  # dotted: "particles.x", "springs.alive", "neighbours.ids", "clock.time"
    owner: object  # the object holding it
    attribute: str  # its attribute on the owner
    kind: str  # FIELD, NDARRAY or VALUE
    physical: bool  # in snapshots (reset, undo); else kept only for a bit-for-bit resume
    rows: str = ""  # what its first axis counts ("particles", "springs", WORLDS), or "": checked when a file is read
    valid: Range = ANY  # the values it may hold there

    def get(self):
        return getattr(self.owner, self.attribute)

    def set(self, value) -> None:
        setattr(self.owner, self.attribute, value)


class State:
    """The particles, springs and clock of a simulation, and what its parts declare (see the module docstring)."""

    def __init__(self, particles: Particles, springs: SpringState | None, dt: float):
        self.particles = particles
        self.springs = springs
        self.time = 0.0  # simulated time (scene units)
        self.step = 0  # steps taken
        self.frames = 0  # frames advanced
        self.dt = dt  # the step size (changes with substeps = "auto" and the window's slider)
        self.layout = 0  # moves on whenever particles are added, removed or moved in storage
        # with worlds, which worlds' particles each recent move of the layout was (None: every world's): a world's
        # lists are rebuilt on its lone run's steps (worlds_moved_since)
        self.moved_worlds: dict[int, frozenset | None] = {}
        self.passengers: tuple = ()  # per-particle fields others keep, moved with the particles
        # what brings fields derived from the state up to date before they are read (the atoms' phases from their
        # structure): called by refresh_derived(), from the measurements and the renderer
        self.refreshers: list = []
        self.mover = Mover(particles, springs)
        self._entries: list[Entry] = []
        self.declare("clock", self, ("time", "step", "frames"), kind=VALUE, valid=COUNT)
        self.declare("clock", self, ("dt",), kind=VALUE, valid=STEP)
        self.declare("state", self, ("layout",), kind=VALUE, physical=False)  # the lists compare theirs with it
        # each world's clock starts at the simulated time it started at (world_state.py); a lone run's at 0
        self.world_started = [0.0] * (particles.world_count if particles.worlds else 1)
        self.world_steps_started = [0] * len(self.world_started)  # ... and the step it started at
        if particles.worlds:
            self.declare("clock", self, ("world_started", "world_steps_started"), kind=VALUE, valid=COUNT)
        self.declare("particles", particles, ("n",), valid=Range(lo=0, atmost="capacity"))
        self._declare_particles(particles)
        # the next id: with gaps (core/worlds.py) a list, a world each
        self.declare("particles", particles, ("next_ident",), kind=VALUE, valid=COUNT)
        if particles.gaps:
            self.declare("particles", particles, ("counts",), rows=WORLDS, valid=Range(lo=0, atmost="capacity"))
        if springs is not None:
            each = "springs"
            self.declare(each, springs, ("i", "j"), rows=each, valid=Range(lo=0, below="capacity"))
            self.declare(each, springs, ("rest", "ks", "kd", "factor"), rows=each, valid=COUNT)
            self.declare(each, springs, ("alive",), rows=each, valid=Range(lo=0, hi=1))
            self.declare(each, springs, ("bonds",), rows="particles", valid=Range(lo=-1, below="springs"))
            gauge = WORLDS if particles.worlds else ""  # counted per world where there are several
            self.declare(each, springs, ("created",), rows=gauge, valid=Range(lo=0, atmost="springs"))
            self.declare(each, springs, ("span",), valid=Range(lo=0, atmost="springs"))

    def _declare_particles(self, p: Particles) -> None:
        """The per-particle fields, each with the values it may hold (core/particles.py declares both)."""
        for field in p.declared():
            self.declare("particles", p, (field.name,), rows="particles", valid=field.valid)

    # ------------------------------------------------------------------ the declarations
    def declare(
        self,
        prefix: str,
        owner,
        names,
        kind: str = FIELD,
        physical: bool = True,
        rows: str = "",
        valid: Range = ANY,
    ) -> None:
        """Add `owner`'s attributes `names` to the state under `prefix.name`: Taichi fields (FIELD), ndarrays
        (NDARRAY: the attribute may be replaced by a wider one) or host numbers and lists (VALUE). `physical`: part
        of a snapshot (else only saved to state files, for a bit-for-bit resume); `rows`: what the first axis of a
        field counts ("particles": the live ones are checked, "springs": those ever used); `valid`: the values it
        may hold (checked when a state file is read)."""
        taken = {e.name for e in self._entries}
        for name in names:
            entry = Entry(f"{prefix}.{name}", owner, name, kind, physical, rows, valid)
            if entry.name in taken:
                raise ValueError(f"state entry {entry.name} declared twice")
            self._entries.append(entry)

    def forget(self, prefix: str) -> None:
        """Drop the entries declared under `prefix` (a part that is replaced: the integrator)."""
        self._entries = [e for e in self._entries if not e.name.startswith(prefix + ".")]

    def entries(self, physical_only: bool = False) -> list[Entry]:
        """Every declared entry in declaration order (only the physical ones with `physical_only`)."""
        return [e for e in self._entries if e.physical or not physical_only]

    def entry(self, name: str) -> Entry | None:
        """The declared entry `name` ("lid.height"), or None where nothing declared it."""
        return next((e for e in self._entries if e.name == name), None)

    @property
    def movable(self) -> tuple:
        """The per-particle fields that move with a particle: the particles' own, then the passengers."""
        return tuple(self.particles.fields()) + self.passengers

    # ------------------------------------------------------------------ snapshots
    def snapshot(self) -> dict:
        """Copies of every physical entry by name (numbers as they are, fields as NumPy arrays; one copy kernel)."""
        entries = self.entries(physical_only=True)
        fields = [e for e in entries if e.kind == FIELD]
        snap = {e.name: _copy_value(e.get()) for e in entries if e.kind == VALUE}
        snap.update(zip((e.name for e in fields), transfer.download_all([e.get() for e in fields])))
        for e in entries:
            if e.kind == NDARRAY:
                snap[e.name] = e.get().to_numpy()
        return snap

    def restore(self, snap: dict) -> None:
        """Put every physical entry back as `snapshot()` saw it (one copy kernel), and move the layout on."""
        entries = self.entries(physical_only=True)
        transfer.upload_all([(e.get(), snap[e.name]) for e in entries if e.kind == FIELD])
        for e in entries:
            if e.kind == VALUE:
                e.set(_copy_value(snap[e.name]))
            elif e.kind == NDARRAY:
                e.get().from_numpy(snap[e.name])
        self.particles_moved()

    # ------------------------------------------------------------------ moving particles
    def particles_moved(self, worlds=None) -> None:
        """Particles were added, removed or moved in storage (or the springs changed): rebuild what was built over
        the old layout (the neighbour lists compare this counter with the one they were built at). `worlds`: the
        worlds whose particles alone moved, in a simulation of worlds (None: every world's)."""
        self.layout += 1
        self.moved_worlds[self.layout] = None if worlds is None else frozenset(int(w) for w in worlds)
        self.moved_worlds.pop(self.layout - MOVES_KEPT, None)

    def worlds_moved_since(self, layout: int) -> frozenset | None:
        """The worlds whose particles moved since the layout numbered `layout`; None: every world's (or moves too
        old to tell, or made before this state was loaded)."""
        moved: frozenset = frozenset()
        for number in range(layout + 1, self.layout + 1):
            worlds = self.moved_worlds.get(number)
            if worlds is None:
                return None
            moved |= worlds
        return moved

    def carry(self, fields) -> None:
        """Attach per-particle fields (capacity rows) that move with the particles from now on."""
        self.passengers = self.passengers + tuple(f for f in fields if f not in self.passengers)

    def drop(self, fields) -> None:
        """Detach passengers attached with carry()."""
        self.passengers = tuple(f for f in self.passengers if all(f is not g for g in fields))

    def permute(self, order, n: int) -> None:
        """Sort the storage: slot k gets the particle at order[k] (a field of n ids), everything that moves with it."""
        self.mover.permute(order, n, self.movable)
        self.particles_moved()

    def fill_holes(self, hole, filler, count: int, worlds=None) -> None:
        """Move the particle at filler[m] into slot hole[m], m < count (the caller then lowers the count); `worlds`:
        as particles_moved's."""
        if count:
            self.mover.fill_holes(hole, filler, count, self.movable)
        self.particles_moved(worlds)

    def refresh_derived(self) -> None:
        """Bring the fields derived from the state up to date (each refresher does nothing when it is)."""
        for refresh in self.refreshers:
            refresh()

    def world_times(self) -> list[float]:
        """Each world's own clock (simulated time since it started); the one clock of a lone run."""
        return [self.time - start for start in self.world_started]

    def world_steps(self) -> list[int]:
        """Each world's own step count (steps since it started); the one count of a lone run."""
        return [self.step - start for start in self.world_steps_started]

    def live_count(self) -> int:
        """The number of slots in use (a host read): the live particles, and with worlds whose counts change (core/
        worlds.py: gaps) every block in use, its idle slots too."""
        return int(self.particles.n[None])

    def live_rows(self) -> slice | np.ndarray:
        """The slots of the live particles: the first live_count(), or with gaps each world's live ones in turn."""
        p, n = self.particles, self.live_count()
        if not p.gaps:
            return slice(0, n)
        blocks = [p.world_size * k + np.arange(c) for k, c in enumerate(p.counts.to_numpy()[: n // p.world_size])]
        return np.concatenate(blocks) if blocks else np.zeros(0, dtype=np.int64)


def _copy_value(value):
    """A host value's copy (lists are copied, so a snapshot does not change with the state)."""
    if isinstance(value, list):
        return [_copy_value(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.copy()
    return value

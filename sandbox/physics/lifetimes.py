"""Lifetimes: a particle with lifetime L > 0 (emitted with one: physics/emitters.py) is dead once its age reaches L.

Every step ages the particles; after each call of Simulation.step the dead are retired by compaction: live particles
from the tail of the storage fill the holes (the State moves everything that rides with them: core/particles.py), so
the live count stays the number alive and memory stays bounded however many particles were ever emitted.
"""

import numpy as np
import taichi as ti

from ..core.oriented import data_oriented
from .term import Term, register


@register
@data_oriented
class Lifetimes(Term):
    """Ageing after each step and retirement of the dead after each Simulation.step call."""

    key = "lifetimes"
    stage = "ageing"

    @staticmethod
    def wanted(parts) -> bool:
        return parts.state.particles.lifetimes

    def __init__(self, parts):
        self.state = parts.state
        self.p = parts.state.particles
        self.loops = parts.model.loops
        capacity = parts.model.capacity
        self.hole = ti.field(ti.i32, shape=capacity)  # compaction: slots of the dead below the new count
        self.filler = ti.field(ti.i32, shape=capacity)  # ... and the live particles above it that move into them
        self.moves = ti.field(ti.i32, shape=2)  # [holes found, fillers found]
        if self.p.gaps:
            self.was = ti.field(ti.i32, shape=self.p.world_count)  # each world's count before the dead left

    def words(self, where: str) -> list[str]:
        return ["ageing; the dead retired by compaction after each step() call"] if where == "after" else []

    def after_step(self, state) -> None:
        self._age(state.dt)

    def after_steps(self, state) -> None:
        self.retire()

    @ti.kernel
    def _age(self, dt: float):
        self.loops.light()
        for i in range(self.p.n[None]):
            self.p.age[i] += dt

    def retire(self) -> int:
        """Remove the dead (age >= lifetime > 0) by compaction; returns how many were removed. With worlds, each
        world's block is compacted as its lone run compacts its particles."""
        if self.p.gaps:
            return self._retire_worlds()
        dead = int(self._count_dead())
        if dead == 0:
            return 0
        n = int(self.p.n[None])
        self._find_moves(0, n - dead, n)
        self.p.n[None] = n - dead
        self.state.fill_holes(self.hole, self.filler, int(self.moves[0]))
        self.p.clear(n - dead, n)  # the slots left hold nothing of the dead: the next born start fresh
        return dead

    def _retire_worlds(self) -> int:
        """Every world's dead retired at once (three launches, one where none died)."""
        dead = int(self._find_moves_worlds())
        if dead:
            worlds = self.p.n[None] // self.p.world_size
            fewer = np.flatnonzero(self.was.to_numpy()[:worlds] != self.p.counts.to_numpy()[:worlds])
            self.state.fill_holes(self.hole, self.filler, int(self.moves[0]), fewer)  # those worlds' lists rebuilt
            self.p.clear_freed(self.was)
        return dead

    @ti.func
    def dead(self, i):
        return self.p.lifetime[i] > 0.0 and self.p.age[i] >= self.p.lifetime[i]

    @ti.kernel
    def _count_dead(self) -> ti.i32:
        total = 0
        for i in range(self.p.n[None]):
            if self.dead(i):
                total += 1
        return total

    @ti.kernel
    def _find_moves_worlds(self) -> ti.i32:
        """Each world's moves as _find_moves finds a lone run's, in its own block, all in one list (world by world:
        hole m and filler m are of one world); each world's count lowered (its count before kept in `was`).
        Returns the dead in all."""
        p = self.p
        block = ti.static(p.world_size)
        self.moves[0] = 0
        self.moves[1] = 0
        total = 0
        ti.loop_config(serialize=True)
        for w in range(p.n[None] // block):
            first, end = p.world_slots(w)
            live = end - first
            dead = 0
            for i in range(first, end):
                if self.dead(i):
                    dead += 1
            keep = live - dead
            self._add_moves(first, keep, live)
            self.was[w] = live
            p.counts[w] = keep
            total += dead
        return total

    @ti.kernel
    def _find_moves(self, first: ti.i32, keep: ti.i32, live: ti.i32):
        """Of the `live` particles from slot `first`: the dead among the first `keep` (holes) and the live after them
        (fillers), as many of each, both in slot order (serial: the same moves whatever the threads)."""
        self.moves[0] = 0
        self.moves[1] = 0
        ti.loop_config(serialize=True)
        for _ in range(1):  # one task: the loops of _add_moves run in order on its thread
            self._add_moves(first, keep, live)

    @ti.func
    def _add_moves(self, first, keep, live):
        """Append the holes (the dead among the first `keep` of the `live` particles from slot `first`) and as many
        fillers (the live after them) to the lists, in slot order (run on one thread)."""
        for i in range(first, first + keep):
            if self.dead(i):
                self.hole[self.moves[0]] = i
                self.moves[0] += 1
        for i in range(first + keep, first + live):
            if not self.dead(i):
                self.filler[self.moves[1]] = i
                self.moves[1] += 1

"""Particle storage sorted into cell order, so that a particle's neighbours sit near it in memory.

A liquid's particles wander away from the neighbours they were stored beside; after a while every neighbour read in
the force loop is a cache miss (a shuffled 2D LJ box runs at about half the throughput of a sorted one at 1M
particles). Every `every` neighbour-list rebuilds the simulation calls `apply()` at a step
boundary: the cell grid's counting sort gives the order, every per-particle field is gathered into it, spring ends
are renumbered and bond tables moved, and listeners (the renderer's motion-blur tails) are told. Particles keep
their identity in `ident` (the particle id).
"""

import taichi as ti

from ..core.oriented import data_oriented


@data_oriented
class CellOrder:
    """Sorts the particle storage of `sim` (a Simulation with a cell grid) into the grid's cell order."""

    def __init__(self, sim, every: int):
        self.sim = sim
        self.every = every
        p = sim.particles
        self.fields = [getattr(p, name) for name in p.names()]
        self.capacity = p.capacity
        self.inverse = ti.field(ti.i32, shape=self.capacity)  # new index of the particle stored at each old index
        self.scratch = [_like(field, self.capacity) for field in self.fields]
        springs = sim.springs
        self.has_springs = springs is not None
        self.bond_scratch = ti.field(ti.i32, shape=springs.bonds.shape) if springs is not None else None
        self.pairs = list(zip(self.fields, self.scratch))
        self.listeners = []  # callables(order, inverse, n): told after the storage was permuted
        self.applied = 0
        self.next_at = every

    def due(self) -> bool:
        """True when the neighbour list has been rebuilt `every` times since the last sort."""
        return self.sim.neighbours.builds >= self.next_at

    def apply(self) -> None:
        """Sort now (at a step boundary: integrators' stage fields are not permuted)."""
        grid = self.sim.grid
        grid.rebuild()
        self._permute(grid.sorted_ids)
        n = int(self.sim.particles.n[None])
        for listener in self.listeners:
            listener(grid.sorted_ids, self.inverse, n)
        self.sim.neighbours.invalidate()
        self.applied += 1
        self.next_at = self.sim.neighbours.builds + 1 + self.every  # the invalidated list rebuilds once more

    @ti.kernel
    def _permute(self, order: ti.template()):
        n = self.sim.particles.n[None]
        for k in range(n):
            self.inverse[order[k]] = k
        # One loop over the particles for all the fields (each top-level loop is a task LLVM compiles on its own,
        # even from the offline cache: a loop per field made the first sort of a run a 0.3 s pause), so each field
        # has its own scratch.
        for k in range(n):
            for pair in ti.static(self.pairs):
                pair[1][k] = pair[0][order[k]]
        for k in range(n):
            for pair in ti.static(self.pairs):
                pair[0][k] = pair[1][k]
        if ti.static(self.has_springs):
            s = self.sim.springs
            for q in range(s.span[None]):
                s.i[q] = self.inverse[s.i[q]]
                s.j[q] = self.inverse[s.j[q]]
            for k, b in ti.ndrange(n, s.max_bonds):
                self.bond_scratch[k, b] = s.bonds[order[k], b]
            for k, b in ti.ndrange(n, s.max_bonds):
                s.bonds[k, b] = self.bond_scratch[k, b]

    def nbytes(self) -> int:
        """Bytes of scratch held for sorting."""
        total = 4 * self.capacity
        for field in self.scratch:
            total += field.shape[0] * _item_bytes(field)
        if self.bond_scratch is not None:
            total += 4 * self.bond_scratch.shape[0] * self.bond_scratch.shape[1]
        return total


def _like(field, capacity: int):
    n = getattr(field, "n", 0)
    if n:
        return ti.Vector.field(n, field.dtype, shape=capacity)
    return ti.field(field.dtype, shape=capacity)


def _item_bytes(field) -> int:
    size = 8 if field.dtype in (ti.f64, ti.i64) else 4
    return size * max(getattr(field, "n", 0), 1)

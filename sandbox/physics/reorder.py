"""Particle storage sorted into cell order, so that a particle's neighbours sit near it in memory.

A liquid's particles wander away from the neighbours they were stored beside; after a while every neighbour read in
the force loop is a cache miss (a shuffled 2D LJ box runs at about half the throughput of a sorted one at 1M
particles). Every `every` neighbour-list rebuilds the stepping plan calls `apply()` at a step boundary: the cell
grid's counting sort gives the order, and the State moves every particle into it (with its springs and any
passengers: core/particles.py's Mover). Particles keep their identity in `ident` (the particle id).
"""

from ..core.ranges import COUNT


class CellOrder:
    """Sorts the particle storage of `state` into the cell order of `grid`, every `every` builds of `lists`."""

    def __init__(self, state, grid, lists, every: int):
        self.state, self.grid, self.lists = state, grid, lists
        self.every = every
        self.applied = 0
        self.next_at = every

    def declare(self, state) -> None:
        """When it sorted and sorts next: saved with a state so a resumed run sorts on the same steps, and put back
        with a snapshot so a reset run does too."""
        state.declare("reorder", self, ("applied", "next_at"), kind="value", valid=COUNT)

    def due(self) -> bool:
        """True when the neighbour list has been rebuilt `every` times since the last sort."""
        return self.lists.builds >= self.next_at

    def apply(self) -> None:
        """Sort now (at a step boundary: integrators' stage fields are not permuted)."""
        self.grid.rebuild()
        self.state.permute(self.grid.sorted_ids, self.state.live_count())  # the lists rebuild: a new layout
        self.applied += 1
        self.next_at = self.lists.builds + 1 + self.every  # the lists rebuild once more after the sort

    def describe(self) -> str:
        return f"particle storage sorted into cell order every {self.every} list rebuilds"

    def nbytes(self) -> int:
        """Bytes of scratch held for sorting."""
        return self.state.mover.scratch_bytes(self.state.movable)

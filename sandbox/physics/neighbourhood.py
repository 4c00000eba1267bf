"""What the pair terms are evaluated over: the cell grid, the Verlet lists on it (physics/neighbours.py), and the sort
of the storage into cell order (physics/reorder.py)."""

import warnings

from .neighbours import no_lists


class Neighbourhood:
    """What the pair terms are evaluated over: the cell grid, the Verlet lists on it (None: the grid is scanned
    each step), and the sort of the storage into cell order (None: never). `half`: the lists hold each pair once
    (the CPU's layout; a GPU gathers from full lists). Built from the reach of the scene's pair terms."""

    def __init__(self, grid, lists, order, half: bool):
        self.grid, self.lists, self.order = grid, lists, order
        self.half = half
        self.marks_bonds = lists is not None and lists.marks_bonds  # half rows flag bonded pairs
        self.no_lists = no_lists()  # what kernels take for the lists when a step does not use them
        self._warned_overflow = False

    def ids(self, use_lists: bool):
        """The lists to hand a kernel: the lists when the step uses them, else the 1 x 1 stand-in."""
        return self.lists.flat if use_lists else self.no_lists

    def refresh(self, moved: bool) -> bool:
        """Before an evaluation: rebuild the lists if stale (`moved`: a particle has moved half the skin), else sort
        the grid for a scan; returns whether the lists are usable (False: scan the grid)."""
        if self.lists is None:
            self.grid.rebuild()
            return False
        usable = self.lists.ensure_fresh(moved)
        if not usable:
            self.grid.rebuild()  # the fallback scans the grid, which must match the current positions
            if not self._warned_overflow:
                self._warned_overflow = True
                warnings.warn(
                    f"neighbour list overflow: some particle has more than {self.lists.width} neighbours; scanning "
                    "the cell grid instead (slower)",
                    stacklevel=3,
                )
        return usable

    def declare(self, state) -> None:
        for part in (self.lists, self.order):
            if part is not None:
                part.declare(state)

    def after_restore(self, state) -> None:
        """A state was put back: sort the grid over its particles (the per-particle pass visits them in the grid's
        order, so every live particle must be in it; the lists, when restored from a file, stay as saved)."""
        self.grid.rebuild()

    def describe(self) -> list[str]:
        if self.lists is None:
            return [f"neighbour grid: counting sort into a {self.grid.describe()}, every step"]
        lines = [self.lists.describe(self.grid)]
        if self.order is not None:
            lines.append(self.order.describe())
        return lines

    def nbytes(self, capacity: int, dim: int) -> dict:
        out = {"grid": self.grid.footprint_bytes(capacity, self.grid.n_cells, dim)}
        if self.lists is not None:
            out["neighbour lists"] = self.lists.nbytes()
        if self.order is not None:
            out["reorder scratch"] = self.order.nbytes()
        return out

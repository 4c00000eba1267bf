"""Verlet neighbour lists with a skin, built from the cell grid and rebuilt only when needed.

Each particle lists every particle within reach + skin (a full list), or only those after it in its own row of cells and
in the rows ahead of it (a half list: each pair once, under one of its two particles; see NeighbourList._visit). The
list stays valid until some particle has moved more than skin / 2 since the build (then no pair within `reach` can be
missing), or the particle count changes; a cheap check kernel decides each step. Lists have a width sized from the
initial packing with a margin; when a particle gets more neighbours than fit, the lists are reallocated wider. They are
a Taichi ndarray, which kernels take as an argument of fixed type and any shape, so widening them recompiles nothing
(a field passed as a template argument would recompile every kernel that reads it, a stall each time the lists
grow). Past MAX_BYTES of lists (say, a thousand particles crushed into one cell) the step falls back to scanning the
cell grid directly: no interaction is ever dropped.

Worlds (core/worlds.py): a build rebuilds the rows of the worlds where some particle has moved half the skin (all of
them where the particles were added, removed or moved in storage), so each world's lists are built on the steps its
lone run's are, and its forces are summed in the same order.

Bonded pairs (half lists given `springs`): a pair joined by a live spring at the build is stored as -(s + 1), s the
spring, so the pair pass can skip its pair force (a bonded pair feels its spring instead) without searching the bond
table, and apply the pair force again once the spring breaks. Spring slots are only reused by new springs, and the code
that makes springs invalidates the list, so an entry never names a slot that now joins other particles.
"""

import math

import numpy as np
import taichi as ti

from ..core import runtime
from ..core.oriented import data_oriented
from ..core.particles import fold_bonds
from ..core.ranges import COUNT, Range
from ..core.worlds import world_of

MAX_BYTES = 1 << 30  # lists wider than this in total are not allocated; the cell-grid scan is used instead
# The type of the lists as a kernel argument (see the docstring): one flat array, row i of width w at [i w, (i + 1) w).
# Flat rather than (capacity, width): a 2D ndarray's row stride is reloaded from memory at every entry the pair pass
# reads (the compiler cannot tell the pass's stores leave it alone). Measured: docs/performance.md, "Why the code
# is shaped so".
LIST_ARRAY = ti.types.ndarray(dtype=ti.i32, ndim=1)


def no_lists():
    """A stand-in for the lists where a kernel takes them but the step does not use them (one entry, never read)."""
    return runtime.ndarray(ti.i32, (1,))


def list_width(widest: int) -> int:
    """Entries per row for lists whose widest row holds `widest` neighbours: 1.5 times that plus 8 (at least 16), and
    never a multiple of 32. Rows a multiple of 32 entries (128 bytes) apart start on a fraction of the cache's sets
    (at 128 entries, 8 of 64), and W1-3D's half lists, once sized from full rows, were exactly that wide (measured:
    docs/performance.md, "Why the code is shaped so")."""
    width = max(16, int(math.ceil(1.5 * widest)) + 8)
    return width + 4 if width % 32 == 0 else width


class ListTable:
    """The flat lists seen as the (capacity, width) table that state files and tests read and write."""

    def __init__(self, lists):
        self.lists = lists
        self.dtype = ti.i32

    @property
    def shape(self) -> tuple[int, int]:
        return (self.lists.capacity, self.lists.width)

    def to_numpy(self) -> np.ndarray:
        return self.lists.flat.to_numpy().reshape(self.shape)

    def from_numpy(self, table: np.ndarray) -> None:
        self.lists.flat.from_numpy(np.ascontiguousarray(table, dtype=np.int32).reshape(-1))


@data_oriented
class NeighbourList:
    """Per-particle lists of neighbour ids within reach + skin, over the cell grid `grid`."""

    def __init__(
        self,
        grid,
        domain,
        state,
        reach: float,
        skin: float,
        capacity: int,
        half: bool = False,
        springs=None,
        loops=None,
    ):
        """Lists for the live particles of `state`; `half`: each pair listed once, under one of the two (the caller
        applies the pair to both particles); `springs` (with `half`): mark bonded pairs (see above); `loops`: the
        LoopPolicy (default: the grid's)."""
        self.loops = loops if loops is not None else grid.loops
        self.grid, self.domain, self.state = grid, domain, state
        self.x, self.n = state.particles.x, state.particles.n
        self.p = state.particles
        self.worlds = self.p.world_count if self.p.worlds else 1
        if self.worlds > 1:
            self.world_stale = ti.field(ti.i32, shape=self.worlds)  # the worlds whose rows the next build rebuilds
            self.world_due = ti.field(ti.i32, shape=self.worlds)  # ... whose particles were added, removed or moved
            self.every_row = ti.field(ti.i32, shape=())  # 1: the next build rebuilds every world's rows
            self.kept = ti.field(ti.i32, shape=())  # 1: the next build rebuilds the worlds the last one marked
        self.half = half
        self.springs = springs
        self.marks_bonds = half and springs is not None
        self.dim = grid.dim
        self.reach, self.skin = reach, skin
        self.capacity = capacity
        self.count = ti.field(ti.i32, shape=capacity)  # neighbours of each particle (may exceed the width)
        self.x_ref = ti.Vector.field(self.dim, self.x.dtype, shape=capacity)  # positions at the last build
        self.stale = ti.field(ti.i32, shape=())  # 1 when the list must be rebuilt
        self.overflow = ti.field(ti.i32, shape=())  # 1 when some particle has more neighbours than fit
        self.n_listed = ti.field(ti.i32, shape=())  # the particle count at the last build
        self.widest = ti.field(ti.i32, shape=())  # the widest row when the lists were sized
        self.forced = True  # rebuild at the next check (invalidate())
        # build again the rows the last build was building, which overflowed (grow); never set between steps
        self.refill = False
        self.built_layout = -1  # the state's layout counter when the lists were last built
        self.usable = False  # the last build fitted every list (no overflow)
        self.host_builds = 0  # builds run by ensure_fresh
        self.fused_builds = ti.field(ti.i32, shape=())  # builds run inside the fused step (Simulation._fused_steps)
        self.fused = False  # the fused step has run: `builds` must read fused_builds
        # Sized from the widest row the lists hold now (a half row for half lists; see list_width). The 1.5x margin
        # covers a liquid's fluctuations and most of a lattice melting into a denser liquid (the melting block's half
        # rows reach 1.6x their lattice widest: the lists grow once, compiling nothing).
        widest = int(self._sort_and_count())
        self._allocate(list_width(widest))
        self.grown = 0

    def declare(self, state) -> None:
        """The lists and when they were built: saved with a state, so a resumed run sums its forces in the same
        order (the lists are not part of a snapshot: restoring one moves the layout on, which rebuilds them; their
        build count is)."""
        listed = Range(below="capacity")  # a particle, or -(s + 1) for a bonded pair's spring s: checked below
        state.declare("neighbours", self, ("ids",), kind="ndarray", physical=False, rows="particles", valid=listed)
        state.declare("neighbours", self, ("count",), physical=False, rows="particles", valid=COUNT)
        state.declare("neighbours", self, ("x_ref",), physical=False, rows="particles")
        state.declare("neighbours", self, ("n_listed",), physical=False, valid=Range(lo=0, atmost="capacity"))
        # the build count is in snapshots: it decides on which steps the storage is sorted (reorder.py), so a reset
        # then sorts on the steps a fresh run does
        state.declare("neighbours", self, ("fused_builds",), valid=COUNT)
        state.declare("neighbours", self, ("forced", "usable"), kind="value", physical=False)
        state.declare("neighbours", self, ("fused",), kind="value")
        state.declare("neighbours", self, ("built_layout",), kind="value", physical=False)
        state.declare("neighbours", self, ("host_builds",), kind="value", valid=COUNT)
        state.declare("neighbours", self, ("grown", "width"), kind="value", physical=False, valid=COUNT)

    def must_rebuild(self) -> bool:
        """Whether the next check rebuilds whatever the particles' displacements: invalidated, or the particles were
        added, removed or moved in storage since the build."""
        return self.forced or self.refill or self.built_layout != self.state.layout

    def mark_built(self) -> None:
        """The lists are (or a launch will have them) built for the current layout."""
        self.forced = self.refill = False
        self.built_layout = self.state.layout

    def describe(self, grid) -> str:
        """The lists in words, for Simulation.pipeline(); `grid` is the cell grid they are built from."""
        return (
            f"{'half' if self.half else 'full'} neighbour lists (reach {self.reach:g} + skin {self.skin:g}, width "
            f"{self.width}), rebuilt from a counting-sort {grid.describe()} when a particle has moved half the skin"
        )

    def mark_rows_to_rebuild(self) -> None:
        """Before a build, with many worlds, mark the rows it rebuilds besides those of the worlds whose particles
        moved half the skin: every world's where the lists were invalidated or every world's particles moved in
        storage; where only some worlds' were seeded or retired (State.worlds_moved_since), those worlds'; after a
        widening alone, none more (the rows the overflowed build was building: grow). One world: every row anyway."""
        if self.worlds == 1 or not (self.forced or self.built_layout != self.state.layout):
            return
        moved = None if self.forced else self.state.worlds_moved_since(self.built_layout)
        if moved is None:
            self.every_row[None] = 1
        else:
            due = self.world_due.to_numpy()
            due[sorted(moved)] = 1
            self.world_due.from_numpy(due)

    def _allocate(self, width: int) -> None:
        self.width = width
        self.flat = runtime.ndarray(ti.i32, (self.capacity * width,))  # neighbour ids, first count[i] of row i valid

    @property
    def ids(self) -> ListTable:
        """The lists as a (capacity, width) table (state files, tests); kernels take `flat`."""
        return ListTable(self)

    @ids.setter
    def ids(self, table) -> None:
        """Lists as wide as `table` (a state file's, widened during its run); its values are then written through
        `ids.from_numpy`."""
        self._allocate(int(table.shape[1]))

    @ti.func
    def width_of(self, ids: ti.template()):
        """Entries per row of the flat lists `ids`."""
        return ids.shape[0] // self.capacity

    @ti.func
    def row(self, i, ids: ti.template()):
        """Where row i of the flat lists `ids` starts."""
        return i * self.width_of(ids)

    def nbytes(self) -> int:
        return self.capacity * (4 * self.width + 4 + 4 * self.dim)

    def ensure_fresh(self, moved: bool | None = None) -> bool:
        """Rebuild the list if it may miss a pair; returns True when it is usable (no overflow). `moved`: the result
        of the displacement check when the caller ran it already (fused into its own kernel)."""
        if moved is None:
            moved = self._moved_too_far()
        if self.must_rebuild() or moved:  # no host read of the count or the overflow flag on steps without a rebuild
            self.mark_rows_to_rebuild()
            self._sort_and_fill(self.flat)
            if self.overflow[None] and self.grow():
                self._fill(self.flat)
            self.usable = self.overflow[None] == 0
            self.mark_built()
            self.host_builds += 1
        return self.usable

    @property
    def builds(self) -> int:
        """How many times the list has been built (a host read of a field once the fused step has run)."""
        return self.host_builds + (int(self.fused_builds[None]) if self.fused else 0)

    def grow(self) -> bool:
        """After a build that overflowed: reallocate the lists for the widest count of that build (see list_width);
        False when that would pass MAX_BYTES (the lists stay as they are). The caller builds them again."""
        n = int(self.n[None])
        widest = int(self.count.to_numpy()[:n].max())
        wider = list_width(widest)
        if self.capacity * wider * 4 > MAX_BYTES:
            return False
        self.refill = True
        if self.worlds == 1:
            self._allocate(wider)
        else:  # the rows of the worlds the build left alone are kept (moved into the wider table), not rebuilt: a
            # world's rows are built on its lone run's steps, its forces summed in its order (module docstring)
            old = self.ids.to_numpy()
            self._allocate(wider)
            table = np.zeros((self.capacity, wider), np.int32)
            table[:, : old.shape[1]] = old
            self.ids.from_numpy(table)
            self.kept[None] = 1
        self.grown += 1
        return True

    def invalidate(self) -> None:
        """Rebuild at the next check (the particles changed: added, removed, moved by hand or reordered)."""
        self.forced = True

    def _moved_too_far(self) -> bool:
        self.stale[None] = 0
        self._check()
        return self.stale[None] != 0

    @ti.kernel
    def _check(self):
        self.check_count()
        self.loops.light()
        for i in range(self.n[None]):
            if self.p.idle(i):
                continue
            self.check_one(i)

    @ti.func
    def check_count(self):
        """Flag the list stale if the particle count changed since the build (count changes also invalidate())."""
        if self.n[None] != self.n_listed[None]:
            self.stale[None] = 1

    @ti.func
    def check_one(self, i):
        """Flag the list stale if particle i has moved more than half the skin since the build."""
        if self.moved_far(i):
            self.stale[None] = 1

    @ti.func
    def moved_far(self, i) -> bool:
        """Whether particle i has moved more than half the skin since the build."""
        d = self.domain.separation(self.x_ref[i], self.x[i])
        return d.dot(d) > (0.5 * self.skin) ** 2

    @ti.kernel
    def _sort_and_count(self) -> ti.i32:
        """Sort the grid, then count[i] = the neighbours of i within reach + skin in the row the lists hold (half or
        full); returns the widest count. One launch: each kernel costs its compile at start-up."""
        self.grid.rebuild_loops()
        r2max = (self.reach + self.skin) ** 2
        self.widest[None] = 0
        self.loops.pairs()
        for i in range(self.n[None]):
            if self.p.idle(i):
                continue
            self.count[i] = self._visit(i, r2max, False, self.count, self.half)
            ti.atomic_max(self.widest[None], self.count[i])
        return self.widest[None]

    @ti.kernel
    def _fill(self, ids: LIST_ARRAY):
        self.fill_loops(ids)

    @ti.kernel
    def _sort_and_fill(self, ids: LIST_ARRAY):
        """The grid's counting sort and the list build in one launch."""
        self.grid.rebuild_loops()
        self.fill_loops(ids)

    @ti.func
    def fill_loops(self, ids: ti.template()):
        """Build the lists into `ids` from the grid as last sorted; sets `overflow` when some list did not fit. A
        ti.func, so the fused step (Simulation) can run it inside its own kernel."""
        self.begin_fill()
        self.loops.pairs()
        for i in range(self.n[None]):
            if self.p.idle(i):
                continue
            self.fill_one(i, ids)

    @ti.func
    def begin_fill(self):
        """Before a build: clear the overflow flag and record the particle count listed; with many worlds, mark
        those whose rows it rebuilds (module docstring; a serial pass, on the steps that build)."""
        if ti.static(self.worlds > 1):
            every = self.every_row[None] != 0 or self.n[None] != self.n_listed[None]
            if every or self.kept[None] == 0:  # kept: the build after a widening redoes the last one's worlds
                for w in range(self.worlds):
                    self.world_stale[w] = 1 if every or self.world_due[w] != 0 else 0
                    self.world_due[w] = 0
                for i in range(self.n[None]):  # (serial: nested in the branch)
                    if self.p.idle(i):
                        continue
                    if self.moved_far(i):
                        self.world_stale[world_of(self.p, i)] = 1
            self.every_row[None] = 0
            self.kept[None] = 0
        self.overflow[None] = 0
        self.n_listed[None] = self.n[None]

    @ti.func
    def fill_one(self, i, ids: ti.template()):
        """Build particle i's list into row i of `ids` (its count, its position at the build; bonded pairs marked);
        set `overflow` when it does not fit. With many worlds, only the rows of the worlds begin_fill marked."""
        rebuild = True
        if ti.static(self.worlds > 1):
            rebuild = self.world_stale[world_of(self.p, i)] != 0
        if rebuild:
            self._fill_row(i, ids)

    @ti.func
    def _fill_row(self, i, ids: ti.template()):
        width = self.width_of(ids)
        c = self._visit(i, (self.reach + self.skin) ** 2, True, ids, self.half)
        self.count[i] = c
        self.x_ref[i] = self.x[i]
        if c > width:
            self.overflow[None] = 1
        if ti.static(self.marks_bonds):  # each live bond of i: if the pair is in i's list (not j's), mark it
            fold_bonds(self.springs, i, 0, self._mark_bond, (ti.min(c, width), i * width, ids))

    @ti.func
    def _mark_bond(self, acc, i, j, spring, extra: ti.template()):
        """Mark the pair (i, j) of live `spring` as bonded where it is among the first extra[0] entries of i's row
        (starting at extra[1]) of the lists extra[2] (it is listed under i or under j, once)."""
        listed, row = extra[0], extra[1]
        ids = ti.static(extra[2])
        for k in range(listed):
            if ids[row + k] == j:
                ids[row + k] = -(spring + 1)
        return acc

    @ti.func
    def _visit(self, i, r2max, store: ti.template(), ids: ti.template(), half: ti.template()):
        """Count (and with `store`, write into row i of `ids`) the neighbours of i within sqrt(r2max); `half`: only
        those of a half row: the cell rows ahead of i's (see CellGrid.row_base), and in i's own row the places after
        i's own (the rest of its cell and the next cell along the last axis). Each pair is then listed once.

        The list build is the hottest scan of a step, so it walks the cells itself rather than through the grid's
        fold (the scan every other part uses), a row of cells along the last axis at a time: their particles are one
        range in cell order (two where the row wraps around a periodic box), so a 2D half row scans two ranges. In 3D
        each row is trimmed to the cells that can hold a point within reach (CellGrid.trims_rows), which changes no
        listed pair: the cells left out hold only particles the count would pass over. Branch-free: every candidate
        is written at the list's end and counted only when within reach (a third are; a branch on that mispredicted
        so often that the build cost 1.4x more)."""
        grid = self.grid
        xi = self.x[i]
        width = 0
        if ti.static(store):
            width = self.width_of(ids)  # read once: a shape is reloaded at every use after a store
        cell = grid.cell_of(xi)
        last = ti.static(self.dim - 1)
        place = grid.place_in_cell(xi, cell)
        first = ti.static(grid.n_rows // 2 if half else 0)  # the row of i's own cell, or the first
        rows = ti.static(grid.n_rows - first)  # rows scanned
        c = 0
        if ti.static(half and store and grid.trims_rows):
            # The CPU's 3D half rows: every row's ranges first, then the scans. A range's bounds hang on a chain of
            # latencies (the trim's square root, the cell_start loads) that a scan long enough to fill the core's
            # window would hold back; unrolled ahead of the scans, the rows' chains overlap (a faster 3D build for a
            # longer compile; docs/performance.md, "Why the code is shaped so").
            # Range 2q is row q's cells inside the box, 2q + 1 those past a periodic box's end along the last axis.
            starts = ti.Vector.zero(ti.i32, 2 * rows)
            ends = ti.Vector.zero(ti.i32, 2 * rows)
            shifts = ti.Matrix.zero(self.x.dtype, 2 * rows, self.dim)
            for q in ti.static(range(rows)):
                ranges, shift, wrap = grid.row_ranges(i, cell, place, first + q, q == 0, r2max)
                starts[2 * q], ends[2 * q], starts[2 * q + 1], ends[2 * q + 1] = ranges
                for a in ti.static(range(self.dim)):
                    shifts[2 * q, a] = shift[a]
                    shifts[2 * q + 1, a] = shift[a]
                shifts[2 * q + 1, last] = wrap
            for q in range(2 * rows):  # a loop, not unrolled: ten copies of the scan tripled the 3D kernels' compile
                xs = xi - ti.Vector([shifts[q, a] for a in ti.static(range(self.dim))])
                c = self._scan(i, xs, starts[q], ends[q], c, width, r2max, store, ids)
        else:  # 2D, full rows (GPU lists) and the count that sizes the lists: a row at a time, less to compile
            for r in range(rows):
                ranges, shift, wrap = grid.row_ranges(i, cell, place, first + r, half and r == 0, r2max)
                c = self._scan(i, xi - shift, ranges[0], ranges[1], c, width, r2max, store, ids)
                if ti.static(grid.periodic):
                    shift[last] = wrap
                    c = self._scan(i, xi - shift, ranges[2], ranges[3], c, width, r2max, store, ids)
        return c

    @ti.func
    def _scan(self, i, xs, start, end, c, width, r2max, store: ti.template(), ids: ti.template()):
        """The candidates in places start .. end - 1 of cell order, seen from xs (i's position less the range's
        periodic shift): each written at row i's end and counted when within reach; returns the new count."""
        row = i * width
        for k in range(start, end):
            j = self.grid.sorted_ids[k]
            d = self.grid.x_sorted[k] - xs
            near = (d.dot(d) < r2max) and j != i
            if ti.static(store and self.loops.gpu):  # on a GPU the stores are the build's memory traffic: kept only
                if near and c < width:
                    ids[row + c] = j
            elif ti.static(store):  # the CPU's: branch-free (see _visit)
                if c < width:
                    ids[row + c] = j
            c += ti.cast(near, ti.i32)
        return c

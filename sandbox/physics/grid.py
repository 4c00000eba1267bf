"""Uniform cell grid for neighbour search, rebuilt by a counting sort (no float atomics).

Cells are at least `reach` wide, and 1 / ROW_SPAN of it along the last axis, so all neighbours of a particle within
`reach` lie in the 3^(D-1) (2 ROW_SPAN + 1) cells around its own.
Build: count particles per cell with an integer atomic (the returned old count is the particle's slot in its cell),
a prefix sum over cells (serial on the CPU, in blocks on a GPU: see CellGrid.prefix_sum), then a scatter of particle
ids into `sorted_ids` in cell order.

A simulation of many worlds (core/worlds.py) has a grid of the box's cells for each world, one after the other in
cell order: a particle's cell is its world's, and every scan stays in it, so nothing is ever found across worlds.
"""

import math

import numpy as np
import taichi as ti

from ..core.oriented import data_oriented
from ..core.worlds import world_of

ROW_SPAN = 3  # cells per reach along the last axis (one along the others)
SCAN_BLOCK = 512  # cells a GPU thread sums in the blocked prefix sum (CellGrid.prefix_sum)
BOUND_SLACK = 1e-3  # cell widths a scan bound is widened by, against rounding in the positions' cell coordinates


@data_oriented
class CellGrid:
    """Neighbour grid over the box lo..hi for particles x (a Vector field), interaction radius `reach`."""

    def __init__(
        self,
        x,
        n_active,
        lo,
        hi,
        reach: float,
        periodic: bool,
        capacity: int,
        loops,
        cells_per_particle: int = 4,
        particles=None,
    ):
        """Grid for positions `x` (first n_active[None] entries) in the box lo..hi; cells at least `reach` wide, at
        most `cells_per_particle` per particle slot (at least 65,536) in a box with walls. `loops`: the LoopPolicy
        that decides which loops run in parallel; `particles`: their fields, whose `world` keys a grid per world
        where there are several (module docstring)."""
        self.p = particles
        self.worlds = particles.world_count if particles is not None and particles.worlds else 1
        capacity = capacity // self.worlds  # each world's grid is its lone run's
        self.loops = loops
        self.dim = len(lo)
        self.periodic = periodic
        self.lo = np.asarray(lo, dtype=np.float64)
        self.hi = np.asarray(hi, dtype=np.float64)
        extent = self.hi - self.lo
        # Along the last axis cells are 1 / ROW_SPAN of the reach: a row of cells along it is one range of cell order
        # whatever its length, so narrower cells there trim the candidates a scan tests at no cost in ranges.
        self.row_span = ROW_SPAN
        # In 3D a list build trims each row of cells to those within reach of the particle (row_base's gap2,
        # row_cells): a quarter fewer candidates; in 2D the bound's square root and floors cost more than the few
        # candidates they save, so 2D rows keep their full span (docs/performance.md, "Why the code is shaped so").
        self.trims_rows = self.dim >= 3
        per_reach = np.array([1] * (len(extent) - 1) + [ROW_SPAN])
        if periodic:  # enough cells that the cells around one are each visited once
            counts = np.maximum(np.floor(extent * per_reach / reach).astype(int), 2 * per_reach + 1)
        else:  # floor, not ceil: a cell narrower than reach / per_reach would hide neighbours
            counts = np.maximum(np.floor(extent * per_reach / reach).astype(int), 1)
        # Bound the cell count so a tiny radius in a huge domain cannot allocate gigabytes.
        # Python integers: the product of a huge domain's counts overflows int64 (and wrapped past this bound)
        while math.prod(int(c) for c in counts) > max(cells_per_particle * capacity, 1 << 16) and not periodic:
            counts = np.maximum(counts // 2, 1)
        self.counts = tuple(int(c) for c in counts)
        self.cell_size = tuple(float(e / c) for e, c in zip(extent, counts))
        self.world_cells = int(np.prod(counts))  # the cells of one world's box
        self.n_cells = self.world_cells * self.worlds
        self.parks = particles is not None and particles.gaps  # the worlds' idle slots are sorted into a cell of their
        if self.parks:  # own, past every world's: no scan visits it (core/particles.py's idle)
            self.n_cells += 1
        self.reach = reach
        self.x = x
        self.n = n_active
        self.cell_count = ti.field(ti.i32, shape=self.n_cells)  # particles per cell
        self.cell_start = ti.field(ti.i32, shape=self.n_cells)  # index of the cell's first entry in sorted_ids
        self.scan_blocks = -(-self.n_cells // SCAN_BLOCK)
        if loops.gpu:
            self.block_start = ti.field(ti.i32, shape=self.scan_blocks)  # the blocked sum's first entry of a block
        slots = capacity * self.worlds
        self.particle_cell = ti.field(ti.i32, shape=slots)  # flat cell index of each particle
        self.slot = ti.field(ti.i32, shape=slots)  # position of the particle within its cell
        self.sorted_ids = ti.field(ti.i32, shape=slots)  # particle ids in cell order
        self.x_sorted = ti.Vector.field(self.dim, x.dtype, shape=slots)  # positions in cell order (contiguous)
        self._lo = ti.Vector(list(self.lo))
        self._inv = ti.Vector([1.0 / c for c in self.cell_size])
        self._ncell = ti.Vector(list(self.counts))
        self._box = ti.Vector(list(extent))

    @staticmethod
    def footprint_bytes(capacity: int, n_cells: int, dim: int) -> int:
        return 4 * (2 * n_cells + 3 * capacity) + 4 * dim * capacity

    def rebuild(self):
        """Sort the particles into cells (one launch)."""
        self._rebuild()

    @ti.kernel
    def _rebuild(self):
        self.rebuild_loops()

    @ti.func
    def rebuild_loops(self):
        """The counting sort: count per cell (the returned old count is the particle's slot), prefix sum, scatter.
        A ti.func, so the fused step (Simulation) can run it inside its own kernel."""
        self.loops.light()
        for c in range(self.n_cells):
            self.cell_count[c] = 0
        self.loops.light()
        for i in range(self.n[None]):
            c = self.flat(self.cell_of(self.x[i])) + self.world_base(i)
            if ti.static(self.parks):
                if self.p.idle(i):
                    c = self.n_cells - 1
            self.particle_cell[i] = c
            self.slot[i] = ti.atomic_add(self.cell_count[c], 1)
        self.prefix_sum()
        self.loops.light()
        for i in range(self.n[None]):
            k = self.cell_start[self.particle_cell[i]] + self.slot[i]
            self.sorted_ids[k] = i
            self.x_sorted[k] = self.x[i]

    @ti.func
    def prefix_sum(self):
        """cell_start[c] = the particles in the cells before c. On the CPU one serial loop (the cells' counts are in
        cache); on a GPU each of a few thousand threads sums a block of SCAN_BLOCK cells, one thread runs over the
        blocks' totals, and each block's thread writes its cells' starts: a serial loop over every cell on one GPU
        thread took most of a million-particle step (`python benchmarks/list_pruning.py --arch cuda`). Integer
        sums, so both orders give the same starts."""
        if ti.static(self.loops.gpu):
            for b in range(self.scan_blocks):
                total = 0
                for c in range(b * SCAN_BLOCK, ti.min((b + 1) * SCAN_BLOCK, self.n_cells)):
                    total += self.cell_count[c]
                self.block_start[b] = total
            running = 0
            ti.loop_config(serialize=True)
            for b in range(self.scan_blocks):
                total = self.block_start[b]
                self.block_start[b] = running
                running += total
            for b in range(self.scan_blocks):
                start = self.block_start[b]
                for c in range(b * SCAN_BLOCK, ti.min((b + 1) * SCAN_BLOCK, self.n_cells)):
                    self.cell_start[c] = start
                    start += self.cell_count[c]
        else:
            total = 0
            ti.loop_config(serialize=True)
            for c in range(self.n_cells):
                self.cell_start[c] = total
                total += self.cell_count[c]

    @ti.func
    def cell_of(self, p):
        """Integer cell coordinates of position p, clamped into the grid (walls keep particles inside anyway)."""
        c = ti.cast(ti.floor((p - self._lo) * self._inv), ti.i32)
        return ti.math.clamp(c, 0, self._ncell - 1)

    @ti.func
    def world_base(self, i):
        """The flat index of particle i's world's first cell (0 with one world)."""
        base = 0
        if ti.static(self.worlds > 1):
            base = world_of(self.p, i) * self.world_cells
        return base

    @ti.func
    def flat(self, c):
        idx = 0
        for k in ti.static(range(self.dim)):
            idx = idx * self.counts[k] + c[k]
        return idx

    @ti.func
    def neighbour_cell(self, c, off):
        """Flat index of cell c + off (-1 when outside a walled grid) and the shift to add to positions found
        there: on periodic grids a cell that wraps around lies one box length away (minimum image without a
        division or rounding per pair)."""
        nc = c + off
        shift = ti.Vector.zero(self.x.dtype, self.dim)
        inside = True
        for a in ti.static(range(self.dim)):
            nc[a], shift[a], inside_a = self.wrap_axis(nc[a], a)
            inside = inside and inside_a
        return self.flat(nc) if inside else -1, shift

    @ti.func
    def wrap_axis(self, n, a: ti.template()):
        """Cell coordinate n (at most one grid length off it) along axis a brought into the grid: (the coordinate,
        the shift to add to positions found there, whether it lies inside). On a periodic grid a cell that wraps
        around lies one box length away (minimum image without a division or rounding per pair) and every cell is
        inside; on a walled grid nothing wraps."""
        wrapped = n
        shift = ti.cast(0.0, self.x.dtype)
        inside = True
        if ti.static(self.periodic):
            if n < 0:
                wrapped = n + self.counts[a]
                shift = -self._box[a]
            elif n >= self.counts[a]:
                wrapped = n - self.counts[a]
                shift = self._box[a]
        else:
            inside = n >= 0 and n < self.counts[a]
        return wrapped, shift, inside

    @ti.func
    def fold(self, i, xi, acc, visit: ti.template(), extra: ti.template()):
        """The one scan of the cells around position xi of particle i's world: acc = visit(acc, j, d, k, extra) for
        each particle j stored there (k: its place in cell order), d = x_j - xi to the image of j nearest xi; returns
        acc. The particle at xi itself is visited too (visitors skip it by id). `extra`: what the visitor reads
        besides, a tuple passed as it is (visitors take it as a template and read fields and flags in it through
        ti.static). Half lists are built by NeighbourList's own scan, a row of cells at a time."""
        cell = self.cell_of(xi)
        base = self.world_base(i)
        for o in range(self.n_offsets):
            nc, shift = self.neighbour_cell(cell, self.offset(o))
            if nc >= 0:
                nc += base
                xs = xi - shift
                for k in range(self.cell_start[nc], self.cell_start[nc] + self.cell_count[nc]):
                    acc = visit(acc, self.sorted_ids[k], self.x_sorted[k] - xs, k, extra)
        return acc

    @ti.func
    def offset(self, k):
        """The k-th of the n_offsets cell offsets around a cell: -1, 0, 1 along the leading axes, -ROW_SPAN ..
        ROW_SPAN along the last.

        Visited with a runtime loop rather than a ti.static unroll: unrolling 27 copies of the fused force and
        heat code made the 3D kernels take tens of seconds to compile."""
        off = ti.Vector.zero(ti.i32, self.dim)
        for a in ti.static(range(self.dim)):
            width = ti.static(2 * ROW_SPAN + 1 if a == self.dim - 1 else 3)
            off[a] = k % width - width // 2
            k //= width
        return off

    @ti.func
    def place_in_cell(self, p, c):
        """Where position p lies in cell c along each axis, in cell widths: 0 at the cell's low face, 1 at its high
        one; clamped to 0 .. 1, so a particle the grid clamped into an edge cell is taken at that cell's face, nearer
        every other cell than it is (a bound built on it stays conservative)."""
        return ti.math.clamp((p - self._lo) * self._inv - ti.cast(c, self.x.dtype), 0.0, 1.0)

    @ti.func
    def row_base(self, c, r, place):
        """Row r (0 .. 3^(D-1) - 1) of the cells around cell c: the cells whose leading coordinates (all but the last)
        are c's plus an offset in -1, 0, 1 (r's digits, the first axis most significant), all along the last axis.
        Returns the flat index of that row's cell at last coordinate 0, the shift to add to positions found there
        (leading axes only; see wrap_axis), whether the row lies inside a walled grid, and the squared distance across
        the leading axes from a point at `place` in cell c (see place_in_cell) to the row (0 for c's own row, and for
        every row without trims_rows; a hair short of it, against rounding). A row's cells are consecutive in cell
        order, so their particles are one range of sorted_ids."""
        base = 0
        shift = ti.Vector.zero(self.x.dtype, self.dim)
        inside = True
        gap2 = ti.cast(0.0, self.x.dtype)
        rem = r
        for b in ti.static(range(self.dim - 1)):
            a = ti.static(self.dim - 2 - b)  # the last leading axis first: the least significant digit of r
            off = rem % 3 - 1
            nc, shift[a], inside_a = self.wrap_axis(c[a] + off, a)
            rem //= 3
            inside = inside and inside_a
            base += nc * self.stride(a)
            if ti.static(self.trims_rows):
                gap = 0.0  # to the row's near face, in cell widths
                if off < 0:
                    gap = place[a]
                elif off > 0:
                    gap = 1.0 - place[a]
                gap = ti.max(gap - BOUND_SLACK, 0.0) * self.cell_size[a]
                gap2 += gap * gap
        return base, shift, inside, gap2

    @ti.func
    def row_cells(self, place, reach2_left):
        """The offsets (lowest, highest) along the last axis, within -row_span .. row_span, of the cells of a row
        that hold points within sqrt(reach2_left) along that axis of a point at `place` in its own cell (see
        place_in_cell): reach2_left is the squared reach less the squared distance to the row across the leading
        axes. Always includes the point's own cell. Without trims_rows: the whole span."""
        last = ti.static(self.dim - 1)
        lowest, highest = -self.row_span, self.row_span
        if ti.static(self.trims_rows):
            along = ti.sqrt(ti.max(reach2_left, 0.0)) * self._inv[last] + BOUND_SLACK  # in cell widths
            lowest = ti.max(lowest, ti.cast(ti.floor(place[last] - along), ti.i32))
            highest = ti.min(highest, ti.cast(ti.floor(place[last] + along), ti.i32))
        return lowest, highest

    @ti.func
    def row_ranges(self, i, cell, place, r, own_row, r2max):
        """The places in cell order to scan in row r of the cells around particle i's cell (see row_base) for its
        neighbours within sqrt(r2max), i at `place` in its cell (see place_in_cell; the row trimmed as row_cells says):
        (start, end) of the row's cells inside the box, then of those past a periodic box's end along the last axis
        (empty where none are); the shift to add to positions of the first range, and the last axis's shift of the
        second. `own_row`: i's own row of a half list, from the place after i's own."""
        last = ti.static(self.dim - 1)
        along = ti.static(self.counts[last])
        ranges = ti.Vector.zero(ti.i32, 4)
        wrap = ti.cast(0.0, self.x.dtype)
        base, shift, inside, gap2 = self.row_base(cell, r, place)
        base += self.world_base(i)
        if inside and gap2 < r2max:
            lowest, highest = self.row_cells(place, r2max - gap2)
            lo = cell[last] if own_row else cell[last] + lowest
            hi = cell[last] + highest
            ranges[0], ranges[1] = self.cells_range(base + ti.max(lo, 0), base + ti.min(hi, along - 1))
            if own_row:
                ranges[0] += self.slot[i] + 1
            if ti.static(self.periodic):  # the row's ends wrap around the box along the last axis
                if lo < 0:  # cells along + lo .. along - 1, one box length below
                    wrap = -self._box[last]
                    ranges[2], ranges[3] = self.cells_range(base + along + lo, base + along - 1)
                elif hi >= along:  # cells 0 .. hi - along, one box length above
                    wrap = self._box[last]
                    ranges[2], ranges[3] = self.cells_range(base, base + hi - along)
        return ranges, shift, wrap

    @ti.func
    def stride(self, a: ti.template()):
        """The flat-index step of one cell along axis a."""
        step = 1
        for k in ti.static(range(a + 1, self.dim)):
            step *= self.counts[k]
        return step

    @ti.func
    def cells_range(self, first, last):
        """(start, end): the places in cell order of the particles of cells first .. last, consecutive cells."""
        return self.cell_start[first], self.cell_start[last] + self.cell_count[last]

    @property
    def n_rows(self) -> int:
        """Rows of cells along the last axis among the cells around a cell (see row_base)."""
        return 3 ** (self.dim - 1)

    @property
    def n_offsets(self) -> int:
        return 3 ** (self.dim - 1) * (2 * ROW_SPAN + 1)

    def describe(self) -> str:
        return (
            f"cell grid {'x'.join(map(str, self.counts))} ({math.prod(self.counts)} cells of {self.cell_size[0]:.3g})"
        )

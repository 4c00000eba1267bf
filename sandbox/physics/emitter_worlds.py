"""Emitters in a simulation of worlds whose particle counts change (core/worlds.py, gaps): each step, every world's
due particles (each world's emitters on its own clock, counting its own serial numbers and ids) are seeded into the
worlds' blocks in one launch, where a launch a world and emitter cost a class of candles a fifth of its frame.

A particle is made from (emitter, serial number, birth time) alone (physics/emitters.py: its random numbers are
hashes of them), so it is the particle its world's lone run seeds, whichever launch makes it.
"""

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented


@data_oriented
class WorldSeeding:
    """The seeding table of `emitters` (an Emitters of a simulation with gaps): a row per (world, emitter) due."""

    def __init__(self, emitters):
        self.emitters = emitters
        self.p = emitters.p
        rows = max(emitters.count, 1) * self.p.world_count
        self.emitter, self.first, self.serial, self.ident, self.world, self.count = (
            ti.field(ti.i32, shape=rows) for _ in range(6)
        )
        self.t = ti.field(float, shape=rows)  # the birth time: the world's clock at its step's start

    def seed_due(self, times: list[float], dt: float) -> None:
        """Seed what is due in the step [t, t + dt) of each live world's clock (`times`: world w's t)."""
        emitters = self.emitters
        wanted = []
        for w, t in enumerate(times):
            carry = emitters.counters(w)[1]
            wanted.append((w, t, [emitters.due(k, t, dt, carry) for k in range(emitters.count)]))
        self.seed(wanted)

    def seed(self, wanted: list[tuple[int, float, list[int]]]) -> None:
        """Seed, for each (world w, birth time t on its clock, particles due from each emitter) of `wanted`, as many
        as world w's block has room for, in one launch."""
        emitters, p = self.emitters, self.p
        counts = p.counts.to_numpy()
        block = p.world_size
        rows = []
        for w, t, due in wanted:
            serial = emitters.counters(w)[0]
            for k, wanted_count in enumerate(due):
                count = emitters.room_for(k, wanted_count, block - int(counts[w]))
                if count:
                    rows.append((k, w * block + int(counts[w]), serial[k], p.next_ident[w], w, count, t))
                    emitters.took(w, k, count, count)
                    counts[w] += count
        if not rows:
            return
        columns = list(zip(*rows))
        fields = (self.emitter, self.first, self.serial, self.ident, self.world, self.count)
        table = [(f, np.array(c, np.int32)) for f, c in zip(fields, columns)]
        transfer.upload(table + [(self.t, np.array(columns[6]))])
        self._spawn(len(rows))
        p.counts.from_numpy(counts)
        emitters.state.particles_moved(columns[4])  # the worlds seeded: their lists rebuilt, as their lone runs'

    @ti.kernel
    def _spawn(self, rows: ti.i32):
        emitters, p = self.emitters, self.p
        for r in range(rows):
            k, first, serial0, t, w = self.emitter[r], self.first[r], self.serial[r], self.t[r], self.world[r]
            for m in range(self.count[r]):
                serial = serial0 + m
                emitters.init_particle(k, first + m, serial, emitters.sample_position(k, serial), t, w)
                p.ident[first + m] = self.ident[r] + m
                p.world[first + m] = w


@data_oriented
class WorldRefill:
    """The refill emitters of a simulation of worlds (`emitters`: an Emitters with gaps): each world's region topped
    up to the target density from its own particles, serial numbers and ids, into its own block; the worlds in order
    and each world's cells in a lone run's order, so each world seeds the particles its lone run seeds."""

    def __init__(self, emitters):
        self.emitters = emitters
        self.p = emitters.p
        worlds = self.p.world_count
        self.counts = {
            k: ti.field(ti.i32, shape=(worlds, *grid["count"].shape)) for k, grid in emitters.refill_grids.items()
        }  # each world's particles per refill cell
        self.first, self.room, self.serial, self.ident, self.reserved = (
            ti.field(ti.i32, shape=worlds) for _ in range(5)
        )
        self.t = ti.field(float, shape=worlds)  # each world's clock

    def refill(self, times: list[float]) -> None:
        """Top up every refill emitter's region in each live world (`times`: world w's clock, one a live world)."""
        emitters, p = self.emitters, self.p
        block, live = p.world_size, len(times)
        changed = set()
        counts = p.counts.to_numpy()  # kept here as each emitter tops up (and uploaded for the next one's kernels)
        clocks = np.zeros(p.world_count)
        clocks[:live] = times
        for k in emitters.refills:
            grid = emitters.refill_grids[k]
            serial = np.array([emitters.counters(w)[0][k] for w in range(live)] + [0] * (p.world_count - live))
            ident = np.array(list(p.next_ident[:live]) + [0] * (p.world_count - live))
            table = [(self.first, np.arange(p.world_count) * block + counts), (self.room, block - counts)]
            table += [(self.serial, serial), (self.ident, ident)]
            transfer.upload([(f, np.asarray(v, np.int32)) for f, v in table] + [(self.t, clocks)])
            self._count(self.counts[k], grid["lo"], grid["cell"])
            self._top_up(k, self.counts[k], grid["lo"], grid["cell"], grid["target"], live)
            reserved = self.reserved.to_numpy()
            for w in range(live):
                made = min(int(reserved[w]), block - int(counts[w]))
                emitters.took(w, k, int(reserved[w]), made)
                counts[w] += made
                if made:
                    changed.add(w)
            p.counts.from_numpy(counts)
        if changed:
            emitters.state.particles_moved(sorted(changed))  # their lists rebuilt, as their lone runs'

    @ti.kernel
    def _count(self, count: ti.template(), lo: ti.template(), cell: ti.template()):
        """count[w, I]: world w's live particles in refill cell I."""
        p = self.p
        for J in ti.grouped(count):
            count[J] = 0
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            c, inside = self.emitters.cell_of(p.x[i], lo, cell, ti.static(count.shape[1:]))
            if inside:
                count[self._at(p.world[i], c)] += 1

    @ti.func
    def _at(self, w, c):
        return ti.Vector([w] + [c[a] for a in ti.static(range(self.emitters.dim))])

    @ti.kernel
    def _top_up(
        self, k: ti.i32, count: ti.template(), lo: ti.template(), cell: ti.template(), target: ti.i32, live: ti.i32
    ):
        """Each live world's cells' deficits below `target` seeded (Emitters._top_up's, world by world)."""
        emitters, p = self.emitters, self.p
        ti.loop_config(serialize=True)
        for w in range(live):
            self.reserved[w] = 0
            for I in ti.grouped(ti.ndrange(*count.shape[1:])):
                deficit = target - count[self._at(w, I)]
                if emitters.refills_cell(k, lo, cell, I) and deficit > 0:
                    start = self.reserved[w]
                    self.reserved[w] = start + deficit
                    for m in range(deficit):
                        slot = start + m
                        if slot < self.room[w]:
                            i = self.first[w] + slot
                            emitters.refill_particle(k, i, self.serial[w] + slot, lo, cell, I, self.t[w], w)
                            p.ident[i] = self.ident[w] + slot
                            p.world[i] = w

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
            serial, _, emitted = emitters.counters(w)
            for k, wanted_count in enumerate(due):
                count = emitters.room_for(k, wanted_count, block - int(counts[w]))
                if count:
                    rows.append((k, w * block + int(counts[w]), serial[k], p.next_ident[w], w, count, t))
                    serial[k] += count
                    emitted[k] += count
                    p.next_ident[w] += count
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

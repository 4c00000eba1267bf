"""Measurements of a running simulation, composed from what each term measures (physics/term.py's `measures`).

One kernel sums (or takes the maximum of) every declared measure over the particles, the springs and each
particle's pairs into 0-d fields: Taichi accumulates a 0-d field per thread and adds once per thread at a loop's
end, where `field[k] += ...` on one field of many is one contended atomic per item. The kernel copies them into
host arrays it is given as arguments (reading fields back would compile a copy kernel each). The motion's own
measures (kinetic energy, mass, the largest speed, non-finite particles: `Motion`) are always there; the pairs' (the
costliest: a scan of the cell grid) may be skipped and the last values kept. A simulation of many worlds
(core/worlds.py) is measured a world at a time: the kernel sums that world's particles, springs and pairs, in the
order a lone run sums them.
"""

import numpy as np
import taichi as ti

from ..config.quantities import check_measures
from ..core import runtime
from ..core.oriented import data_oriented
from ..core.worlds import world_of
from ..physics.term import TERMS, Measure


@data_oriented
class Motion:
    """The measures every simulation has: kinetic energy, mass, the largest speed, non-finite particles, and the
    mass-weighted height (y, the axis every scene's gravity runs along)."""

    measures = (
        Measure("ke", "sum", "particles"),  # kinetic energy, sum of m v^2 / 2
        Measure("mass", "sum", "particles"),
        Measure("vmax", "max", "particles"),  # the largest speed
        Measure("bad", "count", "particles"),  # particles with a non-finite or huge coordinate
        Measure("mass_height", "sum", "particles"),  # sum of m y: the centre of mass's height times the mass
    )

    def __init__(self, particles, dim: int):
        self.p, self.dim = particles, dim

    @ti.func
    def measure_particle(self, i):
        """(m v^2 / 2, m, |v|, 1 if not finite, m y) of particle i."""
        p = self.p
        v2 = p.v[i].dot(p.v[i])
        finite = 1
        for a in ti.static(range(self.dim)):
            if not (ti.abs(p.x[i][a]) < 1e30 and ti.abs(p.v[i][a]) < 1e30):
                finite = 0
        return 0.5 * p.mass[i] * v2, p.mass[i], ti.sqrt(v2), 1 - finite, p.mass[i] * p.x[i][1]


def declared_measures() -> set[str]:
    """Every measure name any term class (physics/term.TERMS) or the motion declares, and the particle count "n"."""
    return {m.name for owner in (Motion, *TERMS) for m in owner.measures} | {"n"}


@data_oriented
class Diagnostics:
    """The measuring kernel of `terms` over `state` (with `hood`'s grid for the pair measures)."""

    def __init__(self, model, state, terms: list, hood):
        check_measures(declared_measures())
        self.state, self.hood, self.loops, self.dim = state, hood, model.loops, model.dim
        self.p = state.particles
        self.springs = state.springs
        self.worlds = model.worlds
        real = ti.f64 if model.arch in ("cpu", "cuda") else ti.f32
        self.owners = [Motion(self.p, self.dim)] + [t for t in terms if t.measures]
        self.real_names, self.int_names = [], []
        for owner in self.owners:
            for m in owner.measures:
                (self.int_names if m.kind == "count" else self.real_names).append(m.name)
        # where each sum, maximum and count starts: (is a count, slot, start)
        self.starts = [(m.kind == "count", self._slot(m), m.start) for o in self.owners for m in o.measures]
        self.acc = [ti.field(real, shape=()) for _ in self.real_names]
        self.count = [ti.field(ti.i32, shape=()) for _ in self.int_names]
        self._real = np.zeros(len(self.real_names), np.float64 if real == ti.f64 else np.float32)
        self.n_counts = len(self.int_names)
        self._int = np.zeros(self.n_counts + 1, np.int32)  # the counts, then the particle count
        self.has_springs = self.springs is not None and self._over("springs")
        self.has_pairs = self._over("pairs")
        self._last_pairs: dict[int, dict] = {}  # by world: the pair measures last taken (pairs=False reuses them)

    def _over(self, over: str) -> list:
        """(term, [(measure, slot)]) for each measuring term with measures over `over`; slot indexes acc or count."""
        out = []
        for owner in self.owners:
            picked = [(m, self._slot(m)) for m in owner.measures if m.over == over]
            if picked:
                out.append((owner, picked))
        return out

    def _slot(self, m: Measure) -> int:
        return self.int_names.index(m.name) if m.kind == "count" else self.real_names.index(m.name)

    def measure(self, pairs: bool = True, world: int = 0) -> dict:
        """Every measure of world `world` now, by name (and `n`: its particle count). `pairs` False skips the pair
        measures' scan and reports the last ones taken."""
        self.state.refresh_derived()
        pairs = pairs or world not in self._last_pairs
        if pairs and self.has_pairs and self.hood is not None:
            self.hood.grid.rebuild()
        with runtime.without_cfg_pass():  # run at most once a frame: see core/transfer.py's docstring
            self._measure(pairs, self._real, self._int, world)
        values = {name: float(v) for name, v in zip(self.real_names, self._real)}
        values.update({name: int(v) for name, v in zip(self.int_names, self._int)})
        values["n"] = int(self._int[-1])
        pair_names = [m.name for _, picked in self._over("pairs") for m, _ in picked]
        if pairs:
            self._last_pairs[world] = {name: values[name] for name in pair_names}
        else:
            values.update(self._last_pairs[world])
        return values

    @ti.func
    def _add(self, picked: ti.template(), values):
        """Accumulate a term's values (one per measure in `picked`, in order) into their 0-d fields."""
        for k in ti.static(range(len(picked))):
            if ti.static(picked[k][0].kind == "sum"):
                self.acc[picked[k][1]][None] += values[k]
            elif ti.static(picked[k][0].kind == "max"):
                ti.atomic_max(self.acc[picked[k][1]][None], values[k])
            else:
                self.count[picked[k][1]][None] += values[k]

    @ti.func
    def world_block(self, world):
        """(first, last + 1): the slots of world `world`'s live particles (every live one, with one world)."""
        first, last = 0, self.p.n[None]
        if ti.static(self.worlds > 1):
            first, last = self.p.world_slots(world)
        return first, last

    @ti.func
    def _in(self, i, world):
        """Whether particle i is of the world measured (always, with one world)."""
        inside = True
        if ti.static(self.worlds > 1):
            inside = world_of(self.p, i) == world
        return inside

    @ti.kernel
    def _measure(self, pairs: ti.template(), real_out: ti.types.ndarray(), int_out: ti.types.ndarray(), world: ti.i32):
        for is_count, slot, start in ti.static(self.starts):
            if ti.static(is_count):
                self.count[slot][None] = 0
            else:
                self.acc[slot][None] = start
        # a world's particles are one block of n / worlds slots (core/worlds.py): a loop over that block alone sums
        # them as the lone run's loop does (a loop over every slot that skipped the others' grouped the sums in
        # other vector lanes: an ulp off where a world's block did not start on a multiple of the lanes)
        first, last = self.world_block(world)
        self.loops.light()
        for i in range(first, last):
            for term, picked in ti.static(self._over("particles")):
                self._add(picked, term.measure_particle(i))
        if ti.static(self.has_springs):
            self.loops.light()
            for s in range(self.springs.span[None]):
                if self._in(self.springs.i[s], world):
                    for term, picked in ti.static(self._over("springs")):
                        self._add(picked, term.measure_spring(s))
        if ti.static(pairs and self.has_pairs):
            self.loops.pairs()
            for i in range(first, last):
                for term, picked in ti.static(self._over("pairs")):
                    self._add(picked, term.measure_pairs(i))
        for term, picked in ti.static(self._over("value")):
            values = term.measure_value(world)
            for k in ti.static(range(len(picked))):
                if ti.static(picked[k][0].kind == "count"):
                    self.count[picked[k][1]][None] = values[k]
                else:
                    self.acc[picked[k][1]][None] = values[k]
        for k in ti.static(range(len(self.real_names))):
            real_out[k] = self.acc[k][None]
        for k in ti.static(range(len(self.int_names))):
            int_out[k] = self.count[k][None]
        int_out[self.n_counts] = last - first

"""Heat sources and the ambient, acting on the particles within `reach` of a source's region in one of three modes:
"exchange" (each receives G (T_source - T_i)), "fixed" (held at T_source after every step: a Dirichlet boundary) or
"power" (a total heat rate P shared in proportion to mass among the particles inside). A source's temperature or
power may follow a schedule (piecewise constant in time, optionally repeating). Every particle also exchanges
G_amb (T_ambient - T_i) with the ambient, a live control (the window's slider). With many worlds (core/worlds.py)
each world has its own ambient and its own sources' temperatures or powers (its sliders), on the one clock they share.
"""

import numpy as np
import taichi as ti

from ..config.scene_tables import SOURCE_MODES
from ..core import transfer
from ..core.oriented import data_oriented
from ..core.worlds import add_to_entry, at, clear_table, entry, per_world, per_world_table, set_world_entry, world_of

EXCHANGE, FIXED, POWER = (SOURCE_MODES.index(m) for m in ("exchange", "fixed", "power"))


@data_oriented
class HeatSources:
    """The [heat] table's sources and ambient as small fields, and their flows into a particle as Taichi funcs."""

    def __init__(self, heat_scene, dim: int, particles, phase, loops):
        self.dim, self.p, self.phase, self.loops = dim, particles, phase, loops
        self.worlds = particles.world_count if particles.worlds else 1
        self.specs = list(heat_scene.sources)
        self.n_sources = len(self.specs)
        ns = max(self.n_sources, 1)
        modes = [SOURCE_MODES.index(src.mode) for src in self.specs]
        self.has_fixed = FIXED in modes  # static flags: scenes without such sources compile none of their code
        self.has_power = POWER in modes
        self.src_lo = ti.Vector.field(dim, float, shape=ns)  # source region lower corner, widened by its reach
        self.src_hi = ti.Vector.field(dim, float, shape=ns)  # source region upper corner, widened by its reach
        self.src_mode = ti.field(ti.i32, shape=ns)  # index into SOURCE_MODES
        # temperature (degrees) or, for power sources, heat / time: (sources,), or (worlds, sources) with many worlds
        self.src_value = per_world_table(self.worlds, float, ns)
        self.src_conductance = ti.field(float, shape=ns)  # heat per time per degree, per particle
        self.src_mass = per_world_table(self.worlds, float, ns)  # power sources: mass inside, summed each step
        self.ambient = per_world(self.worlds, float)  # degrees, per world
        self.ambient_exchange = ti.field(float, shape=())  # heat per time per degree, per particle
        values = [source_value(src, 0.0) for src in self.specs]
        worlds = self.worlds
        every = (lambda v: np.full(worlds, v)) if worlds > 1 else (lambda v: v)  # noqa: E731
        # in the build's one copy (a host write of a field element compiles a writer kernel of its own)
        transfer.upload(
            [
                (self.ambient, every(heat_scene.ambient)),
                (self.ambient_exchange, heat_scene.ambient_exchange),
                (self.src_lo, np.array([np.asarray(src.lo) - src.reach for src in self.specs]).reshape(-1, dim)),
                (self.src_hi, np.array([np.asarray(src.hi) + src.reach for src in self.specs]).reshape(-1, dim)),
                (self.src_mode, np.array(modes, np.int32)),
                (self.src_conductance, np.array([src.conductance for src in self.specs], float)),
                (self.src_value, np.array(values, float) if worlds == 1 else _every_world(values, worlds, ns)),
            ]
        )
        self._values: list[list[float]] = [list(values) for _ in range(worlds)]  # by world: last written to src_value
        # by world: the sources set by hand (the window's sliders), whose schedules no longer apply
        self.by_hands: list[set[int]] = [set() for _ in range(worlds)]

    @property
    def by_hand(self) -> set[int]:
        """The sources set by hand in a lone run (world 0's)."""
        return self.by_hands[0]

    @property
    def scheduled(self) -> bool:
        return any(src.schedule_times for src in self.specs)

    def set_time(self, times: list[float]) -> None:
        """Apply the sources' schedules at each world's simulated time `times[w]` (a host-side write of the values
        that changed)."""
        for w in range(self.worlds):
            for k, src in enumerate(self.specs):
                if k not in self.by_hands[w]:
                    self._write(k, source_value(src, times[w]), w)

    def value(self, k: int, world: int = 0) -> float:
        """Source k's temperature (degrees) or power (heat / time) now, in world `world`."""
        return float(self._values[world][k])

    def hold(self, k: int, value: float, world: int = 0) -> None:
        """Set source k's temperature or power by hand in world `world`; its schedule no longer applies there."""
        self.by_hands[world].add(k)
        self._write(k, float(value), world)

    def release(self, k: int, value: float, world: int = 0) -> None:
        """Set source k's value in world `world` as its schedule (or the scene) has it, no longer held by hand."""
        self.by_hands[world].discard(k)
        self._write(k, float(value), world)

    def _write(self, k: int, value: float, world: int) -> None:
        if value != self._values[world][k]:
            if self.worlds > 1:
                self.src_value[world, k] = value
            else:
                self.src_value[k] = value
            self._values[world][k] = value

    def set_ambient(self, value: float, world: int | None = None) -> None:
        """The air's temperature (degrees) in world `world` (None: in every world)."""
        set_world_entry(self.ambient, self.worlds, world, float(value))

    @ti.func
    def inside(self, k, xi):
        """Is position xi within the (reach-widened) region of source k?"""
        result = True
        for a in ti.static(range(self.dim)):
            if xi[a] < self.src_lo[k][a] or xi[a] > self.src_hi[k][a]:
                result = False
        return result

    @ti.func
    def sum_masses(self):
        """The mass inside each power source (they share their power by mass)."""
        clear_table(self.src_mass)
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            for k in range(self.n_sources):
                if self.src_mode[k] == POWER and self.inside(k, self.p.x[i]):
                    add_to_entry(self.src_mass, world_of(self.p, i), k, self.p.mass[i])

    @ti.func
    def held(self, i, h):
        """Specific enthalpy of particle i after fixed sources: their temperature's enthalpy inside them, else h."""
        for k in range(self.n_sources):
            if self.src_mode[k] == FIXED and self.inside(k, self.p.x[i]):
                h = self.phase.enthalpy(entry(self.src_value, world_of(self.p, i), k), self.p.material[i])
        return h

    @ti.func
    def flow(self, i):
        """Heat flow rate into i from the sources it touches and from the ambient."""
        g, gt = self.terms(i)
        return gt - g * self.p.T[i]

    @ti.func
    def terms(self, i):
        """(G, G T_s summed) over the ambient and the sources particle i touches: their flow is G T_s - G T_i
        (a power source adds its share of power to the second term)."""
        xi = self.p.x[i]
        w = world_of(self.p, i)
        g = self.ambient_exchange[None]
        gt = g * at(self.ambient, w)
        for k in range(self.n_sources):
            if self.inside(k, xi):
                if self.src_mode[k] == EXCHANGE:
                    g += self.src_conductance[k]
                    gt += self.src_conductance[k] * entry(self.src_value, w, k)
                elif self.src_mode[k] == POWER:
                    gt += entry(self.src_value, w, k) * self.p.mass[i] / ti.max(entry(self.src_mass, w, k), 1e-30)
        return g, gt


def _every_world(values: list[float], worlds: int, slots: int) -> np.ndarray:
    """The sources' `values` for each of `worlds` worlds, (worlds, slots) (slots: at least one, used or not)."""
    table = np.zeros((worlds, slots))
    table[:, : len(values)] = values
    return table


def source_value(src, t: float) -> float:
    """A source's temperature (or power) at time t: its schedule's value in force at t, else its fixed value."""
    return scheduled_value(src, src.power if src.mode == "power" else src.temperature, t)


def schedule_flag(value: float) -> str | None:
    """The check of a control's "scheduled" flag (a scheduled heater's power or lid's pressure): 0 set by hand, 1
    following the scene's schedule."""
    return None if value in (0.0, 1.0) else f"expected 0 (set by hand) or 1 (scheduled), got {value:g}"


def set_by_hand(table, values: dict) -> bool:
    """Whether a control with a schedule is set by hand after `values` are applied: without a schedule always, else
    unless the values carry "scheduled": 1 (a state file's record; a slider's value has no flag)."""
    return not table.schedule_times or values.get("scheduled", 0.0) == 0.0


def scheduled_value(table, base: float, t: float) -> float:
    """The value in force at time t of a table with a schedule (`schedule_times`, `schedule_values`,
    `schedule_period`: a heat source, the molecular heater): its schedule's, else `base`."""
    if not table.schedule_times:
        return float(base)
    times = table.schedule_times
    if table.schedule_period > 0:
        t = t % table.schedule_period
    k = int(np.searchsorted(times, t, side="right")) - 1
    return float(table.schedule_values[k]) if k >= 0 else float(base)


def scheduled_start(table, base: str) -> dict:
    """The live controls a scheduled setting starts with (`base`: its key in `table`, "power" or "pressure"): its
    value at time 0, and "scheduled": 1 where the table has a schedule (0 without: as if set by hand)."""
    return {base: scheduled_value(table, getattr(table, base), 0.0), "scheduled": 1.0 if table.schedule_times else 0.0}


class ScheduledSetting:
    """A live setting of each world that follows a scene table's schedule until it is set by hand there (the
    molecular heater's power, the lid's pressure): `values[w]` is world w's value now."""

    def __init__(self, table, base: str, worlds: int) -> None:
        """`base`: the setting's key in `table`; `worlds`: the worlds it has a value for."""
        self.table, self.base = table, base
        start = scheduled_start(table, base)
        self.values = [start[base]] * worlds
        self.by_hands = [start["scheduled"] == 0.0] * worlds  # set by hand (or never scheduled): no schedule
        self.written: tuple | None = None  # (values, factor) the last write() wrote

    def controls(self, world: int = 0) -> dict:
        """World `world`'s value, and "scheduled": 1 while it follows the schedule, 0 once set by hand."""
        return {self.base: self.values[world], "scheduled": 0.0 if self.by_hands[world] else 1.0}

    def apply(self, values: dict, world: int | None = None) -> None:
        """Take `values` (controls()'s names; the value already checked) in world `world` (None: every world):
        without "scheduled": 1 (a state file's record) the value is set by hand and the schedule stops there."""
        for w in range(len(self.values)) if world is None else (world,):
            if self.base in values:
                self.values[w] = float(values[self.base])
            self.by_hands[w] = set_by_hand(self.table, values)

    def follow(self, times: list[float]) -> None:
        """Each world not set by hand takes its schedule's value at its own time `times[w]`."""
        for w, by_hand in enumerate(self.by_hands):
            if not by_hand:
                self.values[w] = scheduled_value(self.table, getattr(self.table, self.base), times[w])

    def write(self, field, factor: float) -> None:
        """Every world's value times `factor` into `field` (an entry a world), only where they changed since the last
        write (a copy costs about 0.2 ms: as much as a small scene's step)."""
        if (self.values, factor) != self.written:
            field.from_numpy(np.array(self.values) * factor)
            self.written = (list(self.values), factor)

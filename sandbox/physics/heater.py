"""The molecular model's heater: heat shared evenly among the atoms at a set power, keeping momentum.

`[molecular.heater]` (power P, energy per time; negative cools) gives the atoms P dt of kinetic energy after each
step, as a stove under a whole pot would, by scaling every atom's velocity about the atoms' centre-of-mass velocity u:

    v_i <- u + lambda (v_i - u),    lambda^2 = 1 + P dt / K,    K = sum_i m_i |v_i - u|^2 / 2

so the total momentum M u is untouched and the kinetic energy changes by exactly (lambda^2 - 1) K = P dt. Each atom's
motion relative to the others grows (or shrinks) in proportion: nothing stirs a flow, and the pair forces share the
heat out from there. The heat it moved is summed (`heater_heat`), so the total energy of the atoms changes by that sum
and the thermal walls' (within the integrator's drift). Cooling stops at rest: where -P dt would take more than K,
lambda is 0 and only K is taken (the sum records what was taken). The sums run in double precision in one fixed
order, so a run repeats bit for bit in any thread order. The power is a live setting (`heater.power`, the heater
slider); it may follow a schedule (`schedule_times`, `schedule_values`, `schedule_period`, as a heat source's) until
it is set by hand. PhET's States of Matter heats the same way (by scaling velocities), without keeping momentum.
With many worlds (core/worlds.py) each world has its own power (its slider; its schedule on the world's own clock)
and shares it among its own atoms, its sums taken in its lone run's order.
"""

import math

import taichi as ti

from ..config.molecular_table import Heater as HeaterTable
from ..config.schema import key_check
from ..core.oriented import data_oriented
from ..core.state import WORLDS
from ..core.worlds import at, per_world, put_at, world_of
from .heat_sources import ScheduledSetting, schedule_flag
from .term import Measure, Slider, Term, register


@register
@data_oriented
class Heater(Term):
    """The molecular model's even heater (module docstring); `moved`: the energy it has given the atoms."""

    key = "heater"
    stage = "thermal_walls"
    measures = (Measure("heater_heat", "sum", "value"),)

    @staticmethod
    def wanted(parts) -> bool:
        molecular = parts.scene.molecular
        return bool(molecular and molecular.heater)

    @staticmethod
    def host_work(scene) -> str | None:
        if scene.molecular and scene.molecular.heater:
            return "the heater shares its energy among the atoms after each step"
        return None

    def __init__(self, parts):
        self.p, self.loops = parts.state.particles, parts.model.loops
        self.dim = parts.model.dim
        self.spec = parts.scene.molecular.heater
        self.worlds = worlds = parts.model.worlds
        self.setting = ScheduledSetting(self.spec, "power", worlds)  # each world's power, on its schedule or by hand
        self.moved = per_world(worlds, ti.f64)  # energy the heater has given the atoms (energy), per world
        self.centre = per_world(worlds, ti.f64, self.dim)  # u of the last step (length / time)
        self.scale = per_world(worlds, ti.f64)  # lambda of the last step
        self.energy = per_world(worlds, ti.f64) if worlds > 1 else None  # P dt of each world this step

    power = property(lambda self: self.setting.values[0], doc="the power of a lone run (world 0's)")

    def declare(self, state) -> None:
        state.declare("heater", self, ("moved",), rows=WORLDS if self.worlds > 1 else "")

    world_controls = True  # each world's heater has its own power (core/worlds.py)

    def controls(self, world: int = 0) -> dict:
        """The power, and whether it still follows the scene's schedule (1) or was set by hand (0), in world
        `world`."""
        return self.setting.controls(world)

    def sliders(self) -> list[Slider]:
        """The power: positive heats, negative cools, up to twice the scene's (1 at least)."""
        top = max(2.0 * max([abs(self.spec.power), *map(abs, self.spec.schedule_values)]), 1.0)
        return [Slider("heater", "heater power", "power", -top, top, "power", top / 200)]

    def control_checks(self) -> dict:
        return {"power": key_check(HeaterTable, "power"), "scheduled": schedule_flag}

    def apply_controls(self, values: dict, world: int | None = None) -> None:
        """Set the power in world `world` (None: every world); without "scheduled": 1 (a state file's record) it is
        set by hand and the schedule stops."""
        if "power" in values:
            value = float(values["power"])
            if not math.isfinite(value):
                raise ValueError(f"heater power {value!r}; expected a finite number (negative cools)")
        self.setting.apply(values, world)

    def words(self, where: str) -> list[str]:
        if where == "after":
            return [f"heater: {self.power:g} energy per time shared among the atoms, keeping momentum"]
        return []

    def after_step(self, state) -> None:
        self.setting.follow(state.world_times())  # the power in force at the start of the step just taken
        if self.worlds == 1:
            if self.power != 0.0:
                self._heat(self.power * state.dt)
        elif any(self.setting.values):
            self.setting.write(self.energy, state.dt)
            self._heat_worlds()

    @ti.func
    def measure_value(self, w):
        return (at(self.moved, w),)

    @ti.kernel
    def _heat(self, energy: ti.f64):
        n = self.p.n[None]
        ti.loop_config(serialize=True)  # one item: waking the thread pool would cost more than the sums
        for _ in range(1):  # the sums in one fixed order (double precision): repeatable in any thread order
            self._share(0, 0, n, energy)
        self.loops.light()
        for i in range(n):
            self._scale(i, 0)

    @ti.kernel
    def _heat_worlds(self):
        """Each world's P dt (`energy`) shared among its own live atoms (Particles.world_slots); a world given none
        is left untouched."""
        worlds = self.p.n[None] // self.p.world_size
        self.loops.light()
        for w in range(worlds):  # a world to a thread; its sums in its lone run's order
            if self.energy[w] != 0.0:
                first, end = self.p.world_slots(w)
                self._share(w, first, end, self.energy[w])
        self.loops.light()
        for i in range(worlds * self.p.world_size):
            if self.p.idle(i):
                continue
            w = world_of(self.p, i)
            if self.energy[w] != 0.0:
                self._scale(i, w)

    @ti.func
    def _share(self, w, first, last, energy):
        """World w's centre-of-mass velocity u and scale lambda for `energy` shared among particles first .. last - 1
        (serial sums in double precision), and the energy moved added to its gauge."""
        p = self.p
        mass = ti.cast(0.0, ti.f64)
        momentum = ti.Vector.zero(ti.f64, self.dim)
        for i in range(first, last):
            if p.mass[i] > 0.0:
                mass += ti.cast(p.mass[i], ti.f64)
                momentum += ti.cast(p.mass[i], ti.f64) * ti.cast(p.v[i], ti.f64)
        u = momentum / ti.max(mass, 1e-300)
        kinetic = ti.cast(0.0, ti.f64)
        for i in range(first, last):
            if p.mass[i] > 0.0:
                d = ti.cast(p.v[i], ti.f64) - u
                kinetic += 0.5 * ti.cast(p.mass[i], ti.f64) * d.dot(d)
        gain = ti.max(energy, -kinetic)  # cooling stops at rest
        scale = ti.cast(1.0, ti.f64)
        if kinetic > 0.0:
            scale = ti.sqrt(1.0 + gain / kinetic)
            put_at(self.moved, w, at(self.moved, w) + gain)
        put_at(self.centre, w, u)
        put_at(self.scale, w, scale)

    @ti.func
    def _scale(self, i, w):
        """Particle i's velocity scaled about its world's centre-of-mass velocity (world w's u and lambda)."""
        p = self.p
        if p.mass[i] > 0.0:
            u = at(self.centre, w)
            p.v[i] = ti.cast(u + at(self.scale, w) * (ti.cast(p.v[i], ti.f64) - u), p.v.dtype)

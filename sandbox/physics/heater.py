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
"""

import math

import taichi as ti

from ..config.molecular_table import Heater as HeaterTable
from ..config.schema import key_check
from ..core.oriented import data_oriented
from .heat_sources import schedule_flag, scheduled_value, set_by_hand
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
        self.p = parts.state.particles
        self.dim = parts.model.dim
        self.spec = parts.scene.molecular.heater
        self.power = scheduled_value(self.spec, self.spec.power, 0.0)
        self.by_hand = not self.spec.schedule_times  # set by hand (or never scheduled): the schedule no longer applies
        self.moved = ti.field(ti.f64, shape=())  # energy the heater has given the atoms (energy)
        self.centre = ti.Vector.field(self.dim, ti.f64, shape=())  # u of the last step (length / time)
        self.scale = ti.field(ti.f64, shape=())  # lambda of the last step

    def declare(self, state) -> None:
        state.declare("heater", self, ("moved",))

    def controls(self) -> dict:
        """The power, and whether it still follows the scene's schedule (1) or was set by hand (0)."""
        return {"power": self.power, "scheduled": 0.0 if self.by_hand else 1.0}

    def sliders(self) -> list[Slider]:
        """The power: positive heats, negative cools, up to twice the scene's (1 at least)."""
        top = max(2.0 * max([abs(self.spec.power), *map(abs, self.spec.schedule_values)]), 1.0)
        return [Slider("heater", "heater power", "power", -top, top, "power", top / 200)]

    def control_checks(self) -> dict:
        return {"power": key_check(HeaterTable, "power"), "scheduled": schedule_flag}

    def apply_controls(self, values: dict) -> None:
        """Set the power; without "scheduled": 1 (a state file's record) it is set by hand and the schedule stops."""
        if "power" in values:
            value = float(values["power"])
            if not math.isfinite(value):
                raise ValueError(f"heater power {value!r}; expected a finite number (negative cools)")
            self.power = value
        self.by_hand = set_by_hand(self.spec, values)

    def words(self, where: str) -> list[str]:
        if where == "after":
            return [f"heater: {self.power:g} energy per time shared among the atoms, keeping momentum"]
        return []

    def after_step(self, state) -> None:
        if not self.by_hand:  # the power in force at the start of the step just taken (the clock moves on after)
            self.power = scheduled_value(self.spec, self.spec.power, state.time)
        if self.power != 0.0:
            self._heat(self.power * state.dt)

    @ti.func
    def measure_value(self, w):
        return (self.moved[None],)

    @ti.kernel
    def _heat(self, energy: ti.f64):
        p = self.p
        n = p.n[None]
        for _ in range(1):  # the sums in one fixed order (double precision): repeatable in any thread order
            mass = ti.cast(0.0, ti.f64)
            momentum = ti.Vector.zero(ti.f64, self.dim)
            for i in range(n):
                if p.mass[i] > 0.0:
                    mass += ti.cast(p.mass[i], ti.f64)
                    momentum += ti.cast(p.mass[i], ti.f64) * ti.cast(p.v[i], ti.f64)
            u = momentum / ti.max(mass, 1e-300)
            kinetic = ti.cast(0.0, ti.f64)
            for i in range(n):
                if p.mass[i] > 0.0:
                    d = ti.cast(p.v[i], ti.f64) - u
                    kinetic += 0.5 * ti.cast(p.mass[i], ti.f64) * d.dot(d)
            gain = ti.max(energy, -kinetic)  # cooling stops at rest
            scale = ti.cast(1.0, ti.f64)
            if kinetic > 0.0:
                scale = ti.sqrt(1.0 + gain / kinetic)
                self.moved[None] += gain
            self.centre[None], self.scale[None] = u, scale
        for i in range(n):
            if p.mass[i] > 0.0:
                u = self.centre[None]
                p.v[i] = ti.cast(u + self.scale[None] * (ti.cast(p.v[i], ti.f64) - u), p.v.dtype)

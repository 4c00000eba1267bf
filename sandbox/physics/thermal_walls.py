"""Thermal walls: heaters and coolers of the molecular model that keep momentum in the bulk and say what they moved.

A thermal wall is one wall of the box ([[molecular.walls]]: its side and temperature kT). An atom that reaches it
leaves with a velocity drawn from the wall's Maxwell distribution, as a gas molecule does from a real wall (the
diffuse, fully accommodating wall of kinetic theory): the speed away from the wall from the flux-weighted
distribution v_n = sqrt(kT / m) sqrt(-2 ln u) (u uniform in (0, 1]), each other component normal with variance
kT / m. A gas between walls at one temperature relaxes to it; between a hot floor and a cold lid heat flows through.
The atoms inside feel nothing but each other, so their motion is never stirred and momentum is kept in the bulk.

The energy each wall gives the atoms (negative: takes) is summed, 1/2 m (v_new^2 - v_old^2) at each hit, so the
total energy of the atoms changes by exactly that sum (within the integrator's drift). The wall's momentum gauge
(the pressure on the walls) counts the momentum each hit gives the wall.

The random numbers come from a counter-based hash of the atom's id and its own count of wall hits, not from a random
state: the same hit draws the same numbers in any thread order, in fused batches and after a resume.
"""

import math

import numpy as np
import taichi as ti

from ..config.molecular_table import WALL_SIDES, ThermalWall
from ..config.schema import key_check
from ..core import transfer
from ..core.oriented import data_oriented
from ..core.ranges import COUNT
from ..core.state import WORLDS
from ..core.worlds import add_at, add_to_entry, entry, per_world_table, world_of
from .agitation import normal
from .fields import random_uniform
from .term import Measure, Slider, Term, register


@register
@data_oriented
class ThermalWalls(Term):
    """The thermal walls of a molecular scene (module docstring); `moved[w]`: energy wall w gave the atoms so far;
    live temperatures as controls (`thermal_walls.<name>`)."""

    key = "thermal_walls"
    stage = "thermal_walls"
    finishes = True
    measures = (Measure("wall_heat", "sum", "value"),)

    @staticmethod
    def wanted(parts) -> bool:
        molecular = parts.scene.molecular
        return bool(molecular and molecular.walls)

    def __init__(self, parts):
        self.walls = list(parts.scene.molecular.walls)
        self.names = [w.name for w in self.walls]
        self.sides = [WALL_SIDES[w.side] for w in self.walls]  # (axis, end): compiled into the finish
        self.p = parts.state.particles
        self.domain = parts.model.domain
        self.dim = parts.model.dim
        count = len(self.walls)
        self.worlds = parts.model.worlds  # each world's walls have their own temperatures and gauges
        self.kT = per_world_table(self.worlds, float, count)  # each wall's temperature as kT (energy)
        self.moved = per_world_table(self.worlds, ti.f64, count)  # energy each wall has given the atoms (energy)
        self.hits = ti.field(ti.i32, shape=parts.model.capacity)  # each atom's thermal-wall hits: its noise counter
        parts.state.carry((self.hits,))
        self.set_temperatures([w.temperature for w in self.walls])

    def declare(self, state) -> None:
        state.declare("thermal_walls", self, ("hits",), rows="particles", valid=COUNT)
        state.declare("thermal_walls", self, ("moved",), rows=WORLDS if self.worlds > 1 else "")

    def set_temperatures(self, values: list[float], world: int | None = None) -> None:
        """Set each wall's temperature (kT, energy units), in the order of [[molecular.walls]], in world `world`
        (None: in every world)."""
        for k, value in enumerate(values):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"thermal wall {self.names[k]!r}: temperature {value!r}; expected a number above 0")
        if self.worlds == 1:
            transfer.upload([(self.kT, np.array(values, dtype=float))])  # one copy, not a kernel per element
            return
        table = self.kT.to_numpy()
        table[slice(None) if world is None else world] = values
        self.kT.from_numpy(table)

    def temperatures(self, world: int = 0) -> list[float]:
        """Each wall's temperature (kT, energy units), in world `world`."""
        table = self.kT.to_numpy()
        return [float(t) for t in (table if self.worlds == 1 else table[world])]

    def energy_moved(self, world: int = 0) -> list[float]:
        """The energy each wall has given the atoms so far (negative: taken), in [[molecular.walls]] order, in world
        `world`."""
        table = self.moved.to_numpy()
        return [float(e) for e in (table if self.worlds == 1 else table[world])]

    world_controls = True  # each world's walls have their own temperatures (core/worlds.py)

    def controls(self, world: int = 0) -> dict:
        return dict(zip(self.names, self.temperatures(world)))

    def sliders(self) -> list[Slider]:
        """The first two walls' temperatures (kT), up to twice the scene's (2 at least)."""
        return [
            Slider(f"wall{k}", f"{w.name} temperature", w.name, 0.02, max(2.0, 2.0 * w.temperature), "kT", 0.01)
            for k, w in enumerate(self.walls[:2])
        ]

    def control_checks(self) -> dict:
        return {name: key_check(ThermalWall, "temperature") for name in self.names}

    def apply_controls(self, values: dict, world: int | None = None) -> None:
        for w in range(self.worlds) if world is None else (world,):
            temps = self.temperatures(w)
            for k, name in enumerate(self.names):
                if name in values:
                    temps[k] = float(values[name])
            self.set_temperatures(temps, w if self.worlds > 1 else None)

    def words(self, where: str) -> list[str]:
        if where != "finish":
            return []
        return [f"thermal wall {w.name} ({w.side}): atoms leave at kT = {w.temperature:g}" for w in self.walls]

    def nbytes(self) -> int:
        return self.hits.shape[0] * 4

    @ti.func
    def measure_value(self, world):
        total = ti.cast(0.0, ti.f64)
        for w in ti.static(range(len(self.sides))):
            total += entry(self.moved, world, w)
        return (total,)

    @ti.func
    def finish(self, i, dt, rates: ti.template()):
        p = self.p
        x, v = p.x[i], p.v[i]
        r, m = p.radius[i], p.mass[i]
        for w in ti.static(range(len(self.sides))):
            axis, end = ti.static(self.sides[w])
            wall = self.domain.lo[axis] + r
            beyond = x[axis] < wall
            if ti.static(end > 0):
                wall = self.domain.hi[axis] - r
                beyond = x[axis] > wall
            if beyond and m > 0.0:
                k = p.ident[i]
                world = world_of(p, i)
                count = self.hits[i]
                self.hits[i] = count + 1
                s = ti.sqrt(entry(self.kT, world, w) / m)
                u = 1.0 - random_uniform(ti.cast(count, ti.u32), ti.cast(k, ti.u32), ti.cast(2 * self.dim + 1, ti.u32))
                new = v
                for b in ti.static(range(self.dim)):
                    if ti.static(b != axis):
                        new[b] = s * normal(k, count, b)
                new[axis] = -end * s * ti.sqrt(-2.0 * ti.log(u))  # away from the wall
                x[axis] = ti.min(ti.max(2.0 * wall - x[axis], self.domain.lo[axis] + r), self.domain.hi[axis] - r)
                add_to_entry(self.moved, world, w, ti.cast(0.5 * m * (new.dot(new) - v.dot(v)), ti.f64))
                add_at(self.domain.impulse, world, m * ti.abs(new[axis] - v[axis]))
                v = new
        p.x[i], p.v[i] = x, v

"""Temperature as motion: a Langevin thermostat that keeps each free particle's thermal agitation at its temperature.

Free particles (melted past half, where the springs have broken) relax their velocity relative to the local flow u_i
(the mean velocity of the other free particles within the pair cutoff, weighted 1 - r/R, the weights summed to at
least 1: where they sum to less, as in a gas, the flow shrinks toward rest) toward a Maxwell distribution at their
own temperature, by the exact Ornstein-Uhlenbeck step over dt with coupling time tau:

    v_i <- u_i + c1 (v_i - u_i) + c2 sqrt(kT_i / m_i) xi,   c1 = exp(-dt / tau),  c2 = sqrt(1 - c1^2)

with kT_i = heat.agitation_scale (pJ per kelvin) x (T_i + 273.15) and xi standard normal per component. So hot
liquid moves faster than cool liquid: its mean kinetic energy per component is kT / 2 (equipartition). Without a
neighbour grid (a scene without pair forces) the flow is taken as zero. The energy the step gives the motion is taken
from the particle's heat (1 pJ per mg is 1e-9 kJ/kg of specific enthalpy), so motion and heat together are
conserved; `moved` sums it (pJ).

The noise comes from a counter-based hash of the particle's id and the step number, not from a random state: the
same step draws the same numbers in any thread order and after a resume, so runs repeat bit for bit. The thermostat
runs between steps (the long way); scenes without heat.agitation_time > 0 do not build it.
"""

import math

import taichi as ti

from ..core.oriented import data_oriented
from .fields import random_uniform
from .term import Measure, Term, register

KELVIN = 273.15  # °C to kelvin
KJ_PER_KG_PER_PJ_PER_MG = 1e-9  # 1 pJ / 1 mg = 1e-12 J / 1e-6 kg = 1e-6 J/kg = 1e-9 kJ/kg
FREE = 0.5  # melt fraction from which a particle's motion follows its temperature (its springs break past half)


@ti.func
def normal(a, b, k):
    """A standard normal number from the counters (a, b, k): particle id, step, which number (Box-Muller on two of
    fields.py's hashed uniforms; 1 - u lies in (0, 1], so the logarithm is finite)."""
    u1 = 1.0 - random_uniform(ti.cast(b, ti.u32), ti.cast(a, ti.u32), ti.cast(2 * k, ti.u32))
    u2 = random_uniform(ti.cast(b, ti.u32), ti.cast(a, ti.u32), ti.cast(2 * k + 1, ti.u32))
    return ti.sqrt(-2.0 * ti.log(u1)) * ti.cos(2.0 * math.pi * u2)


@register
@data_oriented
class Agitation(Term):
    """The Langevin thermostat of free particles' motion to their temperature (module docstring)."""

    key = "agitation"
    stage = "thermostat"
    measures = (Measure("agitation", "sum", "particles"), Measure("free", "count", "particles"))

    @staticmethod
    def wanted(parts) -> bool:
        heat = parts.scene.heat
        return bool(heat and heat.agitation_time > 0)

    @staticmethod
    def host_work(scene) -> str | None:
        if scene.heat and scene.heat.agitation_time > 0:
            return "the thermostat's local flow and noise are computed between steps"
        return None

    def __init__(self, parts):
        self.parts = parts  # the grid it scans is built after the terms
        self.p = parts.state.particles
        self.phase = parts.model.phase
        self.dim = parts.model.dim
        heat = parts.scene.heat
        self.tau = float(heat.agitation_time)
        self.scale = float(heat.agitation_scale)
        pair = parts.scene.pair
        self.reach = float(pair.cutoff) if pair is not None else 0.0
        self.flow = ti.Vector.field(self.dim, float, shape=parts.model.capacity)  # local flow velocity, scratch
        self.is_free = ti.field(ti.i32, shape=parts.model.capacity)  # free() of each particle, for the flow's scan
        self.moved = ti.field(ti.f64, shape=())  # energy given to the motion so far (pJ; taken from the heat)

    def words(self, where: str) -> list[str]:
        if where != "after":
            return []
        return [
            f"thermostat: free particles' motion relaxes to their temperature in {self.tau:g} s "
            f"(kT = {self.scale:g} pJ/K x (T + 273.15))"
        ]

    def nbytes(self) -> int:
        return self.flow.shape[0] * (self.dim * 8 + 4)

    def after_step(self, state) -> None:
        """One thermostat step over the step just taken: the local flow, then each free particle's new velocity."""
        grid = self._grid()
        if grid is not None:
            grid.rebuild()
            self._flow_near(grid)
        else:
            self.flow.fill(0)
        self._agitate(state.dt, state.step)

    def _grid(self):
        hood = self.parts.neighbours
        return hood.grid if hood is not None and self.reach > 0 else None

    @ti.func
    def free(self, i):
        _, phi = self.phase.state(self.p.h[i], self.p.material[i])
        return phi >= FREE

    @ti.func
    def measure_particle(self, i):
        """(m |v - u|^2 / scale, 1) for a free particle, (0, 0) else: the motion's thermometer (kelvin x dim)."""
        heat, free = 0.0, 0
        if self.free(i):
            rel = self.p.v[i] - self.flow[i]
            heat, free = self.p.mass[i] * rel.dot(rel) / self.scale, 1
        return heat, free

    @ti.kernel
    def _flow_near(self, grid: ti.template()):
        for i in range(self.p.n[None]):  # once per particle, not once per pair the scan visits
            self.is_free[i] = int(self.free(i))
        for i in range(self.p.n[None]):
            if self.is_free[i]:
                acc = grid.fold(self.p.x[i], ti.Vector.zero(float, self.dim + 1), self._add_flow, (i,))
                # a particle with few free neighbours (a gas) is held about rest: its flow shrinks toward zero
                self.flow[i] = ti.Vector([acc[k] for k in ti.static(range(self.dim))]) / ti.max(acc[self.dim], 1.0)

    @ti.func
    def _add_flow(self, acc, j, d, k, extra: ti.template()):
        """acc + w (v_j, 1) for free neighbour j (not i itself) within the reach, w = 1 - r / reach."""
        r = d.norm()
        if r < self.reach and self.is_free[j] and j != extra[0]:
            w = 1.0 - r / self.reach
            for a in ti.static(range(self.dim)):
                acc[a] += w * self.p.v[j][a]
            acc[self.dim] += w
        return acc

    @ti.kernel
    def _agitate(self, dt: float, step: ti.i32):
        c1 = ti.exp(-dt / self.tau)
        c2 = ti.sqrt(1.0 - c1 * c1)
        p = self.p
        for i in range(p.n[None]):
            if self.free(i):
                t, _ = self.phase.state(p.h[i], p.material[i])
                kt = self.scale * ti.max(t + KELVIN, 0.0)
                sigma = ti.sqrt(kt / p.mass[i])
                u = self.flow[i]
                v = u + c1 * (p.v[i] - u)
                for a in ti.static(range(self.dim)):
                    v[a] += c2 * sigma * normal(p.ident[i], step, a)
                gained = 0.5 * p.mass[i] * (v.dot(v) - p.v[i].dot(p.v[i]))  # pJ
                p.v[i] = v
                p.h[i] -= gained / p.mass[i] * KJ_PER_KG_PER_PJ_PER_MG
                self.moved[None] += ti.cast(gained, ti.f64)

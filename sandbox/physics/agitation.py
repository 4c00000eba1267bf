"""Temperature as motion: a thermostat that keeps each free particle's thermal agitation at its temperature, and keeps
momentum where the particles touch.

Free particles are those melted past half, where the springs have broken. With pair forces (a neighbour grid) the
thermostat is pairwise, as dissipative particle dynamics (DPD) acting on the whole relative velocity (its
"transverse" form: the wax's own viscosity damps motion across the line of centres too, which DPD along that line
alone would never refill): each pair of free particles i, j within the pair cutoff R, weight w = 1 - r / R and
relative velocity v_ij exchanges the impulse

    dp_ij = -gamma_ij w^2 v_ij dt + sqrt(2 gamma_ij kT_ij dt) w theta_ij,    dp_ji = -dp_ij

with kT_ij = heat.agitation_scale (pJ per kelvin) x the mean of the two absolute temperatures, theta_ij a vector of
numbers of unit variance shared by the pair (unit_noise), and gamma_ij dt = 2 mu_ij s / S_ij (mu the pair's reduced
mass, S_ij the mean of the two particles' sums of w^2, at least GAS_WEIGHT): a particle's motion relative to its
neighbours loses the share s = 1 - exp(-dim dt / tau) a step, so it relaxes in about heat.agitation_time = tau (s at
most MAX_SHARE: with a step longer than a few tenths of tau the coupling is slower than asked, and stable). The
noise's variance is 2 gamma_ij kT_ij dt (1 - s / 2): what an explicit step of share s needs to keep kT (without the
factor a step of 0.4 tau ran 1.7 times too hot). The impulses are equal and opposite: a drop, a puddle or a flow
keeps its momentum (to round-off), and only the motion relative to the neighbours is thermostatted
(fluctuation-dissipation: each pair at kT_ij). The melt's viscous pair force (pair.py) gets its noise partner too,
sqrt(2 gamma_visc kT_ij w dt) along the line of centres (without it the viscosity is a second thermostat, at absolute
zero). A particle with few neighbours (a gas: its sum of w^2 under GAS_WEIGHT) is held about its local flow u_i
(below; rest for a lone particle, as a gas is held by the walls it strikes) for the share it lacks, by the exact
Ornstein-Uhlenbeck step over dt

    v_i <- u_i + c1 (v_i - u_i) + c2 sqrt(kT_i / m_i) xi,   c1 = exp(-a dt / tau),  c2 = sqrt(1 - c1^2),
    a = 1 - S_i / GAS_WEIGHT

and its noise of its own does not keep momentum (a liquid's rim has the neighbours to be pairwise only); without a
neighbour grid (a scene without pair forces) every free particle is held so, about rest (a = 1). So hot liquid moves
faster than cool liquid: its mean kinetic energy per component is kT / 2 (equipartition). The energy each step gives
a particle's motion is taken from its own heat (1 pJ per mg is 1e-9 kJ/kg of specific enthalpy), so motion and heat
together are conserved; `moved` sums it (pJ).

The noise comes from counter-based hashes of the particle ids (a pair's: both, in either order) and the step number,
not from a random state: the same step draws the same numbers in any thread order and after a resume, so runs repeat
bit for bit. The thermostat runs between steps (the long way); scenes without heat.agitation_time > 0 do not build
it. The readout `kinetic_temperature` measures the motion relative to the local flow u_i (the mean velocity of the
other free particles within R, weighted w, the weights summed to at least 1), divided by the share by which the
flow's own scatter inflates it (1 + S_i / W_i^2, W_i the sum of w, at least 1, for neighbours moving independently)."""

import math

import numpy as np
import taichi as ti

from ..core.oriented import data_oriented
from ..core.transfer import real_fields
from ..core.worlds import add_at, per_world, world_of
from .fields import random_uniform
from .term import Measure, Term, register

KELVIN = 273.15  # °C to kelvin
KJ_PER_KG_PER_PJ_PER_MG = 1e-9  # 1 pJ / 1 mg = 1e-12 J / 1e-6 kg = 1e-6 J/kg = 1e-9 kJ/kg
FREE = 0.5  # melt fraction from which a particle's motion follows its temperature (its springs break past half)
GAS_WEIGHT = 0.5  # a free particle whose neighbours' sum of w^2 is under this is partly held about its flow (a gas)
PAIR_STREAM = 16  # the pair noise's counter, apart from a particle's own (0 .. dim - 1)
MAX_SHARE = 0.3  # of a particle's motion relative to its neighbours the pair kicks damp in one step, at most


@ti.func
def normal(a, b, k):
    """A standard normal number from the counters (a, b, k): particle id, step, which number (Box-Muller on two of
    fields.py's hashed uniforms; 1 - u lies in (0, 1], so the logarithm is finite)."""
    u1 = 1.0 - random_uniform(ti.cast(b, ti.u32), ti.cast(a, ti.u32), ti.cast(2 * k, ti.u32))
    u2 = random_uniform(ti.cast(b, ti.u32), ti.cast(a, ti.u32), ti.cast(2 * k + 1, ti.u32))
    return ti.sqrt(-2.0 * ti.log(u1)) * ti.cos(2.0 * math.pi * u2)


@ti.func
def unit_noise(a, b, k):
    """A number of mean 0 and variance 1 from the counters (a, b, k), uniform on [-sqrt 3, sqrt 3]: the pairs' noise
    (a pair's kick needs only the right variance, the velocities' Maxwell shape comes from many kicks; a uniform
    number costs a hash where a normal one costs two and a logarithm and a cosine)."""
    u = random_uniform(ti.cast(b, ti.u32), ti.cast(a, ti.u32), ti.cast(k, ti.u32))
    return (2.0 * u - 1.0) * ti.sqrt(3.0)


@register
@data_oriented
class Agitation(Term):
    """The thermostat of free particles' motion to their temperature: pairwise where they touch (module docstring)."""

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
        self.weight = ti.field(float, shape=parts.model.capacity)  # each free particle's sum of w^2 over neighbours
        self.wsum = ti.field(float, shape=parts.model.capacity)  # and its sum of w
        self.kt = ti.field(float, shape=parts.model.capacity)  # each free particle's kT (pJ), for its pairs
        self.visc_sum = ti.field(float, shape=parts.model.capacity)  # and its sum of the viscosity's gamma w
        self.v_new = ti.Vector.field(self.dim, float, shape=parts.model.capacity)  # velocities after the pair kicks
        # the melt's viscosity (pair.py's viscous force, materials mixed by arithmetic means), whose noise the kicks add
        visc = np.array([m.viscosity for m in parts.model.material_list], float)
        self.visc_np = 0.5 * (visc[:, None] + visc[None, :]) if pair is not None else np.zeros((1, 1))
        (self.visc,) = real_fields(self.visc_np)
        self.viscous = bool(np.any(self.visc_np > 0))
        # energy given to the motion so far (pJ; taken from the heat), per world (core/worlds.py)
        self.moved = per_world(parts.model.worlds, ti.f64)

    def words(self, where: str) -> list[str]:
        if where != "after":
            return []
        return [
            f"thermostat: free particles' motion relaxes to their temperature in {self.tau:g} s "
            f"(kT = {self.scale:g} pJ/K x (T + 273.15))"
        ]

    def nbytes(self) -> int:
        return self.flow.shape[0] * (2 * self.dim * 8 + 4 + 32)

    def after_step(self, state) -> None:
        """One thermostat step over the step just taken: the local flow, then each free particle's new velocity."""
        grid = self._grid()
        if grid is not None:
            grid.rebuild()
            self._flow_near(grid)
            self._pair_kicks(grid, state.dt, state.step)
        else:
            self.flow.fill(0)
            self.weight.fill(0)
            self.wsum.fill(0)
            self.visc_sum.fill(0)
        self._agitate(state.dt, state.step, int(grid is not None))

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
            inflated = 1.0 + self.weight[i] / ti.max(self.wsum[i], 1.0) ** 2  # the flow's own scatter
            heat, free = self.p.mass[i] * rel.dot(rel) / self.scale / inflated, 1
        return heat, free

    @ti.kernel
    def _flow_near(self, grid: ti.template()):
        for i in range(self.p.n[None]):  # once per particle, not once per pair the scan visits
            if self.p.idle(i):
                continue
            t, phi = self.phase.state(self.p.h[i], self.p.material[i])
            self.is_free[i] = int(phi >= FREE)
            self.kt[i] = self.scale * ti.max(t + KELVIN, 0.0)
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.weight[i] = 0.0
            self.wsum[i] = 0.0
            self.visc_sum[i] = 0.0
            if self.is_free[i]:
                acc = grid.fold(i, self.p.x[i], ti.Vector.zero(float, self.dim + 3), self._add_flow, (i,))
                # a particle with few free neighbours (a gas) is measured about rest: its flow shrinks toward zero
                self.flow[i] = ti.Vector([acc[k] for k in ti.static(range(self.dim))]) / ti.max(acc[self.dim], 1.0)
                self.weight[i] = acc[self.dim + 1]
                self.wsum[i] = acc[self.dim]
                self.visc_sum[i] = acc[self.dim + 2]

    @ti.func
    def _add_flow(self, acc, j, d, k, extra: ti.template()):
        """acc + (w v_j, w, w^2) for free neighbour j (not i itself) within the reach, w = 1 - r / reach."""
        r = d.norm()
        if r < self.reach and self.is_free[j] and j != extra[0]:
            w = 1.0 - r / self.reach
            for a in ti.static(range(self.dim)):
                acc[a] += w * self.p.v[j][a]
            acc[self.dim] += w
            acc[self.dim + 1] += w * w
            if ti.static(self.viscous):
                acc[self.dim + 2] += self.visc[self.p.material[extra[0]], self.p.material[j]] * w
        return acc

    @ti.kernel
    def _pair_kicks(self, grid: ti.template(), dt: float, step: ti.i32):
        """Each free particle's velocity after its pairs' equal and opposite impulses (module docstring), into v_new:
        every pair is computed from both ends alike, so the two impulses cancel to the last bit."""
        p = self.p
        share = ti.min(1.0 - ti.exp(-self.dim * dt / self.tau), MAX_SHARE)  # of the relative motion damped a step
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            self.v_new[i] = p.v[i]
            if self.is_free[i]:
                impulse = grid.fold(i, p.x[i], ti.Vector.zero(float, self.dim), self._add_kick, (i, share, step, dt))
                self.v_new[i] = p.v[i] + impulse / p.mass[i]

    @ti.func
    def _add_kick(self, acc, j, d, k, extra: ti.template()):
        """acc + the impulse free neighbour j gives particle i = extra[0] (d = x_j - x_i)."""
        i, share, step, dt = extra[0], extra[1], extra[2], extra[3]
        r = d.norm()
        if r < self.reach and r > 0.0 and self.is_free[j] and j != i:
            p = self.p
            w = 1.0 - r / self.reach
            mu = p.mass[i] * p.mass[j] / (p.mass[i] + p.mass[j])
            gamma_dt = 2.0 * mu * share / ti.max(0.5 * (self.weight[i] + self.weight[j]), GAS_WEIGHT)
            kt = 0.5 * (self.kt[i] + self.kt[j])
            lo, hi = ti.min(p.ident[i], p.ident[j]), ti.max(p.ident[i], p.ident[j])
            pair = ti.cast(lo, ti.u32) ^ (ti.cast(hi, ti.u32) * ti.u32(0x85EBCA6B))
            sign = 1.0 if p.ident[i] == lo else -1.0  # the pair's noise pushes its two ends apart alike
            # an explicit step that damps the share s of the relative motion keeps kT only with the noise's variance
            # times 1 - s / 2; s: the thermostat's share, and the viscosity's, (the pair's mean of) 2 dt sum(gamma w)
            # / (m dim)
            damped = share
            if ti.static(self.viscous):
                damped += dt * (self.visc_sum[i] / p.mass[i] + self.visc_sum[j] / p.mass[j]) / self.dim
            keep = ti.max(1.0 - 0.5 * damped, 0.0)
            kick = ti.sqrt(2.0 * gamma_dt * kt * keep) * w
            acc += -gamma_dt * w * w * (p.v[i] - p.v[j])
            for a in ti.static(range(self.dim)):
                acc[a] += sign * kick * unit_noise(pair, step, PAIR_STREAM + a)
            if ti.static(self.viscous):  # the viscous force's partner: its noise along the line of centres
                visc = self.visc[p.material[i], p.material[j]]
                along = ti.sqrt(2.0 * visc * kt * dt * w * keep) * unit_noise(pair, step, PAIR_STREAM + self.dim)
                acc += along * (-d / r)  # e from j to i turns with the pair: no sign needed
        return acc

    @ti.kernel
    def _agitate(self, dt: float, step: ti.i32, paired: ti.i32):
        """Each free particle's new velocity: after its pair kicks (`paired`), held about its flow for the share of
        neighbours it lacks; its gain in kinetic energy taken from its heat."""
        p = self.p
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            if self.free(i):
                t, _ = self.phase.state(p.h[i], p.material[i])
                kt = self.scale * ti.max(t + KELVIN, 0.0)
                sigma = ti.sqrt(kt / p.mass[i])
                v = p.v[i]
                lacking = 1.0
                if paired:
                    v = self.v_new[i]
                    lacking = ti.max(1.0 - self.weight[i] / GAS_WEIGHT, 0.0)
                if lacking > 0.0:  # about the local flow (rest for a lone particle): a drop's rim is not dragged
                    c1 = ti.exp(-lacking * dt / self.tau)
                    c2 = ti.sqrt(1.0 - c1 * c1)
                    u = self.flow[i]
                    v = u + c1 * (v - u)
                    for a in ti.static(range(self.dim)):
                        v[a] += c2 * sigma * normal(p.ident[i], step, a)
                gained = 0.5 * p.mass[i] * (v.dot(v) - p.v[i].dot(p.v[i]))  # pJ
                p.v[i] = v
                p.h[i] -= gained / p.mass[i] * KJ_PER_KG_PER_PJ_PER_MG
                add_at(self.moved, world_of(p, i), ti.cast(gained, ti.f64))

"""Spring-and-damper (Voigt) bonds with thermoelastic softening and breaking.

For a spring between i and j, with d = x_j - x_i, n = d / |d|, the force on i is

    f_i = k (|d| - l) n  +  c ((v_j - v_i) . n) n,        f_j = -f_i

(the spring pulls i towards j when stretched; the damper resists the rate of stretching). Both ends compute the
force from their own side with mirrored arithmetic, so f_j is exactly -f_i; forces are gathered per particle
through its bond list, with no float atomics.

Thermoelastic law, per material with softening temperature Ts and solidus Tm, from the mean temperature T and mean
melt fraction phi of the two ends (physics/phase.py): k = k_s * f, c = k_d * f with

    f = s(T) (1 - phi),     s = 1 below Ts, falling linearly to the material's stiffness_at_melt at Tm (and held there)

A spring breaks for good when both ends are at least break_melt_fraction molten, or when stretched beyond
`BREAK_STRETCH` times its rest length. Refreezing (physics/phase.py) makes new springs in free slots: a scene that
can refreeze has spare spring slots beyond the built ones. The springs' fields are state (core/particles.py's
SpringState); this term is their physics.
"""

import math

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented
from ..core.worlds import at
from .term import Measure, Term, register


def omega_bound(ks, factor, alive, i, j, mass, n: int) -> float:
    """Gershgorin bound on the fastest spring frequency (1/time): sqrt(max_p 2 sum_s k_s / m_p) over live springs
    s at stiffness ks * factor, for the first n particles (host arrays, one entry per spring or particle)."""
    k = ks * factor * alive
    ksum = np.bincount(i, weights=k, minlength=n)[:n] + np.bincount(j, weights=k, minlength=n)[:n]
    m = mass[:n]  # (a slot of no particle among them, a world's idle one, has no mass and no spring)
    return float(math.sqrt(np.max(np.divide(2 * ksum, m, out=np.zeros(n), where=m > 0)))) if n else 0.0


@register
@data_oriented
class Springs(Term):
    """The springs as a term: their per-step update (softening, breaking), their force on each particle through its
    bond list, their energy, virial and count, and the stable step they allow each integrator."""

    key = "springs"
    stage = "bonds"
    prestep = True
    bonded = True
    BREAK_STRETCH = 100.0  # a spring stretched beyond 100x its rest length breaks (documented clamp)
    measures = (
        Measure("spring", "sum", "springs"),
        Measure("alive", "count", "springs"),
        Measure("spring_virial", "sum", "springs"),
        Measure("created", "count", "value"),
    )

    @staticmethod
    def wanted(parts) -> bool:
        return parts.state.springs is not None

    def __init__(self, parts):
        model = parts.model
        self.s = parts.state.springs
        self.p = parts.state.particles
        self.mats = model.materials
        self.phase = model.phase
        self.heat_enabled = model.phase is not None
        self.separation = model.domain.separation
        self.loops = model.loops
        self.refreezing = parts.scene.heat is not None and bool(parts.scene.heat.refreeze)
        self.omega0 = 0.0  # omega_max() as built (set by the Simulation from its initial snapshot)

    def words(self, where: str) -> list[str]:
        if where == "rates":
            return ["spring-damper forces (gathered per particle)"]
        if where != "prestep":
            return []
        what = "thermoelastic softening and breaking by melt fraction" if self.heat_enabled else "overstretch breaking"
        slots = f" ({self.s.count} slots, room to refreeze)" if self.s.count > self.s.built_count else ""
        return [f"spring update ({what}) over {self.s.built_count} springs{slots}"]

    # ------------------------------------------------------------------ its part of the rates
    @ti.func
    def prestep_loops(self):
        """Each spring's thermoelastic update and breaking, before the forces: heavier than a light loop (it reads
        two phase states), so parallel with the pair loops."""
        self.loops.pairs()
        for s in range(self.s.span[None]):
            self.update_one(s)

    @ti.func
    def prestep_count(self):
        """The items of the per-stage pass (a team of threads shares them out: step/team.py)."""
        return self.s.span[None]

    @ti.func
    def prestep_one(self, s):
        self.update_one(s)

    @ti.func
    def update_one(self, s):
        """Thermoelastic softening and breaking (by temperature and by overstretch) of spring s."""
        if self.s.alive[s]:
            a, b = self.s.i[s], self.s.j[s]
            factor = 1.0
            if ti.static(self.heat_enabled):
                factor = self.thermal_factor(a, b)
            length = self.separation(self.p.x[a], self.p.x[b]).norm()
            if length > self.BREAK_STRETCH * self.s.rest[s]:
                factor = -1.0
            if factor < 0.0:
                self.s.alive[s] = 0
                self.s.factor[s] = 0.0
            else:
                self.s.factor[s] = factor

    @ti.func
    def thermal_factor(self, a, b):
        """s(T) (1 - phi) for a spring joining a and b, or -1 when both ends are molten enough to break it."""
        mat = self.p.material[a]
        ta, pa = self.phase.state(self.p.h[a], mat)
        tb, pb = self.phase.state(self.p.h[b], self.p.material[b])
        t = 0.5 * (ta + tb)
        t_soft, t_melt = self.mats.soften[mat], self.mats.melt[mat]
        soft = 1.0
        if t > t_soft:
            ramp = 1.0
            if t_melt > t_soft:
                ramp = ti.min((t - t_soft) / (t_melt - t_soft), 1.0)
            soft = 1.0 - (1.0 - self.mats.stiff_at_melt[mat]) * ramp
        factor = soft * (1.0 - 0.5 * (pa + pb))
        if ti.min(pa, pb) >= self.mats.break_fraction[mat]:
            factor = -1.0
        return factor

    @ti.func
    def bond(self, i, j, s, d):
        """Force on particle i from live spring s joining it to j, with d = x_j - x_i."""
        return self.force(i, j, s, d)

    @ti.func
    def force(self, i, j, s, d):
        r = d.norm()
        n = d * (1.0 / ti.max(r, 1e-12))
        vrel = (self.p.v[j] - self.p.v[i]).dot(n)
        return self.s.factor[s] * (self.s.ks[s] * (r - self.s.rest[s]) + self.s.kd[s] * vrel) * n

    @ti.func
    def energy(self, s):
        """Elastic energy 1/2 k (|d| - l)^2 of spring s at its current stiffness (0 once broken)."""
        e = 0.0
        if self.s.alive[s]:
            a, b = self.s.i[s], self.s.j[s]
            r = self.separation(self.p.x[a], self.p.x[b]).norm()
            e = 0.5 * self.s.factor[s] * self.s.ks[s] * (r - self.s.rest[s]) ** 2
        return e

    # ------------------------------------------------------------------ its measurements
    @ti.func
    def measure_spring(self, s):
        """(elastic energy, 1 if alive, virial -d . F_a of the spring) of slot s."""
        alive, virial = 0, 0.0
        if self.s.alive[s]:
            alive = 1
            a, b = self.s.i[s], self.s.j[s]
            d = self.separation(self.p.x[a], self.p.x[b])
            virial = -d.dot(self.force(a, b, s, d))
        return self.energy(s), alive, virial

    @ti.func
    def measure_value(self, w):
        return (at(self.s.created, w),)

    # ------------------------------------------------------------------ its stability
    def omega_max(self) -> float:
        """Upper bound on the fastest spring frequency now: omega_max^2 <= max_i 2 sum_s k_s / m_i over live
        springs at their current (softened) stiffness (Gershgorin bound on M^-1 K)."""
        s = self.s
        ks, factor, alive, i, j, mass = transfer.download([s.ks, s.factor, s.alive, s.i, s.j, self.p.mass])
        return omega_bound(ks, factor, alive, i, j, mass, int(self.p.n[None]))

    @staticmethod
    def omega_of(snapshot: dict) -> float:
        """omega_max() of a state snapshot (from its host copies: no copy kernel)."""
        springs = (snapshot[f"springs.{name}"] for name in ("ks", "factor", "alive", "i", "j"))
        return omega_bound(*springs, snapshot["particles.mass"], int(snapshot["particles.n"]))

    def stable_dt(self, integrator) -> float:
        """Largest stable step with `integrator`: its stable h w over omega_max (0 for methods unstable on undamped
        springs at any step, inf without live springs)."""
        omega = self.omega_max()
        return math.inf if omega == 0.0 else integrator.stable_h_omega / omega

    def auto_dt(self, integrator) -> float:
        omega = self.omega_max()
        if omega > 0 and math.isfinite(integrator.auto_h_omega):
            return integrator.auto_h_omega / omega
        return math.inf

    def stable_dt_initial(self, integrator) -> float:
        """stable_dt() for the springs as built (before softening and breaking)."""
        return math.inf if self.omega0 == 0.0 else integrator.stable_h_omega / self.omega0

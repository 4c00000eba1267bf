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
can refreeze has spare spring slots beyond the built ones.
"""

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented


def bond_table(
    spring_i: np.ndarray, spring_j: np.ndarray, n_particles: int, max_bonds: int, spring_ids: np.ndarray | None = None
) -> np.ndarray:
    """(n_particles, max_bonds) int32 table of spring ids at each particle, padded with -1. `spring_ids`: the ids of
    the given springs (default 0..S-1)."""
    table = np.full((max(n_particles, 1), max(max_bonds, 1)), -1, dtype=np.int32)
    ends = np.concatenate([spring_i, spring_j])
    ids = np.concatenate([np.arange(len(spring_i)) if spring_ids is None else spring_ids] * 2)
    order = np.argsort(ends, kind="stable")
    ends, ids = ends[order], ids[order]
    first = np.searchsorted(ends, ends, side="left")
    slot = np.arange(len(ends)) - first
    table[ends, slot] = ids
    return table


@data_oriented
class Springs:
    """Spring fields (S springs; bond table per particle) and their force, energy and update funcs."""

    BREAK_STRETCH = 100.0  # a spring stretched beyond 100x its rest length breaks (documented clamp)

    def __init__(
        self,
        built,
        capacity: int,
        particles,
        materials,
        phase,
        periodic_sep,
        spare: int = 0,
        max_bonds: int = 0,
    ):
        """`capacity`: particle slots; `phase`: the Phase law (None without heat); `spare`: extra spring slots for
        refreezing; `max_bonds`: bond-list width (at least the built one)."""
        self.built_count = built.spring_count
        self.count = built.spring_count + spare  # spring slots; the kernels loop over all of them
        self.max_bonds = max(built.max_bonds(), max_bonds, 1)
        s = max(self.count, 1)
        self.i = ti.field(ti.i32, shape=s)  # first end
        self.j = ti.field(ti.i32, shape=s)  # second end
        self.rest = ti.field(float, shape=s)  # rest length l (length)
        self.ks = ti.field(float, shape=s)  # base stiffness k_s (force / length)
        self.kd = ti.field(float, shape=s)  # base damping k_d (force / speed)
        self.factor = ti.field(float, shape=s)  # thermoelastic factor s(T) in [0, 1]
        self.alive = ti.field(ti.i32, shape=s)  # 1 while the spring holds, 0 once broken (for good)
        self.bonds = ti.field(ti.i32, shape=(capacity, self.max_bonds))  # spring ids at each particle, -1 padded
        self.created = ti.field(ti.i32, shape=())  # springs ever made (built + refrozen): broken = created - alive
        # Slots [0, span) hold every spring that was ever alive: per-spring loops stop there, not at `count` (a scene
        # that can refreeze has 1.5x its built springs again as spare slots, mostly never used)
        self.span = ti.field(ti.i32, shape=())
        pad = np.zeros(s - self.built_count)
        table = np.full((capacity, self.max_bonds), -1, dtype=np.int32)
        table[: built.count] = bond_table(built.spring_i, built.spring_j, built.count, self.max_bonds)[: built.count]
        alive = np.zeros(s, dtype=np.int32)
        alive[: self.built_count] = 1
        transfer.upload(  # one copy kernel for all of them
            [
                (self.i, np.concatenate([built.spring_i, pad]).astype(np.int32)),
                (self.j, np.concatenate([built.spring_j, pad]).astype(np.int32)),
                (self.rest, np.concatenate([built.rest_length, pad])),
                (self.ks, np.concatenate([built.stiffness, pad])),
                (self.kd, np.concatenate([built.damping, pad])),
                (self.factor, np.ones(s)),
                (self.alive, alive),
                (self.bonds, table),
                (self.created, self.built_count),
                (self.span, self.built_count),
            ]
        )
        self.p = particles
        self.mats = materials
        self.phase = phase
        self.heat_enabled = phase is not None
        self.separation = periodic_sep

    def describe(self, thermal: bool, refreezing: bool) -> str:
        """The springs' per-step update in words, for Simulation.pipeline(): `thermal` with heat (softening and
        breaking by melt fraction), `refreezing` when spare slots wait for new bonds."""
        what = "thermoelastic softening and breaking by melt fraction" if thermal else "overstretch breaking"
        slots = f" ({self.count} slots, room to refreeze)" if refreezing else ""
        return f"spring update ({what}) over {self.built_count} springs{slots}"

    def rebuild_bonds(self) -> None:
        """Rebuild every particle's bond list from the live springs (after particles were removed or renumbered)."""
        alive, i, j = transfer.download([self.alive, self.i, self.j], [self.count] * 3)
        alive = np.flatnonzero(alive)
        n = self.bonds.shape[0]
        transfer.upload([(self.bonds, bond_table(i[alive], j[alive], n, self.max_bonds, alive)[:n])])

    @ti.func
    def update_one(self, s):
        """Thermoelastic softening and breaking (by temperature and by overstretch) of spring s, once per step
        before forces; the simulation runs it for every spring in its fused pre-step kernel."""
        if self.alive[s]:
            a, b = self.i[s], self.j[s]
            factor = 1.0
            if ti.static(self.heat_enabled):
                factor = self.thermal_factor(a, b)
            length = self.separation(self.p.x[a], self.p.x[b]).norm()
            if length > self.BREAK_STRETCH * self.rest[s]:
                factor = -1.0
            if factor < 0.0:
                self.alive[s] = 0
                self.factor[s] = 0.0
            else:
                self.factor[s] = factor

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
    def other_end(self, i, s):
        return self.i[s] + self.j[s] - i

    @ti.func
    def force(self, i, j, s, d):
        """Force on particle i from live spring s joining it to j, with d = x_j - x_i."""
        r = d.norm()
        n = d * (1.0 / ti.max(r, 1e-12))
        vrel = (self.p.v[j] - self.p.v[i]).dot(n)
        return self.factor[s] * (self.ks[s] * (r - self.rest[s]) + self.kd[s] * vrel) * n

    @ti.func
    def energy(self, s):
        """Elastic energy 1/2 k (|d| - l)^2 of spring s at its current stiffness (0 once broken)."""
        e = 0.0
        if self.alive[s]:
            a, b = self.i[s], self.j[s]
            r = self.separation(self.p.x[a], self.p.x[b]).norm()
            e = 0.5 * self.factor[s] * self.ks[s] * (r - self.rest[s]) ** 2
        return e

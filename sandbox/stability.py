"""Stable steps: how large a step the springs (per integrator) and explicit heat diffusion allow, and the step that
`substeps = "auto"` takes. A mixin of Simulation; the bounds are Gershgorin bounds on the springs' stiffness matrix
and on the heat matrix.
"""

from __future__ import annotations

import math

import numpy as np

from .core import transfer
from .core.model import material_column


def _omega_bound(ks, factor, alive, i, j, mass, n: int) -> float:
    """Gershgorin bound on the fastest spring frequency (1/time): sqrt(max_p 2 sum_s k_s / m_p) over live springs
    s at stiffness ks * factor, for the first n particles (host arrays, one entry per spring or particle)."""
    k = ks * factor * alive
    ksum = np.bincount(i, weights=k, minlength=n)[:n] + np.bincount(j, weights=k, minlength=n)[:n]
    return float(math.sqrt(np.max(2 * ksum / mass[:n]))) if n else 0.0


class StabilityBounds:
    """Simulation's stable-step bounds (springs, heat) and the auto step."""

    @property
    def stable_dt_initial(self) -> float:
        """stable_dt() for the springs as built (before softening and breaking), for this integrator."""
        if self._spring_omega0 == 0.0:
            return math.inf
        return self.integrator.stable_h_omega / self._spring_omega0

    def omega_max(self) -> float:
        """Upper bound on the fastest spring frequency now: omega_max^2 <= max_i 2 sum_s k_s / m_i over live
        springs at their current (softened) stiffness (Gershgorin bound on M^-1 K); 0 without springs."""
        if self.springs is None:
            return 0.0
        s = self.springs
        ks, factor, alive, i, j, mass = transfer.download([s.ks, s.factor, s.alive, s.i, s.j, self.particles.mass])
        return _omega_bound(ks, factor, alive, i, j, mass, int(self.particles.n[None]))

    def _snapshot_omega_max(self, snap: dict) -> float:
        """omega_max() of the state in `snap` (from the host copies: no copy kernel to compile at start-up)."""
        if self.springs is None:
            return 0.0
        springs = (snap[f"spring_{name}"] for name in ("ks", "factor", "alive", "i", "j"))
        return _omega_bound(*springs, snap["mass"], snap["n"])

    def stable_dt(self) -> float:
        """Largest stable step for the springs with this integrator: (its stable h w) / omega_max. 0 for methods
        unstable on undamped springs at any step (forward Euler, midpoint); inf without springs."""
        omega = self.omega_max()
        if omega == 0.0:
            return math.inf
        return self.integrator.stable_h_omega / omega

    def auto_step(self) -> float:
        """The step substeps = "auto" uses now: the integrator's auto h w over omega_max, half the time for the
        fastest particle to cross the smallest radius, half the explicit heat limit, and world.dt."""
        limits = [self.scene.world.dt]
        omega = self.omega_max()
        if omega > 0 and math.isfinite(self.integrator.auto_h_omega):
            limits.append(self.integrator.auto_h_omega / omega)
        n = int(self.particles.n[None])
        if n:
            v = np.linalg.norm(self.velocities(), axis=1).max()
            r = self.particles.radius.to_numpy()[:n].min()
            if v > 0:
                limits.append(0.5 * r / v)
        if self.has_explicit_heat:
            limits.append(0.5 * self._heat_limit)
        return min(limits)

    def heat_dt_limit(self) -> float:
        """Largest stable explicit heat step on the initial particles (Gershgorin bound), inf without heat."""
        if self.heat is None or self.built.count < 2:
            return math.inf
        from .physics.heat import wendland_grad_factor

        b = self.built
        mats = [self.scene.materials[m] for m in self.material_names]
        rho = material_column(mats, b.material, "density")
        cap = material_column(mats, b.material, "specific_heat") * b.mass
        k = material_column(mats, b.material, "conductivity")
        # Probe a few particles: the diagonal coefficient sum of the heat matrix row.
        probe = np.linspace(0, b.count - 1, num=min(b.count, 64)).astype(int)
        worst = 0.0
        for i in probe:
            r = np.linalg.norm(b.x - b.x[i], axis=1)
            near = (r > 0) & (r < self.heat.support)
            vol = b.mass / rho
            kij = 2 * k[i] * k[near] / np.maximum(k[i] + k[near], 1e-30)
            grad = np.array([wendland_grad_factor(rr, self.heat.support, self.dim) for rr in r[near]])
            grad /= self.heat.correction
            row = np.sum(vol[i] * vol[near] * 2 * kij * grad) / cap[i]
            worst = max(worst, row)
        return 2.0 / (2.0 * worst) if worst > 0 else math.inf

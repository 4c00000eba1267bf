"""Implicit (backward) Euler for heat: unconditionally stable, solved by Jacobi-preconditioned CG.

With C_i = m_i c_i, conductances G_ij (heat.py) and source terms (G_i, G_i T_s), one step solves

    (C_i + h G_i) T_i' + h sum_j G_ij (T_i' - T_j') = C_i T_i + h G_i T_s

a symmetric positive definite system (a weighted graph Laplacian plus a positive diagonal). Without sources the
row sums give sum_i C_i T_i' = sum_i C_i T_i: heat is conserved to the solver tolerance.

With latent heat the solve is linearised: its heat gain C_i dT_i goes into the specific enthalpy (h += c dT), and the
temperature follows from h (physics/phase.py). That keeps the total heat exact and the step stable (a melting
particle's temperature changes less than the linear solve assumed); near a melting front it lags the exact
nonlinear backward Euler step by up to a step.
"""

import taichi as ti

from ..core.oriented import data_oriented
from ..core.solvers import CGResult, CGSums, pcg
from .neighbours import LIST_ARRAY
from .term import Term, register


@register
@data_oriented
class ImplicitHeat(Term):
    """Backward-Euler heat stepper over the neighbourhood (lists or grid), after each step."""

    key = "implicit_heat"
    stage = "solve"

    @staticmethod
    def wanted(parts) -> bool:
        heat = parts.scene.heat
        return heat is not None and heat.stepper != "explicit"

    @staticmethod
    def host_work(scene) -> str | None:
        """Why this pass needs the host between `scene`'s steps (see the stepping plan), or None."""
        implicit = scene.heat is not None and scene.heat.stepper != "explicit"
        return "the implicit heat solve iterates from the host" if implicit else None

    def __init__(self, parts, tolerance: float = 1e-10, max_iterations: int = 500):
        self.parts = parts  # the neighbourhood it sums over is built after the terms
        self.p = parts.state.particles
        self.heat = parts.terms["heat"]
        self.phase = parts.model.phase  # each phase's specific heat: the solve's heat capacity
        self.domain = parts.model.domain
        self.tolerance, self.max_iterations = tolerance, max_iterations
        cap = parts.model.capacity
        self.dT = ti.field(float, shape=cap)  # the step's temperature change, accumulated by the solve
        self.r = ti.field(float, shape=cap)
        self.z = ti.field(float, shape=cap)
        self.d = ti.field(float, shape=cap)
        self.ad = ti.field(float, shape=cap)
        self.diag = ti.field(float, shape=cap)  # C_i + h G_i + h sum_j G_ij
        self.sums = CGSums()
        self.last = CGResult(0, 0.0)

    def words(self, where: str) -> list[str]:
        return (
            ["implicit heat: backward Euler by preconditioned CG, then the enthalpy update"] if where == "after" else []
        )

    def after_step(self, state) -> None:
        """The implicit heat solve over the step just taken, then its enthalpy update."""
        hood = self.parts.neighbours
        use_list = hood.lists is not None and hood.lists.ensure_fresh()
        if not use_list:
            hood.grid.rebuild()
        self.step(state.dt, use_list, hood.ids(use_list))
        self.apply()

    def step(self, h: float, use_list: bool, ids) -> CGResult:
        """Advance every particle's temperature by h (positions as they are now)."""
        self._assemble(h, use_list, ids)
        self.last = pcg(
            self.sums,
            lambda: self._matvec(h, use_list, ids),
            self._update,
            self._direction,
            self.tolerance,
            self.max_iterations,
        )
        return self.last

    @ti.func
    def _laplacian(self, i, y: ti.template(), use_list: ti.template(), ids: ti.template()):
        """(sum_j G_ij, sum_j G_ij (y_i - y_j)) over the neighbours of i within the kernel support."""
        acc = ti.Vector([0.0, 0.0])
        xi = self.p.x[i]
        if ti.static(use_list):
            lists = self.parts.neighbours.lists
            row = lists.row(i, ids)
            for k in range(lists.count[i]):
                j = ids[row + k]
                acc = self._add_neighbour(acc, j, self.domain.separation(xi, self.p.x[j]), k, (i, y))
        else:
            acc = self.parts.neighbours.grid.fold(i, xi, acc, self._add_neighbour, (i, y))
        return acc[0], acc[1]

    @ti.func
    def _add_neighbour(self, acc, j, d, k, extra: ti.template()):
        """acc + (G_ij, G_ij (y_i - y_j)) for neighbour j of i = extra[0] at separation d (y = extra[1])."""
        i = extra[0]
        y = ti.static(extra[1])
        r2 = d.dot(d)
        if j != i and r2 < self.heat.support**2:
            g = self.heat.conductance(i, j, r2)
            acc += ti.Vector([g, g * (y[i] - y[j])])
        return acc

    @ti.kernel
    def _assemble(self, h: float, use_list: ti.template(), ids: LIST_ARRAY):
        self.sums.clear_for_assembly()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            cap = self.p.mass[i] * self.phase.capacity(self.p.h[i], self.p.material[i])
            g, gt = self.heat.sources.terms(i)
            gsum, lap = self._laplacian(i, self.p.T, use_list, ids)
            # Solve for the change dT = T' - T: A dT = h (G T_s - G T - sum_j G_ij (T_i - T_j)), starting at 0.
            b = h * (gt - g * self.p.T[i] - lap)
            self.diag[i] = cap + h * (g + gsum)
            self.r[i] = b
            self.z[i] = b / self.diag[i]
            self.d[i] = self.z[i]
            self.dT[i] = 0.0
            self.sums.rz[None] += b * self.z[i]
            self.sums.rr[None] += b * b
            self.sums.bb[None] += b * b

    @ti.kernel
    def _matvec(self, h: float, use_list: ti.template(), ids: LIST_ARRAY):
        self.sums.p_ap[None] = 0.0
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            cap = self.p.mass[i] * self.phase.capacity(self.p.h[i], self.p.material[i])
            g, _ = self.heat.sources.terms(i)
            _, lap = self._laplacian(i, self.d, use_list, ids)
            self.ad[i] = (cap + h * g) * self.d[i] + h * lap
            self.sums.p_ap[None] += self.d[i] * self.ad[i]

    @ti.kernel
    def _update(self, alpha: ti.f64):
        self.sums.clear_for_update()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.dT[i] += alpha * self.d[i]
            self.r[i] -= alpha * self.ad[i]
            self.z[i] = self.r[i] / self.diag[i]
            self.sums.rz[None] += self.r[i] * self.z[i]
            self.sums.rr[None] += self.r[i] * self.r[i]

    @ti.kernel
    def _direction(self, beta: ti.f64):
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.d[i] = self.z[i] + beta * self.d[i]

    @ti.kernel
    def apply(self):
        """h += c dT (dT accumulated by the solve); T follows from h."""
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            c = self.phase.capacity(self.p.h[i], self.p.material[i])
            self.heat.set_enthalpy(i, self.p.h[i] + c * self.dT[i])

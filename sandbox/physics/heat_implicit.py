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


@data_oriented
class ImplicitHeat:
    """Backward-Euler heat stepper over the simulation's neighbours (lists or grid)."""

    @staticmethod
    def host_work(scene) -> str | None:
        """Why this pass needs the host between `scene`'s steps (see Simulation's stepping plan), or None."""
        implicit = scene.heat is not None and scene.heat.stepper != "explicit"
        return "the implicit heat solve iterates from the host" if implicit else None

    def __init__(self, sim, tolerance: float = 1e-10, max_iterations: int = 500):
        self.sim = sim
        self.p = sim.particles
        self.heat = sim.heat
        self.tolerance, self.max_iterations = tolerance, max_iterations
        cap = sim.capacity
        self.r = ti.field(float, shape=cap)
        self.z = ti.field(float, shape=cap)
        self.d = ti.field(float, shape=cap)
        self.ad = ti.field(float, shape=cap)
        self.diag = ti.field(float, shape=cap)  # C_i + h G_i + h sum_j G_ij
        self.sums = CGSums()
        self.last = CGResult(0, 0.0)

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
        gsum = 0.0
        lap = 0.0
        h2 = self.heat.support**2
        xi = self.p.x[i]
        if ti.static(use_list):
            for k in range(self.sim.neighbours.count[i]):
                j = ids[i, k]
                d = self.sim.domain.separation(xi, self.p.x[j])
                r2 = d.dot(d)
                if r2 < h2:
                    g = self.heat.conductance(i, j, r2)
                    gsum += g
                    lap += g * (y[i] - y[j])
        else:
            grid = self.sim.grid
            c = grid.cell_of(xi)
            for o in range(grid.n_offsets):
                nc, shift = grid.neighbour_cell(c, grid.offset(o))
                if nc >= 0:
                    for k in range(grid.cell_start[nc], grid.cell_start[nc] + grid.cell_count[nc]):
                        j = grid.sorted_ids[k]
                        if j != i:
                            d = grid.x_sorted[k] - (xi - shift)
                            r2 = d.dot(d)
                            if r2 < h2:
                                g = self.heat.conductance(i, j, r2)
                                gsum += g
                                lap += g * (y[i] - y[j])
        return gsum, lap

    @ti.kernel
    def _assemble(self, h: float, use_list: ti.template(), ids: LIST_ARRAY):
        self.sums.clear_for_assembly()
        for i in range(self.p.n[None]):
            cap = self.p.mass[i] * self.sim.materials.specific_heat[self.p.material[i]]
            g, gt = self.heat.source_terms(i)
            gsum, lap = self._laplacian(i, self.p.T, use_list, ids)
            # Solve for the change dT = T' - T: A dT = h (G T_s - G T - sum_j G_ij (T_i - T_j)), starting at 0.
            b = h * (gt - g * self.p.T[i] - lap)
            self.diag[i] = cap + h * (g + gsum)
            self.r[i] = b
            self.z[i] = b / self.diag[i]
            self.d[i] = self.z[i]
            self.p.dhdt[i] = 0.0  # holds the accumulating dT during the solve
            self.sums.rz[None] += b * self.z[i]
            self.sums.rr[None] += b * b
            self.sums.bb[None] += b * b

    @ti.kernel
    def _matvec(self, h: float, use_list: ti.template(), ids: LIST_ARRAY):
        self.sums.p_ap[None] = 0.0
        for i in range(self.p.n[None]):
            cap = self.p.mass[i] * self.sim.materials.specific_heat[self.p.material[i]]
            g, _ = self.heat.source_terms(i)
            _, lap = self._laplacian(i, self.d, use_list, ids)
            self.ad[i] = (cap + h * g) * self.d[i] + h * lap
            self.sums.p_ap[None] += self.d[i] * self.ad[i]

    @ti.kernel
    def _update(self, alpha: ti.f64):
        self.sums.clear_for_update()
        for i in range(self.p.n[None]):
            self.p.dhdt[i] += alpha * self.d[i]
            self.r[i] -= alpha * self.ad[i]
            self.z[i] = self.r[i] / self.diag[i]
            self.sums.rz[None] += self.r[i] * self.z[i]
            self.sums.rr[None] += self.r[i] * self.r[i]

    @ti.kernel
    def _direction(self, beta: ti.f64):
        for i in range(self.p.n[None]):
            self.d[i] = self.z[i] + beta * self.d[i]

    @ti.kernel
    def apply(self):
        """h += c dT (dT was accumulated in p.dhdt by the solve); T follows from h."""
        for i in range(self.p.n[None]):
            c = self.sim.materials.specific_heat[self.p.material[i]]
            self.sim.set_enthalpy(i, self.p.h[i] + c * self.p.dhdt[i])

"""Backward Euler on the springs by matrix-free preconditioned conjugate gradients."""

import taichi as ti

from ..core.particles import fold_bonds
from ..core.solvers import CGSums, pcg
from .base import Integrator, register


@register("implicit_euler")
class ImplicitEuler(Integrator):
    """Backward Euler for the springs (Baraff & Witkin 1998), explicit for everything else (pair force, gravity).

    Solves (M - h df/dv - h^2 df/dx) dv = h (f + h df/dx v) for dv with matrix-free preconditioned conjugate
    gradients, then v += dv, x += h v. For a spring with n = d/|d|, L = |d|, per-spring blocks are
    K = k (n n^T + max(0, 1 - l/L) (I - n n^T)) (the clamp keeps it positive semi-definite when compressed) and
    D = c n n^T, so the system matrix is M plus a weighted graph Laplacian of PSD blocks: symmetric positive
    definite. Unconditionally stable on springs, at the price of numerical damping that grows with h w.
    """

    stable_h_omega = float("inf")
    auto_h_omega = float("inf")
    stages = 0  # a step of its own: the CG iterations between the evaluation and the update

    def __init__(self, rates, state):
        super().__init__(rates, state)
        world = rates.model.scene.world
        self.tolerance = world.implicit_tolerance
        self.max_iterations = world.implicit_max_iterations
        self.last_iterations = 0
        self.total_iterations = 0
        self.last_residual = 0.0
        self._stage_fields("dv", "r", "z", "d", "Ap", "b")
        self.diag = ti.field(float, shape=self.p.capacity)  # Jacobi preconditioner: m_i + trace of its blocks / dim
        self.springs = state.springs
        self.has_springs = state.springs is not None
        self.domain = rates.domain
        self.dim = dim = self.p.dim
        s = max(state.springs.count, 1) if self.has_springs else 1
        self.block = ti.Matrix.field(dim, dim, float, shape=s)  # h D_s + h^2 K_s per spring
        self.kmat = ti.Matrix.field(dim, dim, float, shape=s)  # K_s per spring
        self.sums = CGSums()

    def step(self, dt: float, first_stage: int = 0) -> None:
        self.rates.evaluate()
        self._assemble(dt)
        result = pcg(self.sums, self._matvec, self._update, self._direction, self.tolerance, self.max_iterations)
        self.last_iterations = result.iterations
        self.total_iterations += result.iterations
        self.last_residual = result.relative_residual
        self._finish(dt)

    @ti.func
    def _spring_blocks(self, s, h):
        a, b = self.springs.i[s], self.springs.j[s]
        d = self.domain.separation(self.p.x[a], self.p.x[b])
        length = ti.max(d.norm(), 1e-12)
        n = d / length
        nn = n.outer_product(n)
        eye = ti.Matrix.identity(float, self.dim)
        k = self.springs.factor[s] * self.springs.ks[s]
        c = self.springs.factor[s] * self.springs.kd[s]
        kmat = k * (nn + ti.max(0.0, 1.0 - self.springs.rest[s] / length) * (eye - nn))
        return kmat, h * c * nn + h * h * kmat

    @ti.kernel
    def _assemble(self, h: float):
        self.sums.clear_for_assembly()
        if ti.static(self.has_springs):
            self.loops.light()
            for s in range(self.springs.span[None]):
                if self.springs.alive[s]:
                    self.kmat[s], self.block[s] = self._spring_blocks(s, h)
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            b = h * self.f[i]
            diag = self.p.mass[i]
            if ti.static(self.has_springs):
                row = fold_bonds(self.springs, i, self._row(b, diag), self._add_bond_row, (h,))
                b = ti.Vector([row[a] for a in ti.static(range(self.dim))])
                diag = row[self.dim]
            self.b[i] = b
            self.diag[i] = diag
            self.dv[i] = ti.Vector.zero(float, self.dim)
            self.r[i] = b
            self.z[i] = b / diag
            self.d[i] = self.z[i]
            self.sums.rz[None] += b.dot(self.z[i])
            self.sums.rr[None] += b.dot(b)
            self.sums.bb[None] += b.dot(b)

    @ti.func
    def _row(self, b, diag):
        """b and the diagonal entry packed in one vector, as the bond loop accumulates them."""
        return ti.Vector([b[a] for a in ti.static(range(self.dim))] + [diag])

    @ti.func
    def _add_bond_row(self, row, i, j, s, extra: ti.template()):
        """Live spring s to j's terms in particle i's right-hand side, h^2 K_s (v_j - v_i), and in its diagonal
        (the Jacobi preconditioner), trace(h D_s + h^2 K_s) / dim; extra: (h,)."""
        h = extra[0]
        b = h * h * (self.kmat[s] @ (self.p.v[j] - self.p.v[i]))
        for a in ti.static(range(self.dim)):
            row[a] += b[a]
        row[self.dim] += self.block[s].trace() / self.dim
        return row

    @ti.func
    def _add_bond_product(self, ap, i, j, s, extra: ti.template()):
        """Live spring s to j's block of the product A d for particle i."""
        return ap + self.block[s] @ (self.d[i] - self.d[j])

    @ti.kernel
    def _matvec(self):
        self.sums.p_ap[None] = 0.0
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            ap = self.p.mass[i] * self.d[i]
            if ti.static(self.has_springs):
                ap = fold_bonds(self.springs, i, ap, self._add_bond_product, ())
            self.Ap[i] = ap
            self.sums.p_ap[None] += self.d[i].dot(ap)

    @ti.kernel
    def _update(self, alpha: ti.f64):
        self.sums.clear_for_update()
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.dv[i] += alpha * self.d[i]
            self.r[i] -= alpha * self.Ap[i]
            self.z[i] = self.r[i] / self.diag[i]
            self.sums.rz[None] += self.r[i].dot(self.z[i])
            self.sums.rr[None] += self.r[i].dot(self.r[i])

    @ti.kernel
    def _direction(self, beta: ti.f64):
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.d[i] = self.z[i] + beta * self.d[i]

    @ti.kernel
    def _finish(self, h: float):
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.p.v[i] = self.p.v[i] + self.dv[i]
            self.p.x[i] = self.p.x[i] + h * self.p.v[i]
            self.rates.finish_particle(i, h)

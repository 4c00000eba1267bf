"""The smoke grid's pressure projection: make the face velocities discretely divergence-free by solving

    sum over neighbours (p_c - p_n) = -h^2 div_c      (Neumann at the walls)

with Jacobi-preconditioned CG to the grid's tolerance, warm-started from the last step's pressure, then subtracting
the pressure gradient from interior faces. On the CPU a small grid is solved in one launch on one thread
(SmokeGrid.one_launch), with the sums in registers; else the host drives the iterations (core/solvers.py).
"""

import taichi as ti

from ..core.oriented import data_oriented
from ..core.solvers import CGResult, CGSums, pcg


@data_oriented
class PressureProjection:
    """The projection of `grid` (a SmokeGrid): the pressure and the CG vectors, one value per cell."""

    def __init__(self, grid):
        self.grid = grid
        res = grid.res
        self.p = ti.field(float, shape=res)  # pressure (times dt / density)
        self.r = ti.field(float, shape=res)
        self.z = ti.field(float, shape=res)
        self.d = ti.field(float, shape=res)
        self.ad = ti.field(float, shape=res)
        self.sums = CGSums()
        self.divergence_before = 0.0

    def project(self) -> CGResult:
        """Make the face velocities discretely divergence-free (to the CG tolerance)."""
        if self.grid.one_launch:
            iterations = int(self._project_in_one_launch())
            bb = float(self.sums.bb[None])
            self.divergence_before = bb**0.5 / self.grid.h**2
            return CGResult(iterations, float(self.sums.rr[None]) ** 0.5 / max(bb**0.5, 1e-300))
        self._assemble()
        self.divergence_before = float(self.sums.bb[None]) ** 0.5 / self.grid.h**2
        last = pcg(
            self.sums,
            self._matvec,
            self._update,
            self._direction,
            self.grid.cfg.tolerance,
            self.grid.cfg.max_iterations,
        )
        self._subtract_gradient()
        return last

    @ti.func
    def _neighbours(self, I):
        """Number of neighbour cells inside the domain (the Neumann walls drop the others)."""
        n = 0
        for a in ti.static(range(self.grid.dim)):
            if I[a] > 0:
                n += 1
            if I[a] < self.grid.res[a] - 1:
                n += 1
        return n

    @ti.func
    def _laplace(self, y: ti.template(), I):
        """sum over inside neighbours n of (y_I - y_n)."""
        s = 0.0
        for a in ti.static(range(self.grid.dim)):
            e = ti.Vector.unit(self.grid.dim, a, ti.i32)
            if I[a] > 0:
                s += y[I] - y[I - e]
            if I[a] < self.grid.res[a] - 1:
                s += y[I] - y[I + e]
        return s

    # Each CG stage per cell, shared by the host-driven kernels and the one-launch projection; each returns its
    # cell's terms of the stage's sums.
    @ti.func
    def _assemble_cell(self, I):
        """r = b - A p (warm start from the last step's pressure: the flow changes little between steps), z = M^-1 r,
        d = z; returns (r.z, r.r, b.b) terms."""
        b = -self.grid.h * self.grid.h * self.grid.divergence(I)
        r = b - self._laplace(self.p, I)
        z = r / self._neighbours(I)
        self.r[I] = r
        self.z[I] = z
        self.d[I] = z
        return r * z, r * r, b * b

    @ti.func
    def _matvec_cell(self, I):
        """ad = A d; returns the d.Ad term."""
        ad = self._laplace(self.d, I)
        self.ad[I] = ad
        return self.d[I] * ad

    @ti.func
    def _update_cell(self, I, alpha):
        """p += alpha d, r -= alpha Ad, z = M^-1 r; returns (r.z, r.r) terms."""
        self.p[I] += alpha * self.d[I]
        r = self.r[I] - alpha * self.ad[I]
        z = r / self._neighbours(I)
        self.r[I] = r
        self.z[I] = z
        return r * z, r * r

    @ti.func
    def _direction_cell(self, I, beta):
        """d = z + beta d."""
        self.d[I] = self.z[I] + beta * self.d[I]

    @ti.func
    def _subtract_gradient_face(self, a: ti.template(), I):
        if 0 < I[a] < self.grid.res[a]:
            below = I - ti.Vector.unit(self.grid.dim, a, ti.i32)
            self.grid.u[a][I] -= (self.p[I] - self.p[below]) / self.grid.h

    @ti.kernel
    def _assemble(self):
        self.sums.clear_for_assembly()
        for I in ti.grouped(self.p):
            rz, rr, bb = self._assemble_cell(I)
            self.sums.rz[None] += rz
            self.sums.rr[None] += rr
            self.sums.bb[None] += bb

    @ti.kernel
    def _matvec(self):
        self.sums.p_ap[None] = 0.0
        for I in ti.grouped(self.d):
            self.sums.p_ap[None] += self._matvec_cell(I)

    @ti.kernel
    def _update(self, alpha: ti.f64):
        self.sums.clear_for_update()
        for I in ti.grouped(self.p):
            rz, rr = self._update_cell(I, alpha)
            self.sums.rz[None] += rz
            self.sums.rr[None] += rr

    @ti.kernel
    def _direction(self, beta: ti.f64):
        for I in ti.grouped(self.d):
            self._direction_cell(I, beta)

    @ti.kernel
    def _subtract_gradient(self):
        for a in ti.static(range(self.grid.dim)):
            for I in ti.grouped(self.grid.u[a]):
                self._subtract_gradient_face(a, I)

    @ti.kernel
    def _project_in_one_launch(self) -> ti.i32:
        """The whole projection on one thread (solvers.pcg's iteration, with the sums kept in registers): leaves
        r.r and b.b in the sums; returns the CG iterations."""
        iterations = 0
        for _ in range(1):  # one task: the loops below are nested in it, so they run in order on its thread
            rz, rr, bb = ti.f64(0.0), ti.f64(0.0), ti.f64(0.0)
            for I in ti.grouped(ti.ndrange(*self.grid.res)):
                c_rz, c_rr, c_bb = self._assemble_cell(I)
                rz += c_rz
                rr += c_rr
                bb += c_bb
            bnorm = ti.max(ti.sqrt(bb), 1e-300)
            while iterations < self.grid.cfg.max_iterations and ti.sqrt(rr) > self.grid.cfg.tolerance * bnorm:
                p_ap = ti.f64(0.0)
                for I in ti.grouped(ti.ndrange(*self.grid.res)):
                    p_ap += self._matvec_cell(I)
                if p_ap <= 0.0:  # the search direction vanished (converged to round-off)
                    break
                alpha = rz / p_ap
                rz_new = ti.f64(0.0)
                rr = 0.0
                for I in ti.grouped(ti.ndrange(*self.grid.res)):
                    c_rz, c_rr = self._update_cell(I, alpha)
                    rz_new += c_rz
                    rr += c_rr
                beta = rz_new / rz if rz > 0.0 else 0.0
                for I in ti.grouped(ti.ndrange(*self.grid.res)):
                    self._direction_cell(I, beta)
                rz = rz_new
                iterations += 1
            for a in ti.static(range(self.grid.dim)):
                for I in ti.grouped(ti.ndrange(*self.grid.u[a].shape)):
                    self._subtract_gradient_face(a, I)
            self.sums.rr[None] = rr
            self.sums.bb[None] = bb
        return iterations

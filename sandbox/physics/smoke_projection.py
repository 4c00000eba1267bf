"""The smoke grid's pressure projection: make the face velocities discretely divergence-free by solving

    sum over neighbours (p_c - p_n) = -h^2 div_c      (Neumann at the walls)

with Jacobi-preconditioned CG to the grid's tolerance, warm-started from the last step's pressure, then subtracting
the pressure gradient from interior faces. On the CPU a small grid is solved in one launch on one thread
(SmokeGrid.one_launch), with the sums in registers; else the host drives the iterations (core/solvers.py).
"""

import numpy as np
import taichi as ti

from ..core.loops import SPREAD_STRIDE, spread_item
from ..core.oriented import data_oriented
from ..core.solvers import CGResult, CGSums, pcg


@data_oriented
class PressureProjection:
    """The projection of `grid` (a SmokeGrid): the pressure and the CG vectors, one value per cell."""

    def __init__(self, grid):
        self.grid = grid
        res = grid.res
        self.p = grid.grid_field(res)  # pressure (times dt / density); a grid a world, where there are several
        self.r = grid.grid_field(res)
        self.z = grid.grid_field(res)
        self.d = grid.grid_field(res)
        self.ad = grid.grid_field(res)
        self.sums = CGSums()
        self.divergence_before = 0.0
        if grid.worlds > 1:
            self.due = ti.field(ti.i32, shape=grid.worlds)  # the worlds project_worlds solves

    def project(self, w: int = 0) -> CGResult:
        """Make world w's face velocities discretely divergence-free (to the CG tolerance)."""
        if self.grid.one_launch:
            iterations = int(self._project_in_one_launch(w))
            bb = float(self.sums.bb[None])
            self.divergence_before = bb**0.5 / self.grid.h**2
            return CGResult(iterations, float(self.sums.rr[None]) ** 0.5 / max(bb**0.5, 1e-300))
        self._assemble(w)
        self.divergence_before = float(self.sums.bb[None]) ** 0.5 / self.grid.h**2
        last = pcg(
            self.sums,
            lambda: self._matvec(w),
            lambda alpha: self._update(alpha, w),
            lambda beta: self._direction(beta, w),
            self.grid.cfg.tolerance,
            self.grid.cfg.max_iterations,
        )
        self._subtract_gradient(w)
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
    def _laplace(self, y: ti.template(), I, w):
        """sum over inside neighbours n of (y_I - y_n), in world w's grid."""
        s = 0.0
        at = ti.static(self.grid.at)
        for a in ti.static(range(self.grid.dim)):
            e = ti.Vector.unit(self.grid.dim, a, ti.i32)
            if I[a] > 0:
                s += y[at(I, w)] - y[at(I - e, w)]
            if I[a] < self.grid.res[a] - 1:
                s += y[at(I, w)] - y[at(I + e, w)]
        return s

    # Each CG stage per cell, shared by the host-driven kernels and the one-launch projection; each returns its
    # cell's terms of the stage's sums.
    @ti.func
    def _assemble_cell(self, I, w):
        """r = b - A p (warm start from the last step's pressure: the flow changes little between steps), z = M^-1 r,
        d = z; returns (r.z, r.r, b.b) terms."""
        b = -self.grid.h * self.grid.h * self.grid.divergence(I, w)
        r = b - self._laplace(self.p, I, w)
        z = r / self._neighbours(I)
        c = self.grid.at(I, w)
        self.r[c] = r
        self.z[c] = z
        self.d[c] = z
        return r * z, r * r, b * b

    @ti.func
    def _matvec_cell(self, I, w):
        """ad = A d; returns the d.Ad term."""
        ad = self._laplace(self.d, I, w)
        c = self.grid.at(I, w)
        self.ad[c] = ad
        return self.d[c] * ad

    @ti.func
    def _update_cell(self, I, alpha, w):
        """p += alpha d, r -= alpha Ad, z = M^-1 r; returns (r.z, r.r) terms."""
        c = self.grid.at(I, w)
        self.p[c] += alpha * self.d[c]
        r = self.r[c] - alpha * self.ad[c]
        z = r / self._neighbours(I)
        self.r[c] = r
        self.z[c] = z
        return r * z, r * r

    @ti.func
    def _direction_cell(self, I, beta, w):
        """d = z + beta d."""
        c = self.grid.at(I, w)
        self.d[c] = self.z[c] + beta * self.d[c]

    @ti.func
    def _subtract_gradient_face(self, a: ti.template(), I, w):
        if 0 < I[a] < self.grid.res[a]:
            below = I - ti.Vector.unit(self.grid.dim, a, ti.i32)
            at = ti.static(self.grid.at)
            self.grid.u[a][at(I, w)] -= (self.p[at(I, w)] - self.p[at(below, w)]) / self.grid.h

    @ti.kernel
    def _assemble(self, w: ti.i32):
        self.sums.clear_for_assembly()
        for I in ti.grouped(ti.ndrange(*self.grid.res)):
            rz, rr, bb = self._assemble_cell(I, w)
            self.sums.rz[None] += rz
            self.sums.rr[None] += rr
            self.sums.bb[None] += bb

    @ti.kernel
    def _matvec(self, w: ti.i32):
        self.sums.p_ap[None] = 0.0
        for I in ti.grouped(ti.ndrange(*self.grid.res)):
            self.sums.p_ap[None] += self._matvec_cell(I, w)

    @ti.kernel
    def _update(self, alpha: ti.f64, w: ti.i32):
        self.sums.clear_for_update()
        for I in ti.grouped(ti.ndrange(*self.grid.res)):
            rz, rr = self._update_cell(I, alpha, w)
            self.sums.rz[None] += rz
            self.sums.rr[None] += rr

    @ti.kernel
    def _direction(self, beta: ti.f64, w: ti.i32):
        for I in ti.grouped(ti.ndrange(*self.grid.res)):
            self._direction_cell(I, beta, w)

    @ti.kernel
    def _subtract_gradient(self, w: ti.i32):
        for a in ti.static(range(self.grid.dim)):
            for I in ti.grouped(ti.ndrange(*self.grid.face_res[a])):
                self._subtract_gradient_face(a, I, w)

    def project_worlds(self, worlds: list[int]) -> None:
        """Make the face velocities of each world in `worlds` divergence-free, every world's projection on one thread
        of its own and all of them in one launch (a grid that one_launch solves); each world's sums are its own, in
        its lone run's order."""
        due = np.zeros(self.grid.worlds, np.int32)
        due[worlds] = 1
        self.due.from_numpy(due)
        self._project_due_worlds()

    @ti.kernel
    def _project_due_worlds(self):
        for u in range(self.grid.worlds * SPREAD_STRIDE):  # the worlds spread over the threads (spread_item)
            w = spread_item(u)
            if w >= 0:
                if self.due[w] != 0:
                    self._solve(w)  # its sums are its own (the lone run's diagnostics are not kept per world)

    @ti.kernel
    def _project_in_one_launch(self, w: ti.i32) -> ti.i32:
        """The whole projection on one thread (solvers.pcg's iteration, with the sums kept in registers): leaves
        r.r and b.b in the sums; returns the CG iterations."""
        iterations = 0
        for _ in range(1):  # one task: the loops below are nested in it, so they run in order on its thread
            done, rr, bb = self._solve(w)
            self.sums.rr[None] = rr
            self.sums.bb[None] = bb
            iterations = done
        return iterations

    @ti.func
    def _solve(self, w):
        """World w's projection, its loops in order on the calling thread; returns (CG iterations, r.r, b.b)."""
        iterations = 0
        rz, rr, bb = ti.f64(0.0), ti.f64(0.0), ti.f64(0.0)
        for I in ti.grouped(ti.ndrange(*self.grid.res)):
            c_rz, c_rr, c_bb = self._assemble_cell(I, w)
            rz += c_rz
            rr += c_rr
            bb += c_bb
        bnorm = ti.max(ti.sqrt(bb), 1e-300)
        while iterations < self.grid.cfg.max_iterations and ti.sqrt(rr) > self.grid.cfg.tolerance * bnorm:
            p_ap = ti.f64(0.0)
            for I in ti.grouped(ti.ndrange(*self.grid.res)):
                p_ap += self._matvec_cell(I, w)
            if p_ap <= 0.0:  # the search direction vanished (converged to round-off)
                break
            alpha = rz / p_ap
            rz_new = ti.f64(0.0)
            rr = 0.0
            for I in ti.grouped(ti.ndrange(*self.grid.res)):
                c_rz, c_rr = self._update_cell(I, alpha, w)
                rz_new += c_rz
                rr += c_rr
            beta = rz_new / rz if rz > 0.0 else 0.0
            for I in ti.grouped(ti.ndrange(*self.grid.res)):
                self._direction_cell(I, beta, w)
            rz = rz_new
            iterations += 1
        for a in ti.static(range(self.grid.dim)):
            for I in ti.grouped(ti.ndrange(*self.grid.face_res[a])):
                self._subtract_gradient_face(a, I, w)
        return iterations, rr, bb

"""A small stable-fluids smoke solver (Stam 1999) on a MAC grid, in 2D and 3D, whose velocity carries particles.

State: face velocities u_a (one field per axis a, normal to the faces across that axis) and a cell temperature T.
Each step:
  1. sources: cells inside a source region are set to its temperature (and its inflow velocity on their faces);
  2. buoyancy: vertical faces gain dt * buoyancy * (T - ambient) (T averaged onto the face), along -gravity's axis;
     T relaxes to the ambient at `cooling` per unit time;
  3. advection: velocity and temperature semi-Lagrangian, back-traced with the midpoint rule, multilinear lookups;
  4. projection: solve sum over neighbours (p_c - p_n) = -h^2 div_c (Neumann at the walls) by Jacobi-
     preconditioned CG to `tolerance`, warm-started from the last step's pressure, then subtract the pressure
     gradient from interior faces. The discrete divergence left is the solver's residual over h^2: divergence-free
     to the tolerance (tested).
The walls of the domain are solid (normal velocity 0). Particles read the velocity by multilinear interpolation
of each face component (sample()); VelocityField adds it to the designed elements.
"""

import math

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented
from ..core.solvers import CGResult
from ..core.state import WORLDS
from .smoke_projection import PressureProjection
from .term import Term, register

# On the CPU backend a grid of up to this many cells is projected in one kernel launch on one thread (assembly, every
# CG iteration, the gradient), instead of launching three kernels and reading three sums back per CG iteration
# (each launch a 20-40 us round trip through the thread pool): faster up to about 37,000 cells, a draw at 90,000
# (`python benchmarks/smoke_projection.py` times both ways).
ONE_LAUNCH_CELLS = 50_000


@data_oriented
class SmokeGrid:
    """MAC-grid smoke: face velocities, cell temperature, and a CG pressure projection."""

    def __init__(self, dim: int, lo, hi, cfg, gravity, on_cpu: bool = True, worlds: int = 1):
        """`on_cpu`: Taichi runs on the CPU backend (a small grid is then projected in one launch: ONE_LAUNCH_CELLS);
        `worlds`: a grid for each world of a simulation of worlds (core/worlds.py), each field a leading axis of
        them, each stepped alone (`w`, its index, in every kernel and lookup; one grid: its lone run's fields)."""
        self.dim = dim
        self.worlds = worlds
        self.lo_np = np.asarray(lo, dtype=float)
        extent = np.asarray(hi, dtype=float) - self.lo_np
        self.h = float(extent.max() / cfg.resolution)
        self.res = tuple(max(2, int(math.ceil(e / self.h - 1e-9))) for e in extent)
        self.one_launch = on_cpu and math.prod(self.res) <= ONE_LAUNCH_CELLS
        self.cfg = cfg
        g = np.asarray(gravity, dtype=float)
        self.up_axis = int(np.argmax(np.abs(g))) if np.any(g) else dim - 1
        self.up_sign = -float(np.sign(g[self.up_axis])) if np.any(g) else 1.0
        self.u = []
        self.u_new = []
        self.face_res = []  # the faces across each axis, one grid's
        for a in range(dim):
            shape = tuple(r + (1 if b == a else 0) for b, r in enumerate(self.res))
            self.face_res.append(shape)
            self.u.append(self.grid_field(shape))  # velocity normal to faces across axis a
            self.u_new.append(self.grid_field(shape))
            setattr(self, f"u{a}", self.u[a])  # by name too: the state declares them
        self.T = self.grid_field(self.res)  # cell temperature (degrees)
        self.T_new = self.grid_field(self.res)
        self.projection = PressureProjection(self)
        n_src = max(len(cfg.sources), 1)
        self.src_lo = ti.Vector.field(dim, float, shape=n_src)
        self.src_hi = ti.Vector.field(dim, float, shape=n_src)
        self.src_T = ti.field(float, shape=n_src)
        self.src_v = ti.Vector.field(dim, float, shape=n_src)
        self.n_sources = len(cfg.sources)
        if cfg.sources:  # one copy kernel for the table (in the build's batched copy)
            transfer.upload(
                [
                    (self.src_lo, np.array([src.lo for src in cfg.sources], float)),
                    (self.src_hi, np.array([src.hi for src in cfg.sources], float)),
                    (self.src_T, np.array([src.temperature for src in cfg.sources], float)),
                    (self.src_v, np.array([src.velocity or [0.0] * dim for src in cfg.sources], float)),
                ]
            )
        self._lo = ti.Vector(list(self.lo_np))
        self.T.fill(cfg.ambient)
        self.last = CGResult(0, 0.0)
        self.divergence_before = 0.0

    def grid_field(self, shape: tuple):
        """A real field of one grid's `shape`, with a leading axis of the worlds where there are several."""
        return ti.field(float, shape=shape if self.worlds == 1 else (self.worlds, *shape))

    @ti.func
    def at(self, I, w):
        """The index of one grid's cell I in world w's grid (I itself for a lone run)."""
        if ti.static(self.worlds == 1):
            return I
        else:
            return ti.Vector([w] + [I[a] for a in ti.static(range(self.dim))])

    def describe(self) -> str:
        return f"{'x'.join(map(str, self.res))} MAC grid, cell {self.h:.3g}"

    # ------------------------------------------------------------------ lookups
    @ti.func
    def _lerp(self, f: ti.template(), g, shape, world):
        """Multilinear interpolation of world `world`'s grid of field f at grid coordinate g (index space), clamped
        to one grid's shape."""
        base = ti.floor(g)
        frac = g - base
        total = 0.0
        # a run-time loop over the corners, not unrolled: a velocity sample inlines dim of these, advection three
        # samples, and the unrolled 3D advection took seconds to compile
        for c in range(2**self.dim):
            w = 1.0
            idx = ti.Vector.zero(ti.i32, self.dim)
            for a in ti.static(range(self.dim)):
                bit = (c >> a) & 1
                w *= ti.select(bit, frac[a], 1.0 - frac[a])
                idx[a] = ti.min(ti.max(ti.cast(base[a], ti.i32) + bit, 0), shape[a] - 1)
            total += w * f[self.at(idx, world)]
        return total

    @ti.func
    def face_value(self, a: ti.template(), x, w):
        """Velocity component a at position x in world w's grid (faces across axis a sit at integer index along a)."""
        g = (x - self._lo) / self.h - 0.5
        g[a] += 0.5
        return self._lerp(self.u[a], g, self.face_res[a], w)

    @ti.func
    def sample(self, x, w):
        """Velocity at position x (a dim-vector) in world w's grid (0: a lone run's)."""
        v = ti.Vector.zero(float, self.dim)
        for a in ti.static(range(self.dim)):
            v[a] = self.face_value(a, x, w)
        return v

    @ti.func
    def temperature_at(self, x, w):
        return self._lerp(self.T, (x - self._lo) / self.h - 0.5, self.res, w)

    @ti.func
    def face_position(self, a: ti.template(), I):
        x = self._lo + (ti.cast(I, float) + 0.5) * self.h
        x[a] -= 0.5 * self.h
        return x

    # ------------------------------------------------------------------ step
    def step(self, dt: float, w: int = 0) -> None:
        """Advance the smoke of world w's grid (0: a lone run's) by dt (simulated seconds)."""
        self._advance(dt, w)
        self.project(w)

    def step_worlds(self, dt: float, worlds: list[int]) -> None:
        """Advance the grids of `worlds` by dt: each world's sources and advection, then (a grid one_launch solves)
        every world's projection in one launch, each on a thread of its own."""
        for w in worlds:
            self._advance(dt, w)
        if self.one_launch:
            self.projection.project_worlds(worlds)
        else:
            for w in worlds:
                self.project(w)

    def _advance(self, dt: float, w: int) -> None:
        """World w's sources, buoyancy and advection (the step before its projection)."""
        self._sources_and_forces(dt, w)
        for a in range(self.dim):
            self._advect_face(a, dt, w)
        self._advect_temperature(dt, w)
        for a in range(self.dim):
            self._copy(self.u_new[a], self.u[a], self.face_res[a], w)
        self._copy(self.T_new, self.T, self.res, w)

    @ti.kernel
    def _copy(self, src: ti.template(), dst: ti.template(), shape: ti.template(), w: ti.i32):
        for I in ti.grouped(ti.ndrange(*shape)):
            dst[self.at(I, w)] = src[self.at(I, w)]

    @ti.func
    def _inside(self, k, x):
        ok = True
        for a in ti.static(range(self.dim)):
            if x[a] < self.src_lo[k][a] or x[a] > self.src_hi[k][a]:
                ok = False
        return ok

    @ti.kernel
    def _sources_and_forces(self, dt: float, w: ti.i32):
        for I in ti.grouped(ti.ndrange(*self.res)):
            x = self._lo + (ti.cast(I, float) + 0.5) * self.h
            c = self.at(I, w)
            self.T[c] += dt * self.cfg.cooling * (self.cfg.ambient - self.T[c])
            for k in range(self.n_sources):
                if self._inside(k, x):
                    self.T[c] = self.src_T[k]
        up = ti.static(self.up_axis)
        for I in ti.grouped(ti.ndrange(*self.face_res[up])):
            if 0 < I[up] < self.res[up]:
                below = I
                below[up] -= 1
                t_face = 0.5 * (self.T[self.at(I, w)] + self.T[self.at(below, w)])
                self.u[up][self.at(I, w)] += dt * self.cfg.buoyancy * self.up_sign * (t_face - self.cfg.ambient)
        for a in ti.static(range(self.dim)):
            for I in ti.grouped(ti.ndrange(*self.face_res[a])):
                x = self.face_position(a, I)
                for k in range(self.n_sources):
                    if self._inside(k, x) and self.src_v[k].norm() > 0:
                        self.u[a][self.at(I, w)] = self.src_v[k][a]

    @ti.kernel
    def _advect_face(self, a: ti.template(), dt: float, w: ti.i32):
        for I in ti.grouped(ti.ndrange(*self.face_res[a])):
            x = self.face_position(a, I)
            mid = x - 0.5 * dt * self.sample(x, w)
            back = x - dt * self.sample(mid, w)
            value = self.face_value(a, back, w)
            if I[a] == 0 or I[a] == self.res[a]:
                value = 0.0  # solid walls
            self.u_new[a][self.at(I, w)] = value

    @ti.kernel
    def _advect_temperature(self, dt: float, w: ti.i32):
        for I in ti.grouped(ti.ndrange(*self.res)):
            x = self._lo + (ti.cast(I, float) + 0.5) * self.h
            mid = x - 0.5 * dt * self.sample(x, w)
            back = x - dt * self.sample(mid, w)
            self.T_new[self.at(I, w)] = self.temperature_at(back, w)

    # ------------------------------------------------------------------ projection (physics/smoke_projection.py)
    def project(self, w: int = 0) -> CGResult:
        """Make world w's face velocities discretely divergence-free (to the CG tolerance)."""
        self.last = self.projection.project(w)
        self.divergence_before = self.projection.divergence_before
        return self.last

    @ti.func
    def divergence(self, I, w):
        s = 0.0
        for a in ti.static(range(self.dim)):
            e = ti.Vector.unit(self.dim, a, ti.i32)
            s += self.u[a][self.at(I + e, w)] - self.u[a][self.at(I, w)]
        return s / self.h

    def divergence_norm(self, w: int = 0) -> float:
        """L2 norm of world w's discrete divergence now (after a projection: the solver's residual / h^2)."""
        return float(self._divergence_norm(w)) ** 0.5

    @ti.kernel
    def _divergence_norm(self, w: ti.i32) -> ti.f64:
        total = ti.f64(0.0)
        for I in ti.grouped(ti.ndrange(*self.res)):
            d = self.divergence(I, w)
            total += d * d
        return total


@register
class Smoke(Term):
    """The smoke grid as a term: it steps every smoke.interval particle steps, before the particles' step."""

    key = "smoke"
    stage = "flow"

    @staticmethod
    def wanted(parts) -> bool:
        return parts.scene.smoke is not None

    @staticmethod
    def host_work(scene) -> str | None:
        return "the smoke grid steps between particle steps" if scene.smoke else None

    def __init__(self, parts):
        world, cfg = parts.scene.world, parts.scene.smoke
        self.p = parts.state.particles
        worlds = self.p.world_count if self.p.worlds else 1
        on_cpu = parts.model.arch == "cpu"
        self.grid = SmokeGrid(parts.model.dim, world.lo, world.hi, cfg, world.gravity, on_cpu, worlds)
        self.every = cfg.interval

    def words(self, where: str) -> list[str]:
        if where != "before":
            return []
        return [f"smoke: stable fluids on a {self.grid.describe()} (buoyancy, advection, CG projection)"]

    def before_step(self, state) -> None:
        """The grid steps every `interval` particle steps, a world's counted from its own start."""
        if self.grid.worlds == 1:
            if state.step % self.every == 0:
                self.grid.step(state.dt * self.every)
            return
        live = state.live_count() // self.p.world_size
        due = [w for w, steps in enumerate(state.world_steps()[:live]) if steps % self.every == 0]
        if due:
            self.grid.step_worlds(state.dt * self.every, due)

    def declare(self, state) -> None:
        """The grid's velocities, temperatures and pressure (the warm start of the next projection): with worlds, a
        row of each a world."""
        grid = self.grid
        rows = WORLDS if grid.worlds > 1 else ""
        state.declare("smoke", grid, tuple(f"u{a}" for a in range(grid.dim)) + ("T",), rows=rows)
        state.declare("smoke", grid.projection, ("p",), rows=rows)

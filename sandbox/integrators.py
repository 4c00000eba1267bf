"""Time integrators: a registry of name -> class, one signature for all: `step(dt)` advances the simulation by dt.

Most integrators are a sequence of stages, each one force evaluation followed by a per-particle update:
  sim.eval_rates(then_update=dt, stage=k)
                          forces into p.f (and heat rates into p.dhdt) at the current positions and velocities,
                          then the integrator's ti.func update_particle(i, dt, k) on every particle, in one launch
  sim.finish_particle()   (ti.func) walls / periodic wrap and the explicit heat update for one particle, called by
                          the last stage's update
A staged integrator (`stages` > 0) runs on every path symplectic Euler runs on: the long way (a launch per
evaluation), many steps to a launch (Simulation._fused_steps) and a team of threads (team.py); each path runs the
stages in order with the same per-evaluation passes, so all three give the same trajectory bit for bit.
Particle updates write `x[i] = x[i] + ...`, never `x[i] += ...`: Taichi turns `+=` on a field into an atomic
(a compare-and-swap loop for floats) unless the index is the loop's own, and update_particle runs where i is read
from the cell order (the per-particle pass, the team's workers).
Walls act once per step, at its end (multi-stage methods do not see them between stages). Heat is a first-order
equation with its own stepping: explicit Euler on the rates of the step's last force evaluation.

| name             | order | symplectic | force evaluations per step |
| forward_euler    | 1     | no         | 1                          |
| symplectic_euler | 1     | yes        | 1                          |
| midpoint         | 2     | no         | 2                          |
| verlet           | 2     | yes        | 1 (position Verlet as leapfrog)  |
| velocity_verlet  | 2     | yes        | 1 (leapfrog), + 1 per Simulation.step call            |
| rk4              | 4     | no         | 4                          |
| implicit_euler   | 1     | no         | 1 + conjugate-gradient iterations on the springs |
"""

import taichi as ti

from .oriented import data_oriented
from .scene_tables import INTEGRATORS
from .solvers import CGSums, pcg

REGISTRY: dict[str, type] = {}


def register(name: str):
    def deco(cls):
        cls.name = name
        REGISTRY[name] = cls
        return cls

    return deco


def make_integrator(name: str, sim) -> "Integrator":
    """The integrator registered under `name`, bound to `sim`."""
    if name not in REGISTRY:
        raise ValueError(f"unknown integrator {name!r}; expected one of {', '.join(REGISTRY)}")
    return REGISTRY[name](sim)


@data_oriented
class Integrator:
    name = "base"
    order = 1
    symplectic = False
    # Largest stable h*w on an undamped oscillator (theory); 0: unstable at any step; inf: unconditionally stable.
    stable_h_omega = 0.0
    # The h*w that substeps = "auto" aims for: half the limit, or for the methods that are never stable on an
    # undamped spring a step where their amplitude grows by under 1% per period (forward Euler 0.01: 0.03%... see
    # the study's growth table).
    auto_h_omega = 0.01

    # Stages of a step: each is a force evaluation and then update_particle(i, dt, stage) on every particle (see
    # the module docstring). 0: the integrator steps its own way (step() launches its own kernels).
    stages = 1

    def __init__(self, sim):
        self.sim = sim
        self.p = sim.particles

    def step(self, dt: float, first_stage: int = 0) -> None:
        """One step of dt from stage `first_stage` on (a step that a fused launch left after its first stages)."""
        for stage in range(first_stage, self.stages):
            self.sim.eval_rates(then_update=dt, stage=stage)

    def begin(self, dt: float) -> None:
        """Called before a run of steps of `dt` (Simulation.step): a leapfrog method staggers its state here."""

    def end(self, dt: float) -> None:
        """Called after a run of steps of `dt`: the state is synchronised here for anything outside stepping."""

    def _stage_fields(self, *names: str) -> None:
        """Allocate per-particle vector buffers (x0, v0, ...) that only this integrator needs."""
        for name in names:
            setattr(self, name, ti.Vector.field(self.sim.dim, float, shape=self.sim.capacity))


@register("symplectic_euler")
class SymplecticEuler(Integrator):
    """v += dt f(x, v)/m; x += dt v (semi-implicit Euler: first order, symplectic, stable for dt w < 2)."""

    symplectic = True
    stable_h_omega = 2.0
    auto_h_omega = 1.0

    @ti.func
    def update_particle(self, i, dt, stage):
        self.p.v[i] = self.p.v[i] + dt * self.p.f[i] / self.p.mass[i]
        self.p.x[i] = self.p.x[i] + dt * self.p.v[i]
        self.sim.finish_particle(i, dt)


@register("forward_euler")
class ForwardEuler(Integrator):
    """x += dt v; v += dt f(x, v)/m (explicit Euler: first order; an undamped oscillator's amplitude grows)."""

    @ti.func
    def update_particle(self, i, dt, stage):
        self.p.x[i] = self.p.x[i] + dt * self.p.v[i]
        self.p.v[i] = self.p.v[i] + dt * self.p.f[i] / self.p.mass[i]
        self.sim.finish_particle(i, dt)


@register("midpoint")
class Midpoint(Integrator):
    """Explicit midpoint (RK2): evaluate at t + dt/2 from an Euler half step, then take the full step with those
    rates. Second order; an undamped oscillator's amplitude grows slowly (by (dt w)^4 / 8 per step)."""

    order = 2
    stages = 2
    auto_h_omega = 0.05

    def __init__(self, sim):
        super().__init__(sim)
        self._stage_fields("x0", "v0")

    @ti.func
    def update_particle(self, i, dt, stage):
        p = self.p
        if stage == 0:  # rates at the step's start: keep it, and go half a step along them
            self.x0[i], self.v0[i] = p.x[i], p.v[i]
            p.x[i] = p.x[i] + 0.5 * dt * p.v[i]
            p.v[i] = p.v[i] + 0.5 * dt * p.f[i] / p.mass[i]
        else:  # rates at the midpoint: the whole step along them
            v_mid = p.v[i]
            p.x[i] = self.x0[i] + dt * v_mid
            p.v[i] = self.v0[i] + dt * p.f[i] / p.mass[i]
            self.sim.finish_particle(i, dt)


@register("rk4")
class RungeKutta4(Integrator):
    """Classical fourth-order Runge-Kutta: the high-accuracy reference (4 evaluations per step, not symplectic)."""

    order = 4
    stages = 4
    stable_h_omega = 2 * 2**0.5
    auto_h_omega = 1.4

    def __init__(self, sim):
        super().__init__(sim)
        self._stage_fields("x0", "v0", "dx", "dv")

    @ti.func
    def update_particle(self, i, dt, stage):
        """Stage k's rates (at the current trial state) k1..k4: accumulate dx, dv = k1 + 2 k2 + 2 k3 and set the next
        trial state x0 + (dt/2, dt/2, dt) k; after k4 the step is x0 + dt/6 (k1 + 2 k2 + 2 k3 + k4)."""
        p = self.p
        kx, kv = p.v[i], p.f[i] / p.mass[i]
        if stage == 0:
            self.x0[i], self.v0[i] = p.x[i], p.v[i]
            self.dx[i], self.dv[i] = kx, kv
            p.x[i] = self.x0[i] + 0.5 * dt * kx
            p.v[i] = self.v0[i] + 0.5 * dt * kv
        elif stage < 3:
            self.dx[i] = self.dx[i] + 2.0 * kx
            self.dv[i] = self.dv[i] + 2.0 * kv
            advance = 0.5 if stage == 1 else 1.0
            p.x[i] = self.x0[i] + advance * dt * kx
            p.v[i] = self.v0[i] + advance * dt * kv
        else:
            p.x[i] = self.x0[i] + dt / 6.0 * (self.dx[i] + kx)
            p.v[i] = self.v0[i] + dt / 6.0 * (self.dv[i] + kv)
            self.sim.finish_particle(i, dt)


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

    def __init__(self, sim):
        super().__init__(sim)
        self.tolerance = sim.scene.world.implicit_tolerance
        self.max_iterations = sim.scene.world.implicit_max_iterations
        self.last_iterations = 0
        self.total_iterations = 0
        self.last_residual = 0.0
        self._stage_fields("dv", "r", "z", "d", "Ap", "b")
        self.diag = ti.field(float, shape=sim.capacity)  # Jacobi preconditioner: m_i + trace of its blocks / dim
        self.springs = sim.springs
        self.has_springs = sim.springs is not None
        s = max(sim.springs.count, 1) if self.has_springs else 1
        dim = sim.dim
        self.block = ti.Matrix.field(dim, dim, float, shape=s)  # h D_s + h^2 K_s per spring
        self.kmat = ti.Matrix.field(dim, dim, float, shape=s)  # K_s per spring
        self.sums = CGSums()

    def step(self, dt: float, first_stage: int = 0) -> None:
        self.sim.eval_rates()
        self._assemble(dt)
        result = pcg(self.sums, self._matvec, self._update, self._direction, self.tolerance, self.max_iterations)
        self.last_iterations = result.iterations
        self.total_iterations += result.iterations
        self.last_residual = result.relative_residual
        self._finish(dt)

    @ti.func
    def _spring_blocks(self, s, h):
        a, b = self.springs.i[s], self.springs.j[s]
        d = self.sim.domain.separation(self.p.x[a], self.p.x[b])
        length = ti.max(d.norm(), 1e-12)
        n = d / length
        nn = n.outer_product(n)
        eye = ti.Matrix.identity(float, self.sim.dim)
        k = self.springs.factor[s] * self.springs.ks[s]
        c = self.springs.factor[s] * self.springs.kd[s]
        kmat = k * (nn + ti.max(0.0, 1.0 - self.springs.rest[s] / length) * (eye - nn))
        return kmat, h * c * nn + h * h * kmat

    @ti.kernel
    def _assemble(self, h: float):
        self.sums.clear_for_assembly()
        if ti.static(self.has_springs):
            self.sim.loops.light()
            for s in range(self.springs.span[None]):
                if self.springs.alive[s]:
                    self.kmat[s], self.block[s] = self._spring_blocks(s, h)
        self.sim.loops.light()
        for i in range(self.p.n[None]):
            b = h * self.p.f[i]
            diag = self.p.mass[i]
            if ti.static(self.has_springs):
                for k in range(self.springs.max_bonds):
                    s = self.springs.bonds[i, k]
                    if s < 0:
                        break
                    if self.springs.alive[s]:
                        j = self.springs.other_end(i, s)
                        b += h * h * (self.kmat[s] @ (self.p.v[j] - self.p.v[i]))
                        diag += self.block[s].trace() / self.sim.dim
            self.b[i] = b
            self.diag[i] = diag
            self.dv[i] = ti.Vector.zero(float, self.sim.dim)
            self.r[i] = b
            self.z[i] = b / diag
            self.d[i] = self.z[i]
            self.sums.rz[None] += b.dot(self.z[i])
            self.sums.rr[None] += b.dot(b)
            self.sums.bb[None] += b.dot(b)

    @ti.kernel
    def _matvec(self):
        self.sums.p_ap[None] = 0.0
        self.sim.loops.light()
        for i in range(self.p.n[None]):
            ap = self.p.mass[i] * self.d[i]
            if ti.static(self.has_springs):
                for k in range(self.springs.max_bonds):
                    s = self.springs.bonds[i, k]
                    if s < 0:
                        break
                    if self.springs.alive[s]:
                        j = self.springs.other_end(i, s)
                        ap += self.block[s] @ (self.d[i] - self.d[j])
            self.Ap[i] = ap
            self.sums.p_ap[None] += self.d[i].dot(ap)

    @ti.kernel
    def _update(self, alpha: ti.f64):
        self.sums.clear_for_update()
        self.sim.loops.light()
        for i in range(self.p.n[None]):
            self.dv[i] += alpha * self.d[i]
            self.r[i] -= alpha * self.Ap[i]
            self.z[i] = self.r[i] / self.diag[i]
            self.sums.rz[None] += self.r[i].dot(self.z[i])
            self.sums.rr[None] += self.r[i].dot(self.r[i])

    @ti.kernel
    def _direction(self, beta: ti.f64):
        self.sim.loops.light()
        for i in range(self.p.n[None]):
            self.d[i] = self.z[i] + beta * self.d[i]

    @ti.kernel
    def _finish(self, h: float):
        self.sim.loops.light()
        for i in range(self.p.n[None]):
            self.p.v[i] = self.p.v[i] + self.dv[i]
            self.p.x[i] = self.p.x[i] + h * self.p.v[i]
            self.sim.finish_particle(i, h)


from . import leapfrog  # noqa: E402, F401 - registers velocity_verlet and verlet

# The order the window's i key cycles through and reports list: the registry of names (scene_tables.INTEGRATORS).
for _name in INTEGRATORS:
    REGISTRY[_name] = REGISTRY.pop(_name)

"""The explicit one-step integrators: symplectic and forward Euler, explicit midpoint and classical RK4, each as
stages (a force evaluation, then update_particle on every particle)."""

import taichi as ti

from .base import Integrator, register


@register("symplectic_euler")
class SymplecticEuler(Integrator):
    """v += dt f(x, v)/m; x += dt v (semi-implicit Euler: first order, symplectic, stable for dt w < 2)."""

    symplectic = True
    stable_h_omega = 2.0
    auto_h_omega = 1.0

    @ti.func
    def update_particle(self, i, dt, stage):
        self.p.v[i] = self.p.v[i] + dt * self.f[i] / self.p.mass[i]
        self.p.x[i] = self.p.x[i] + dt * self.p.v[i]
        self.rates.finish_particle(i, dt)


@register("forward_euler")
class ForwardEuler(Integrator):
    """x += dt v; v += dt f(x, v)/m (explicit Euler: first order; an undamped oscillator's amplitude grows)."""

    @ti.func
    def update_particle(self, i, dt, stage):
        self.p.x[i] = self.p.x[i] + dt * self.p.v[i]
        self.p.v[i] = self.p.v[i] + dt * self.f[i] / self.p.mass[i]
        self.rates.finish_particle(i, dt)


@register("midpoint")
class Midpoint(Integrator):
    """Explicit midpoint (RK2): evaluate at t + dt/2 from an Euler half step, then take the full step with those
    rates. Second order; an undamped oscillator's amplitude grows slowly (by (dt w)^4 / 8 per step)."""

    order = 2
    stages = 2
    auto_h_omega = 0.05

    def __init__(self, rates, state):
        super().__init__(rates, state)
        self._stage_fields("x0", "v0")

    @ti.func
    def update_particle(self, i, dt, stage):
        p = self.p
        if stage == 0:  # rates at the step's start: keep it, and go half a step along them
            self.x0[i], self.v0[i] = p.x[i], p.v[i]
            p.x[i] = p.x[i] + 0.5 * dt * p.v[i]
            p.v[i] = p.v[i] + 0.5 * dt * self.f[i] / p.mass[i]
        else:  # rates at the midpoint: the whole step along them
            v_mid = p.v[i]
            p.x[i] = self.x0[i] + dt * v_mid
            p.v[i] = self.v0[i] + dt * self.f[i] / p.mass[i]
            self.rates.finish_particle(i, dt)


@register("rk4")
class RungeKutta4(Integrator):
    """Classical fourth-order Runge-Kutta: the high-accuracy reference (4 evaluations per step, not symplectic)."""

    order = 4
    stages = 4
    stable_h_omega = 2 * 2**0.5
    auto_h_omega = 1.4

    def __init__(self, rates, state):
        super().__init__(rates, state)
        self._stage_fields("x0", "v0", "dx", "dv")

    @ti.func
    def update_particle(self, i, dt, stage):
        """Stage k's rates (at the current trial state) k1..k4: accumulate dx, dv = k1 + 2 k2 + 2 k3 and set the next
        trial state x0 + (dt/2, dt/2, dt) k; after k4 the step is x0 + dt/6 (k1 + 2 k2 + 2 k3 + k4)."""
        p = self.p
        kx, kv = p.v[i], self.f[i] / p.mass[i]
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
            self.rates.finish_particle(i, dt)

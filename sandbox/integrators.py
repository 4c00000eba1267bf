"""Time integrators: a registry of name -> class, one signature for all: `step(dt)` advances the simulation by dt.

Each integrator is a few lines over the simulation's shared pieces:
  sim.eval_rates()        forces into p.f (and heat rates into p.dTdt) at the current positions and velocities
  sim.finish_particle()   (ti.func) walls / periodic wrap and the explicit heat update for one particle
Heat always advances by explicit Euler on the rates of the step's first evaluation.
"""

import taichi as ti

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


@ti.data_oriented
class Integrator:
    name = "base"
    order = 1
    symplectic = False

    def __init__(self, sim):
        self.sim = sim
        self.p = sim.particles

    def step(self, dt: float) -> None:
        raise NotImplementedError


@register("symplectic_euler")
class SymplecticEuler(Integrator):
    """v += dt f(x, v)/m; x += dt v (semi-implicit Euler: first order, symplectic, stable for dt w < 2)."""

    symplectic = True

    def step(self, dt: float) -> None:
        self.sim.eval_rates()
        self._update(dt)

    @ti.kernel
    def _update(self, dt: float):
        for i in range(self.p.n[None]):
            self.p.v[i] += dt * self.p.f[i] / self.p.mass[i]
            self.p.x[i] += dt * self.p.v[i]
            self.sim.finish_particle(i, dt)


@register("forward_euler")
class ForwardEuler(Integrator):
    """x += dt v; v += dt f(x, v)/m (explicit Euler: first order; an undamped oscillator's amplitude grows)."""

    def step(self, dt: float) -> None:
        self.sim.eval_rates()
        self._update(dt)

    @ti.kernel
    def _update(self, dt: float):
        for i in range(self.p.n[None]):
            self.p.x[i] += dt * self.p.v[i]
            self.p.v[i] += dt * self.p.f[i] / self.p.mass[i]
            self.sim.finish_particle(i, dt)


@register("velocity_verlet")
class VelocityVerlet(Integrator):
    """v += dt/2 a; x += dt v; a = f(x)/m; v += dt/2 a (second order, symplectic for position-only forces)."""

    order = 2
    symplectic = True

    def step(self, dt: float) -> None:
        self.sim.eval_rates()
        self._half_kick_drift(dt)
        self.sim.eval_rates()
        self._half_kick(dt)

    @ti.kernel
    def _half_kick_drift(self, dt: float):
        for i in range(self.p.n[None]):
            self.p.v[i] += 0.5 * dt * self.p.f[i] / self.p.mass[i]
            self.p.x[i] += dt * self.p.v[i]
            self.sim.finish_particle(i, dt)

    @ti.kernel
    def _half_kick(self, dt: float):
        for i in range(self.p.n[None]):
            self.p.v[i] += 0.5 * dt * self.p.f[i] / self.p.mass[i]

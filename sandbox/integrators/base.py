"""The integrator registry, the base class and the interface an integrator steps through (see the package
docstring for the stages)."""

from typing import Protocol

import taichi as ti

from ..core.oriented import data_oriented


class StepRates(Protocol):
    """What an integrator may use of the simulation it steps (Simulation provides it): the particles, the rates and
    each particle's end-of-step work (step/rates.py), the loop policy, and the few parts implicit Euler assembles
    its matrix from."""

    dim: int  # 2 or 3
    capacity: int  # particle slots (field rows)
    particles: object  # model.ParticleFields: x, v, f (force), mass, ... (rows 0..n-1 live)
    loops: object  # loops.LoopPolicy: how each particle loop runs (parallel or serial)
    domain: object  # physics/boundary.Domain: separation() between two positions
    springs: object  # physics/springs.Springs or None
    heat: object  # physics/heat.Heat or None
    scene: object  # the Scene (world settings: implicit tolerance and iterations)

    def eval_rates(self, then_update: float | None = None, stage: int = 0) -> None:
        """Forces into particles.f (and heat rates) at the current state; with `then_update`, the integrator's
        update_particle(i, then_update, stage) on every particle in the same launch."""

    def finish_particle(self, i, dt) -> None:
        """(ti.func) Walls and the explicit heat update of particle i at a step's end, after its last stage."""


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

    def __init__(self, sim: StepRates):
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

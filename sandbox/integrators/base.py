"""The integrator registry and the base class: an integrator steps a State through the Rates (see the package
docstring for the stages)."""

import taichi as ti

from ..core.oriented import data_oriented

REGISTRY: dict[str, type] = {}


def register(name: str):
    def deco(cls):
        cls.name = name
        REGISTRY[name] = cls
        return cls

    return deco


def make_integrator(name: str, rates, state) -> "Integrator":
    """The integrator registered under `name`, stepping `state` through `rates` (step/rates.py)."""
    if name not in REGISTRY:
        raise ValueError(f"unknown integrator {name!r}; expected one of {', '.join(REGISTRY)}")
    return REGISTRY[name](rates, state)


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

    def __init__(self, rates, state):
        """`rates`: what it steps through (step/rates.py): evaluate() fills rates.force (and the heat rate), and its
        ti.func finish_particle(i, dt) is each particle's end-of-step work; `state`: the particles it moves."""
        self.rates = rates
        self.state = state
        self.p = state.particles
        self.f = rates.force
        self.loops = rates.loops

    def step(self, dt: float, first_stage: int = 0) -> None:
        """One step of dt from stage `first_stage` on (a step that a fused launch left after its first stages)."""
        for stage in range(first_stage, self.stages):
            self.rates.evaluate(dt, stage, self)

    def begin(self, dt: float) -> None:
        """Called before a run of steps of `dt` (Simulation.step): a leapfrog method staggers its state here."""

    def end(self, dt: float) -> None:
        """Called after a run of steps of `dt`: the state is synchronised here for anything outside stepping."""

    def _stage_fields(self, *names: str) -> None:
        """Allocate per-particle vector buffers (x0, v0, ...) that only this integrator needs."""
        for name in names:
            setattr(self, name, ti.Vector.field(self.p.dim, float, shape=self.p.capacity))

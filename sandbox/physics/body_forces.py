"""Body forces: per-particle forces that read no other particle (gravity, drag, the drag toward a velocity field).

Each term is a class in BODY_FORCES. A simulation builds, in registry order, every term whose `wanted(sim)` is true;
the rates pass (step/rates.py) sums `force(i)` of each for every particle, in every way of stepping (pass by pass,
fused, team), and pipeline() lists what `describe()` returns. Adding a force term is a class that follows the
`BodyForce` shape below, registered with `@body_force`, in this file or in a module the registry imports.

A term keeps its settings in Taichi fields of its own (0-d fields for values the user may change while it runs);
they are saved and resumed with the rest of the state (persist.walk finds them under `body_forces.<k>`).
"""

from __future__ import annotations

from typing import Protocol

import taichi as ti

from ..config.scene_tables import COUPLINGS
from ..core.oriented import data_oriented

DRAG = COUPLINGS.index("drag")


class BodyForce(Protocol):
    """The shape of a body-force term (see the module docstring)."""

    @staticmethod
    def wanted(sim) -> bool:
        """Whether the simulation `sim` (built up to its rates) has this term."""

    def describe(self) -> list[str]:
        """The words pipeline() lists for the term (none: it adds nothing in this scene)."""

    def force(self, i):  # a @ti.func in each term
        """The force on particle i (mass x length / time^2), a dim-vector."""


BODY_FORCES: list[type] = []  # in the order their forces are summed (the order decides the rounding)


def body_force(cls: type) -> type:
    """Class decorator: add a term to the registry (after those already there)."""
    BODY_FORCES.append(cls)
    return cls


def build_body_forces(sim) -> tuple:
    """The terms `sim` has, built in registry order."""
    return tuple(term(sim) for term in BODY_FORCES if term.wanted(sim))


@body_force
@data_oriented
class GravityAndDrag:
    """Uniform gravity g and linear drag at rate c: F = m (g - c v). The fields are the simulation's own
    (sim.gravity, sim.drag), which the window changes while it runs."""

    @staticmethod
    def wanted(sim) -> bool:
        return True  # always built: the window may switch gravity on in a scene that starts without it

    def __init__(self, sim):
        self.particles = sim.particles
        self.gravity = sim.gravity  # acceleration (length / time^2), 0-d vector field
        self.drag = sim.drag  # rate (1 / time), 0-d field
        self.world = sim.scene.world

    def describe(self) -> list[str]:
        return (["gravity"] if any(self.world.gravity) else []) + (["drag"] if self.world.drag else [])

    @ti.func
    def force(self, i):
        p = self.particles
        return p.mass[i] * (self.gravity[None] - self.drag[None] * p.v[i])


@body_force
@data_oriented
class FieldDrag:
    """Groups coupled to the velocity field by `field = "drag"` relax toward it at their rate k:
    F = m k (v_field(x) - v), with v_field sampled at the step's start (step/plan.py)."""

    @staticmethod
    def wanted(sim) -> bool:
        return sim.has_field_drag

    def __init__(self, sim):
        self.particles = sim.particles
        self.dim = sim.dim
        self.coupling = sim.g_coupling  # per group: index into COUPLINGS
        self.rate = sim.g_drag  # per group: relaxation rate (1 / time)
        self.target = sim.v_field  # per particle: the field's velocity there

    def describe(self) -> list[str]:
        return ["drag toward the velocity field"]

    @ti.func
    def force(self, i):
        p = self.particles
        f = ti.Vector.zero(float, self.dim)
        if self.coupling[p.group[i]] == DRAG:
            f = p.mass[i] * self.rate[p.group[i]] * (self.target[i] - p.v[i])
        return f

"""Body forces: per-particle forces that read no other particle (gravity and linear drag, the drag toward a velocity
field). Each is a term (physics/term.py) with `particle_force`: the rates sum `force(i)` of each for every particle, in
every way of stepping (pass by pass, fused, team), in the terms' order.
"""

import taichi as ti

from ..config.scene_tables import COUPLINGS
from ..core.oriented import data_oriented
from ..core.worlds import at, world_of
from .term import Measure, Term, register

DRAG = COUPLINGS.index("drag")


@register
@data_oriented
class GravityAndDrag(Term):
    """Uniform gravity g and linear drag at rate c: F = m (g - c v). The fields are the model's live controls
    (model.gravity, model.drag, each world's own), which the window changes while it runs. Measures the
    gravitational energy -m g.x."""

    key = "gravity"
    stage = "forces"
    particle_force = True
    measures = (Measure("grav", "sum", "particles"),)

    @staticmethod
    def wanted(parts) -> bool:
        return True  # always built: the window may switch gravity on in a scene that starts without it

    def __init__(self, parts):
        self.particles = parts.state.particles
        self.gravity = parts.model.gravity  # acceleration (length / time^2), 0-d vector field
        self.drag = parts.model.drag  # rate (1 / time), 0-d field
        self.world = parts.scene.world

    def words(self, where: str) -> list[str]:
        if where != "rates":
            return []
        return (["gravity"] if any(self.world.gravity) else []) + (["drag"] if self.world.drag else [])

    @ti.func
    def force(self, i):
        p = self.particles
        w = world_of(p, i)
        return p.mass[i] * (at(self.gravity, w) - at(self.drag, w) * p.v[i])

    @ti.func
    def measure_particle(self, i):
        p = self.particles
        return (-p.mass[i] * at(self.gravity, world_of(p, i)).dot(p.x[i]),)


@register
@data_oriented
class FieldDrag(Term):
    """Groups coupled to the velocity field by `field = "drag"` relax toward it at their rate k:
    F = m k (v_field(x) - v), with v_field sampled at the step's start (before_step)."""

    key = "field_drag"
    stage = "coupling"  # built after the velocity field
    particle_force_stage = "forces"  # summed with gravity, after it
    before_stage = "coupling"  # sampled after the smoke grid has stepped
    particle_force = True

    @staticmethod
    def wanted(parts) -> bool:
        fields = parts.terms.get("fields")
        return fields is not None and fields.has_drag

    @staticmethod
    def host_work(scene) -> str | None:
        return None  # the velocity field says so (physics/fields.py)

    def __init__(self, parts):
        self.particles = parts.state.particles
        self.dim = parts.model.dim
        self.fields = parts.terms["fields"]
        self.coupling = self.fields.coupling  # per group: index into COUPLINGS
        self.rate = self.fields.drag_rate  # per group: relaxation rate (1 / time)
        self.target = self.fields.v_field  # per particle: the field's velocity there

    def words(self, where: str) -> list[str]:
        return {
            "rates": ["drag toward the velocity field"],
            "before": ["velocity field sampled at field-coupled particles (their drag target)"],
        }.get(where, [])

    def before_step(self, state) -> None:
        self.fields.sample_at_particles(state.time)

    @ti.func
    def force(self, i):
        p = self.particles
        f = ti.Vector.zero(float, self.dim)
        if self.coupling[p.group[i]] == DRAG:
            f = p.mass[i] * self.rate[p.group[i]] * (self.target[i] - p.v[i])
        return f

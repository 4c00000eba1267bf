"""Kinematic particles: groups with `field = "kinematic"` are carried by the velocity field (physics/fields.py) and
feel no force. The integrator's update of them is undone at the step's end, and after the step they move
x += dt v(x, t) from the step's start (forward Euler), or dt v(x + dt/2 v, t + dt/2) (world.advection = "midpoint").
"""

import taichi as ti

from ..core.oriented import data_oriented
from .fields import KINEMATIC
from .term import Term, register


@register
@data_oriented
class Kinematic(Term):
    """The kinematic coupling as a term: remember x and v at the step's start, zero the force, undo the integrator's
    update at the step's end, then advect through the field."""

    key = "kinematic"
    stage = "moving"
    after_stage = "advect"  # after the implicit heat solve, as its positions were the step's
    adjusts_force = True
    finishes = True

    @staticmethod
    def wanted(parts) -> bool:
        fields = parts.terms.get("fields")
        return fields is not None and fields.has_kinematic

    def __init__(self, parts):
        self.p = parts.state.particles
        self.domain = parts.model.domain
        self.loops = parts.model.loops
        self.dim = parts.model.dim
        self.fields = parts.terms["fields"]
        self.coupling = self.fields.coupling
        self.v_field = self.fields.v_field
        self.advection = parts.scene.world.advection
        capacity = parts.model.capacity
        self.x_start = ti.Vector.field(self.dim, float, shape=capacity)  # x at the step's start
        self.v_start = ti.Vector.field(self.dim, float, shape=capacity)

    def words(self, where: str) -> list[str]:
        # its start of step (remembering x and v) is told with its advection
        return [f"kinematic advection through the velocity field ({self.advection})"] if where == "after" else []

    def before_step(self, state) -> None:
        self._begin()

    def after_step(self, state) -> None:
        self.advect(state.dt, state.time)

    @ti.kernel
    def _begin(self):
        """Remember x and v at the step start (the integrator's updates are undone)."""
        p = self.p
        self.loops.light()
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            if self.coupling[p.group[i]] == KINEMATIC:
                self.x_start[i] = p.x[i]
                self.v_start[i] = p.v[i]

    @ti.func
    def adjust_force(self, i, f):
        """Moved by the field alone: no force."""
        if self.coupling[self.p.group[i]] == KINEMATIC:
            f = ti.Vector.zero(float, self.dim)
        return f

    @ti.func
    def finish(self, i, dt, rates: ti.template()):
        """The integrator does not move them: advect() does."""
        if self.coupling[self.p.group[i]] == KINEMATIC:
            self.p.x[i], self.p.v[i] = self.x_start[i], self.v_start[i]

    def advect(self, dt: float, t: float) -> None:
        """Move the kinematic particles through the field from the step's start (the field is sampled by one kernel
        at the current positions, so its code, long for curl noise, compiles once)."""
        self.fields.sample_at_particles(t)
        if self.advection == "midpoint":
            self._move(0.5 * dt, False)
            self.fields.sample_at_particles(t + 0.5 * dt)
        self._move(dt, True)

    @ti.kernel
    def _move(self, dt: float, final: ti.template()):
        p = self.p
        self.loops.light()
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            if self.coupling[p.group[i]] == KINEMATIC:
                x = self.x_start[i] + dt * self.v_field[i]
                if ti.static(final):
                    p.x[i], p.v[i] = self.domain.enforce(x, self.v_field[i], p.radius[i], 0.0, 0)
                else:
                    p.x[i] = x

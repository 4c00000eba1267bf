"""The walls of the domain (or its periodic wrap) as a term: each particle's end-of-step position and velocity, and
the walls' momentum gauge (the pressure they feel)."""

import taichi as ti

from ..core.oriented import data_oriented
from ..core.worlds import at, world_of
from .term import Measure, Term, register


@register
@data_oriented
class Walls(Term):
    """Walls with restitution and Coulomb friction, or periodic wrapping (core/domain.py), once per step at its end
    (multi-stage methods do not see them between stages). Measures the momentum the walls took since the gauge
    restarted (`impulse`)."""

    key = "walls"
    stage = "boundaries"
    finishes = True
    measures = (Measure("impulse", "sum", "value"),)

    @staticmethod
    def wanted(parts) -> bool:
        return True

    def __init__(self, parts):
        self.p = parts.state.particles
        self.domain = parts.model.domain
        self.gauge_since = 0.0  # the time the momentum gauge restarted

    def restart_gauge(self, time: float) -> None:
        """Zero the momentum gauge: pressure() averages from `time` on (advance_frame restarts it every frame)."""
        self.domain.impulse.fill(0.0)
        self.gauge_since = time

    def pressure(self, impulse: float, time: float) -> float:
        """Momentum into the walls (`impulse`, as measured) per unit time and wall area since the gauge restarted,
        at `time`; nan without walls (a periodic box) or before any time has passed."""
        elapsed = time - self.gauge_since
        area = self.domain.wall_area
        return impulse / (elapsed * area) if area and elapsed > 0.0 else float("nan")

    def after_restore(self, state) -> None:
        self.restart_gauge(state.time)

    def words(self, where: str) -> list[str]:
        return (
            ["periodic wrap" if self.domain.periodic else "walls (restitution, friction)"] if where == "finish" else []
        )

    @ti.func
    def finish(self, i, dt, rates: ti.template()):
        p = self.p
        p.x[i], p.v[i] = self.domain.enforce(p.x[i], p.v[i], p.radius[i], p.mass[i], world_of(p, i))

    @ti.func
    def measure_value(self, w):
        return (at(self.domain.impulse, w),)

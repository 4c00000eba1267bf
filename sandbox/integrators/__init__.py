"""Time integrators: a registry of name -> class, one signature for all: an integrator is built from the rates and
the state it steps (`make_integrator(name, rates, state)`), never the simulation, and `step(dt)` advances the state
by dt.

Most integrators are a sequence of stages, each one force evaluation followed by a per-particle update:
  rates.evaluate(dt, k, integrator)
                          forces into rates.force (and heat rates) at the current positions and velocities, then
                          the integrator's ti.func update_particle(i, dt, k) on every particle, in one launch
  rates.finish_particle() (ti.func) each particle's end-of-step work (walls or the periodic wrap, the explicit heat
                          update), called by the last stage's update
A staged integrator (`stages` > 0) runs on every path symplectic Euler runs on: the long way (a launch per
evaluation), many steps to a launch (step/fused.py) and a team of threads (team.py); each path runs the
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
# The integrators live in this package's modules, one family each: base.py (the registry and the stages every
# stepping path runs), explicit.py (symplectic and forward Euler, midpoint, RK4), leapfrog.py (velocity and position
# Verlet), implicit.py (backward Euler on the springs). Importing a module registers its integrators; a new module
# is imported here, and its names join scene_tables.INTEGRATORS.

from ..config.scene_tables import INTEGRATORS
from . import explicit, implicit, leapfrog  # noqa: F401 - registers the integrators
from .base import REGISTRY, Integrator, make_integrator, register

__all__ = ["REGISTRY", "Integrator", "make_integrator", "register"]

# The order the window's i key cycles through and reports list: the registry of names (scene_tables.INTEGRATORS).
for _name in INTEGRATORS:
    REGISTRY[_name] = REGISTRY.pop(_name)

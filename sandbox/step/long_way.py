"""A step the long way: each pass launched from the host, one step at a time (any scene, any integrator). A mixin of
Simulation; scenes whose steps need the host between them (emitters, smoke, velocity fields, scheduled sources, the
implicit heat solve, ageing: step/plan.py) always step this way, and others when a fused launch cannot run. The
host's passes around the integrator, and their order, are the plan's (StepPlan.before and .after); the kernels of
the field coupling and ageing, which the plan names, are here.
"""

import taichi as ti

from .rates import KINEMATIC, NO_COUPLING


class LongWay:
    """Simulation's pass-by-pass step (see the module docstring)."""

    def _step_once(self) -> None:
        """One step of dt, each pass launched from here (any scene, any integrator); or the rest of a step whose
        first stages a fused launch ran (self.pending_stage: only fusable scenes, which have no host work)."""
        if self.pending_stage:
            self.integrator.step(self.dt, self.pending_stage)
            self.pending_stage = 0
            self._count_steps(1)
            return
        for part in self.plan.before:
            part.run()
        self.integrator.step(self.dt)
        for part in self.plan.after:
            part.run()
        self._count_steps(1)

    def _implicit_heat_step(self) -> None:
        """The implicit heat solve over the step just taken, then its enthalpy update."""
        use_list = self.neighbours is not None and self.neighbours.ensure_fresh()
        if not use_list and self.grid is not None:
            self.grid.rebuild()
        self.implicit_heat.step(self.dt, use_list, self._lists(use_list))
        self.implicit_heat.apply()

    @ti.kernel
    def _kinematic_begin(self):
        """Kinematic particles: remember x and v at the step start (the integrator's updates are undone)."""
        p = self.particles
        self.loops.light()
        for i in range(p.n[None]):
            if self.g_coupling[p.group[i]] == KINEMATIC:
                self.x_start[i] = p.x[i]
                self.v_start[i] = p.v[i]

    def _advect_kinematic(self, dt: float, t: float) -> None:
        """x += dt v(x, t) from the step's start (forward Euler), or dt v(x + dt/2 v, t + dt/2) (midpoint). The field
        is sampled by one kernel at the current positions, so its code (curl noise is long) compiles once."""
        self._sample_field(t)
        if self.scene.world.advection == "midpoint":
            self._kinematic_move(0.5 * dt, False)
            self._sample_field(t + 0.5 * dt)
        self._kinematic_move(dt, True)

    @ti.kernel
    def _sample_field(self, t: float):
        p = self.particles
        for i in range(p.n[None]):
            if self.g_coupling[p.group[i]] != NO_COUPLING:
                self.v_field[i] = self.fields.velocity(p.x[i], t)

    @ti.kernel
    def _kinematic_move(self, dt: float, final: ti.template()):
        p = self.particles
        self.loops.light()
        for i in range(p.n[None]):
            if self.g_coupling[p.group[i]] == KINEMATIC:
                x = self.x_start[i] + dt * self.v_field[i]
                if ti.static(final):
                    p.x[i], p.v[i] = self.domain.enforce(x, self.v_field[i], p.radius[i], 0.0)
                else:
                    p.x[i] = x

    @ti.kernel
    def _age(self, dt: float):
        self.loops.light()
        for i in range(self.particles.n[None]):
            self.particles.age[i] += dt

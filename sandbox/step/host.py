"""A step the long way: each pass launched from the host, one step at a time (any scene, any integrator).

Scenes whose terms do host work between steps (emitters, smoke, velocity fields, scheduled sources, the implicit
heat solve, ageing: step/plan.py) always step this way, and others when a fused launch cannot run. The host passes
around the integrator's step, and their order, are the plan's.
"""


class LongWay:
    """Runs one step of `plan` pass by pass."""

    def __init__(self, plan):
        self.plan = plan

    def step_once(self) -> None:
        """One step of dt: the cell-order sort when due, the terms' host passes before the step, the integrator's
        step (its rates evaluations and updates), the passes after it; or the rest of a step whose first stages a
        fused launch ran (plan.pending_stage: only fusable scenes, which have no host work)."""
        plan, state = self.plan, self.plan.state
        if plan.pending_stage:
            plan.integrator.step(state.dt, plan.pending_stage)
            plan.pending_stage = 0
            plan.count_steps(1)
            return
        if plan.order is not None and plan.order.due():
            plan.order.apply()
        for term in plan.before:
            term.before_step(state)
        plan.integrator.step(state.dt)
        for term in plan.after:
            term.after_step(state)
        plan.count_steps(1)

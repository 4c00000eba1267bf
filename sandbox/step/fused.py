"""Many steps to one kernel launch.

A scene whose steps need no host work between them (step/plan.py) runs batches of whole steps of a staged
integrator in one launch: on one thread (`_fused_steps`) when every loop of a step is small enough to run serially,
or by a team of threads (step/team.py). The neighbour-list check and rebuild are decided on the device; a list build
that overflows stops the batch before the forces of its stage, and the host widens the lists and goes on from there.
"""

import taichi as ti

from ..core import runtime
from ..core.oriented import data_oriented
from ..physics.neighbours import LIST_ARRAY

REORDER_BATCH = 20  # most steps per fused launch when the storage is sorted into cell order between launches


@data_oriented
class FusedSteps:
    """Batches of whole steps over `rates` in one launch (by `team` when it is given and starts)."""

    def __init__(self, rates, state, team=None, lone=None):
        """`team`: the team that runs the batches; `lone`: a team of one worker, which runs them on one thread
        (`alone`) where there is a team. Not the one-thread kernel below: that is another kernel, which the compiler
        (with Taichi's fast math) may sum in another order, where the team's own kernel on one worker gives its
        trajectory bit for bit (the melting block's forces parted by an ulp at the second step)."""
        self.rates, self.state, self.team, self.lone = rates, state, team, lone
        self.lists = rates.hood.lists if rates.hood is not None else None
        self.has_lists = self.lists is not None
        self.has_grid = rates.has_grid
        self.stopped_stage = ti.field(ti.i32, shape=())  # where a launch stopped inside a step (overflow)
        self.batches = 0  # launches so far

    def stopped_at(self) -> int:
        """The stage the last launch stopped before (after an overflow)."""
        return int(self.stopped_stage[None])

    def run(self, steps: int, forced: int, first_stage: int, integrator, dt: float, alone: bool = False) -> int:
        """Up to `steps` steps (the first from `first_stage` on), the lists built first if `forced`, by the team
        unless `alone` (then on one thread: the same trajectory); returns the steps done (fewer after an overflow),
        or -1 when the team could not start (nothing ran)."""
        ids = self.rates.ids(self.has_lists)
        with runtime.without_cfg_pass():  # a whole step in one kernel: see the function
            if self.team is not None and not alone:
                done = self.team.run(steps, forced, first_stage, integrator, ids, dt, self.stopped_stage)
            elif self.team is not None and self.lone is not None:
                done = self.lone.run(steps, forced, first_stage, integrator, ids, dt, self.stopped_stage)
            else:
                done = int(self._fused_steps(steps, forced, first_stage, integrator, ids, dt))
        if done >= 0:
            self.batches += 1
        return done

    @ti.kernel
    def _fused_steps(
        self, steps: ti.i32, forced: ti.i32, first_stage: ti.i32, integrator: ti.template(), ids: LIST_ARRAY, dt: float
    ) -> ti.i32:
        """Up to `steps` whole steps of a staged integrator in a single launch, the first from `first_stage` on: per
        stage the terms' per-stage passes, the neighbour-list check and rebuild decided here on the device, forces and
        heat rates, and the update. A launch costs 30-50 us of host time, as much as a whole step of a 1,000-particle
        scene. Stops before the forces of a stage whose list build overflowed (returns the steps done and leaves
        the stage in stopped_stage; the host grows the list and goes on from there)."""
        rates = self.rates
        done = 0
        rebuild = forced
        stage = first_stage
        stopped = 0
        while done < steps and not stopped:
            while stage < ti.static(integrator.stages) and not stopped:
                rates.prestep_loops()
                if ti.static(self.has_lists):
                    if rebuild or self.lists.stale[None]:
                        rates.hood.grid.rebuild_loops()
                        self.lists.fill_loops(ids)
                        self.lists.fused_builds[None] += 1
                        if self.lists.overflow[None]:
                            stopped = 1
                            self.stopped_stage[None] = stage
                elif ti.static(self.has_grid):
                    rates.hood.grid.rebuild_loops()
                if not stopped:
                    rebuild = 0
                    merged = ti.static(rates.updates_in_gather(self.has_lists))
                    rates.rate_loops(self.has_lists, ids, integrator, dt, stage, merged)
                    if ti.static(not merged):
                        for i in range(self.state.particles.n[None]):
                            if self.state.particles.idle(i):
                                continue
                            integrator.update_particle(i, dt, stage)
                    stage += 1
            if not stopped:
                done += 1
                stage = 0
        return done

"""Many steps to one kernel launch: a mixin of Simulation.

A scene whose steps need no host work between them (step/plan.py) runs batches of whole steps of a staged
integrator in one launch: on one thread (_fused_steps) when every loop of a step is small enough to run serially, or
by a team of threads (step/team.py). The neighbour-list check and rebuild are decided on the device; a list build
that overflows stops the batch before the forces of its stage, and the host widens the lists and goes on from there.
"""

import taichi as ti

from ..core import runtime
from ..physics.neighbours import LIST_ARRAY
from .plan import host_work_between_steps

REORDER_BATCH = 20  # most steps per fused launch when the storage is sorted into cell order between launches


class FusedStepping:
    """Simulation's fused stepping (see the module docstring)."""

    def _fusable_scene(self) -> bool:
        """Whether this scene's steps can run many to a launch: in _fused_steps when every loop of a step runs on
        one thread (a small scene on the CPU: a parallel loop inside a kernel's step loop would not be parallel), or
        as a team of threads (self.team); and the step has no work that the host does between steps (emitters,
        scheduled sources, smoke, velocity fields, lifetimes, the implicit heat solve). Sorting the storage into
        cell order runs between batches, which are at most REORDER_BATCH steps long when the scene sorts."""
        one_launch = self.loops.serial_pairs and self.loops.serial_light or self.team is not None
        return one_launch and not host_work_between_steps(self.scene)

    def _fused_batch(self, n: int) -> int:
        """How many of the next n steps to run in one _fused_steps launch (0: step the long way)."""
        if not (self.fuses_steps and self.integrator.stages):
            return 0
        if self.neighbours is not None and not (self.neighbours.usable or self.neighbours.forced):
            return 0  # lists too wide to allocate: the long way scans the grid
        if self.refreezer is not None:  # end the batch at the next refreeze step
            interval = self.scene.heat.refreeze_interval
            n = min(n, interval - self.step_count % interval)
        if self.reorder is not None:
            n = min(n, REORDER_BATCH)
        return n

    def _run_fused(self, batch: int) -> int:
        """Run up to `batch` steps in one launch (the first from self.pending_stage on); returns the steps done: fewer
        when a list build overflowed, which leaves self.pending_stage at the stage it stopped before."""
        nb = self.neighbours
        forced = 0
        if nb is not None:
            forced = int(nb.forced)
            nb.forced, nb.fused = False, True
        ids = self._lists(nb is not None)
        with runtime.without_cfg_pass():  # a whole step in one kernel: see the function
            if self.team is not None:
                done = self.team.run(batch, forced, self.pending_stage, self.integrator, ids, self.dt)
            else:
                done = int(self._fused_steps(batch, forced, self.pending_stage, self.integrator, ids, self.dt))
        if done < 0:  # the team's thread pool did not start every worker: nothing ran; step the long way from now on
            nb.forced = bool(forced)
            self.team, self.fuses_steps = None, False
            return 0
        self.fused_batches += 1
        self.pending_stage = int(self.stopped_stage[None]) if done < batch else 0
        if nb is not None:
            if done < batch:  # the build of step `done` overflowed: widen the lists (the next batch rebuilds them)
                if nb.grow():
                    nb.invalidate()
                else:
                    nb.usable = False  # too wide to allocate: the long way scans the grid
            else:
                nb.usable = True  # every build in the batch fitted (an overflow stops the batch)
        self._count_steps(done)
        return done

    @ti.kernel
    def _fused_steps(
        self, steps: ti.i32, forced: ti.i32, first_stage: ti.i32, integrator: ti.template(), ids: LIST_ARRAY, dt: float
    ) -> ti.i32:
        """Up to `steps` whole steps of a staged integrator in a single launch, the first from `first_stage` on: per
        stage the per-step passes, the neighbour-list check and rebuild decided here on the device, forces and heat
        rates, and the update. A launch costs 30-50 us of host time, as much as a whole step of a 1,000-particle
        scene. Stops before the forces of a stage whose list build overflowed (returns the steps done and leaves
        the stage in stopped_stage; the host grows the list and goes on from there)."""
        done = 0
        rebuild = forced
        stage = first_stage
        stopped = 0
        while done < steps and not stopped:
            while stage < ti.static(integrator.stages) and not stopped:
                self._prestep_loops()
                if ti.static(self.has_neighbours):
                    if rebuild or self.neighbours.stale[None]:
                        self.grid.rebuild_loops()
                        self.neighbours.fill_loops(ids)
                        self.neighbours.fused_builds[None] += 1
                        if self.neighbours.overflow[None]:
                            stopped = 1
                            self.stopped_stage[None] = stage
                elif ti.static(self.has_grid):
                    self.grid.rebuild_loops()
                if not stopped:
                    rebuild = 0
                    merged = ti.static(self._updates_in_gather(self.has_neighbours))
                    self._rate_loops(self.has_neighbours, ids, integrator, dt, stage, merged)
                    if ti.static(not merged):
                        for i in range(self.particles.n[None]):
                            integrator.update_particle(i, dt, stage)
                    stage += 1
            if not stopped:
                done += 1
                stage = 0
        return done

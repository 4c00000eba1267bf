"""Many steps of a scene in one launch on every CPU thread at once (a "team" of workers with barriers).

Taichi runs only a kernel's top-level loops in parallel, so a step in parallel costs a launch of each pass and a
wake-up of the thread pool per pass: at 10,000 particles (about 0.7 ms a step on one thread) that round trip eats
most of what the second thread brings, and the step runs many to a launch on one thread instead
(step/fused.py). A team does both: one launch whose single top-level loop starts one worker per thread;
each worker runs every step over its share of the particles and waits for the others at a spin barrier between the
passes that read what another worker wrote.

Each stage of a step (one for symplectic Euler and the Verlet methods: see sandbox/integrators/) of a scene with half
neighbour lists, per worker w of W:
  (with per-stage passes, such as the springs' update and breaking) its share of each pass's items; barrier;
  (rebuild step only) worker 0 sorts the particles into cells; barrier; each builds the lists of its particles;
  barrier (all stop if some list overflowed);
  the half-list pairs (forces and heat flows) of its chunks of particles, into its chunks' buffer rows; barrier;
  for its share of the particles in cell order: sum the rows (and, with springs, add the spring forces; barrier),
  update the particle, and flag the next stage's rebuild if it has moved half the skin since the build; barrier.
The trajectory is that of the parallel long way (same chunks, same rows, same sums in the same order).

A worker that waits at the first barrier for longer than START_SPINS reads of the barrier gives up: the thread pool
did not start every worker (a worker can only be absent at the start; once every worker has passed the first
barrier, each keeps running until the launch ends). Then no worker has changed anything, the launch returns 0 steps
done and the caller steps the long way from then on.
"""

import taichi as ti

from ..core.loops import SPREAD_STRIDE, spread_item
from ..core.oriented import data_oriented
from ..physics.neighbours import LIST_ARRAY

START_SPINS = 20_000_000  # reads of the barrier at the launch's first wait before a worker gives up (~0.2-1 s)


@data_oriented
class Team:
    """Team stepping over `rates` (a scene whose steps qualify: see plan.can_step_as_a_team) on `workers` threads."""

    def __init__(self, rates, workers: int):
        self.rates = rates
        self.workers = workers
        self.chunks_per_worker = rates.n_chunks // workers
        for term in rates.prestep_terms:
            if not hasattr(term, "prestep_one"):
                raise ValueError(f"the {term.key} term's per-stage pass cannot be shared out among a team's workers")
        self.arrived = ti.field(ti.i32, shape=())  # workers at the current barrier
        self.generation = ti.field(ti.i32, shape=())  # barriers passed (workers spin until it moves on)
        self.gave_up = ti.field(ti.i32, shape=())  # 1: a worker did not start (see the module docstring)
        self.moved = ti.field(ti.i32, shape=2)  # rebuild flags, by step parity (set by one step, read by the next)
        self.done = ti.field(ti.i32, shape=())  # steps completed in the last launch

    def run(self, steps: int, forced: int, first_stage: int, integrator, ids, dt: float, stopped_stage) -> int:
        """Up to `steps` steps of `integrator` (a staged one: see Integrator.stages), the first from `first_stage`
        on, in one launch over the neighbour lists `ids`, built first if `forced`; returns the steps done: fewer
        when a list build overflowed (the caller widens the lists; `stopped_stage` says which stage stopped), -1
        when the team could not start (nothing changed)."""
        return int(self._steps(steps, forced, first_stage, integrator, ids, dt, stopped_stage))

    @ti.func
    def barrier(self, gen, patient: ti.template()):
        """Wait until every worker has arrived at barrier number `gen` (counted from 0 in the launch); returns
        the next barrier's number. `patient` False: give up after START_SPINS reads (sets gave_up). A worker that
        finds gave_up set leaves at once too. The atomics are sequentially consistent: a worker's stores before
        the barrier are seen by every worker after it."""
        if ti.atomic_add(self.arrived[None], 1) == self.workers - 1:
            ti.atomic_sub(self.arrived[None], self.workers)  # an atomic too: ordered before the release below
            ti.atomic_add(self.generation[None], 1)
        else:
            spins = 0
            while ti.atomic_add(self.generation[None], 0) == gen:
                spins += 1
                if ti.atomic_add(self.gave_up[None], 0) != 0:
                    break
                if ti.static(not patient):
                    if spins > START_SPINS:
                        ti.atomic_max(self.gave_up[None], 1)
                        break
        return gen + 1

    @ti.kernel
    def _steps(
        self,
        steps: ti.i32,
        forced: ti.i32,
        first_stage: ti.i32,
        integrator: ti.template(),
        ids: LIST_ARRAY,
        dt: float,
        stopped_stage: ti.template(),
    ) -> ti.i32:
        for u in range(self.workers * SPREAD_STRIDE):  # one item per thread (see spread_item)
            w = spread_item(u)
            if w >= 0:
                self._work(w, steps, forced, first_stage, integrator, ids, dt, stopped_stage)
        done = self.done[None]
        if self.gave_up[None]:  # set the barrier up for a later launch (after all workers have left it)
            done = -1
            self.gave_up[None] = 0
            self.arrived[None] = 0
            self.generation[None] = 0
        return done

    @ti.func
    def _work(self, w, steps, forced, first_stage, integrator: ti.template(), ids: ti.template(), dt, stopped_stage):
        rates = self.rates
        p, nb, grid = rates.state.particles, rates.hood.lists, rates.hood.grid
        n = p.n[None]
        lo, hi = w * n // self.workers, (w + 1) * n // self.workers  # this worker's particle ids / cell-order slots
        gen = 0
        # Whether to build before the first step: the caller's flag, or some particle has moved half the skin.
        if w == 0:
            self.moved[0] = forced
            self.moved[1] = 0
            nb.stale[None] = 0
            nb.check_count()
            if nb.stale[None]:
                self.moved[0] = 1
        gen = self.barrier(gen, False)  # every worker has started (or all leave)
        if self.gave_up[None] == 0:
            for i in range(lo, hi):
                nb.check_one(i)  # sets nb.stale (a plain store of 1 from any worker)
            gen = self.barrier(gen, True)
            if nb.stale[None]:
                self.moved[0] = 1
            gen = self.barrier(gen, True)
            done = 0
            stage = first_stage
            evaluation = 0  # evaluations in this launch: the rebuild flags alternate by its parity
            stopped = 0
            while done < steps and self.gave_up[None] == 0 and not stopped:
                while stage < ti.static(integrator.stages) and not stopped:
                    parity = evaluation % 2
                    for term in ti.static(rates.prestep_terms):
                        items = term.prestep_count()
                        for s in range(w * items // self.workers, (w + 1) * items // self.workers):
                            term.prestep_one(s)  # the pair pass reads which springs live
                        gen = self.barrier(gen, True)
                    if self.moved[parity]:
                        if w == 0:
                            grid.rebuild_loops()  # serial here: nested in the workers' loop
                            nb.begin_fill()
                            nb.fused_builds[None] += 1
                        gen = self.barrier(gen, True)
                        for i in range(lo, hi):
                            nb.fill_one(i, ids)
                        gen = self.barrier(gen, True)
                        if nb.overflow[None]:
                            stopped = 1
                            if w == 0:
                                stopped_stage[None] = stage
                    if not stopped:
                        if ti.static(rates.world_chunks):  # every live world's chunks, shared out in order
                            items = n // rates.world_size * rates.n_chunks
                            for item in range(w * items // self.workers, (w + 1) * items // self.workers):
                                rates.world_chunk_rows(item, n, ids)
                        else:
                            for t in range(w * self.chunks_per_worker, (w + 1) * self.chunks_per_worker):
                                rates.half_rows_of_chunk(t, n, ids)
                        if w == 0:
                            self.moved[1 - parity] = 0  # every worker has read moved[parity]; next evaluation's flag
                        gen = self.barrier(gen, True)
                        # not with springs: a spring force reads the other end
                        merged = ti.static(rates.updates_in_gather(True))
                        if ti.static(not merged):  # every force before any particle moves
                            for ks in range(lo, hi):
                                rates.gather_particle(grid.sorted_ids[ks], True, ids, integrator, dt, stage, False)
                            gen = self.barrier(gen, True)
                        moved = 0
                        for ks in range(lo, hi):
                            i = grid.sorted_ids[ks]
                            if ti.static(merged):
                                rates.gather_particle(i, True, ids, integrator, dt, stage, True)
                            else:
                                integrator.update_particle(i, dt, stage)
                            if nb.moved_far(i):
                                moved = 1
                        if moved:
                            self.moved[1 - parity] = 1
                        gen = self.barrier(gen, True)
                        stage += 1
                        evaluation += 1
                if not stopped:
                    done += 1
                    stage = 0
            if w == 0:
                self.done[None] = done
                self.generation[None] = 0  # all have passed the last barrier: a waiter reads 0 != its number

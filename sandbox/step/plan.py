"""The stepping plan, derived from the term list: which host passes run around each step and in what order, whether
steps may run many to a launch (fused, or as a team of threads), and the driver that runs steps the chosen way.

Every way of stepping runs the same per-stage device work (the rates: step/rates.py) in the same order; they differ
only in how it is launched:
  the long way (host.py)   each pass launched from the host, one step at a time: any scene, any integrator;
  fused (fused.py)         many whole steps in one launch on one thread (a small scene on the CPU);
  team (team.py)           many whole steps in one launch on every CPU thread, meeting at barriers.
A term with host work between steps (seeding particles, a grid of its own, a solve iterated from the host, values
that change on a schedule) says so in `host_work(scene)`; such a scene always steps the long way. A term that rules
out team stepping says so in `team_blocker(scene)`. pipeline() prints this plan (`sandbox check`).
"""

from __future__ import annotations

import os
import time

from ..core.threads import LoadWatch, free_workers
from ..integrators import REGISTRY
from ..physics import TERMS
from ..physics.term import Term, hook_order
from .crowd import ALONE, STINT, CrowdedWays
from .fused import REORDER_BATCH, FusedSteps
from .host import LongWay
from .team import Team


def host_work_reasons(scene) -> list[str]:
    """Why `scene`'s steps need the host between them (empty: they can run many to a launch), as each term says, in
    the order of their host passes."""
    terms = sorted(TERMS, key=lambda cls: hook_order(cls, "before"))
    return [reason for cls in terms if (reason := cls.host_work(scene))]


def can_step_as_a_team(scene) -> bool:
    """Whether team stepping can run `scene`'s steps, given half neighbour lists (the CPU's): the scene keeps
    neighbour lists, needs no host work between steps, and no term rules a team out."""
    blocked = any(cls.team_blocker(scene) for cls in TERMS)
    return scene.world.neighbor_list and not (blocked or host_work_reasons(scene))


HOOK_ORDERS = {"before_step": "before", "after_step": "after", "after_steps": "after_steps", "at_step": "at_step"}


def _hooks(terms: list, hook: str) -> list:
    """The terms whose class overrides `hook` (a host method of physics/term.py's Term), in that hook's order."""
    having = [t for t in terms if getattr(type(t), hook) is not getattr(Term, hook)]
    return sorted(having, key=lambda t: hook_order(t, HOOK_ORDERS[hook]))


class StepPlan:
    """What one step of a simulation runs, in order, and how its steps are launched."""

    def __init__(self, model, state, terms: list, rates, integrator):
        self.model, self.state, self.terms, self.rates = model, state, terms, rates
        self.hood = rates.hood
        self.lists = rates.hood.lists if rates.hood is not None else None
        self.order = rates.hood.order if rates.hood is not None else None  # the cell-order sort
        self.before = _hooks(terms, "before_step")
        self.after = _hooks(terms, "after_step")
        self.after_calls = _hooks(terms, "after_steps")
        self.boundary = _hooks(terms, "at_step")
        self.reasons = host_work_reasons(model.scene)
        loops = model.loops
        # a team steps half lists; many worlds, where each world's pair rows are summed in its lone run's chunks
        teams = rates.half and (model.worlds == 1 or rates.world_chunks)
        self.team = Team(rates, model.threads) if loops.team and teams else None
        # while other work shares the cores the team's spinning workers wait on each other: step the long way or on
        # one thread, whichever is faster now (step/crowd.py), until it clears; all give the same trajectory
        self.load = (
            LoadWatch(model.threads) if self.team is not None and os.environ.get("SANDBOX_TEAM") != "always" else None
        )
        # many worlds step as a team or the long way (a launch a pass, for all of them), never fused into one serial
        # kernel: there a world's pair sums came out an ulp away from its lone run's on a few particles a step
        # (freeze_thaw, melting_block on two threads: the compiler contracts the inlined pair pass differently there)
        one_launch = (loops.serial_pairs and loops.serial_light and model.worlds == 1) or self.team is not None
        self.fuses = one_launch and not self.reasons
        lone = Team(rates, 1) if self.team is not None else None  # the crowded machine's one-thread way
        self.fused = FusedSteps(rates, state, self.team, lone)
        self.long_way = LongWay(self)
        self.integrator = integrator
        self.pending_stage = 0  # the stage the current step goes on from (0: at a step boundary)
        self.crowd = CrowdedWays()
        self.crowded_steps = 0  # steps taken another way than the team's because the machine was crowded

    def use_team(self, team) -> None:
        """Run the fused batches by `team` (None: on one thread)."""
        self.team = self.fused.team = team

    @property
    def fused_batches(self) -> int:
        """Launches of many steps (fused or team) so far."""
        return self.fused.batches

    def step(self, n: int) -> None:
        """Advance n steps of state.dt: many to a launch where the plan allows, else one at a time the long way."""
        if n <= 0:
            return
        state, integrator = self.state, self.integrator
        integrator.begin(state.dt)
        while n > 0:
            crowded = self.load is not None and self.team is not None and self.load.busy()
            if self.load is not None:
                free_workers(crowded)  # one worker at a time while crowded: the scheduler places it (threads.py)
            if crowded:
                n -= self._crowded_stint(n)
            else:
                n -= self._batch(n)
        for term in self.after_calls:
            term.after_steps(state)
        integrator.end(state.dt)

    def _batch(self, n: int, alone: bool = False) -> int:
        """Up to n steps: a fused batch (by the team unless `alone`) where one can run now, else one step the long
        way; returns the steps done (0 after a list build overflowed and the lists were widened)."""
        if self.order is not None and self.fuses and self.order.due() and not self.pending_stage:
            self.order.apply()  # between fused batches (the long way sorts at the start of its step)
        batch = self._fused_batch(n)
        done = self._run_fused(batch, alone) if batch else 0
        if done < batch and self.lists is not None and self.lists.refill:
            pass  # a list build overflowed and the lists were widened: the next batch builds them again
        elif done < max(batch, 1):  # not fusable now, or the lists cannot be widened: one step the long way
            self.long_way.step_once()
            done += 1
        return done

    def _crowded_stint(self, n: int) -> int:
        """Up to STINT of n steps the way the crowded machine steps fastest now (step/crowd.py); returns the steps
        done."""
        way = self.crowd.choose()
        stint = min(n, STINT)
        start = time.perf_counter()
        done = 0
        while done < stint:
            if way == ALONE:
                done += self._batch(stint - done, alone=True)
            else:
                self.long_way.step_once()
                done += 1
        self.crowd.record(way, time.perf_counter() - start, done)
        self.crowded_steps += done
        return done

    def count_steps(self, done: int) -> None:
        """Advance the clock by `done` steps and run what is due at a step boundary (refreezing)."""
        state = self.state
        for _ in range(done):
            state.time += state.dt  # added one step at a time: the same clock as stepping one by one
        state.step += done
        for term in self.boundary:
            if term.at_step(state, done) and self.rates.marks_bonds:
                self.lists.invalidate()  # the lists mark bonded pairs: new springs must be marked

    def steps_to_every_pass(self) -> int:
        """Steps from now until every boundary pass has run once (0 where there is none)."""
        return max((term.next_due(self.state) for term in self.boundary), default=0)

    def _fused_batch(self, n: int) -> int:
        """How many of the next n steps to run in one fused launch (0: step the long way)."""
        if not (self.fuses and self.integrator.stages):
            return 0
        if self.lists is not None and not (self.lists.usable or self.lists.must_rebuild()):
            return 0  # lists too wide to allocate: the long way scans the grid
        for term in self.boundary:  # end the batch where a boundary pass is due
            n = min(n, term.next_due(self.state))
        if self.order is not None:
            n = min(n, REORDER_BATCH)
        return n

    def _run_fused(self, batch: int, alone: bool = False) -> int:
        """Up to `batch` steps in one launch (the first from pending_stage on; on one thread if `alone`, else by the
        team where there is one); returns the steps done: fewer when a list build overflowed, which leaves
        pending_stage at the stage it stopped before."""
        lists = self.lists
        forced = 0
        if lists is not None:
            forced = int(lists.must_rebuild())
            lists.mark_rows_to_rebuild()
            lists.mark_built()
            lists.fused = True
        done = self.fused.run(batch, forced, self.pending_stage, self.integrator, self.state.dt, alone)
        if done < 0:  # the team's thread pool did not start every worker: nothing ran; step the long way from now on
            if forced:  # the long way builds first, as this launch would have (every world's rows where it must)
                lists.refill = True
            self.use_team(None)
            self.fuses = False
            return 0
        self.pending_stage = self.fused.stopped_at() if done < batch else 0
        if lists is not None:
            if done < batch:  # the build of step `done` overflowed: widen the lists (the next batch builds them)
                if not lists.grow():
                    lists.usable = False  # too wide to allocate: the long way scans the grid
            else:
                lists.usable = True  # every build in the batch fitted (an overflow stops the batch)
        self.count_steps(done)
        return done

    def lines(self) -> list[str]:
        """The passes a step runs, in order, in words (`sandbox check`): the same lists the stepping runs."""
        texts = _words(self.before, "before")
        if self.hood is not None:
            texts += self.hood.describe()
        texts += _words(self.rates.prestep_terms, "prestep")
        texts.append(self.rates.describe())
        texts.append(f"integrator {self.integrator.name}, then {', '.join(_words(self.rates.finish_terms, 'finish'))}")
        texts += _words(self.after, "after")
        if self.reasons:
            texts.append("launch: one launch per pass, one step at a time: " + "; ".join(self.reasons))
        if self.fuses:
            fused = "/".join(name for name, cls in REGISTRY.items() if cls.stages)
            team = (
                f", run by a team of {self.team.workers} threads meeting at barriers (while other work wants their "
                "cores: the long way or one thread, whichever is timed faster)"
                if self.team
                else ""
            )
            texts.append(
                "launch: every pass of a step, and many steps, in one kernel launch (the list rebuild decided on the "
                f"device{team}) with {fused}; other integrators one launch per pass"
            )
        texts += _words(self.boundary, "boundary")
        return texts


def _words(terms: list, where: str) -> list[str]:
    return [line for term in terms for line in term.words(where)]

"""How a team-stepped scene steps while other work shares its cores: the way measured fastest now.

Invariant: every way gives the team's trajectory bit for bit (tests/test_fast_paths.py holds it), so the choice is
speed alone. A team's workers spin at barriers and need a core each (core/threads.py's LoadWatch says when they would
not get one); two ways need no core to themselves:
  LONG   the long way: each pass launched from the host onto Taichi's thread pool, whose workers sleep between
         passes, so the process uses what share of every core the scheduler gives it;
  ALONE  the team's launch with one worker: many steps with no wait on another thread (the team's own kernel, so its
         sums and trajectory: step/fused.py).

Tuning: which is faster depends on how the scheduler shares the cores (other programs in sessions of their own, or
in this one), not on the CPU, so both are timed in stints of STINT steps and the faster kept; the slower is tried
again after RETRY seconds, then after twice as long each time it proves slower still, up to MAX_RETRY. A way's
seconds a step is its recent seconds over its recent steps (both halved every STINT steps it runs), not an average of
its stints' rates: a stint cut short by a call's remainder, holding no list build, would read far faster than its way.
The measurements behind these choices are in docs/performance.md ("Per CPU").
"""

from __future__ import annotations

import time

LONG, ALONE = "long way", "one thread"
STINT = 20  # steps stepped one way before the choice is looked at again
RETRY = 2.0  # seconds of crowded stepping before the way not chosen is tried again
MAX_RETRY = 32.0  # the longest wait between tries, once the slower way has proved slower again and again
DECAY = 0.5  # a way's recent seconds and steps are scaled by this for every STINT steps it runs


class CrowdedWays:
    """Times LONG and ALONE while the machine is crowded and picks the faster (see the module docstring)."""

    def __init__(self, clock=time.monotonic) -> None:
        self.clock = clock
        self.seconds = {LONG: 0.0, ALONE: 0.0}  # each way's recent timed seconds and steps (see DECAY)
        self.steps = {LONG: 0.0, ALONE: 0.0}
        self.tried = {LONG: 0.0, ALONE: 0.0}  # when each way last ran
        self.stints = {LONG: 0, ALONE: 0}  # stints run each way (the first of each compiles)
        self.wait = {LONG: RETRY, ALONE: RETRY}  # seconds before each way, when not chosen, is tried again

    @property
    def per_step(self) -> dict[str, float | None]:
        """Each way's seconds a step: its recent seconds over its recent steps (None: not yet timed)."""
        return {way: self.seconds[way] / self.steps[way] if self.steps[way] else None for way in (LONG, ALONE)}

    def choose(self) -> str:
        """The way to step the next stint: one not yet timed, else the one due for another try, else the faster."""
        for way in (ALONE, LONG):
            if not self.steps[way]:
                return way
        best = self._best()
        other = LONG if best == ALONE else ALONE
        return other if self.clock() - self.tried[other] >= self.wait[other] else best

    def _best(self) -> str | None:
        """The way timed faster, None until both are timed."""
        per_step = self.per_step
        if None in per_step.values():
            return None
        return min(per_step, key=lambda way: per_step[way])

    def record(self, way: str, seconds: float, steps: int) -> None:
        """A stint of `steps` steps of `way` took `seconds` of wall time (a way's first stint compiles: not timed)."""
        self.tried[way] = self.clock()
        self.stints[way] += 1
        if self.stints[way] == 1 or steps <= 0:
            return
        before = self._best()
        fade = DECAY ** (steps / STINT)
        self.seconds[way] = fade * self.seconds[way] + seconds
        self.steps[way] = fade * self.steps[way] + steps
        after = self._best()
        if before is not None and after != before:  # the other way leads now: both are tried at the first pace
            self.wait = {LONG: RETRY, ALONE: RETRY}
        elif before is not None and way != after:  # a try of the slower way that found it slower still
            self.wait[way] = min(2.0 * self.wait[way], MAX_RETRY)

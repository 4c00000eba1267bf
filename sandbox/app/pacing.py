"""How many of a frame's steps the next shown frame of a running scene takes, so that frames keep coming at the
view's rate. Where the steps do not fit beside the rest of a frame's work (drawing, encoding, sending), fewer are
taken: the scene runs in slow motion rather than in jerks, and the view reports its pace (simulated seconds per wall
second).

Two views, two rules: the window is alone on its machine, and FramePacer fits each frame's steps in the frame's
time from what they cost; a classroom tab's frames take turns with its host's other tabs on one core, where no tab's
own costs say how long the turns are, so SceneClock (the steps the wall clock owes a scene) and Turns (one allowance
of steps a frame for every tab on the core, fed back from the turns) pace them (app/serve_session.py).
"""

from __future__ import annotations

import math

import numpy as np

TARGET_FPS = 60.0  # the frame rate the window's pacing aims for
FLOOR_FPS = 30.0  # ... and where the frame's other work leaves too little room for that, this one
MIN_SUBSTEP_VARIANCE = 0.1  # the recent frames' substeps must vary this much (squared) to fit a fixed cost


class FramePacer:
    """Each shown frame's substeps from what they cost, so the frame rate holds: at most the wanted substeps (the
    scene's, or as the window's keys set them), fewer when a frame of them would not fit in 1 / target_fps beside
    the rest of the frame's work (the window's events, readouts and drawing; a classroom tab's picture or particle
    frame, encoded and sent); where that work leaves under a quarter of the frame, the budget is 1 / floor_fps
    instead (a frame of drawing alone cannot be made faster by stepping less). The simulation then runs slower than
    its pace: slow motion, which the panel reports as simulated seconds per wall second. The window aims for
    TARGET_FPS; a classroom tab for its SMOOTH_FPS (app/serve_session.py).

    A frame's simulation costs a fixed part (list rebuilds, sorting, the launch) plus a part per substep; both are
    fitted to the recent frames (exponentially weighted least squares over their substeps), and where the substeps
    have not varied enough to tell them apart, the whole cost is taken as per substep. That estimate is pessimistic
    at few substeps, so while it is in use, after a frame that fitted its budget the pacer tries one substep more:
    the frames then vary and the fit learns the fixed part."""

    def __init__(self, target_fps: float = TARGET_FPS, smoothing: float = 0.25, floor_fps: float = FLOOR_FPS):
        self.budget = 1.0 / target_fps
        self.floor_budget = 1.0 / min(floor_fps, target_fps)
        self.smoothing = smoothing
        self.sums: np.ndarray | None = None  # weighted sums of 1, n, n^2, t, n t over recent frames (t: seconds)
        self.rest_seconds = 0.0  # the frame's other work, seconds
        self.last = 0  # the last frame's substeps
        self.last_fitted = False  # ... and whether its work fitted the budget it was chosen for

    def costs(self) -> tuple[float, float] | None:
        """(fixed seconds, seconds per substep) of a frame's simulation, from the recent frames; None before any."""
        fitted = self._fit()
        return None if fitted is None else fitted[:2]

    def _fit(self) -> tuple[float, float, bool] | None:
        """(fixed seconds, seconds per substep, whether the two were told apart) from the recent frames."""
        if self.sums is None:
            return None
        w, sn, snn, st, snt = self.sums
        mean_n, mean_t = sn / w, st / w
        var_n = snn / w - mean_n**2
        if var_n > MIN_SUBSTEP_VARIANCE:
            per_step = (snt / w - mean_n * mean_t) / var_n
            fixed = mean_t - per_step * mean_n
            if per_step > 0.0 and fixed >= 0.0:
                return fixed, per_step, True
        return 0.0, mean_t / max(mean_n, 1.0), False

    def _room(self) -> tuple[float, float]:
        """(seconds left for the simulation, the budget aimed for)."""
        room = self.budget - self.rest_seconds
        if room < 0.25 * self.budget:  # drawing alone nearly fills the target's frame: aim for the floor instead
            return self.floor_budget - self.rest_seconds, self.floor_budget
        return room, self.budget

    def choose(self, wanted: int) -> int:
        """Substeps for the next frame: `wanted` while they fit the budget, else as many as fit (at least 1)."""
        fit = self._fit()
        if fit is None or fit[1] <= 0.0:
            return wanted
        fixed, per_step, told_apart = fit
        n = int((self._room()[0] - fixed) / per_step)
        if not told_apart and self.last_fitted and n <= self.last:  # the estimate may be pessimistic: one more
            n = self.last + 1
        return max(1, min(wanted, n))

    def record(self, substeps: int, simulation_seconds: float, rest_seconds: float) -> None:
        """What the last frame cost: its `substeps` took simulation_seconds, everything else rest_seconds."""
        n, t = float(max(substeps, 1)), simulation_seconds
        sample = np.array([1.0, n, n * n, t, n * t])
        if self.sums is None:
            self.sums, self.rest_seconds = sample, rest_seconds
        else:
            a = self.smoothing
            self.sums = (1.0 - a) * self.sums + a * sample
            self.rest_seconds += a * (rest_seconds - self.rest_seconds)
        self.last = substeps
        self.last_fitted = simulation_seconds + rest_seconds <= self._room()[1]


TURN_SMOOTHING = 0.25  # weight of the newest time between frames, and of a step's newest cost, in Turns' averages
TURN_GAIN = 0.5  # the part of what the last turn was short of or over that Turns' allowed steps take up
# at most this many 1 / fps of stepping a frame (shared among the views): where a scene's steps cost more than the
# core has, the allowance starts there, not at CATCH_UP frames' worth creeping down a few steps a turn (a 3D lid
# scene's class took minutes to come down from 1,600 steps a frame, at 1.5 s a picture)
STEP_BUDGET = 4.0
CHEAPEST_RISE = 1.02  # the cheapest step seen (what STEP_BUDGET reads) may rise by this much a frame: a stall is one
# dear frame and moves it not at all, steps that grow dearer for good move it within a few dozen frames
CATCH_UP = 4.0  # frames of the scene's steps a late frame may take at most (the rest is slow motion, no backlog)
STALL = 2.0  # turns longer than this many 1 / fps count as this long in Turns' average (one stall cuts no steps)
FEWEST = 0.5  # frames of the scene's steps a frame takes at least, where it is owed them (a core too short for fps
# pictures a second at that gives fewer pictures, not a scene at a step a picture)


class SceneClock:
    """The steps a view's scene is owed by the wall clock: a frame's substeps for every frame interval since its
    last frame was stepped, so a frame that comes late (a classroom host's other tabs had their turns first) shows
    the scene at its pace; at most CATCH_UP frames' worth (a stall is not made up)."""

    def __init__(self, interval: float) -> None:
        """`interval`: the view's frame interval (s)."""
        self.interval = interval
        self.owed = 0.0  # steps owed
        self.stepped_at: float | None = None  # when the last frame was stepped (wall seconds)

    def wait(self) -> None:
        """The view takes no frame now (no one watches it): its scene's clock waits with it."""
        self.stepped_at = None

    def owes(self, now: float | None, substeps: int) -> tuple[int, float]:
        """(whole steps owed, seconds since the last frame) at wall time `now` (s) for a scene of `substeps` steps a
        frame interval; `now` None: a frame asked for outside the clock (a warm-up, a script), one interval's."""
        elapsed = self.interval if self.stepped_at is None or now is None else max(now - self.stepped_at, 0.0)
        self.stepped_at = now
        self.owed = min(self.owed + elapsed / self.interval * substeps, CATCH_UP * substeps)
        return int(self.owed + 1e-6), elapsed

    def paid(self, steps: int) -> None:
        """`steps` were given to the scene: owed no more."""
        self.owed = max(self.owed - steps, 0.0)


class Turns:
    """How many steps a frame may take where views take turns on one core (a classroom host's tabs; a tab alone in
    its process is one of one), so that each keeps `fps` pictures a second: one allowance for every view on the
    core, so that where the core is short every tab runs at the same pace.

    Each frame reports how long since that view's last frame (a turn: every view's frame and what the core did
    beside them) and what its steps cost; over a turn the allowance moves by TURN_GAIN of what the turn was short of
    or over 1 / fps, in steps at what a step costs, shared among the views (integral control: the turns settle at
    1 / fps wherever the steps owed would make them longer, whatever the core does beside the frames: drawing,
    sending, other programs)."""

    def __init__(self, fps: float) -> None:
        self.aim = 1.0 / fps  # seconds a turn may take
        self.allowed = math.inf  # steps a frame may take (nothing measured yet: all that are owed)
        self.per_step = 0.0  # seconds a step costs, smoothed
        self.cheapest = math.inf  # seconds the cheapest recent step cost (the first frame's, compiling, not counted)
        self.frames = 0  # frames recorded with steps
        self.budget = math.inf  # the most steps a frame may take by STEP_BUDGET
        self.turn = 0.0  # seconds between a view's frames, smoothed over every view's
        self.share = 1  # views taking turns on the core (the host says)
        self.most = math.inf  # the most a frame is ever owed (CATCH_UP frames' worth)

    def limit(self, owed: int, substeps: int) -> int:
        """The steps a frame owed `owed` (of a scene of `substeps` a frame interval) takes now: as many as allowed
        (and as STEP_BUDGET allows), but at least FEWEST frames' worth (and 1) where owed."""
        self.most = CATCH_UP * substeps
        fewest = max(1, math.ceil(FEWEST * substeps))
        return max(min(owed, fewest), min(owed, int(min(self.allowed, self.most, self.budget))), 1)

    def record(self, elapsed: float, steps: int, seconds: float) -> None:
        """A view's frame came `elapsed` (s) after its last and took `steps` in `seconds` (s; none where paused)."""
        elapsed = min(elapsed, STALL * self.aim)  # a stall (a kernel compiled, another program) is not a turn
        self.turn = elapsed if not self.turn else self.turn + TURN_SMOOTHING * (elapsed - self.turn)
        if steps <= 0 or seconds <= 0.0:
            return
        per_step = seconds / steps
        self.per_step = per_step if not self.per_step else self.per_step + TURN_SMOOTHING * (per_step - self.per_step)
        # seconds each view's frame may grow (shrink: negative) for the turns to take 1 / fps; each of the `share`
        # views reports once a turn, so each report moves the allowance by a share of that
        share = max(self.share, 1)
        spare = (self.aim - self.turn) / share
        self.allowed = min(max(self.allowed + TURN_GAIN * spare / share / self.per_step, FEWEST), self.most)
        if self.frames:
            self.cheapest = min(per_step, self.cheapest * CHEAPEST_RISE)
            self.budget = STEP_BUDGET * self.aim / share / self.cheapest
        self.frames += 1

"""One pacing rule for every view that shows a running scene (the window, each classroom tab): how many of a frame's
steps the next shown frame takes, so that frames keep coming at the view's rate. Where a frame of the scene's steps
does not fit in the time a shown frame may take beside the rest of its work (drawing, encoding, sending), fewer
steps are taken: the scene runs in slow motion rather than in jerks, and the view reports its pace (simulated
seconds per wall second)."""

from __future__ import annotations

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

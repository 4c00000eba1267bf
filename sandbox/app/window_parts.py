"""The window's helpers that hold no simulation state: the frame clock (seconds per part of the loop), the 3D orbit
camera driven by the mouse, the MP4 recorder of the window's pictures, and the watch on the window's size."""

from __future__ import annotations

import time

import numpy as np
import taichi as ti

from ..config.arguments import file_stem
from ..render.video import open_writer

FRAME_PARTS = ("events", "simulation", "readouts", "drawing", "display")  # the window loop's parts, in order
TARGET_FPS = 60.0  # the frame rate the window's pacing aims for
FLOOR_FPS = 30.0  # ... and where the frame's other work leaves too little room for that, this one
MIN_SUBSTEP_VARIANCE = 0.1  # the recent frames' substeps must vary this much (squared) to fit a fixed cost


class FramePacer:
    """Each window frame's substeps from what they cost, so the frame rate holds: at most the wanted substeps (the
    scene's, or as + and - set them), fewer when a frame of them would not fit in 1 / TARGET_FPS beside the rest of
    the frame's work (events, readouts, drawing); where that work leaves under a quarter of the frame, the budget is
    1 / FLOOR_FPS instead (a frame of drawing alone cannot be made faster by stepping less). The simulation then
    runs slower than its pace: slow motion, which the panel reports as simulated seconds per wall second.

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


class FrameClock:
    """Seconds per part of each window frame, for `run_window(timings=...)`; does nothing without a dict."""

    def __init__(self, timings: dict[str, list[float]] | None):
        self.timings = timings
        if timings is not None:
            for part in (*FRAME_PARTS, "frame"):
                timings.setdefault(part, [])

    def start(self) -> None:
        if self.timings is not None:
            ti.sync()
            self.t0 = self.last = time.perf_counter()

    def lap(self, part: str) -> None:
        """The time since the last lap (or the start) was spent on `part`."""
        if self.timings is not None:
            ti.sync()
            now = time.perf_counter()
            self.timings[part].append(now - self.last)
            self.last = now

    def stop(self) -> None:
        if self.timings is not None:
            self.timings["frame"].append(self.last - self.t0)


class OrbitCamera:
    """3D camera for the mouse: orbit about a target (yaw, pitch), zoom (distance) and pan (moves the target).
    Cursor movements are fractions of the window (GGUI's cursor coordinates)."""

    def __init__(self, eye, target):
        self.target = np.asarray(target, dtype=float)
        d = np.asarray(eye, dtype=float) - self.target
        self.distance = float(np.linalg.norm(d))
        self.yaw = float(np.arctan2(d[0], d[2]))
        self.pitch = float(np.arcsin(np.clip(d[1] / self.distance, -1.0, 1.0)))

    def eye(self) -> np.ndarray:
        c = np.cos(self.pitch)
        return self.target + self.distance * np.array([c * np.sin(self.yaw), np.sin(self.pitch), c * np.cos(self.yaw)])

    def orbit(self, du: float, dv: float) -> None:
        """A drag across the whole window turns the view half a turn (and tilts it a quarter, within the poles)."""
        self.yaw -= np.pi * du
        self.pitch = float(np.clip(self.pitch - 0.5 * np.pi * dv, -1.45, 1.45))

    def zoom(self, dv: float) -> None:
        """Dragging up by the window's height moves 7.4x closer (exponential, so it never reaches the target)."""
        self.distance *= float(np.exp(-2.0 * dv))

    def pan(self, du: float, dv: float) -> None:
        """Move the target across the view, by the distance per window width."""
        fwd = self.target - self.eye()
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        right /= max(np.linalg.norm(right), 1e-9)
        up = np.cross(right, fwd)
        self.target = self.target - self.distance * (du * right + dv * up)

    def drag(self, buttons, du: float, dv: float) -> None:
        """A mouse drag of (du, dv) window fractions with `buttons` (left, right, middle) held: the left orbits,
        the right zooms, the middle pans."""
        if buttons[0]:
            self.orbit(du, dv)
        elif buttons[1]:
            self.zoom(dv)
        elif buttons[2]:
            self.pan(du, dv)


class Recorder:
    """Starts, feeds and stops MP4 recordings of the window's pictures through the headless video writer."""

    def __init__(self, scene_name: str, width: int, height: int, fps: float, first_path: str | None = None):
        self.scene_name, self.size, self.fps = scene_name, (width, height), fps
        self.next_path = first_path
        self.writer = None
        self.count = 0

    def update(self, recording: bool, renderer) -> str:
        """Called once per frame after rendering; returns a message when a recording starts or stops."""

        message = ""
        if recording and self.writer is None:
            self.count += 1
            path = self.next_path or f"out/{file_stem(self.scene_name)}_{self.count}.mp4"
            self.next_path = None
            self.writer = open_writer(path, *self.size, self.fps)
            self.path = path
            message = f"recording {path}"
        if self.writer is not None and recording:
            self.writer.write(renderer.picture())
        if self.writer is not None and not recording:
            self.writer.close()
            message = f"saved {self.path} ({self.writer.frames_written} frames)"
            self.writer = None
        return message


class ResizeWatch:
    """When the user resizes the window, its new size once it has held still for SETTLE seconds (a drag reports
    every size on the way; each new size builds a renderer); never while recording (a video keeps one size)."""

    SETTLE = 0.3  # seconds
    SMALLEST = (320, 180)  # pixels: a window dragged smaller is drawn at this size (GGUI stretches it)

    def __init__(self, shape: tuple[int, int]):
        self.shape = tuple(shape)
        self.seen, self.since = self.shape, time.perf_counter()

    def settled(self, shape, recording: bool = False, now: float | None = None) -> tuple[int, int] | None:
        """The window's new (width, height) when it differs from the size drawn at and has held still; else None."""
        now = time.perf_counter() if now is None else now
        shape = (max(int(shape[0]), self.SMALLEST[0]), max(int(shape[1]), self.SMALLEST[1]))
        if shape != self.seen:
            self.seen, self.since = shape, now
            return None
        if shape == self.shape or recording or now - self.since < self.SETTLE:
            return None
        self.shape = shape
        return shape


def screen_size() -> tuple[int, int, int, int] | None:
    """(x, y, width, height) in pixels of the primary screen (the first where none is marked primary), or None where
    it cannot be known (no display, or screeninfo not installed): GGUI does not tell."""
    try:
        import screeninfo

        monitors = screeninfo.get_monitors()
    except Exception:  # ImportError, or screeninfo's ScreenInfoError without a display
        return None
    if not monitors:
        return None
    m = next((m for m in monitors if m.is_primary), monitors[0])
    return int(m.x), int(m.y), int(m.width), int(m.height)

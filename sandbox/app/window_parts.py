"""The window's helpers that hold no simulation state: the frame clock (seconds per part of the loop), the 3D orbit
camera driven by the mouse, the MP4 recorder of the window's pictures, and the watch on the window's size."""

from __future__ import annotations

import time

import numpy as np
import taichi as ti

from ..config.arguments import file_stem
from ..render.video import open_writer

FRAME_PARTS = ("events", "simulation", "readouts", "drawing", "display")  # the window loop's parts, in order


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

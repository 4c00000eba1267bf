"""Features of a measured curve that a lesson asks students to find: the plateau of a heating curve."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Plateau:
    """Where a curve stays level: from `start` to `end` (s) at `level` (the curve's mean there, e.g. °C)."""

    start: float
    end: float
    level: float

    @property
    def duration(self) -> float:
        """Seconds the curve stays level."""
        return self.end - self.start

    def __str__(self) -> str:
        return f"level at {self.level:.1f} from {self.start:.1f} s to {self.end:.1f} s ({self.duration:.1f} s)"


def plateau(time, values, tolerance: float = 1.0) -> Plateau | None:
    """The longest stretch of the curve `values` against `time` (equal-length 1D arrays, time increasing) that stays
    within `tolerance` (in the values' unit, e.g. °C) of its own mean: the melting plateau of a heating curve.
    None when no stretch spans more than one sample."""
    t = np.asarray(time, float)
    v = np.asarray(values, float)
    if t.shape != v.shape or t.ndim != 1:
        raise ValueError(f"time and values: expected two 1D arrays of one length, got shapes {t.shape} and {v.shape}")
    best, lo = None, 0
    for hi in range(len(v)):  # two pointers: the window [lo, hi] stays within 2 * tolerance from top to bottom
        while v[lo : hi + 1].max() - v[lo : hi + 1].min() > 2 * tolerance:
            lo += 1
        if hi > lo and (best is None or t[hi] - t[lo] > best[1] - best[0]):
            best = (t[lo], t[hi], lo, hi)
    if best is None:
        return None
    start, end, lo, hi = best
    return Plateau(float(start), float(end), float(v[lo : hi + 1].mean()))

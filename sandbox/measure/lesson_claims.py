"""A lesson's claims held against its scene's run (config/lesson.py): each claim's measurement, reduced over its window
of simulated time, and whether it lies within its bounds.

The run is a table of measurements by frame (files/table.py's FrameTable, or any mapping of column name to a NumPy
array with a `time` column); a claim needing fewer frames than the run looks only at its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config.lesson import RANGED, LessonClaim
from ..errors import SandboxError
from .stats import STAT_COLUMNS


@dataclass(frozen=True)
class Verdict:
    """One claim against the run: its reduced `value` (NaN: the measurement was missing) and whether it `holds`."""

    claim: LessonClaim
    value: float
    holds: bool

    def line(self) -> str:
        """The verdict as one line: holds or fails, the words, the value and the bound."""
        c = self.claim
        bounds = " and ".join(
            f"{word} {bound:g}" for word, bound in (("above", c.above), ("below", c.below)) if bound is not None
        )
        what = f"{c.stat} of {c.measure}" + (f" over {c.over}'s" if c.over else "")
        if c.where:
            what += f" while {c.where} is {c.where_between[0]:g}..{c.where_between[1]:g}"
        window = f" in t = {c.window[0]:g}..{c.window[1]:g} s" if c.window else ""
        return f'{"holds" if self.holds else "FAILS"}  "{c.says}": {what}{window} = {self.value:.4g}, expected {bounds}'


def check_measures(claims: list[LessonClaim]) -> None:
    """A SandboxError naming the first claim whose measure (or `where`) is no column of the stats table."""
    for k, claim in enumerate(claims):
        for key, name in (("measure", claim.measure), ("where", claim.where)):
            if name and name not in STAT_COLUMNS:
                raise SandboxError(
                    f"scene.lesson.claims[{k}].{key} {name!r}: expected a column of the stats table "
                    f"({', '.join(STAT_COLUMNS[2:])})"
                )


def reduce(
    claim: LessonClaim, time: np.ndarray, values: np.ndarray, frame_time: float, where: np.ndarray | None = None
) -> float:
    """The claim's stat of `values` (by frame, at simulated `time`) within its window, over the frames where `where`
    (the claim's `where` measurement, by frame) lies in its range; `frame_time` the simulated seconds a frame spans
    (a duration counts frames)."""
    keep = np.ones(len(time), bool)
    if claim.window:
        keep = (time >= claim.window[0] - 1e-9) & (time <= claim.window[1] + 1e-9)
    if claim.where:
        lo, hi = claim.where_between
        keep &= (where >= lo) & (where <= hi)
    t, v = time[keep], values[keep]
    if len(v) == 0 or (claim.stat not in RANGED and not np.all(np.isfinite(v))):
        return math.nan
    if claim.stat in RANGED:
        lo, hi = claim.between
        inside = (v >= lo) & (v <= hi)
        if claim.stat == "duration":
            return float(inside.sum() * frame_time)
        return float(t[np.argmax(inside)]) if inside.any() else math.inf
    return float(
        {
            "first": lambda: v[0],
            "last": lambda: v[-1],
            "min": lambda: v.min(),
            "max": lambda: v.max(),
            "mean": lambda: v.mean(),
            "change": lambda: v[-1] - v[0],
        }[claim.stat]()
    )


def evaluate(claims: list[LessonClaim], table, frame_time: float, scene_frames: int) -> list[Verdict]:
    """Each claim against `table` (column -> array by frame, with `frame` and `time`); `scene_frames` the frames a
    claim without its own `frames` looks at."""
    check_measures(claims)
    frames, time = np.asarray(table["frame"]), np.asarray(table["time"], float)
    verdicts, named = [], {}
    for claim in claims:
        upto = frames <= (claim.frames or scene_frames)
        where = np.asarray(table[claim.where], float)[upto] if claim.where else None
        value = reduce(claim, time[upto], np.asarray(table[claim.measure], float)[upto], frame_time, where)
        if claim.over:
            base = named[claim.over]
            value = value / base if base else math.inf
        if claim.name:
            named[claim.name] = value
        holds = math.isfinite(value) or claim.stat == "time_of_first"
        holds = holds and not math.isnan(value)
        holds = holds and (claim.above is None or value > claim.above) and (claim.below is None or value < claim.below)
        verdicts.append(Verdict(claim, value, bool(holds)))
    return verdicts

"""The values a piece of the state may hold, checked when a state file is read (files/state_check.py)."""

from __future__ import annotations

from dataclasses import dataclass

from ..config.schema import MAX_MAGNITUDE, MIN_MAGNITUDE


@dataclass(frozen=True)
class Range:
    """The values an entry may hold, checked when a state file is read (files/state_check.py): between `lo` and
    `hi` (numbers, inclusive), below `below` and at most `atmost` (names of counts known at the check: "capacity",
    "n" live particles, "materials", "groups", "springs" slots, "next_ident"), and finite (reals)."""

    lo: float | None = None
    hi: float | None = None
    below: str | None = None
    atmost: str | None = None
    finite: bool = True


ANY = Range()  # any finite value
COUNT = Range(lo=0, hi=2**31 - 1)  # a count or a counter (kernels and id fields hold them as i32)
POSITIVE = Range(lo=1e-300)  # masses, radii: above zero
STEP = Range(lo=MIN_MAGNITUDE, hi=MAX_MAGNITUDE)  # a step size: within the range every scene number keeps

"""What a simulation measures at an instant (`Stats`), and the columns of the measurements CSV, both derived from
the quantities declared once in config/quantities.py."""

from __future__ import annotations

from dataclasses import make_dataclass

from ..config.quantities import QUANTITIES, compute

STAT_COLUMNS = ("frame", *(q.name for q in QUANTITIES), "step_seconds")


def stat_values(frame: int, stats: Stats, step_seconds: float) -> dict:
    """The STAT_COLUMNS of frame `frame` by name: its measurements `stats` and its steps' wall time (seconds)."""
    row = {"frame": frame, "step_seconds": step_seconds}
    row.update({k: getattr(stats, k) for k in STAT_COLUMNS if k not in row})
    return row


class _Measured:
    """What a Stats record offers beyond its fields (the fields: one per declared quantity, in its units)."""

    @property
    def phase_shares(self) -> tuple[float, float, float]:
        """(solid, liquid, gas) shares in [0, 1] of a scene whose material melts and boils: the gas is counted among
        the molten."""
        gas = min(max(self.gas_fraction, 0.0), 1.0)
        molten = max(self.molten_fraction, gas)
        return 1.0 - molten, molten - gas, gas

    @classmethod
    def from_sums(cls, m: dict, time: float, dim: int, volume: float, wall_pressure: float, heat: bool, springs: bool):
        """The Stats of the named sums and counts `m` (measure/diagnostics.py) at `time`: the pressure over the box's
        volume `volume` (area in 2D)."""
        return cls(**compute(m, time, dim, volume, wall_pressure, heat, springs))


Stats = make_dataclass(
    "Stats",
    [(q.name, int if q.integer else float) for q in QUANTITIES],
    bases=(_Measured,),
    namespace={"__doc__": "Measurements of one instant: one field per quantity of config/quantities.py."},
)
Stats.__module__ = __name__

"""A run's measurements as a table: one row per frame, the columns of the stats CSV (diagnostics.STAT_COLUMNS).

Plain NumPy underneath, so pandas stays optional: `table.to_pandas()` gives a DataFrame where pandas is installed.
"""

from __future__ import annotations

import html
from collections.abc import Iterator, Sequence

import numpy as np

from ..measure.stats import STAT_COLUMNS, Stats, stat_values


class FrameTable:
    """Measurements by frame: `table["time"]` is a NumPy column (float; counts are int), `len(table)` the rows.

    Units: time in simulation seconds, energies in the scene's scaled units, temperatures in degrees, speeds in
    length units per second; step_seconds is the wall time of the frame's steps. A measurement the scene does not
    have (the temperature of a scene without heat) is NaN.
    """

    columns: tuple[str, ...] = STAT_COLUMNS

    def __init__(self, rows: Sequence[dict] = ()) -> None:
        self._rows: list[dict] = list(rows)

    def append(self, frame: int, stats: Stats, step_seconds: float) -> None:
        """Add the row of frame `frame` (its measurements `stats`, its steps' wall time in seconds)."""
        self._rows.append(stat_values(frame, stats, step_seconds))

    def __len__(self) -> int:
        return len(self._rows)

    def __getitem__(self, column: str) -> np.ndarray:
        if column not in self.columns:
            raise KeyError(f"no column {column!r}; expected one of {', '.join(self.columns)}")
        values = [row[column] for row in self._rows]
        integer = column in ("frame", "broken_springs", "particles")
        return np.asarray(values, dtype=np.int64 if integer else np.float64)

    def __iter__(self) -> Iterator[str]:
        return iter(self.columns)

    def rows(self) -> list[dict]:
        """The rows as dicts (column -> value), a copy."""
        return [dict(row) for row in self._rows]

    def to_dict(self) -> dict[str, np.ndarray]:
        """Every column by name."""
        return {c: self[c] for c in self.columns}

    def to_pandas(self):
        """A pandas DataFrame of the table, indexed by frame (needs pandas: pip install pandas)."""
        try:
            import pandas as pd
        except ImportError as exc:
            raise ImportError("FrameTable.to_pandas() needs pandas; pip install pandas") from exc
        return pd.DataFrame(self.to_dict()).set_index("frame")

    def __repr__(self) -> str:
        return f"FrameTable({len(self)} frames: {', '.join(self.columns)})"

    def _repr_html_(self) -> str:
        """Jupyter's view: the first and last few rows."""
        shown = self._rows if len(self._rows) <= 10 else [*self._rows[:5], None, *self._rows[-5:]]
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = []
        for row in shown:
            if row is None:
                body.append(f"<tr><td colspan={len(self.columns)}>…</td></tr>")
                continue
            cells = (f"{v:.6g}" if isinstance(v, float) else str(v) for v in (row[c] for c in self.columns))
            body.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
        return f"<table><tr>{head}</tr>{''.join(body)}</table><p>{len(self)} frames</p>"

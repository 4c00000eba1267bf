"""Undo for interactive tools: a bounded ring of Simulation snapshots taken before each tool stroke.

A stroke is everything the mouse does between pressing and releasing the button (a heat stroke, a drag, a spawn):
the window pushes the state just before it and `undo` puts the newest back exactly. The ring keeps at most `size`
snapshots and at most `max_bytes` of them (the oldest go first), so a long session's memory stays bounded.
"""

from __future__ import annotations

from collections import deque

import numpy as np

UNDO_STEPS = 30  # strokes the window can undo
UNDO_BYTES = 256 * 2**20  # and at most this much memory for them


def snapshot_bytes(snap: dict) -> int:
    """Bytes a snapshot's arrays hold."""
    return sum(v.nbytes for v in snap.values() if isinstance(v, np.ndarray))


class UndoRing:
    """The states before the last strokes, newest last: push before a stroke, undo to go back one."""

    def __init__(self, size: int = UNDO_STEPS, max_bytes: int = UNDO_BYTES):
        self.size, self.max_bytes = size, max_bytes
        self._snaps: deque[dict] = deque()
        self.nbytes = 0

    def __len__(self) -> int:
        return len(self._snaps)

    def push(self, sim) -> None:
        """Keep `sim`'s state as it is now (before a stroke), dropping the oldest beyond the ring's bounds."""
        snap = sim.snapshot()
        self._snaps.append(snap)
        self.nbytes += snapshot_bytes(snap)
        while len(self._snaps) > 1 and (len(self._snaps) > self.size or self.nbytes > self.max_bytes):
            self.nbytes -= snapshot_bytes(self._snaps.popleft())

    def undo(self, sim) -> bool:
        """Put the newest kept state back into `sim` (exactly, clock included); False when there is none."""
        if not self._snaps:
            return False
        snap = self._snaps.pop()
        self.nbytes -= snapshot_bytes(snap)
        sim.restore(snap)
        return True

"""What a headless run writes besides its pictures and CSV: rolling checkpoints and extended-XYZ dumps."""

from __future__ import annotations

from pathlib import Path

from ..files.persist import save_state
from ..render.video import partial_path, publish


class RunFiles:
    """Called after each frame (run_headless's on_frame): every `dump_every` frames an extended-XYZ frame appended
    to `dump`, every `checkpoint_every` frames the whole state saved to `checkpoint` (replacing the last one
    atomically, so the file is always a whole state). The dump is written under a temporary name and takes its own
    name at close(), holding every frame dumped before a stop or an interrupt."""

    def __init__(self, sim, dump, dump_every: int, checkpoint, checkpoint_every: int | None) -> None:
        self.sim = sim
        self.dump = Path(dump) if dump else None
        self.dump_every = dump_every
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.checkpoint_every = checkpoint_every
        self.dumped = 0
        self.checkpoints = 0
        if self.dump is not None:
            self.dump.parent.mkdir(parents=True, exist_ok=True)
            partial_path(self.dump).unlink(missing_ok=True)

    def after_frame(self, frame: int, stats) -> None:
        """After frame index `frame` (0-based; the simulation has run frame + 1 frames)."""
        done = frame + 1
        if self.dump is not None and done % self.dump_every == 0:
            self.sim.write_extxyz(partial_path(self.dump), append=True)
            self.dumped += 1
        if self.checkpoint is not None and self.checkpoint_every and done % self.checkpoint_every == 0:
            save_state(self.sim, self.checkpoint, frame=done)
            self.checkpoints += 1

    def close(self) -> None:
        if self.dump is not None:
            publish(partial_path(self.dump), self.dump, keep=self.dumped > 0)

"""One output path held by one run: a lock file beside it, so that a second live run writing the same path is
refused, and partial names unique to the run (process id and a random part), so that two runs never write the same
temporary file. Partial files left by a killed run are found by the next run that claims the path: a resume adopts
the ones its checkpoint names, anything else is removed (safe: the lock proves their writer is gone).

    .NAME.lock                          the lock (fcntl.flock; it holds the writer's process id)
    .NAME.<pid>-<random>.partial.EXT    what the run is writing, renamed to NAME when complete
    .NAME.<pid>-<random>.seg0003.partial.EXT   numbered pieces of one output (video segments)
"""

from __future__ import annotations

import fcntl
import os
import secrets
from pathlib import Path

from ..errors import SandboxError

RUN_TOKEN = f"{os.getpid()}-{secrets.token_hex(3)}"  # this process's part of every partial name


def partial_name(path: Path, piece: str = "", token: str = RUN_TOKEN) -> Path:
    """The hidden name `path` is written under until it is complete (its suffix kept last, for ffmpeg); `piece`:
    a tag for one of several pieces (a video segment)."""
    tag = f".{piece}" if piece else ""
    return path.with_name(f".{path.name}.{token}{tag}.partial{path.suffix}")


class Claim:
    """`path` held for this run under the option `option` (for messages): acquire() takes the lock or raises a
    SandboxError naming the live run that holds it; release() gives it back."""

    def __init__(self, option: str, path: str | Path) -> None:
        self.option = option
        self.path = Path(path)
        self.lock_path = self.path.with_name(f".{self.path.name}.lock")
        self._fd: int | None = None

    def partial(self, piece: str = "") -> Path:
        return partial_name(self.path, piece)

    def acquire(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 32).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise SandboxError(
                    f"{self.option} {self.path}: another run (process {holder}) is writing it; expected another path "
                    "or that run to end"
                ) from None
            try:  # the lock file may have been removed by its last holder between our open and our lock
                same = os.fstat(fd).st_ino == os.stat(self.lock_path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            self.lock_path.unlink(missing_ok=True)
            os.close(self._fd)
            self._fd = None

    def leftovers(self) -> list[Path]:
        """Partial files of this path written by other runs (only meaningful while the lock is held: their writers
        are gone)."""
        mine = f".{RUN_TOKEN}."
        return sorted(p for p in self.path.parent.glob(f".{self.path.name}.*.partial*") if mine not in p.name)

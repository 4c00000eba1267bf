"""A text output that grows by appending (the stats CSV, the extended-XYZ dump), written under the run's partial
name and renamed when complete. A checkpoint marks it: flushed to disk, and its length and SHA-256 recorded, so that
a resume can continue the very file the checkpoint belongs to (the partial left by a killed run, or the finished
file of a run that ended) after proving its first bytes are the ones recorded."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from pathlib import Path

from ..errors import OutputError, SandboxError
from .claim import RESTART_HINT, Claim, create_exclusive, own_partial

CHUNK = 1 << 20


class AppendFile:
    """The output `claim.path`, opened by start() (fresh) or find(record, ...) then adopt() (continuing a marked
    file). `lines_at(frame)`: the lines the file holds after `frame` frames, when that is fixed (the stats CSV: a
    header and a row a frame), so that a record claiming another count is refused."""

    RECORD = {"partial": str, "bytes": int, "sha256": str}  # what mark() records
    kind, words = "text", "a text file"

    def __init__(self, claim: Claim, lines_at: Callable[[int], int] | None = None) -> None:
        self.claim = claim
        self.lines_at = lines_at
        self.partial = claim.partial()
        self._file = None
        self._hash = hashlib.sha256()
        self._bytes = 0

    # ------------------------------------------------------------------ opening
    def start(self, header: str = "") -> None:
        self._file = self._create(self.partial)
        if header:
            self.write(header)

    def find(self, record: dict, checkpoint: Path, frame: int):
        """The file the checkpoint of frame `frame` marked (the partial a killed run left, or the finished file),
        proven to begin with the `record["bytes"]` bytes recorded, holding the lines `frame` implies, and, when it is
        the finished file, not claimed as nothing; else a SandboxError saying what does not match. Changes nothing."""
        path, size, digest = self.claim.path, record["bytes"], record["sha256"]
        left = own_partial(path, record["partial"])  # only a name of this output's own partial pattern
        for source in (left, path):
            prefix = _prefix_hash(source, size) if source is not None else None
            if prefix is not None and prefix[0].hexdigest() == digest:
                self._check_claim(source, size, prefix[1], checkpoint, frame)
                return source, prefix[0], size
        raise SandboxError(
            f"{self.claim.option} {path}: does not begin with the {size:,} bytes the checkpoint {checkpoint} was "
            f"written with; {RESTART_HINT}"
        )

    def _check_claim(self, source: Path, size: int, lines: int, checkpoint: Path, frame: int) -> None:
        """A proven prefix must still be one this output holds at `frame`: the digest of nothing or of the CSV's
        header alone is anyone's to write, so a record claiming less than its frame implies would cut the file."""
        option, path = self.claim.option, self.claim.path
        if source == path and size == 0 and path.stat().st_size > 0:
            raise SandboxError(
                f"{option} {path}: the checkpoint {checkpoint} claims none of its {path.stat().st_size:,} bytes, so "
                f"continuing would empty it; {RESTART_HINT}"
            )
        if self.lines_at is not None and lines != self.lines_at(frame):
            raise SandboxError(
                f"{option} {path}: holds {lines} lines in the part the checkpoint {checkpoint} claims, where its frame "
                f"{frame} makes {self.lines_at(frame)}; {RESTART_HINT}"
            )

    def adopt(self, found) -> None:
        """Continue the file find() returned: a killed run's partial is cut back to the checkpoint and written on;
        a finished file's first bytes are copied (the file keeps its name and content until this run publishes)."""
        source, prefix, size = found
        try:
            if source == self.claim.path:
                with open(source, "rb") as src, self._create(self.partial) as dst:
                    _copy(src, dst, size)
            else:
                self.partial = source
                os.truncate(source, size)
        except OSError as exc:
            raise OutputError(self.partial, exc.strerror or type(exc).__name__) from exc
        self._hash, self._bytes = prefix, size
        self._file = self._open(self.partial, "ab")

    def in_use(self) -> list[Path]:
        return [self.partial]

    def _create(self, path: Path):
        """A new partial file (never one that exists, never through a link)."""
        return os.fdopen(create_exclusive(path, self.claim.option), "wb")

    def _open(self, path: Path, mode: str):
        try:
            return open(path, mode)  # noqa: SIM115 - closed in publish()/abandon()
        except OSError as exc:
            raise OutputError(path, exc.strerror or type(exc).__name__) from exc

    # ------------------------------------------------------------------ writing
    def write(self, text: str) -> None:
        data = text.encode()
        try:
            self._file.write(data)
        except OSError as exc:
            raise OutputError(self.claim.path, exc.strerror or type(exc).__name__) from exc
        self._hash.update(data)
        self._bytes += len(data)

    def mark(self) -> dict:
        """Flush to disk; the record a checkpoint keeps."""
        try:
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as exc:
            raise OutputError(self.claim.path, exc.strerror or type(exc).__name__) from exc
        return {
            "kind": self.kind,
            "path": str(self.claim.path),
            "partial": self.partial.name,
            "bytes": self._bytes,
            "sha256": self._hash.hexdigest(),
        }

    # ------------------------------------------------------------------ ending
    def publish(self) -> None:
        """Close and give the file its name."""
        self._file.close()
        try:
            os.replace(self.partial, self.claim.path)
        except OSError as exc:
            raise OutputError(self.claim.path, exc.strerror or type(exc).__name__) from exc

    def abandon(self) -> list[Path]:
        """Close, leaving the partial file in place (a failed run); the files kept."""
        if self._file is None:
            return []
        try:
            self._file.close()
        except OSError:
            pass
        return [self.partial] if self.partial.exists() else []


def _prefix_hash(path: Path, size: int):
    """The SHA-256 state of the first `size` bytes of `path` and the line ends among them, or None when it is
    missing or shorter."""
    try:
        if not path.is_file() or path.stat().st_size < size:
            return None
        digest, lines = hashlib.sha256(), 0
        with open(path, "rb") as src:
            left = size
            while left:
                chunk = src.read(min(CHUNK, left))
                if not chunk:
                    return None
                digest.update(chunk)
                lines += chunk.count(b"\n")
                left -= len(chunk)
        return digest, lines
    except OSError:
        return None


def _copy(src, dst, size: int) -> None:
    left = size
    while left:
        chunk = src.read(min(CHUNK, left))
        dst.write(chunk)
        left -= len(chunk)

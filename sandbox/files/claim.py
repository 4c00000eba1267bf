"""One output path held by one run: a lock file beside it, so that a second live run writing the same path is
refused, and partial names unique to the run (process id and a random part), so that two runs never write the same
temporary file. Partial files left by a killed run are found by the next run that claims the path: a resume adopts
the ones its checkpoint names, anything else of the path's own partial pattern is removed (safe: the lock proves
their writer is gone).

    .NAME.lock                          the lock (fcntl.flock; it holds the writer's process id)
    .NAME.<pid>-<random>.partial.EXT    what the run is writing, renamed to NAME when complete
    .NAME.<pid>-<random>.seg0003.partial.EXT   numbered pieces of one output (video segments)

Trust: a name read from a file (a state file's record of its outputs) is used only when it matches the pattern
above for the path named on this command line, in that path's folder, and is a regular file of one name, not a
link (`own_partial`: a hard link's second name would carry the writes to another file). Locks and partials are
opened with O_NOFOLLOW (and partials with O_EXCL), so a link or a folder planted at one of these names is refused,
never written through. A NAME too long to carry the decorations is shortened in the hidden names to its first bytes
and a digest of the whole (`hidden_stem`).
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import os
import re
import secrets
import stat
from collections.abc import Callable
from pathlib import Path

from ..errors import OutputError, SandboxError


def new_token() -> str:
    """A writer's part of its partial names: the process id and a random part."""
    return f"{os.getpid()}-{secrets.token_hex(3)}"


RUN_TOKEN = new_token()  # this process's part of the partial names of files written whole (a checkpoint, a frame)
NAME_MAX = 255  # bytes in one file name on the file systems the sandbox writes to (ext4, xfs, btrfs, tmpfs, APFS)
_DECORATION = 64  # bytes the hidden names add around the stem: ".", ".<pid>-<hex6>", ".seg0000", ".partial.EXT"
_TOKEN = r"\d{1,10}-[0-9a-f]{6}"
LISTING = ".pieces.txt"  # added to a joined video's partial name for ffmpeg's list of the pieces
_PARTIAL = re.compile(rf"\.(.+)\.{_TOKEN}\.partial(\.[^.]*)?")  # any file's partial name: its name is group 1


def hidden_stem(path: Path) -> str:
    """The part of the hidden names (lock, partials) that stands for `path`'s name: the name itself, or, when the
    name is too long to be decorated within NAME_MAX bytes, its first bytes and 12 hex digits of its SHA-256."""
    name = path.name
    raw = name.encode()
    if len(raw) + _DECORATION <= NAME_MAX:
        return name
    head = raw[: NAME_MAX - _DECORATION - 13].decode(errors="ignore")
    return f"{head}~{hashlib.sha256(raw).hexdigest()[:12]}"


def partial_name(path: Path, piece: str = "", token: str = RUN_TOKEN) -> Path:
    """The hidden name `path` is written under until it is complete (its suffix kept last, for ffmpeg); `piece`:
    a tag for one of several pieces (a video segment, "seg0003")."""
    tag = f".{piece}" if piece else ""
    return path.with_name(f".{hidden_stem(path)}.{token}{tag}.partial{_suffix(path)}")


def _suffix(path: Path) -> str:
    suffix = path.suffix
    return suffix if len(suffix) <= 16 else ""


def partial_pattern(path: Path, pieces: bool = False) -> re.Pattern:
    """The names partial_name() makes for `path` in any run (with a piece tag `segNNNN` when `pieces`)."""
    tag = r"\.seg\d{4}" if pieces else ""
    return re.compile(rf"\.{re.escape(hidden_stem(path))}\.{_TOKEN}{tag}\.partial{re.escape(_suffix(path))}")


def is_regular_file(path: Path, single: bool = False) -> bool:
    """`path` is a regular file itself (not a link, folder, FIFO or device); `single`: and its only name (a hard
    link's second name would let a write to it change another file)."""
    try:
        info = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(info.st_mode) and (info.st_nlink == 1 or not single)


def own_partial(path: Path, name: object, pieces: bool = False) -> Path | None:
    """The partial file `name` (read from a file, so untrusted) of the output `path`, when it is one a run of the
    sandbox would have made for `path` (its pattern, `path`'s folder) and is a regular file of one name; else None."""
    if not isinstance(name, str) or not partial_pattern(path, pieces).fullmatch(name):
        return None
    candidate = path.with_name(name)
    return candidate if is_regular_file(candidate, single=True) else None


def create_exclusive(path: Path, option: str = "") -> int:
    """A new file at `path` for writing, never one that exists nor a link's target: the descriptor, or an
    OutputError naming the path (`option` first, as the user gave it)."""
    try:
        return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        if exc.errno == errno.EEXIST:
            reason = "something is already at this run's own temporary name; expected nothing there"
        raise OutputError(path, reason) from None


class Claim:
    """`path` held for this run under the option `option` (for messages): acquire() takes the lock or raises a
    SandboxError naming the live run that holds it; release() gives it back."""

    def __init__(self, option: str, path: str | Path) -> None:
        self.option = option
        self.path = Path(path)
        self.lock_path = self.path.with_name(f".{hidden_stem(self.path)}.lock")
        self.token = new_token()  # this claim's own: an earlier claim of the same process is another writer
        self._fd: int | None = None

    def partial(self, piece: str = "") -> Path:
        return partial_name(self.path, piece, self.token)

    def acquire(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = self._open_lock()
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
                same = os.fstat(fd).st_ino == os.lstat(self.lock_path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self._fd = fd

    def _open_lock(self) -> int:
        """The lock file's descriptor; a SandboxError when something other than a plain file of its own is there (a
        link, a folder, a FIFO, a second name of another file): it is never followed or written through."""
        refused = f"{self.option} {self.path}: {self.lock_path.name} beside it is not a lock file this sandbox made"
        flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
        try:
            fd = os.open(self.lock_path, flags, 0o644)
        except OSError as exc:
            kind = {errno.ELOOP: "a symbolic link", errno.EISDIR: "a folder"}.get(exc.errno)
            if kind is None:
                raise OutputError(self.lock_path, exc.strerror or type(exc).__name__) from None
            raise SandboxError(f"{refused} ({kind}); expected it removed") from None
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
            os.close(fd)
            kind = "a file with other names" if stat.S_ISREG(info.st_mode) else "not a regular file"
            raise SandboxError(f"{refused} ({kind}); expected it removed")
        return fd

    def release(self) -> None:
        if self._fd is not None:
            self.lock_path.unlink(missing_ok=True)
            os.close(self._fd)
            self._fd = None

    def leftovers(self) -> list[Path]:
        """Partial files of this path written by other runs: regular files of the path's own partial pattern, whole
        or in pieces (only meaningful while the lock is held: their writers are gone)."""
        mine = f".{self.token}."
        whole, pieces = partial_pattern(self.path), partial_pattern(self.path, pieces=True)
        listing = re.compile(whole.pattern + LISTING.replace(".", r"\."))  # a join's concat list (render/encoder.py)
        found = []
        try:
            names = os.listdir(self.path.parent)
        except OSError:
            return []
        for name in names:
            if mine not in name and any(p.fullmatch(name) for p in (whole, pieces, listing)):
                candidate = self.path.with_name(name)
                if is_regular_file(candidate):
                    found.append(candidate)
        return sorted(found)


RESTART_HINT = "expected the files that run wrote, or --restart-outputs to start the outputs over"


def digest_of(items: list[str]) -> str:
    """One SHA-256 over a list of digests (a checkpoint's record of many frames or files)."""
    return hashlib.sha256("\n".join(items).encode()).hexdigest()


def write_whole(target: Path, data: bytes | Callable[[Path], None], option: str, token: str = RUN_TOKEN) -> None:
    """Write `target` as a whole: `data` (bytes, or a function that writes the path it is given) under a new partial
    name (never through a link), then renamed. An OutputError naming `target` (the partial removed) when the write
    fails."""
    partial = partial_name(target, token=token)
    try:
        fd = create_exclusive(partial, option)
        if isinstance(data, bytes):
            with os.fdopen(fd, "wb") as out:
                out.write(data)
        else:
            os.close(fd)
            data(partial)
        os.replace(partial, target)
    except OSError as exc:
        partial.unlink(missing_ok=True)
        raise OutputError(target, exc.strerror or type(exc).__name__) from exc


def remove_numbered(folder: Path, pattern: re.Pattern, first: int) -> list[Path]:
    """Remove the regular files in `folder` whose names match `pattern` (its last group a frame number) numbered
    `first` or later: an earlier run's frames; and the partial files of any of them that a killed run left (never
    complete, and the claim held proves their writer gone). Returns those removed."""
    try:
        names = sorted(os.listdir(folder))
    except OSError:  # no folder yet
        return []
    removed = []
    for name in names:
        match = pattern.fullmatch(name)
        partial = _PARTIAL.fullmatch(name)
        late = match is not None and int(match.group(match.lastindex)) >= first
        path = folder / name
        if (late or (partial is not None and pattern.fullmatch(partial.group(1)))) and is_regular_file(path):
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed

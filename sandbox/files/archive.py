"""A state file's `.npz` archive read with nothing it declares believed before it is checked.

`np.load` believes an array's header: a 64-byte member declaring shape (2**40,) makes it allocate 8 TiB before it
reads a byte. Here every member is checked first: the archive is a regular file (never a FIFO or a device, which
would block or never end), each member is stored or deflated (no other compression method, not encrypted), its
declared uncompressed size is within the caller's cap, and its `.npy` header's shape times its dtype's size plus
the header is exactly that declared size; only then is the array read, into a buffer of that size. zipfile stops
decompressing at the declared size and checks the CRC, so a deflate bomb costs at most the cap.
"""

from __future__ import annotations

import math
import os
import stat
import zipfile
import zlib
from pathlib import Path

import numpy as np

from ..errors import SandboxError

ALLOWED_METHODS = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED)
MAX_MEMBERS = 4096
ENCRYPTED = 0x1  # bit 0 of a zip entry's general-purpose flags


class ArchiveError(SandboxError):
    """The archive is not one this sandbox reads: the message says what is wrong (without the path)."""


def read_arrays(path: str | Path, names: list[str] | None = None, limit: int = 1 << 30) -> dict[str, np.ndarray]:
    """The arrays of the `.npz` at `path` (those in `names`, or all), each checked before it is allocated and all
    together at most `limit` bytes uncompressed. FileNotFoundError when there is no file; ArchiveError for anything
    else wrong."""
    path = Path(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(fd, "rb") as file:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ArchiveError("not a regular file (a folder, a FIFO or a device); expected an .npz file")
        try:
            with zipfile.ZipFile(file) as archive:
                members = _members(archive, limit)
                wanted = members if names is None else {n: members[n] for n in names if n in members}
                return {name: _read(archive, info, name) for name, info in wanted.items()}
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError) as exc:
            raise ArchiveError(f"not a readable .npz archive ({type(exc).__name__}: {_short(exc)})") from None


def _members(archive: zipfile.ZipFile, limit: int) -> dict[str, zipfile.ZipInfo]:
    """The archive's `.npy` members by array name, each of an allowed method, not encrypted, and their declared
    sizes within `limit` in all."""
    infos = archive.infolist()
    if len(infos) > MAX_MEMBERS:
        raise ArchiveError(f"has {len(infos)} members; expected at most {MAX_MEMBERS}")
    members: dict[str, zipfile.ZipInfo] = {}
    total = 0
    for info in infos:
        name = info.filename[:-4] if info.filename.endswith(".npy") else None
        if name is None or name in members:
            raise ArchiveError(f"member {info.filename[:80]!r} is not one array of its own; expected NAME.npy members")
        if info.compress_type not in ALLOWED_METHODS:
            raise ArchiveError(
                f"member {name[:80]!r} uses compression method {info.compress_type}; expected stored or deflated"
            )
        if info.flag_bits & ENCRYPTED:
            raise ArchiveError(f"member {name[:80]!r} is encrypted; expected a plain archive")
        total += info.file_size
        if total > limit:
            raise ArchiveError(f"declares more than {limit:,} bytes of arrays; expected at most that for this scene")
        members[name] = info
    return members


def _read(archive: zipfile.ZipFile, info: zipfile.ZipInfo, name: str) -> np.ndarray:
    """One member's array: its header read and checked against the member's declared size before any allocation."""
    with archive.open(info) as member:
        try:
            version = np.lib.format.read_magic(member)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(member)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(member)
            else:
                raise ValueError(f"format version {version}")
        except ValueError as exc:
            raise ArchiveError(f"member {name[:80]!r} has no valid array header ({_short(exc)})") from None
        if dtype.hasobject:
            raise ArchiveError(f"member {name[:80]!r} holds Python objects; expected numbers")
        nbytes = math.prod(shape) * dtype.itemsize
        if member.tell() + nbytes != info.file_size:
            raise ArchiveError(
                f"member {name[:80]!r} declares shape {shape} of {dtype} ({nbytes:,} bytes) in "
                f"{info.file_size - member.tell():,} bytes; expected the two to agree"
            )
        buffer = bytearray(nbytes)
        if member.readinto(buffer) != nbytes:
            raise ArchiveError(f"member {name[:80]!r} is shorter than its header says")
    return np.frombuffer(buffer, dtype=dtype).reshape(shape, order="F" if fortran else "C")


def _short(exc: Exception) -> str:
    return str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__

"""Where the shipped scenes and assets live: inside the installed package as `sandbox.scenes` and `sandbox.assets`.

pyproject.toml maps the repository's top-level scenes/ and assets/ folders into the package, so a wheel, a plain
`pip install .` and an editable install all find them through importlib.resources. A source tree that was never
installed (tests run from a checkout) falls back to the folders beside the package.
"""

from __future__ import annotations

import os
import stat
from importlib import resources
from pathlib import Path


def _shipped_folder(name: str) -> Path:
    try:
        return Path(str(resources.files(f"sandbox.{name}")))
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / name  # the repository root: sandbox/config/ is two below


SCENES_DIR = _shipped_folder("scenes")
ASSETS_DIR = _shipped_folder("assets")
MATERIALS_FILE = ASSETS_DIR / "materials.toml"


def shipped_scenes() -> list[Path]:
    """Every shipped scene file, sorted by name."""
    return sorted(SCENES_DIR.glob("*.toml"))


def shipped_scene(name: str) -> Path | None:
    """The shipped scene called `name` (without .toml), or None."""
    path = SCENES_DIR / f"{name}.toml"
    return path if path.is_file() else None


MAX_TEXT_BYTES = 4 << 20  # a scene, a materials library or a run record larger than 4 MiB is not one


def read_small_text(path: Path, limit: int = MAX_TEXT_BYTES) -> str:
    """The text of the regular file `path`, at most `limit` bytes. Raises FileNotFoundError, IsADirectoryError,
    UnicodeDecodeError, or ValueError naming what is wrong (a FIFO, a device, a file over the limit): nothing is
    read from what is not a regular file, so `/dev/zero`, `/dev/urandom` and a FIFO are refused at once, never
    waited on or read into memory."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)  # a FIFO opens without waiting for a writer
    with os.fdopen(fd, "rb") as file:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise IsADirectoryError(path)
        if not stat.S_ISREG(info.st_mode):
            raise ValueError("not a regular file (a FIFO, a device or a socket); expected a file")
        data = file.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"larger than {limit >> 20} MiB; expected a text file of at most that")
    return data.decode()

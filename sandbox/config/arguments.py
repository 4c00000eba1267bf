"""Checks of command-line values and output paths, made before anything is built or written.

Each problem is a SandboxError with one line naming the option, the value and what was expected; the CLI prints it
and exits 2.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
from pathlib import Path

from ..errors import SandboxError

MAX_FRAMES = 1_000_000
MAX_SUBSTEPS = 100_000
MAX_SIDE = 8192  # pixels: an 8K picture
MAX_FPS = 1000.0
VIDEO_SUFFIXES = (".mp4", ".mov", ".gif")
FRAME_SUFFIXES = (*VIDEO_SUFFIXES, ".png", "")


GIF_WIDTH = 400  # pixels: a default GIF's width when no --width or --height is given
GIF_FPS = 15.0  # a default GIF's highest frame rate
GIF_BUDGET = 8e6  # bytes a default GIF aims below
GIF_WARN = 50e6  # bytes: a GIF estimated larger is warned about before the run
GIF_BYTES_PER_PIXEL = 0.36  # per pixel per frame, measured on melting_block (480 x 270, 300 frames: 13.8 MB)


def file_stem(name: str) -> str:
    """A scene's name as the stem of the files named after it (out/NAME.mp4): letters, digits, `-`, `_` and `.`
    kept, anything else (`/`, `..`, spaces, quotes, control characters) as `_`, no leading `.` or `-`, at most 100
    characters; "scene" when nothing is left. A name from someone else's scene file never leaves the folder."""
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", name)[:100].lstrip(".-")
    return stem if stem.strip("_.") else "scene"


def gif_plan(width: int, height: int, fps: float, frames: int, sized: bool) -> tuple[int, int, int, float]:
    """A GIF a teacher can share: (width, height, every, estimated bytes). Unless `sized` (the size was asked
    for), the picture is scaled to GIF_WIDTH wide; every `every`-th frame is kept, enough to stay at most GIF_FPS
    and, where the size was not asked for, under GIF_BUDGET (but at least 5 frames a second)."""
    if not sized and width > GIF_WIDTH:
        width, height = GIF_WIDTH, max(16, 2 * round(height * GIF_WIDTH / width / 2))
    every = max(1, math.ceil(fps / GIF_FPS - 1e-9))

    def estimate(k: int) -> float:
        return math.ceil(frames / k) * width * height * GIF_BYTES_PER_PIXEL

    while not sized and estimate(every) > GIF_BUDGET and fps / (every + 1) >= 5:
        every += 1
    return width, height, every, estimate(every)


def gif_warning(out, width: int, height: int, fps: float, size: float) -> str:
    """What a run says before writing a GIF of an estimated `size` bytes over GIF_WARN."""
    return (
        f"{out} will be about {size / 1e6:.0f} MB ({width} x {height}, {fps:g} frames a second); a smaller --width "
        "and --height, a lower --fps or an .mp4 makes it smaller"
    )


def check_count(option: str, value: int | None, lo: int, hi: int) -> None:
    """An integer option (None: not given) must lie in lo..hi."""
    if value is not None and not lo <= value <= hi:
        raise SandboxError(f"{option} {value}: expected an integer from {lo:,} to {hi:,}")


def check_rate(option: str, value: float | None, hi: float) -> None:
    """A rate option (None: not given) must be finite, above zero and at most hi."""
    if value is not None and not (math.isfinite(value) and 0 < value <= hi):
        raise SandboxError(f"{option} {value}: expected a number above 0 and at most {hi:g}")


def check_picture(width: int, height: int, out: str | None) -> None:
    """The picture size of a run: each side in 16..MAX_SIDE pixels, and even for MP4, MOV and GIF (YUV video)."""
    for option, side in (("--width", width), ("--height", height)):
        check_count(option, side, 16, MAX_SIDE)
    if out is not None and Path(out).suffix.lower() in VIDEO_SUFFIXES and (width % 2 or height % 2):
        raise SandboxError(f"--width/--height {width}x{height}: expected even numbers for {Path(out).suffix} video")


def _probe_folder(option: str, path: Path, folder: Path) -> None:
    """Create `folder` (and its parents) if needed and prove a file can be written in it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".sandbox-probe-"):
            pass
    except FileExistsError:
        problem = f"'{folder}' exists and is not a folder"
    except OSError as exc:
        problem = f"cannot write in '{folder}' ({exc.strerror or type(exc).__name__})"
    else:
        return
    raise SandboxError(f"{option} {path}: {problem}; expected a writable folder")


NAME_MAX = 255  # bytes in one file or folder name (ext4, xfs, btrfs, tmpfs, APFS)


def check_name_lengths(option: str, path: str | Path) -> None:
    """Every name along `path` fits the file system's limit on one name (a longer one fails only when written)."""
    for part in Path(path).parts:
        if len(os.fsencode(part)) > NAME_MAX:
            raise SandboxError(
                f"{option} {str(path)[:60]}...: a name of {len(os.fsencode(part))} bytes; expected at most {NAME_MAX}"
            )


def check_file_output(option: str, path: str | Path, suffixes: tuple[str, ...] | None = None) -> Path:
    """An output file: a known suffix (when `suffixes` is given), not an existing folder, in a writable folder
    (created if missing). Returns the path."""
    path = Path(path)
    check_name_lengths(option, path)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise SandboxError(f"{option} {path}: expected a file ending in {' or '.join(suffixes)}")
    if path.is_dir():
        raise SandboxError(f"{option} {path}: is a folder; expected a file name")
    _probe_folder(option, path, path.parent if str(path.parent) else Path("."))
    return path


def check_frames_output(option: str, path: str | Path) -> Path:
    """The run's --out: a .mp4/.mov/.gif/.png file or a folder for numbered PNG frames (created if missing)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FRAME_SUFFIXES:
        raise SandboxError(
            f"{option} {path}: unknown output kind {suffix!r}; expected .mp4, .mov, .gif, .png or a folder"
        )
    if suffix:
        return check_file_output(option, path)
    return check_folder_output(option, path, "a folder for PNG frames (or a .mp4, .mov, .gif or .png)")


def check_folder_output(option: str, path: str | Path, what: str = "a folder") -> Path:
    """An output folder: not an existing file, writable (created if missing). Returns the path."""
    path = Path(path)
    check_name_lengths(option, path)
    if path.exists() and not path.is_dir():
        raise SandboxError(f"{option} {path}: is a file; expected {what}")
    _probe_folder(option, path, path)
    return path


def distinct_outputs(paths: dict[str, str | None]) -> None:
    """No two options may write the same file (same_file: through links too)."""
    seen: list[tuple[str, str | Path]] = []
    for option, path in paths.items():
        if path is None:
            continue
        for other, earlier in seen:
            if same_file(path, earlier):
                raise SandboxError(f"{option} {path}: the same file as {other}; expected different outputs")
        seen.append((option, path))


def outside_numbered(outputs: dict[str, str | Path | None], numbered: dict[str, tuple[Path, re.Pattern]]) -> None:
    """No output may be one of the numbered files another output writes (a cache's frames and surfaces, a PNG
    folder's frames): `numbered` gives each such option's folder and the pattern of its files' names."""
    for owner, (folder, pattern) in numbered.items():
        for option, path in outputs.items():
            if path is None or option == owner:
                continue
            path = Path(path)
            if pattern.fullmatch(path.name) and os.path.realpath(path.parent) == os.path.realpath(folder):
                raise SandboxError(
                    f"{option} {path}: one of the numbered files {owner} {outputs[owner]} writes; expected another name"
                )


def outputs_not_inputs(outputs: dict[str, str | None], inputs: dict[str, str | None]) -> None:
    """No output may be a file the run reads (the scene, a mask, the state resumed), except that the checkpoint may
    be the state resumed (a checkpoint replaces its file whole, after the state was read)."""
    for option, path in outputs.items():
        for source, read in inputs.items():
            if path is None or read is None or (option == "--checkpoint" and source == "--resume"):
                continue
            if same_file(path, read):
                raise SandboxError(f"{option} {path}: is the {source} file this run reads; expected another path")


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether two paths name one file (through links too, or by their resolved paths before either exists)."""
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def check_pool_arguments(args) -> None:
    """--scheduler, --workers and --threads of sweep and study."""
    check_count("--workers", args.workers, 1, 1024)
    check_count("--threads", args.threads, 1, 1024)
    if args.scheduler not in ("auto", "local", "serial") and "://" not in args.scheduler:
        raise SandboxError(f"--scheduler {args.scheduler}: expected auto, local, serial or an address tcp://HOST:PORT")


def pool_arguments(parser, job: str) -> None:
    """Add --scheduler, --workers and --threads to `parser`; `job` names what one task is ("run", "task")."""
    parser.add_argument(
        "--scheduler",
        default="auto",
        help="auto (a local Dask cluster with the sweep extra, else serial), local, serial, or tcp://HOST:8786",
    )
    parser.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    parser.add_argument("--threads", type=int, help=f"Taichi CPU threads per {job} (default: the cores / workers)")


def check_names(option: str, text: str | None, known: tuple) -> tuple:
    if text is None:
        return known
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise SandboxError(f"{option} {text}: expected a comma-separated list of {', '.join(known)}")
    return names

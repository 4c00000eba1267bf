"""Frame writers chosen by the output path: .mp4 (H.264, yuv420p), .gif (palette per clip), .png (one still) or a
folder (a numbered PNG sequence). MP4 and GIF use imageio-ffmpeg, whose wheel carries its own ffmpeg binary, so no
system ffmpeg is needed. Frames are (H, W, 3) uint8 arrays, top row first. Every writer is a context manager: on
any exit, including Ctrl-C, what was written so far is closed into a valid file. A video or still is written under a
hidden partial name and renamed when it is complete, so no half-written file ever carries the name asked for; a run
that wrote no frame leaves no file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image

from ..config.arguments import VIDEO_SUFFIXES
from ..errors import OutputError, SandboxError
from ..files.claim import partial_name
from .encoder import Encoder, ffmpeg_exe

VIDEO_HINT = "install the video extra: python3 -m pip install -e '.[video]'"


def write_png(path: str | Path, frame: np.ndarray) -> None:
    """Write one (H, W, 3) uint8 frame as a PNG."""
    Image.fromarray(np.ascontiguousarray(frame)).save(str(path), format="PNG")


def read_png(path: str | Path) -> np.ndarray:
    """Read a PNG as an (H, W, C) uint8 array, top row first (RGB, or RGBA where it has alpha)."""
    with Image.open(path) as img:
        return np.array(img.convert("RGBA" if "A" in img.mode else "RGB"))


class FrameWriter:
    """Base: `write(frame)`, `close()`; `frames_written` counts frames."""

    def __init__(self, path: Path, width: int, height: int, fps: float):
        self.path, self.width, self.height, self.fps = path, width, height, fps
        self.frames_written = 0

    def write(self, frame: np.ndarray) -> None:
        self._write(frame)
        self.frames_written += 1

    def _write(self, frame: np.ndarray) -> None:
        raise NotImplementedError

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


class PngSequenceWriter(FrameWriter):
    """frame_00000.png, frame_00001.png, ... in a folder."""

    def __init__(self, path: Path, width: int, height: int, fps: float):
        super().__init__(path, width, height, fps)
        path.mkdir(parents=True, exist_ok=True)

    def _write(self, frame):
        write_png(self.path / f"frame_{self.frames_written:05d}.png", frame)


def publish(partial: Path, path: Path, keep: bool) -> None:
    """Rename a completed `partial` file to `path`, or remove it when there is nothing to keep."""
    if keep:
        os.replace(partial, path)
    else:
        partial.unlink(missing_ok=True)


class StillWriter(FrameWriter):
    """Keeps the frame numbered `still_frame` (default: the last) and writes it as one PNG on close."""

    def __init__(self, path: Path, width: int, height: int, fps: float, still_frame: int | None = None):
        super().__init__(path, width, height, fps)
        self.still_frame = still_frame
        self._kept: np.ndarray | None = None

    def _write(self, frame):
        if self.still_frame is None or self.frames_written == self.still_frame:
            self._kept = frame.copy()

    def close(self):
        """Write the kept frame under a partial name and give it its name; OutputError (the partial removed) when
        the write fails (a full disk)."""
        if self._kept is not None:
            partial = partial_name(self.path)
            kept, self._kept = self._kept, None
            try:
                write_png(partial, kept)
                publish(partial, self.path, keep=True)
            except OSError as exc:
                partial.unlink(missing_ok=True)
                raise OutputError(self.path, exc.strerror or type(exc).__name__) from None


class FfmpegWriter(FrameWriter):
    """MP4 (H.264, yuv420p) or GIF (one palette for the clip) through ffmpeg (render/encoder.py)."""

    def __init__(self, path: Path, width: int, height: int, fps: float):
        super().__init__(path, width, height, fps)
        ffmpeg_exe()  # fail here, before the run, when imageio-ffmpeg is missing
        self._encoder: Encoder | None = None  # ffmpeg starts with the first frame: a run that draws none writes nothing

    def _write(self, frame):
        if self._encoder is None:
            self._encoder = Encoder(partial_name(self.path), self.width, self.height, self.fps)
        self._encoder.write(frame)

    def close(self):
        if self._encoder is not None:
            encoder, self._encoder = self._encoder, None
            try:
                encoder.close()
            except Exception:
                encoder.path.unlink(missing_ok=True)
                raise
            publish(encoder.path, self.path, keep=self.frames_written > 0)


def check_output(path: str | Path) -> None:
    """Fail early (before any simulation) when the output kind needs a package that is missing."""
    suffix = Path(path).suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError as exc:
            raise SandboxError(f"{path}: writing {suffix} needs imageio-ffmpeg; {VIDEO_HINT}") from exc
    elif suffix not in ("", ".png"):
        raise SandboxError(f"{path}: unknown output kind {suffix!r}; expected .mp4, .mov, .gif, .png or a folder")


def open_writer(path: str | Path, width: int, height: int, fps: float, still_frame: int | None = None) -> FrameWriter:
    """The writer for `path` by its extension; a path without extension is a folder of PNGs."""
    path = Path(path)
    check_output(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        if width % 2 or height % 2:
            raise SandboxError(f"{path}: {suffix} needs an even width and height, got {width}x{height}")
        return FfmpegWriter(path, width, height, fps)
    if suffix == ".png":
        return StillWriter(path, width, height, fps, still_frame)
    return PngSequenceWriter(path, width, height, fps)

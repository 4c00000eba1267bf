"""Inline display in Jupyter: a simulation shows its current picture, a Movie plays as an HTML5 video.

Pictures are PNGs and videos MP4s (H.264 through imageio-ffmpeg, the `video` extra), embedded as base64 in the
cell's HTML output, so a saved notebook shows them without the sandbox installed. Without imageio-ffmpeg a movie
shows its last frame as a still.
"""

from __future__ import annotations

import base64
import html
import tempfile
from pathlib import Path

import numpy as np

from ..files.table import FrameTable
from .video import open_writer, write_png


def png_bytes(picture: np.ndarray) -> bytes:
    """A (H, W, 3) uint8 picture as PNG file bytes."""

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "picture.png"
        write_png(path, picture)
        return path.read_bytes()


def png_html(picture: np.ndarray, caption: str = "") -> str:
    """An <img> of the picture (embedded PNG), with a caption line below."""
    data = base64.b64encode(png_bytes(picture)).decode("ascii")
    text = f"<div><small>{html.escape(caption)}</small></div>" if caption else ""
    return f'<div><img src="data:image/png;base64,{data}"/>{text}</div>'


class Movie:
    """Frames drawn while a simulation ran (Simulation.movie): `frames` (list of (H, W, 3) uint8), `fps`, and the
    run's measurements as `table` (a FrameTable). Shows as a looping video in Jupyter; save() writes it to a file."""

    def __init__(self, frames: list[np.ndarray], fps: float, table: FrameTable, title: str = "") -> None:
        self.frames = frames
        self.fps = fps
        self.table = table
        self.title = title

    def save(self, path: str | Path) -> Path:
        """Write the frames to `path` by its extension (.mp4, .gif, .png still, or a folder of PNGs)."""

        if not self.frames:
            raise ValueError("the movie has no frames")
        height, width = self.frames[0].shape[:2]
        writer = open_writer(path, width, height, self.fps)
        try:
            for frame in self.frames:
                writer.write(frame)
        finally:
            writer.close()
        return Path(path)

    def mp4_bytes(self) -> bytes:
        """The movie as MP4 file bytes (needs imageio-ffmpeg)."""
        with tempfile.TemporaryDirectory() as folder:
            path = self.save(Path(folder) / "movie.mp4")
            return path.read_bytes()

    def __repr__(self) -> str:
        return f"Movie({len(self.frames)} frames at {self.fps:g} fps{': ' + self.title if self.title else ''})"

    def _repr_html_(self) -> str:
        if not self.frames:
            return "<p>(a movie with no frames)</p>"
        caption = f"{self.title}: {len(self.frames)} frames" if self.title else f"{len(self.frames)} frames"
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            return png_html(self.frames[-1], caption + " (the last; install the video extra to play them)")
        data = base64.b64encode(self.mp4_bytes()).decode("ascii")
        return (
            f'<video controls autoplay loop muted playsinline src="data:video/mp4;base64,{data}"></video>'
            f"<div><small>{html.escape(caption)}</small></div>"
        )

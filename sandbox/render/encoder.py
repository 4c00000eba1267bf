"""ffmpeg as a child process (the binary imageio-ffmpeg ships): encode raw RGB frames into one MP4 or GIF, join
pieces, cut a video after its first frames, and list the MD5 of each decoded frame (how a resume proves that a video
holds the frames its checkpoint recorded).

ffmpeg runs in its own session, so a Ctrl-C or SIGTERM sent to the terminal's process group reaches only the
sandbox, which then closes the file in order; every exit status is checked, so a full disk is an OutputError rather
than a silently truncated file.

ffmpeg is given every path as `file:` and an absolute path, so no name is read as an option (a leading `-`), a
protocol (`concat:`, `a:b`) or a quoted string (`'`); the concat list quotes its names the way ffmpeg unquotes them.
"""

from __future__ import annotations

import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..files.claim import LISTING
from .video_codec import VideoCodec

GIF_PALETTE = "split[a][b];[a]palettegen=stats_mode=diff[p];[b][p]paletteuse=dither=none:diff_mode=rectangle"


def ffmpeg_exe() -> str:
    import imageio_ffmpeg

    return imageio_ffmpeg.get_ffmpeg_exe()


def _codec(path: Path, codec: VideoCodec | None = None) -> list[str]:
    """ffmpeg's output arguments for `path`: a GIF's palette, else `codec`'s (render/video_codec.py; default H.264)
    and, in an MP4 or MOV, its index at the front."""
    if path.suffix.lower() == ".gif":
        return ["-vcodec", "gif", "-pix_fmt", "rgb24", "-qscale:v", "16", "-filter_complex", GIF_PALETTE]
    return [*(codec or VideoCodec()).args(), "-movflags", "+faststart"]


def _copied(path: Path) -> list[str]:
    """ffmpeg's output arguments for writing `path` from other videos: MP4 and MOV packets copied as they are (the
    encoding, its tags included, kept); a GIF encoded again, with its palette."""
    return ["-c", "copy", "-movflags", "+faststart"] if path.suffix.lower() != ".gif" else _codec(path)


def _run(args: list[str], what: Path) -> str:
    """Run ffmpeg with `args`; its stdout, or an OutputError naming `what` and ffmpeg's last line."""
    done = subprocess.run(
        [ffmpeg_exe(), "-nostdin", "-v", "error", *args], capture_output=True, text=True, start_new_session=True
    )
    if done.returncode != 0:
        raise OutputError(what, _last_line(done.stderr))
    return done.stdout


def ff_path(path: Path) -> str:
    """`path` as ffmpeg reads it without interpreting it: the file protocol and an absolute path."""
    return "file:" + str(Path(path).absolute())


def _quoted(text: str) -> str:
    """`text` as one word of an ffmpeg concat list: inside single quotes, a quote written as '\\''."""
    return "'" + text.replace("'", "'\\''") + "'"


def _last_line(text: str) -> str:
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else "ffmpeg failed"


class Encoder:
    """One ffmpeg process writing `path` (.mp4 or .mov: `codec`, H.264 by default; .gif: one palette for the clip)
    from (H, W, 3) uint8 frames, top row first ((H, W, 4) RGBA where the codec has alpha). close() waits for it and
    raises OutputError when it failed; kill() abandons the file."""

    def __init__(self, path: Path, width: int, height: int, fps: float, codec: VideoCodec | None = None) -> None:
        self.path = path
        codec = codec or VideoCodec()
        rate = str(Fraction(fps).limit_denominator())
        pixels = "rgb24" if path.suffix.lower() == ".gif" else codec.input_format
        args = ["-y", "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{width}x{height}", "-pix_fmt", pixels]
        args += ["-r", rate, "-i", "-", "-an", *_codec(path, codec), ff_path(path)]
        self._log = tempfile.TemporaryFile()  # noqa: SIM115 - closed in close()/kill()
        self._proc = subprocess.Popen(
            [ffmpeg_exe(), "-nostdin", "-v", "error", *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=self._log,
            start_new_session=True,
        )

    def write(self, frame: np.ndarray) -> None:
        try:
            self._proc.stdin.write(np.ascontiguousarray(frame, dtype=np.uint8).tobytes())
        except (BrokenPipeError, OSError):
            self._proc.wait()
            raise OutputError(self.path, self._reason()) from None

    def close(self) -> None:
        try:
            self._proc.stdin.close()
        except OSError:
            pass
        code = self._proc.wait()
        reason = self._reason()
        if code != 0:
            raise OutputError(self.path, reason)

    def kill(self) -> None:
        if self._proc.poll() is None:
            self._proc.kill()
        self._proc.wait()
        self._log.close()

    def _reason(self) -> str:
        self._log.seek(0)
        text = self._log.read().decode(errors="replace")
        self._log.close()
        return _last_line(text)


def frame_digests(path: Path, frames: int | None = None) -> list[str]:
    """The MD5 of each decoded frame of a video (the first `frames`, or all)."""
    limit = ["-frames:v", str(frames)] if frames is not None else []
    out = _run(["-i", ff_path(path), "-map", "0:v", *limit, "-f", "framemd5", "-"], path)
    return [line.rsplit(",", 1)[-1].strip() for line in out.splitlines() if line and not line.startswith("#")]


def join(pieces: list[Path], path: Path) -> None:
    """Write the videos `pieces` one after another into `path`: MP4 and MOV pieces are copied packet for packet
    (every piece starts on a key frame), GIF pieces are decoded and given one palette again."""
    listing = path.with_name(path.name + LISTING)
    listing.write_text("".join(f"file {_quoted(ff_path(p))}\n" for p in pieces))
    try:
        _run(["-y", "-f", "concat", "-safe", "0", "-i", ff_path(listing), *_copied(path), ff_path(path)], path)
    finally:
        listing.unlink(missing_ok=True)


def cut(source: Path, frames: int, path: Path) -> None:
    """Write the first `frames` frames of `source` to `path` (MP4, MOV: copied, and exact where a piece began
    there)."""
    _run(["-y", "-i", ff_path(source), "-map", "0:v", "-frames:v", str(frames), *_copied(path), ff_path(path)], path)

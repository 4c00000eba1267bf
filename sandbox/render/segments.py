"""The pictures of a headless run that a resume can continue: a video written in pieces (a new piece at every
checkpoint, each a whole MP4 or GIF under the run's partial names, joined into the final file at the end), or a
folder of numbered PNGs. A checkpoint marks them: the pieces closed, the count of frames, and a digest of the
decoded frames (of the PNG files' bytes), which a resume checks before it continues them."""

from __future__ import annotations

import hashlib
import io
import os
import re
from pathlib import Path

import numpy as np
from PIL import Image

from ..errors import OutputError, SandboxError
from ..files.claim import RESTART_HINT, Claim, create_exclusive, digest_of, own_partial, remove_numbered, write_whole
from .encoder import Encoder, cut, frame_digests, join
from .video_codec import VideoCodec

VIDEO_WORDS = {"mp4": "an MP4 video", "mov": "a MOV video", "gif": "a GIF"}  # by kind (the suffix)


def _settings(words: str, width: int, height: int, fps: float, every: int) -> str:
    return f"{words} of {width}x{height} at {fps:g} frames/s" + (f", every {every} frames kept" if every > 1 else "")


def _new_file(path: Path, option: str) -> Path:
    """Create `path` empty for a writer that opens it by name (ffmpeg), never through a link or over a file."""
    os.close(create_exclusive(path, option))
    return path


class SegmentedVideo:
    """`claim.path` (.mp4, .mov or .gif) written piece by piece, encoded as `codec` (render/video_codec.py)."""

    # what mark() records
    RECORD = {"pieces": list, "frames": int, "offered": int, "digest": str, "size": list, "fps": float, "every": int}

    def __init__(
        self, claim: Claim, width: int, height: int, fps: float, every: int = 1, codec: VideoCodec | None = None
    ) -> None:
        """`every`: keep every `every`-th frame offered (a GIF's lower frame rate; the video plays at fps / every)."""
        self.claim, self.width, self.height, self.fps, self.every = claim, width, height, fps / every, every
        self.kind = claim.path.suffix.lower().lstrip(".")
        self.codec = codec or VideoCodec()
        self.words = VIDEO_WORDS[self.kind]
        self.encoding = "GIF" if self.kind == "gif" else self.codec.words()
        self.pieces: list[Path] = []
        self.digests: list[str] = []  # of the frames in closed pieces
        self.frames = 0  # written, in all pieces
        self.offered = 0  # given to write()
        self._encoder: Encoder | None = None
        self._cut: Path | None = None  # a piece cut from a finished video by find()

    def find(self, record: dict, checkpoint: Path, frame: int):
        """The video the checkpoint of frame `frame` marked, as pieces holding its `record["frames"]` frames (those
        `frame` frames offered imply): those a killed run left, else the first frames of the finished video cut into
        a piece of this run's own (for a GIF, whose finished frames were given one palette again, only their count
        is checked). A SandboxError when neither matches, or when a record of no frames meets a finished video."""
        path, frames = self.claim.path, record["frames"]
        self._check_settings(record, checkpoint)
        if record["offered"] != frame or frames != -(-frame // self.every):
            raise SandboxError(
                f"{self.claim.option} {path}: the checkpoint {checkpoint} records {frames} frames of "
                f"{record['offered']} offered, where its frame {frame} makes {-(-frame // self.every)} of {frame}; "
                f"{RESTART_HINT}"
            )
        if frames == 0:
            if path.is_file() and path.stat().st_size > 0:
                raise SandboxError(
                    f"{self.claim.option} {path}: the checkpoint {checkpoint} claims none of its frames, so continuing "
                    f"would replace it; {RESTART_HINT}"
                )
            return [], [], record["offered"]
        left = [own_partial(path, name, pieces=True) for name in record["pieces"]]  # only names of its own pattern
        if left and all(p is not None for p in left):
            pieces, exact = left, True
        elif path.is_file():
            first = self.claim.partial("seg0000")
            self._cut = _new_file(first, self.claim.option)
            try:
                cut(path, frames, first)
            except OutputError:
                raise SandboxError(
                    f"{self.claim.option} {path}: is not a video this run can continue; {RESTART_HINT}"
                ) from None
            pieces, exact = [first], path.suffix.lower() != ".gif"
        else:
            raise SandboxError(
                f"{self.claim.option} {path}: missing, and so are the pieces the checkpoint {checkpoint} names; "
                f"{RESTART_HINT}"
            )
        digests = [d for piece in pieces for d in frame_digests(piece)]
        if len(digests) != frames or (exact and digest_of(digests) != record["digest"]):
            raise SandboxError(
                f"{self.claim.option} {path}: does not hold the {frames} frames the checkpoint {checkpoint} was "
                f"written with; {RESTART_HINT}"
            )
        return pieces, digests, record["offered"]

    def _check_settings(self, record: dict, checkpoint: Path) -> None:
        """The picture size, frame rate, kept frames and encoding of this run are those the checkpoint's video was
        made with (a record without an encoding is an earlier version's untagged H.264)."""
        was = record.get("codec", "an earlier version's untagged H.264")
        if was != self.encoding:
            raise SandboxError(
                f"{self.claim.option} {self.claim.path}: the checkpoint {checkpoint} continues a video encoded as "
                f"{str(was)[:80]}, this run encodes {self.encoding}; expected the same --codec, --quality, --lossless "
                "and --alpha, or --restart-outputs to start the outputs over"
            )
        saved = (record["size"], float(record["fps"]), record["every"])
        if saved != ([self.width, self.height], float(self.fps), self.every):
            was = _settings(self.words, *(saved[0] if len(saved[0]) == 2 else (0, 0)), saved[1], saved[2])
            now = _settings(self.words, self.width, self.height, self.fps, self.every)
            raise SandboxError(
                f"{self.claim.option} {self.claim.path}: the checkpoint {checkpoint} continues {was}, this run "
                f"writes {now}; expected the same --width, --height and --fps, or --restart-outputs to start the "
                "outputs over"
            )

    def start(self) -> None:
        """A fresh video: nothing to prepare (pieces are made as frames come)."""

    def adopt(self, found) -> None:
        """Continue after the pieces find() returned (new pieces are numbered on, under this run's names)."""
        self.pieces, self.digests, self.offered = list(found[0]), list(found[1]), found[2]
        self.frames = len(self.digests)

    def in_use(self) -> list[Path]:
        return list(self.pieces)

    def write(self, frame: np.ndarray) -> None:
        self.offered += 1
        if (self.offered - 1) % self.every:
            return
        if self._encoder is None:
            # this run's name: pieces adopted from a killed run carry that run's, so the numbers cannot collide
            piece = _new_file(self.claim.partial(f"seg{len(self.pieces):04d}"), self.claim.option)
            self._encoder = Encoder(piece, self.width, self.height, self.fps, self.codec)
            self.pieces.append(piece)
        self._encoder.write(frame)
        self.frames += 1

    def _close_piece(self) -> None:
        if self._encoder is not None:
            encoder, self._encoder = self._encoder, None
            encoder.close()
            self.digests += frame_digests(encoder.path)

    def mark(self) -> dict:
        """Close the piece being written; the record a checkpoint keeps."""
        self._close_piece()
        return {
            "kind": self.kind,
            "path": str(self.claim.path),
            "pieces": [p.name for p in self.pieces],
            "frames": self.frames,
            "offered": self.offered,
            "digest": digest_of(self.digests),
            "size": [self.width, self.height],
            "fps": float(self.fps),
            "every": self.every,
            "codec": self.encoding,
        }

    def publish(self) -> None:
        """Join the pieces into the file asked for (none written: no file)."""
        if self._encoder is not None:
            encoder, self._encoder = self._encoder, None
            encoder.close()
        if not self.pieces:
            return
        if len(self.pieces) == 1:
            os.replace(self.pieces[0], self.claim.path)
        else:
            joined = _new_file(self.claim.partial(), self.claim.option)
            join(self.pieces, joined)
            os.replace(joined, self.claim.path)
            for piece in self.pieces:
                piece.unlink(missing_ok=True)
        self.pieces = []

    def abandon(self) -> list[Path]:
        """Stop writing, leaving the pieces (all but an unfinished one, which no player opens) in place."""
        if self._cut is not None and self._cut not in self.pieces:
            self._cut.unlink(missing_ok=True)
        if self._encoder is not None:
            self._encoder.kill()
            self._encoder.path.unlink(missing_ok=True)
            self.pieces.remove(self._encoder.path)
            self._encoder = None
        return [p for p in self.pieces if p.exists()]


class PngFolder:
    """`claim.path` a folder of frame_00000.png, frame_00001.png, ... numbered from the run's first frame; each file
    written under a partial name and renamed. The folder is the run's like a file is: frames of an earlier run
    (`frame_NNNNN.png` past the ones continued) are removed when the run starts, so it never holds two runs' frames."""

    RECORD = {"frames": int, "digest": str, "size": list}
    FRAME = re.compile(r"frame_(\d{5,})\.png")

    def __init__(self, claim: Claim, width: int = 0, height: int = 0) -> None:
        self.claim, self.width, self.height = claim, width, height
        self.kind, self.words = "png-folder", "a folder of PNG frames"
        self.frames = 0
        self.hashes: list[str] = []
        self.removed: list[Path] = []

    def find(self, record: dict, checkpoint: Path, frame: int):
        """The hashes of the `record["frames"]` frame files the checkpoint of frame `frame` marked (one a frame), or
        a SandboxError."""
        frames = record["frames"]
        if frames != frame:
            raise SandboxError(
                f"{self.claim.option} {self.claim.path}: the checkpoint {checkpoint} records {frames} frames where its "
                f"frame {frame} makes {frame}; {RESTART_HINT}"
            )
        if frames == 0 and self._file(0).exists():
            raise SandboxError(
                f"{self.claim.option} {self.claim.path}: the checkpoint {checkpoint} claims none of its frames, so "
                f"continuing would remove them; {RESTART_HINT}"
            )
        if record["size"] != [self.width, self.height]:
            raise SandboxError(
                f"{self.claim.option} {self.claim.path}: the checkpoint {checkpoint} continues frames of "
                f"{'x'.join(map(str, record['size']))}, this run draws {self.width}x{self.height}; expected the same "
                "--width and --height, or --restart-outputs to start the outputs over"
            )
        hashes = []
        for k in range(frames):
            try:
                hashes.append(hashlib.sha256(self._file(k).read_bytes()).hexdigest())
            except OSError:
                break
        if len(hashes) != frames or digest_of(hashes) != record["digest"]:
            raise SandboxError(
                f"{self.claim.option} {self.claim.path}: does not hold the {frames} frames the checkpoint {checkpoint} "
                f"was written with; {RESTART_HINT}"
            )
        return hashes

    def start(self) -> None:
        """A fresh folder of frames: any frame files of an earlier run are removed."""
        self._remove_from(0)

    def adopt(self, hashes) -> None:
        self.frames, self.hashes = len(hashes), list(hashes)
        self._remove_from(self.frames)

    def _remove_from(self, first: int) -> None:
        """Remove the frame files numbered `first` and on (regular files of the frame pattern only)."""
        self.removed += remove_numbered(self.claim.path, self.FRAME, first)

    def in_use(self) -> list[Path]:
        return []

    def _file(self, k: int) -> Path:
        return self.claim.path / f"frame_{k:05d}.png"

    def write(self, frame: np.ndarray) -> None:
        buffer = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(frame)).save(buffer, format="PNG")
        data = buffer.getvalue()
        try:
            self.claim.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(self.claim.path, exc.strerror or type(exc).__name__) from exc
        write_whole(self._file(self.frames), data, self.claim.option)
        self.hashes.append(hashlib.sha256(data).hexdigest())
        self.frames += 1

    def mark(self) -> dict:
        return {
            "kind": self.kind,
            "path": str(self.claim.path),
            "frames": self.frames,
            "digest": digest_of(self.hashes),
            "size": [self.width, self.height],
        }

    def publish(self) -> None:
        pass

    def abandon(self) -> list[Path]:
        return []

"""A particle cache written frame by frame beside the path named for it, under the rules of docs/files.md.

    --cache out/wax.ply   out/wax.ply.00000.ply, out/wax.ply.00001.ply, ... (and out/wax.ply.surface.00000.ply ...),
                          out/wax.ply.parts.00000.ply, ... (the walls, plates and lid)
    --cache out/wax.vtp   out/wax.pvd.00000.vtp ... (and out/wax.pvd.surface.00000.vtp ...) and the collection
                          out/wax.pvd
    --cache out/wax.usd   out/wax.usd.00000.usdc ... and the stage out/wax.usd (.usda and .usdc as asked)

The frame files' names begin with the whole name of the file the claim holds (the index: the `.pvd`, the USD stage,
the named PLY), so two caches of different names never share a frame file (wax.usd and wax.usda, or wax.surface.ply
beside wax.ply's surfaces), and the claim's lock holds the frames with the index. Every file is written under the
run's partial name and renamed when whole, the index again at every checkpoint and at the end, so a reader never
meets half a file. The frame files are the run's like a PNG folder's frames: those of an earlier run (of the cache's
own pattern, beyond the frames continued) are removed when the run starts. A checkpoint records the frames written,
their times and a digest of every file's SHA-256; a resume checks that they are the frames its checkpoint's frame,
--cache-every and --cache-surface make, and that every file is there with its digest, before it numbers on.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
from pathlib import Path

from ..config.arguments import MAX_FRAMES
from ..errors import SandboxError
from .cache_formats import (
    SURFACE_VELOCITY,
    CacheFrame,
    ply_bytes,
    pvd_text,
    surface_ply_bytes,
    surface_vtp_bytes,
    vtp_bytes,
)
from .cache_parts import parts_comment, parts_surface
from .claim import RESTART_HINT, Claim, digest_of, is_regular_file, remove_numbered, write_whole

CACHE_SUFFIXES = (".usd", ".usda", ".usdc", ".vtp", ".pvd", ".ply")
FRAME_EXT = {"usd": ".usdc", "vtk": ".vtp", "ply": ".ply"}  # a frame file's extension, by kind


def cache_kind(path: Path) -> str:
    """ "usd", "vtk" or "ply" by the path's extension; a SandboxError for any other."""
    suffix = path.suffix.lower()
    if suffix not in CACHE_SUFFIXES:
        raise SandboxError(
            f"--cache {path}: unknown cache kind {suffix!r}; expected one of {', '.join(CACHE_SUFFIXES)}"
        )
    return {".vtp": "vtk", ".pvd": "vtk", ".ply": "ply"}.get(suffix, "usd")


def index_path(path: Path) -> Path:
    """The file the claim holds and readers open: the .pvd of a VTK cache, the stage of a USD cache, the named path of
    a PLY cache (a PLY sequence has no index: the name is claimed for its frames)."""
    return path.with_suffix(".pvd") if cache_kind(path) == "vtk" else path


def frame_name(index: Path, frame: int, surface: bool = False, parts: bool = False) -> str:
    """The name of the frame file numbered `frame` (its surface's with `surface`, the scene's parts' with `parts`)
    of the cache whose index is `index`."""
    ext = FRAME_EXT[cache_kind(index)]
    return f"{index.name}{'.surface' if surface else '.parts' if parts else ''}.{frame:05d}{ext}"


class CacheSequence:
    """The cache `claim.path` (its index, index_path()) holding one frame per write(); `fps`: time codes per second
    of a USD stage; `lines`: springs as line cells in a VTK cache; `every` and `surface`: what a run of the command
    line caches (every `every`-th frame from frame `first` on, with surfaces or not), which a resume's record must
    match; `parts` and `camera`: the scene's walls, plates and lid and its pictures' camera (a frame written brings
    its own), which PLY and VTK write as a file a frame (`parts`: whether the frames have one) and USD in its
    stage."""

    RECORD = {"written": list, "digest": str}

    def __init__(
        self,
        claim: Claim,
        named: Path,
        fps: float = 30.0,
        lines: bool = True,
        every: int = 1,
        surface: bool = False,
        first: int = 0,
        parts: list | None = None,
        camera=None,
    ) -> None:
        self.claim, self.named, self.fps, self.lines = claim, named, fps, lines
        self.every, self.surface_asked, self.first = every, surface, first
        self.format = cache_kind(named)
        self.kind = f"cache-{self.format}"
        self.words = f"a {self.format.upper()} particle cache"
        self.frames: list[list] = []  # [frame, time, has surface] per written frame
        self.hashes: list[str] = []
        self.up, self.surface = "Y", False
        self.removed: list[Path] = []
        self._pattern = frame_pattern(claim.path)
        self.parts, self.camera = list(parts or []), camera

    # ------------------------------------------------------------------ names
    def frame_file(self, index: int, surface: bool = False, parts: bool = False) -> Path:
        return self.claim.path.with_name(frame_name(self.claim.path, index, surface, parts))

    def _files(self, k: int) -> list[Path]:
        frame, _, surface = self.frames[k]
        files = [self.frame_file(frame)]
        if self.format != "usd":
            files += [self.frame_file(frame, True)] if surface else []
            files += [self.frame_file(frame, parts=True)] if self.parts else []
        return files

    # ------------------------------------------------------------------ opening
    def start(self) -> None:
        """A fresh cache: frame files of an earlier run are removed."""
        self._remove_beyond(-1)

    def find(self, record: dict, checkpoint: Path, frame: int):
        """The frames the checkpoint of frame `frame` recorded, when they are the ones this run's cache (every
        `self.every` frames, with surfaces or not) holds then, and their files are there with their digests; else a
        SandboxError."""
        every, surface = self.every, self.surface_asked
        frames = record["written"]
        if not _well_formed(frames):
            raise SandboxError(f"{checkpoint}: its record of --cache is damaged; {RESTART_HINT}")
        numbers, expected = [f[0] for f in frames], list(range(self.first, frame + 1, every))
        if numbers != expected or any(f[2] != surface for f in frames):
            asked = f"every {every} frames from frame {self.first}" + (" with surfaces" if surface else "")
            raise SandboxError(
                f"--cache {self.named}: the checkpoint {checkpoint} records {len(frames)} cached frames, not those a "
                f"cache of {asked} holds at its frame {frame}; expected the same --cache-every, --cache-from and "
                "--cache-surface, or "
                "--restart-outputs to start the outputs over"
            )
        if not frames and any(self._pattern.fullmatch(p.name) for p in self.claim.path.parent.iterdir()):
            raise SandboxError(
                f"--cache {self.named}: the checkpoint {checkpoint} claims none of its frame files, so continuing "
                f"would remove them; {RESTART_HINT}"
            )
        self.frames, hashes = [list(f) for f in frames], []
        for k in range(len(frames)):
            for path in self._files(k):
                try:
                    if not is_regular_file(path, single=True):
                        raise OSError
                    hashes.append(hashlib.sha256(path.read_bytes()).hexdigest())
                except OSError:
                    self.frames = []
                    raise SandboxError(
                        f"--cache {self.named}: {path.name}, which the checkpoint {checkpoint} records, is missing or "
                        f"not a file this run can read; {RESTART_HINT}"
                    ) from None
        if digest_of(hashes) != record["digest"]:
            self.frames = []
            raise SandboxError(
                f"--cache {self.named}: does not hold the {len(frames)} frames the checkpoint {checkpoint} was written "
                f"with; {RESTART_HINT}"
            )
        return frames, hashes

    def adopt(self, found) -> None:
        frames, self.hashes = found
        self.frames = [list(f) for f in frames]
        self.surface = any(f[2] for f in self.frames)
        self._remove_beyond(self.frames[-1][0] if self.frames else -1)

    def _remove_beyond(self, last: int) -> None:
        """Remove the cache's frame files numbered after `last` (regular files of its own pattern only)."""
        self.removed += remove_numbered(self.named.parent, self._pattern, last + 1)

    def in_use(self) -> list[Path]:
        return []

    # ------------------------------------------------------------------ writing
    def write(self, frame: CacheFrame) -> None:
        """Write one frame's files (and the index is rewritten at the next mark or at the end)."""
        frame = self._timed(frame)
        self.up = frame.up
        self.parts, self.camera = frame.parts or self.parts, frame.camera or self.camera
        surface = frame.surface is not None
        self.surface = self.surface or surface
        target = self.frame_file(frame.frame)
        if self.format == "usd":
            from .cache_usd import write_frame_layer

            self._publish(target, lambda partial: write_frame_layer(partial, frame))
        else:
            data = ply_bytes(frame) if self.format == "ply" else vtp_bytes(frame, self.lines)
            self._publish(target, data)
            if surface:
                data = surface_ply_bytes(frame) if self.format == "ply" else surface_vtp_bytes(frame)
                self._publish(self.frame_file(frame.frame, True), data)
            if self.parts:
                mesh = parts_surface(self.parts)
                data = (
                    surface_ply_bytes(frame, mesh, (parts_comment(self.parts),))
                    if self.format == "ply"
                    else surface_vtp_bytes(frame, mesh)
                )
                self._publish(self.frame_file(frame.frame, parts=True), data)
        self.frames.append([frame.frame, frame.time, surface])

    def _timed(self, frame: CacheFrame) -> CacheFrame:
        """The frame with its velocity in the time its format plays at (docs/export.md, "Time"): USD and PLY in
        length per second of playback at `fps` frames a second (a stage's time code, or a Houdini frame, is one frame
        of the run), so that position + velocity x (frames apart / fps) is the later frame's position; VTK in length
        per simulated second, the unit of its collection's timesteps."""
        velocity = frame.point_data.get("velocity")
        if velocity is None or self.format == "vtk" or not frame.frame_seconds:
            return frame
        scale = self.fps * frame.frame_seconds  # simulated seconds per second of playback
        note = f"velocity in length per second at {self.fps:g} frames a second (a frame: {frame.frame_seconds:g} s)"
        data = {**frame.point_data, "velocity": (velocity * scale).astype(velocity.dtype)}
        surface = frame.surface
        if surface is not None and surface.velocity() is not None:  # the surface's velocity, in the same time
            vertex_data = {k: v * scale if k in SURFACE_VELOCITY else v for k, v in surface.vertex_data.items()}
            surface = dataclasses.replace(surface, vertex_data=vertex_data)
        return dataclasses.replace(frame, point_data=data, velocity_note=note, surface=surface)

    def _publish(self, target: Path, data) -> None:
        """Write `target` whole (bytes, or a function that writes the path it is given) and keep its digest."""
        write_whole(target, data, "--cache", self.claim.token)
        self.hashes.append(hashlib.sha256(data if isinstance(data, bytes) else target.read_bytes()).hexdigest())

    def _write_index(self) -> None:
        """The .pvd collection or the USD stage over the frames written so far (a PLY sequence has none)."""
        if self.format == "ply":
            return
        if self.format == "vtk":
            entries = []
            for frame, time, surface in self.frames:
                entries.append((time, 0, self.frame_file(frame).name))
                if surface:
                    entries.append((time, 1, self.frame_file(frame, True).name))
                if self.parts:
                    entries.append((time, 2, self.frame_file(frame, parts=True).name))
            write_whole(self.claim.path, pvd_text(entries).encode(), "--cache", self.claim.token)
        else:
            from .cache_usd import write_stage

            clips = [(frame, self.frame_file(frame).name) for frame, _, _ in self.frames]
            stage = lambda path: write_stage(  # noqa: E731
                path, clips, self.fps, self.up, self.surface, self.parts, self.camera
            )
            write_whole(self.claim.path, stage, "--cache", self.claim.token)

    def mark(self) -> dict:
        """Rewrite the index; the record a checkpoint keeps."""
        self._write_index()
        return {"kind": self.kind, "path": str(self.named), "written": self.frames, "digest": digest_of(self.hashes)}

    # ------------------------------------------------------------------ ending
    def publish(self) -> None:
        self._write_index()

    def abandon(self) -> list[Path]:
        return []


def frame_pattern(index: Path) -> re.Pattern:
    """The names of every frame file (and surface) of the cache whose index is `index`; the number is group 1."""
    ext = FRAME_EXT[cache_kind(index)]
    return re.compile(rf"{re.escape(index.name)}(?:\.surface|\.parts)?\.(\d{{5,}}){re.escape(ext)}")


def _well_formed(frames) -> bool:
    """A record's list of cached frames: [frame number, simulated time, has a surface], numbers in range, times
    finite, not negative and not decreasing."""
    if not isinstance(frames, list):
        return False
    last = 0.0
    for f in frames:
        if not (isinstance(f, list) and len(f) == 3 and type(f[0]) is int and isinstance(f[2], bool)):
            return False
        time = f[1]
        if isinstance(time, bool) or not isinstance(time, int | float) or not math.isfinite(time):
            return False
        if not (0 <= f[0] <= MAX_FRAMES and last <= time):
            return False
        last = time
    return True

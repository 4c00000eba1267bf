"""Everything a headless run writes, held together: the pictures (a video in pieces, a PNG folder or a still), the
stats CSV, the extended-XYZ dump and the checkpoint.

- Each output is claimed (files/claim.py): a second live run writing it is refused, partial names are the run's own,
  and partial files a killed run left are adopted by a resume or removed, and named either way.
- A checkpoint flushes every output and records what each held (bytes and SHA-256, frames and a digest of them) in
  the state file, so `--resume` continues the very files the checkpoint belongs to, or says they do not match.
- close(complete=True) gives every output its name (Ctrl-C, SIGTERM, the blow-up guard: the files hold the frames
  done); close(complete=False) (a write that failed: a full disk) leaves them under partial names and lists them.
"""

from __future__ import annotations

import csv
import io
import math
import sys
from collections.abc import Callable
from pathlib import Path

from ..caching import cache_frame, scene_parts
from ..config.arguments import VIDEO_SUFFIXES
from ..errors import OutputError, SandboxError
from ..files.appending import AppendFile
from ..files.cache_sequence import CacheSequence, index_path
from ..files.claim import RESTART_HINT, Claim
from ..files.persist import save_state
from ..measure.stats import stat_values
from ..render.camera import scene_camera
from ..render.segments import VIDEO_WORDS, PngFolder, SegmentedVideo
from ..render.video import StillWriter
from ..render.video_codec import VideoCodec
from ..scripting import extxyz_text
from ..simulation import STAT_COLUMNS, Stats

KIND_WORDS = {**VIDEO_WORDS, "png-folder": "a folder of PNG frames", "text": "a text file"}
KIND_WORDS.update({f"cache-{k}": f"a {k.upper()} particle cache" for k in ("usd", "vtk", "ply")})


def stats_row(frame: int, s: Stats, step_seconds: float) -> dict:
    """One CSV row (the STAT_COLUMNS) for frame `frame`; a measurement the scene does not have (the temperature of a
    scene without heat) is left empty."""
    row = stat_values(frame, s, step_seconds)
    return {k: (("" if math.isnan(v) else f"{v:.9g}") if isinstance(v, float) else v) for k, v in row.items()}


def _csv_text(row: dict | None) -> str:
    """The CSV header (row None) or one row, as text."""
    buffer = io.StringIO()
    table = csv.DictWriter(buffer, fieldnames=STAT_COLUMNS)
    table.writeheader() if row is None else table.writerow(row)
    return buffer.getvalue()


class RunOutputs:
    """The outputs of one headless run of `sim`. `out`: the pictures (.mp4, .gif, .png or a folder; None: none),
    `stats`: the CSV, `dump`: extended XYZ every `dump_every` frames, `checkpoint`: the state every
    `checkpoint_every` frames; `every`: a video keeps every `every`-th frame (a GIF's frame rate); `codec`: an MP4's
    or MOV's encoding (render/video_codec.py); `resume`:
    (state path, its meta) when continuing; `restart`: start the outputs over instead of continuing."""

    def __init__(
        self,
        sim,
        out: str | Path | None = None,
        stats: str | Path | None = None,
        *,
        size: tuple[int, int, float] = (0, 0, 0.0),
        every: int = 1,
        still_frame: int | None = None,
        dump: str | Path | None = None,
        dump_every: int = 1,
        checkpoint: str | Path | None = None,
        checkpoint_every: int | None = None,
        resume: tuple[Path, dict] | None = None,
        restart: bool = False,
        cache: str | Path | None = None,
        cache_every: int = 1,
        cache_surface: bool = False,
        cache_from: int = 0,
        codec: VideoCodec | None = None,
    ) -> None:
        self.sim = sim
        self.codec = codec
        self.dump_every = dump_every
        self.cache = Path(cache) if cache else None
        self.cache_every, self.cache_surface, self.cache_from = cache_every, cache_surface, cache_from
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.checkpoint_every = checkpoint_every if self.checkpoint is not None else None
        named = {"--out": out, "--stats": stats, "--dump": dump, "--checkpoint": self.checkpoint}
        named["--cache"] = index_path(self.cache) if self.cache else None
        self.named = {option: Path(p) for option, p in named.items() if p is not None}
        self.claims = [Claim(option, path) for option, path in self.named.items()]
        self.writers: dict[str, object] = {}
        self.removed: list[Path] = []
        try:
            for claim in self.claims:
                claim.acquire()
            self._open(size, every, still_frame, resume, restart)
        except BaseException:
            self._abandon_all()
            self._release()
            raise

    @property
    def pictures(self) -> bool:
        return "--out" in self.writers

    # ------------------------------------------------------------------ opening
    def _open(self, size, every, still_frame, resume, restart) -> None:
        claims = {c.option: c for c in self.claims}
        width, height, fps = size
        if "--out" in claims:
            claim = claims["--out"]
            suffix = claim.path.suffix.lower()
            if suffix in VIDEO_SUFFIXES:
                self.writers["--out"] = SegmentedVideo(claim, width, height, fps, every, self.codec)
            elif suffix == ".png":
                self.writers["--out"] = StillWriter(claim.path, width, height, fps, still_frame)
            else:
                self.writers["--out"] = PngFolder(claim, width, height)
        if "--stats" in claims:
            self.writers["--stats"] = AppendFile(claims["--stats"], lines_at=lambda frame: frame + 1)  # header, rows
        if "--dump" in claims:
            self.writers["--dump"] = AppendFile(claims["--dump"])
        if "--cache" in claims:
            self.writers["--cache"] = CacheSequence(
                claims["--cache"],
                self.cache,
                fps,
                every=self.cache_every,
                surface=self.cache_surface,
                first=self.cache_from,
                parts=scene_parts(self.sim),
                camera=scene_camera(self.sim.scene),
            )
        records = _records(resume, restart)
        found = {}  # every output checked before any is touched
        for option, writer in self.writers.items():
            if records is None or isinstance(writer, StillWriter):
                continue
            record = records.get(option)
            if record is None:
                raise SandboxError(
                    f"{option} {claims[option].path}: the checkpoint {resume[0]} was written by a run without it, so "
                    f"there is nothing to continue; {RESTART_HINT}"
                )
            _check_kind(record, resume[0], option, claims[option].path, writer)
            _check_record(record, resume[0], option, writer.RECORD)
            # proven against the files and against what the checkpoint's frame implies (rows, pictures, cached frames)
            found[option] = writer.find(record, resume[0], resume[1]["frame"])
        for option, writer in self.writers.items():
            if option in found:
                writer.adopt(found[option])
            elif isinstance(writer, AppendFile):
                writer.start(_csv_text(None) if option == "--stats" else "")
            elif not isinstance(writer, StillWriter):
                writer.start()
                if option == "--cache" and self.caches(0) and resume is None:
                    writer.write(cache_frame(self.sim, self.cache_surface))  # the state the run starts from
        in_use = {p for w in self.writers.values() if not isinstance(w, StillWriter) for p in w.in_use()}
        for claim in self.claims:
            for leftover in claim.leftovers():
                if leftover not in in_use:
                    _remove(leftover)
                    self.removed.append(leftover)
        if self.removed:
            names = ", ".join(p.name for p in self.removed)
            print(f"removed {len(self.removed)} partial file(s) a killed run left: {names}", file=sys.stderr)
        for option in ("--out", "--cache"):
            stale = getattr(self.writers.get(option), "removed", [])
            if stale:
                where = claims[option].path if option == "--out" else self.cache.parent
                print(f"removed {len(stale)} frame file(s) of an earlier run from {where}", file=sys.stderr)

    # ------------------------------------------------------------------ each frame
    def frame(self, frame: int, stats: Stats, step_seconds: float, picture: Callable[[], object] | None) -> None:
        """After frame index `frame` (0-based; `frame + 1` frames are done): its row, picture, dump and
        checkpoint."""
        done = frame + 1
        if "--stats" in self.writers:
            self.writers["--stats"].write(_csv_text(stats_row(frame, stats, step_seconds)))
        if "--out" in self.writers and picture is not None:
            self.writers["--out"].write(picture())
        if "--dump" in self.writers and done % self.dump_every == 0:
            self.writers["--dump"].write(extxyz_text(self.sim))
        if "--cache" in self.writers and self.caches(done):
            self.writers["--cache"].write(cache_frame(self.sim, self.cache_surface))
        if self.checkpoint_every and done % self.checkpoint_every == 0:
            self._checkpoint(done)

    def caches(self, done: int) -> bool:
        """Whether the cache holds the state after `done` frames (0: the state the run starts from): every
        `cache_every`-th frame from `cache_from` on."""
        return done >= self.cache_from and (done - self.cache_from) % self.cache_every == 0

    def _checkpoint(self, done: int) -> None:
        records = {option: w.mark() for option, w in self.writers.items() if not isinstance(w, StillWriter)}
        save_state(self.sim, self.checkpoint, frame=done, outputs=records)  # an OutputError when it fails

    # ------------------------------------------------------------------ ending
    def close(self, complete: bool, finished_frame: int | None = None) -> list[Path]:
        """complete: every output takes its name; else (a failed write) each is left under its partial name.
        `finished_frame`: the run reached its last frame, this many frames done: a checkpoint is written there first
        (where it was not already), so a kill while the outputs are joined and named leaves a state whose resume
        finishes them. Returns the partial files kept (empty when complete)."""
        try:
            if complete and finished_frame is not None and self.checkpoint_every:
                if finished_frame % self.checkpoint_every:
                    self._checkpoint(finished_frame)
            if complete:
                for writer in self.writers.values():
                    writer.close() if isinstance(writer, StillWriter) else writer.publish()
                return []
            return self._abandon_all()
        except OutputError as exc:
            raise OutputError(exc.path, exc.reason, self._abandon_all()) from None
        finally:
            self._release()

    def _abandon_all(self) -> list[Path]:
        kept = []
        for writer in self.writers.values():
            if not isinstance(writer, StillWriter):
                kept += writer.abandon()
        return kept

    def _release(self) -> None:
        for claim in self.claims:
            claim.release()


def _records(resume, restart: bool) -> dict | None:
    """The output records of the checkpoint resumed (None: start every output afresh)."""
    if resume is None or restart:
        return None
    records = resume[1].get("outputs")
    return records if isinstance(records, dict) else None


def _check_kind(record, checkpoint: Path, option: str, path: Path, writer) -> None:
    """The checkpoint continued the same kind of output (an MP4, a GIF, a PNG folder) as this run writes."""
    kind = record.get("kind") if isinstance(record, dict) else None
    if kind != writer.kind:
        was = (
            KIND_WORDS.get(kind, "an output of unknown kind") if isinstance(kind, str) else "an output of unknown kind"
        )
        raise SandboxError(
            f"{option} {path}: the checkpoint {checkpoint} continues {was}, this run writes {writer.words}; "
            f"{RESTART_HINT}"
        )


def _check_record(record, checkpoint: Path, option: str, needs: dict) -> None:
    """A record of a crafted or damaged state file is refused before any of it names a file: the keys `needs`
    (name: type) present, counts not negative, file names plain names in the output's folder."""
    ok = isinstance(record, dict) and all(isinstance(record.get(k), t) for k, t in needs.items())
    if ok:
        counts = [record[k] for k in ("frames", "bytes", "offered") if k in needs]
        names = [record["partial"]] if "partial" in needs else list(record.get("pieces", []))
        ok = all(not isinstance(c, bool) and c >= 0 for c in counts)
        ok = ok and all(isinstance(n, str) and n and "/" not in n and n not in (".", "..") for n in names)
    if not ok:
        raise SandboxError(f"{checkpoint}: its record of {option} is damaged; {RESTART_HINT}")


def _remove(path: Path) -> None:
    try:
        path.unlink(missing_ok=True)
    except OSError:  # left for the next run to name again
        pass

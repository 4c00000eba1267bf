"""A forged state file never shortens a finished output (issue 72): each output record of the checkpoint resumed
must prove what it claims, and what it claims must be what the checkpoint's frame implies. A record of nothing (0
bytes, the digest of nothing, a video of 0 frames), of the CSV's header alone, of frames that do not exist, or of
another --cache-every or --cache-surface is refused in one line, and every file stays as it was. Each run is
`sandbox run` in this process (its kernels come from the cache)."""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import pytest

from sandbox.app.cli import EXIT_BAD_INPUT
from sandbox.files.claim import digest_of, partial_name
from tests.test_hostile_files import errors, rewrite_meta, run

pytestmark = pytest.mark.xdist_group("run_files")

NOTHING = hashlib.sha256(b"").hexdigest()
OUTPUTS = ["--checkpoint", "c.npz", "--stats", "s.csv", "--dump", "d.extxyz", "--out", "m.mp4"]
CACHED = ["--checkpoint", "c.npz", "--cache", "w.ply", "--out", "frames"]


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """8 frames with a CSV, a dump and a video, checkpointed at 4 and 8 (copied by each test)."""
    folder = tmp_path_factory.mktemp("forged")
    assert run(folder, outputs=OUTPUTS) == 0
    return folder


@pytest.fixture(scope="module")
def cached(tmp_path_factory) -> Path:
    """8 frames with a PLY cache and a folder of PNG frames, checkpointed at 4 and 8."""
    folder = tmp_path_factory.mktemp("forged_cache")
    assert run(folder, outputs=CACHED) == 0
    return folder


def forged(source: Path, tmp_path: Path, change) -> tuple[Path, dict]:
    """A copy of the run's folder whose checkpoint says what change(meta) makes it say; its files' bytes before."""
    folder = tmp_path / "run"
    shutil.copytree(source, folder)
    rewrite_meta(folder / "c.npz", change)
    return folder, contents(folder)


def contents(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def refused(folder: Path, before: dict, capsys, says: str, outputs=OUTPUTS) -> None:
    code = run(folder, resume=True, frames=12, outputs=outputs)
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert says in lines[0] and "--restart-outputs" in lines[0], lines
    after = contents(folder)
    assert {k: v for k, v in after.items() if k != "c.npz"} == {k: v for k, v in before.items() if k != "c.npz"}


def _header(folder: Path) -> bytes:
    return (folder / "s.csv").read_bytes().split(b"\n")[0] + b"\n"


@pytest.mark.parametrize("at_frame_zero", [False, True], ids=["frame-8", "frame-0"])
def test_a_record_of_nothing_never_cuts_the_finished_csv(finished, tmp_path, capsys, at_frame_zero):
    """The issue's case: bytes 0 and the SHA-256 of nothing (the finished s.csv went from 21 lines to 4, its header
    gone); a checkpoint that also claims frame 0 (so the record agrees with its frame) is refused too."""

    def change(meta):
        meta["outputs"]["--stats"].update(bytes=0, sha256=NOTHING)
        if at_frame_zero:
            meta["frame"] = 0
            meta["outputs"]["--dump"].update(bytes=0, sha256=NOTHING)
            meta["outputs"]["--out"].update(pieces=[], frames=0, offered=0, digest=digest_of([]))

    folder, before = forged(finished, tmp_path, change)
    refused(folder, before, capsys, "claims none of its" if at_frame_zero else "--stats s.csv")


def test_a_header_only_prefix_is_not_the_checkpoints_rows(finished, tmp_path, capsys):
    folder = tmp_path / "header"
    shutil.copytree(finished, folder)
    header = _header(folder)
    rewrite_meta(
        folder / "c.npz",
        lambda meta: meta["outputs"]["--stats"].update(bytes=len(header), sha256=hashlib.sha256(header).hexdigest()),
    )
    refused(folder, contents(folder), capsys, "--stats s.csv: holds")


def test_a_header_only_prefix_of_a_killed_runs_partial_is_refused(finished, tmp_path, capsys):
    """The partial a killed run left is cut back to the checkpoint; never to less than the checkpoint's rows."""
    folder = tmp_path / "partial"
    shutil.copytree(finished, folder)
    partial = partial_name(folder / "s.csv", token="4242-abcdef")
    os.replace(folder / "s.csv", partial)
    header = _header(finished)

    def change(meta):
        meta["outputs"]["--stats"].update(
            partial=partial.name, bytes=len(header), sha256=hashlib.sha256(header).hexdigest()
        )

    rewrite_meta(folder / "c.npz", change)
    refused(folder, contents(folder), capsys, "--stats s.csv")


def test_a_video_of_no_frames_never_replaces_the_finished_one(finished, tmp_path, capsys):
    """m.mp4 went from 20 frames to 4 while the run said "wrote m.mp4 (8 frames...)"."""

    def change(meta):
        meta["outputs"]["--out"].update(pieces=[], frames=0, offered=0, digest=digest_of([]))

    folder, before = forged(finished, tmp_path, change)
    refused(folder, before, capsys, "--out m.mp4")


def test_a_video_record_short_of_its_checkpoint_is_refused(finished, tmp_path, capsys):
    """4 frames claimed (and offered) at a checkpoint of frame 8: the frames 5 to 8 would be cut."""

    def change(meta):
        meta["outputs"]["--out"].update(frames=4, offered=4)

    folder, before = forged(finished, tmp_path, change)
    refused(folder, before, capsys, "--out m.mp4")


def test_a_dump_record_of_nothing_is_refused(finished, tmp_path, capsys):
    folder, before = forged(finished, tmp_path, lambda m: m["outputs"]["--dump"].update(bytes=0, sha256=NOTHING))
    refused(folder, before, capsys, "--dump d.extxyz")


def test_a_png_folder_record_of_no_frames_removes_none(cached, tmp_path, capsys):
    folder, before = forged(cached, tmp_path, lambda m: m["outputs"]["--out"].update(frames=0, digest=digest_of([])))
    refused(folder, before, capsys, "--out frames", outputs=CACHED)


@pytest.mark.parametrize(
    "written, says",
    [
        ([], "--cache w.ply"),  # a cache of no frames: the 8 frame files would be removed
        ([[0, 0.0, False], [4, 0.08, False], [8, 0.16, False], [9, 0.18, False]], "--cache w.ply"),  # unwritten
        ([[4, "0.08", False], [8, 0.16, False]], "record of --cache is damaged"),  # a string time was a traceback
        ([[4, float("nan"), False], [8, 0.16, False]], "record of --cache is damaged"),
        ([[4, 0.08, False], [10**30, 0.16, False]], "record of --cache is damaged"),
        ([[k, 0.02 * k, False] for k in range(0, 9, 2)], "--cache w.ply"),  # every 2
        ([[k, 0.02 * k, True] for k in range(9)], "--cache w.ply"),  # surfaces this run does not write
    ],
    ids=["none", "unwritten", "string-time", "nan-time", "huge-frame", "other-every", "surfaces"],
)
def test_a_cache_record_proves_only_the_frames_on_disk(cached, tmp_path, capsys, written, says):
    """The record's digest is made to agree with its frames (unreadable files hashed as the word "missing", as the
    checker did): a resume must still refuse, and remove no frame file."""

    def change(meta):
        record = meta["outputs"]["--cache"]
        hashes = []
        for frame, _, surface in written:
            if isinstance(frame, int) and frame < 10**6:
                names = [f"w.ply.{frame:05d}.ply"] + ([f"w.ply.surface.{frame:05d}.ply"] if surface else [])
                for name in [*names, f"w.ply.parts.{frame:05d}.ply"]:
                    path = cached / name
                    hashes.append(hashlib.sha256(path.read_bytes()).hexdigest() if path.exists() else "missing")
        record.update(written=written, digest=digest_of(hashes))

    folder, before = forged(cached, tmp_path, change)
    refused(folder, before, capsys, says, outputs=CACHED)


def test_a_missing_frame_file_is_refused_by_name_never_hashed_as_a_word(cached, tmp_path, capsys):
    """The checker hashed an unreadable file as the word "missing", which a record could carry too."""
    folder = tmp_path / "missing"
    shutil.copytree(cached, folder)
    (folder / "w.ply.00008.ply").unlink()
    hashes = [hashlib.sha256((folder / "w.ply.00004.ply").read_bytes()).hexdigest(), "missing"]
    rewrite_meta(folder / "c.npz", lambda meta: meta["outputs"]["--cache"].update(digest=digest_of(hashes)))
    refused(folder, contents(folder), capsys, "w.ply.00008.ply, which the checkpoint", outputs=CACHED)


def test_a_resume_with_another_cache_every_or_surfaces_is_refused(cached, tmp_path, capsys):
    folder = tmp_path / "other"
    shutil.copytree(cached, folder)
    before = contents(folder)
    for extra in (["--cache-every", "2"], ["--cache-surface"]):
        code = run(folder, *extra, resume=True, frames=12, outputs=CACHED)
        lines = errors(capsys)
        assert code == EXIT_BAD_INPUT and len(lines) == 1 and "--cache w.ply" in lines[0], lines
        assert contents(folder) == before


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_an_honest_checkpoint_still_continues_every_output(finished, cached, tmp_path, capsys):
    """The rules refuse forgeries only: the checkpoint each run ended with continues its files to 12 frames."""
    for source, outputs in ((finished, OUTPUTS), (cached, CACHED)):
        folder = tmp_path / source.name
        shutil.copytree(source, folder)
        assert run(folder, resume=True, frames=12, outputs=outputs) == 0, errors(capsys)
    assert (tmp_path / finished.name / "s.csv").read_text().count("\n") == 13
    assert len(list((tmp_path / cached.name / "frames").glob("frame_*.png"))) == 12
    assert len(list((tmp_path / cached.name).glob("w.ply.0*.ply"))) == 13  # frames 0 to 12


def test_a_hard_link_at_a_partials_name_is_never_appended_to(finished, tmp_path, capsys):
    """A killed run's partial that is a second name of someone's file: adopting it would append to that file."""
    folder = tmp_path / "linked"
    shutil.copytree(finished, folder)
    victim = folder / "victim.csv"
    shutil.copy(folder / "s.csv", victim)
    partial = partial_name(folder / "s.csv", token="4242-abcdef")
    os.link(victim, partial)
    (folder / "s.csv").unlink()
    kept = victim.read_bytes()
    rewrite_meta(folder / "c.npz", lambda meta: meta["outputs"]["--stats"].update(partial=partial.name))
    code = run(folder, resume=True, frames=12, outputs=OUTPUTS)
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert victim.read_bytes() == kept

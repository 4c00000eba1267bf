"""Caches own their frames and fail like every writer (issue 72): frame files named from the whole cache name, so
caches of different names never share one; no other output of the run may take a frame's name; a USD cache that
cannot be written (a size limit, as a full disk meets the writer) exits 4 with one line, as PLY and VTK do; a name
USD would misread is refused. Each run is `sandbox run` in this process (its kernels come from the cache)."""

from __future__ import annotations

import resource
from pathlib import Path

import pytest

from sandbox.app.cli import EXIT_BAD_INPUT
from tests.test_hostile_files import errors, run

pytestmark = pytest.mark.xdist_group("run_files")

STILL = ["--out", "s.png"]  # no video: the cache is what is written


def frames_of(folder: Path, prefix: str) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob(f"{prefix}.*")) if p.name != prefix}


@pytest.mark.parametrize(
    "first, second",  # two of the three pairs in the long tier (`python3 -m pytest -m long`)
    [
        ("a.usd", "a.usda"),
        pytest.param("a.usd", "a.usdc", marks=pytest.mark.long),
        pytest.param("a.usda", "a.usdc", marks=pytest.mark.long),
    ],
)
def test_caches_of_different_names_never_share_a_frame_file(tmp_path, capsys, first, second):
    """`--cache a.usd` then `--cache a.usda` wrote the same a.NNNNN.usdc frames: the second run replaced the
    first's (a.usd's frames then showed the other run's particles, or nothing)."""
    assert run(tmp_path, frames=4, outputs=[*STILL, "--cache", first]) == 0, errors(capsys)
    kept = frames_of(tmp_path, first)
    assert len(kept) == 5  # frames 0 to 4
    code = run(tmp_path, "--substeps", "4", frames=2, outputs=["--out", "t.png", "--cache", second])  # other frames
    assert code == 0, errors(capsys)
    assert frames_of(tmp_path, first) == kept
    assert len(frames_of(tmp_path, second)) == 3


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_surface_named_cache_never_removes_another_caches_surfaces(tmp_path, capsys):
    """`--cache w.surface.ply` beside a finished `w.ply --cache-surface` deleted w.ply's surfaces."""
    assert run(tmp_path, "--cache-surface", frames=2, outputs=[*STILL, "--cache", "w.ply"]) == 0, errors(capsys)
    kept = frames_of(tmp_path, "w.ply")
    assert sorted(kept) == [f"w.ply.{kind}{k:05d}.ply" for kind in ("", "parts.", "surface.") for k in range(3)]
    assert run(tmp_path, frames=2, outputs=["--out", "t.png", "--cache", "w.surface.ply"]) == 0, errors(capsys)
    assert frames_of(tmp_path, "w.ply") == kept


@pytest.mark.parametrize(
    "cache, other",
    [
        ("w.ply", "w.ply.00001.ply"),
        ("w.ply", "w.ply.surface.00002.ply"),
        ("w.ply", "w.ply.parts.00002.ply"),
        ("w.usd", "w.usd.00001.usdc"),
    ],
)
def test_no_other_output_may_take_a_cache_frames_name(tmp_path, capsys, cache, other):
    """`--cache w.ply --stats w.00001.ply` replaced that frame: the check compared only the index path."""
    code = run(tmp_path, frames=2, outputs=[*STILL, "--cache", cache, "--stats", other])
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert f"--stats {other}: one of the numbered files --cache" in lines[0]
    assert not list(tmp_path.iterdir())


def test_a_stats_file_inside_a_png_folder_is_not_one_of_its_frames(tmp_path, capsys):
    code = run(tmp_path, frames=2, outputs=["--out", "frames", "--stats", "frames/frame_00001.png"])
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1 and "one of the numbered files --out" in lines[0], lines


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_usd_cache_past_a_size_limit_exits_4_in_one_line(tmp_path, capsys):
    """A full disk or `ulimit -f` was a traceback (exit 1) for USD, where PLY and VTK exit 4 with one line. The
    candle's frame layers grow as its flame emits: the limit, set between the sizes of its second and third frame
    layers (measured by a first run), lets two be written and stops the third."""
    (tmp_path / "warm").mkdir()  # kernels compiled and saved, and the frames' sizes known
    assert run(tmp_path / "warm", frames=3, outputs=[*STILL, "--cache", "a.usd"]) == 0
    sizes = [(tmp_path / "warm" / f"a.usd.{k:05d}.usdc").stat().st_size for k in (1, 2, 3)]
    assert sizes[1] < sizes[2] and max(sizes[1], (tmp_path / "warm" / "s.png").stat().st_size) < sizes[2]
    limit = (sizes[1] + sizes[2]) // 2
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
    try:
        code = run(tmp_path, frames=6, outputs=[*STILL, "--cache", "a.usd"])
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    lines = errors(capsys)
    assert code == 4 and len(lines) == 1, lines
    assert "a.usd.00003.usdc" in lines[0] and "File too large" in lines[0], lines
    assert not (tmp_path / "a.usd").exists() and not list(tmp_path.glob(".a.usd.00003.usdc*"))


@pytest.mark.parametrize("name", ["a\\b.usda", "a\\b.usd"])
def test_a_usd_cache_name_with_a_backslash_is_refused(tmp_path, capsys, name):
    code = run(tmp_path, frames=2, outputs=[*STILL, "--cache", name])
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1 and "backslash" in lines[0], lines
    assert not list(tmp_path.iterdir())


def test_a_cache_only_run_with_no_video_encodes_nothing_and_touches_no_video(tmp_path, capsys):
    """A cache-only run encoded a default out/SCENE.mp4 (1.7x the wall time) and replaced the one there (issue 76):
    --no-video writes the cache alone; with --out it is refused in one line."""
    (tmp_path / "out").mkdir()
    earlier = tmp_path / "out" / "candle.mp4"
    earlier.write_bytes(b"someone's video")
    assert run(tmp_path, "--no-video", frames=3, outputs=["--cache", "w.ply"]) == 0, errors(capsys)
    assert earlier.read_bytes() == b"someone's video"
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["out", *sorted(f"w.ply.{kind}{k:05d}.ply" for kind in ("", "parts.") for k in range(4))]
    assert "-> w.ply" in capsys.readouterr().err
    assert run(tmp_path, "--no-video", frames=2, outputs=["--out", "m.mp4"]) == EXIT_BAD_INPUT
    lines = errors(capsys)
    assert len(lines) == 1 and "--no-video with --out" in lines[0]

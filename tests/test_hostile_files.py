"""Nothing a file from someone else says decides what is deleted, joined or overwritten (issue 54): a state file's
record of its outputs naming other files, links and folders planted at a lock's name, a scene whose name climbs out
of the output folder, resumes under other picture settings, a kill while the outputs are joined, stale PNG frames,
hostile output names and `nohup`. Each run is `sandbox run` in this process (its kernels come from the cache)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sandbox.app.cli import EXIT_BAD_INPUT, main
from sandbox.config.arguments import file_stem
from sandbox.files.claim import partial_name
from sandbox.render import segments
from sandbox.render.encoder import frame_digests

pytestmark = pytest.mark.xdist_group("run_files")

SCENE = ["candle", "--set", "bodies.0.hi=[70.0,8.0]"]  # 96 particles
SMALL = ["--width", "160", "--height", "96"]
OUTPUTS = ["--checkpoint", "c.npz", "--stats", "s.csv", "--dump", "d.extxyz", "--out", "m.mp4"]


def run(folder: Path, *args: str, resume: bool = False, frames: int = 8, outputs=OUTPUTS, size=SMALL) -> int:
    """`sandbox run` in `folder` (4 frames a checkpoint); its exit code."""
    scene = ["candle", "--resume", "c.npz"] if resume else SCENE
    argv = ["run", *scene, "--headless", "--quiet", "--frames", str(frames), "--checkpoint-every", "4", *size]
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        return main([*argv, *outputs, *args])
    finally:
        os.chdir(cwd)


def errors(capsys) -> list[str]:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return [line for line in err.splitlines() if line.startswith("error")]


def rewrite_meta(path: Path, change) -> None:
    """Rewrite a state file with change(meta) applied to its meta table (what a crafted file can say)."""
    with np.load(path, allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    meta = json.loads(str(arrays["meta"]))
    change(meta)
    arrays["meta"] = np.array(json.dumps(meta))
    with open(path, "wb") as out:
        np.savez(out, **arrays)


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """A run of 8 frames with every output and a checkpoint at frame 8 (copied by each test)."""
    folder = tmp_path_factory.mktemp("finished")
    assert run(folder) == 0
    return folder


def copy_of(finished: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "run"
    shutil.copytree(finished, folder)
    return folder


def test_a_state_file_naming_other_files_as_its_partials_never_touches_them(finished, tmp_path, capsys):
    """The record names victim.txt as the CSV's partial (with its true length and digest), notes.npz as the
    dump's, and holiday.mp4 (a video of the same frames) as the video's only piece: a resume that trusted the
    record would rename the victim over the CSV and join the holiday video in and delete it."""
    folder = copy_of(finished, tmp_path)
    victim = folder / "victim.txt"
    victim.write_text("frame,time\nsomeone's data\n")
    other = folder / "notes.npz"
    other.write_bytes(b"PK not really")
    holiday = folder / "holiday.mp4"
    shutil.copy(folder / "m.mp4", holiday)
    kept = {p: p.read_bytes() for p in (victim, other, holiday)}

    def craft(meta):
        outputs = meta["outputs"]
        data = victim.read_bytes()
        outputs["--stats"].update(partial=victim.name, bytes=len(data), sha256=hashlib.sha256(data).hexdigest())
        data = other.read_bytes()
        outputs["--dump"].update(partial=other.name, bytes=len(data), sha256=hashlib.sha256(data).hexdigest())
        outputs["--out"]["pieces"] = [holiday.name]

    rewrite_meta(folder / "c.npz", craft)
    code = run(folder, resume=True, frames=12)
    lines = errors(capsys)
    assert {p: p.read_bytes() if p.exists() else None for p in kept} == kept
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines  # the CSV does not begin with the victim's bytes
    assert "--stats s.csv: does not begin with" in lines[0]


def test_a_record_naming_a_partial_of_another_output_is_not_adopted(finished, tmp_path, capsys):
    """A name of the partial pattern of another output (the dump's, given as the CSV's) is not the CSV's."""
    folder = copy_of(finished, tmp_path)
    foreign = partial_name(folder / "d.extxyz")
    foreign.write_text("frame,time\n")
    data = foreign.read_bytes()

    def craft(meta):
        meta["outputs"]["--stats"].update(
            partial=foreign.name, bytes=len(data), sha256=hashlib.sha256(data).hexdigest()
        )

    rewrite_meta(folder / "c.npz", craft)
    assert run(folder, resume=True, frames=12) == EXIT_BAD_INPUT
    assert len(errors(capsys)) == 1
    assert foreign.read_bytes() == data


@pytest.mark.parametrize("planted", ["symlink", "folder", "hardlink", "fifo"])
def test_a_link_or_folder_at_a_lock_name_is_refused_and_never_written_through(tmp_path, capsys, planted):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    lock = tmp_path / ".s.csv.lock"
    {
        "symlink": lambda: lock.symlink_to(victim),
        "folder": lambda: lock.mkdir(),
        "hardlink": lambda: os.link(victim, lock),
        "fifo": lambda: os.mkfifo(lock),
    }[planted]()
    code = run(tmp_path, frames=2, outputs=["--stats", "s.csv"])
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert "--stats s.csv: .s.csv.lock beside it is not a lock file this sandbox made" in lines[0]
    assert victim.read_text() == "precious\n"
    assert not (tmp_path / "s.csv").exists()


def test_only_partial_files_of_the_outputs_own_pattern_are_cleaned_up(tmp_path, capsys):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    left = tmp_path / ".s.csv.4242-abcdef.partial.csv"  # a killed run's: removed
    left.write_text("x")
    look_alike = tmp_path / ".s.csv.notes.partial.csv"  # not of the pattern: kept
    look_alike.write_text("mine")
    link = tmp_path / ".s.csv.4243-abcdef.partial.csv"  # of the pattern but a link: kept, and so is its target
    link.symlink_to(victim)
    assert run(tmp_path, frames=2, outputs=["--stats", "s.csv"]) == 0
    assert not left.exists() and look_alike.read_text() == "mine" and link.is_symlink()
    assert victim.read_text() == "precious\n"


def test_a_scene_name_never_leaves_the_output_folder(tmp_path, monkeypatch, capsys):
    scenes = Path(__file__).parents[1] / "scenes"
    text = (scenes / "candle.toml").read_text().replace('name = "candle"', 'name = "../../escaped"')
    deep = tmp_path / "a" / "b"
    deep.mkdir(parents=True)
    (deep / "mine.toml").write_text(text)
    monkeypatch.chdir(deep)
    code = main(
        ["run", "mine.toml", "--headless", "--quiet", "--frames", "1", *SMALL, "--set", "bodies.0.hi=[70.0,8.0]"]
    )
    assert code == 0, errors(capsys)
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file())
    assert written == ["a/b/mine.toml", f"a/b/out/{file_stem('../../escaped')}.mp4"]
    for name in ("../../x", "..", "/etc/passwd", "-rf", ".hidden", "a b'c:d", "", "\x00\n"):
        stem = file_stem(name)
        assert stem and "/" not in stem and not stem.startswith((".", "-")) and stem not in (".", "..")


@pytest.mark.parametrize(
    "change, said",
    [
        (["--width", "192"], "continues an MP4 video of 160x96 at 30 frames/s, this run writes an MP4 video of 192x96"),
        (["--fps", "24"], "this run writes an MP4 video of 160x96 at 24 frames/s"),
        (["--out", "m.gif"], "continues an MP4 video, this run writes a GIF"),
    ],
)
def test_a_resume_under_other_picture_settings_or_kind_is_refused(finished, tmp_path, capsys, change, said):
    folder = copy_of(finished, tmp_path)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    outputs = list(OUTPUTS)
    if change[0] == "--out":
        outputs[-1] = change[1]
        change = []
    code = run(folder, *change, resume=True, frames=12, outputs=outputs)
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert said in lines[0] and "--restart-outputs" in lines[0], lines
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


class Killed(BaseException):
    """A stand-in for kill -9 in the middle of joining the pieces: nothing after it runs."""


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_kill_while_the_outputs_are_joined_is_finished_by_resume(tmp_path, monkeypatch, capsys):
    """Killed while the video's pieces are joined (10 frames, checkpoints every 4): the run checkpointed its last
    frame before joining, so the resume with the same frame count finishes every output from the pieces without
    running a frame again."""
    folder = tmp_path / "killed"
    folder.mkdir()

    def killed(pieces, path):
        raise Killed

    monkeypatch.setattr(segments, "join", killed)
    with pytest.raises(Killed):
        run(folder, frames=10)
    monkeypatch.undo()
    assert not (folder / "m.mp4").exists()
    capsys.readouterr()
    code = run(folder, resume=True, frames=10)
    err = capsys.readouterr().err
    assert code == 0, err
    assert "no frames (the outputs of the 10 saved are finished)" in err
    assert len(frame_digests(folder / "m.mp4")) == 10
    assert (folder / "s.csv").read_text().count("\n") == 11 and (folder / "d.extxyz").read_text().count("Lattice") == 10
    assert not [p.name for p in folder.iterdir() if p.name.startswith(".")]


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_kill_inside_ffmpegs_join_leaves_no_concat_list_after_the_resume(tmp_path, monkeypatch, capsys):
    """kill -9 while ffmpeg joins the pieces leaves its concat list (`...partial.mp4.pieces.txt`), which the resume
    left in the folder for good (issue 72); it is removed with the other partial files now."""
    folder = tmp_path / "killed"
    folder.mkdir()
    monkeypatch.setattr(segments, "join", lambda pieces, path: (_ for _ in ()).throw(Killed()))
    with pytest.raises(Killed):
        run(folder, frames=10)
    monkeypatch.undo()
    listing = folder / (partial_name(folder / "m.mp4", token="4242-abcdef").name + ".pieces.txt")
    listing.write_text("file 'x'\n")  # what the killed join left
    assert run(folder, resume=True, frames=10) == 0, errors(capsys)
    assert len(frame_digests(folder / "m.mp4")) == 10
    assert not [p.name for p in folder.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize(
    "output, planted",  # both in the long tier (`python3 -m pytest -m long`)
    [
        pytest.param("frames", "frames/.frame_00005.png", marks=pytest.mark.long),
        pytest.param("w.ply", ".w.ply.00005.ply", marks=pytest.mark.long),
    ],
)
def test_a_killed_runs_partial_frame_file_is_removed_by_the_resume(tmp_path, capsys, output, planted):
    """kill -9 while a PNG frame (or a cache frame) is written leaves its hidden partial file in the folder; the
    resume left it there for good (issue 72)."""
    option = "--out" if output == "frames" else "--cache"
    outputs = ["--checkpoint", "c.npz", option, output] + (["--out", "m.png"] if option == "--cache" else [])
    assert run(tmp_path, frames=4, outputs=outputs) == 0, errors(capsys)
    partial = tmp_path / f"{planted}.4242-abcdef.partial{Path(planted).suffix}"
    partial.write_bytes(b"half a frame")
    assert run(tmp_path, resume=True, frames=8, outputs=outputs) == 0, errors(capsys)
    assert not partial.exists()
    assert not [p for p in tmp_path.rglob(".*") if ".partial" in p.name]


@pytest.mark.long  # two runs to 40 frames: `python3 -m pytest -m long`
def test_a_resumed_gif_keeps_the_frames_the_uninterrupted_gif_keeps(tmp_path, monkeypatch, capsys):
    """A GIF keeps every k-th frame, k planned from the run's length: planned from the frames left after the
    checkpoint, the resumed part kept other frames (151 where the uninterrupted run kept 150). A small size budget
    makes k depend on the length here (12 frames: every 4th; 4 frames: every 2nd)."""
    from sandbox.app import run_outputs
    from sandbox.config import arguments

    monkeypatch.setattr(arguments, "GIF_BUDGET", 100e3)
    outputs = ["--checkpoint", "c.npz", "--out", "m.gif"]
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    whole.mkdir(), killed.mkdir()
    assert run(whole, frames=12, outputs=outputs, size=[]) == 0
    original = run_outputs.RunOutputs.frame

    def kill_at_frame_10(self, frame, *rest):
        if frame == 9:
            raise Killed
        original(self, frame, *rest)

    monkeypatch.setattr(run_outputs.RunOutputs, "frame", kill_at_frame_10)
    with pytest.raises(Killed):
        run(killed, frames=12, outputs=outputs, size=[])
    monkeypatch.setattr(run_outputs.RunOutputs, "frame", original)
    assert run(killed, resume=True, frames=12, outputs=outputs, size=[]) == 0, errors(capsys)
    assert len(frame_digests(killed / "m.gif")) == len(frame_digests(whole / "m.gif")) == 3


def test_a_still_png_that_cannot_be_written_fails_with_exit_4(tmp_path, monkeypatch, capsys):
    from sandbox.render import video

    def full_disk(path, frame):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(video, "write_png", full_disk)
    code = run(tmp_path, frames=2, outputs=["--out", "still.png"])
    lines = errors(capsys)
    assert code == 4 and len(lines) == 1 and "No space left on device" in lines[0], lines
    assert not (tmp_path / "still.png").exists() and not list(tmp_path.glob(".still.png*"))


def test_a_png_folder_holds_only_this_runs_frames(tmp_path, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(19):  # an earlier, longer run
        (frames / f"frame_{k:05d}.png").write_bytes(b"old")
    (frames / "notes.txt").write_text("mine")
    assert run(tmp_path, frames=3, outputs=["--out", "frames"]) == 0
    assert sorted(p.name for p in frames.iterdir()) == [
        "frame_00000.png",
        "frame_00001.png",
        "frame_00002.png",
        "notes.txt",
    ]
    assert all(p.read_bytes() != b"old" for p in frames.glob("frame_*.png"))
    assert "removed 19 frame file(s) of an earlier run" in capsys.readouterr().err


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
@pytest.mark.parametrize(
    "name",
    ["-it's a:b.mp4", "concat:" + "x" * 243 + ".mp4"],
    ids=["quote-colon-dash", "concat-long"],
)
def test_output_names_that_ffmpeg_could_misread_are_written_and_resumed(tmp_path, capsys, name):
    """Quotes, a leading dash, colons and the longest name the file system takes: written in pieces and joined."""
    outputs = ["--checkpoint", "c.npz", f"--out={name}"]  # `--out=-lead.mp4`: as a shell user writes it
    assert run(tmp_path, frames=4, outputs=outputs) == 0, errors(capsys)
    assert run(tmp_path, resume=True, frames=8, outputs=outputs) == 0, errors(capsys)
    assert len(frame_digests(tmp_path / name)) == 8
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, "c.npz"])


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_nohup_runs_ignore_sighup(tmp_path):
    """A run started with SIGHUP ignored (as `nohup` starts it) keeps running when the terminal closes; SIGTERM
    still stops it."""
    argv = [sys.executable, "-m", "sandbox", "run", *SCENE, "--headless", "--quiet", "--frames", "100000", *SMALL]
    proc = subprocess.Popen(
        [*argv, "--stats", "s.csv"],
        cwd=tmp_path,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN),
    )
    rows = 0  # wait for a frame's row: the run is past its start-up and in its frame loop
    while rows < 2 and proc.poll() is None:
        rows = max([p.read_text().count("\n") for p in tmp_path.glob(".s.csv.*.partial.csv")], default=0)
        time.sleep(0.01)
    proc.send_signal(signal.SIGHUP)
    time.sleep(0.5)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 143, err
    assert err.splitlines()[-1].startswith("stopped by SIGTERM")


@pytest.mark.parametrize("kind", ["fifo", "/dev/zero", "/dev/urandom", "oversized", "folder"])
def test_a_scene_path_that_is_not_a_small_regular_file_is_refused_at_once(tmp_path, capsys, kind):
    """A FIFO or /dev/urandom used to hang, /dev/zero to take 22 GB: refused in one line before anything is read."""
    path = {"fifo": tmp_path / "s.toml", "oversized": tmp_path / "big.toml", "folder": tmp_path}.get(kind, Path(kind))
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "oversized":
        path.write_text("# " + "x" * (5 << 20) + "\n")
    signal.alarm(60)  # a hang fails the test instead of the suite
    try:
        code = main(["run", str(path), "--headless", "--frames", "1"])
    finally:
        signal.alarm(0)
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    said = {"folder": "is a folder", "oversized": "larger than 4 MiB"}.get(kind, "not a regular file")
    assert said in lines[0]


def test_a_name_longer_than_the_file_system_takes_is_refused_before_the_run(tmp_path, capsys):
    name = "y" * 300 + ".csv"
    assert run(tmp_path, frames=1, outputs=["--stats", name]) == EXIT_BAD_INPUT
    lines = errors(capsys)
    assert len(lines) == 1 and "a name of 304 bytes; expected at most 255" in lines[0], lines
    assert not list(tmp_path.iterdir())

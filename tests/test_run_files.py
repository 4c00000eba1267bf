"""Nothing a run writes is lost or left broken (issue 42): real `sandbox run` processes killed with -9 and resumed,
stopped by SIGTERM, racing for one output, and writing past a file-size limit (a full disk as the process meets it).

The reference is one uninterrupted run; a run killed at a random frame and resumed from its last checkpoint must
leave the same CSV (row for row, but the wall-time column and the wall gauge, whose sums follow the thread team's
order), the same dump byte for byte, and a video whose decoded frames are the reference's."""

from __future__ import annotations

import csv
import os
import random
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sandbox.app.cli import EXIT_BAD_INPUT, main
from sandbox.files.persist import read_meta
from sandbox.render.encoder import frame_digests

pytestmark = [pytest.mark.xdist_group("run_files"), pytest.mark.long]

FRAMES, EVERY = 24, 4
SCENE = ["candle", "--set", "bodies.0.hi=[70.0,8.0]"]  # 96 particles: springs, heat, flame, emitters
RUN = ["--headless", "--quiet", "--checkpoint-every", str(EVERY)]
UNTIMED = ("step_seconds", "wall_pressure")


def command(folder: Path, *extra: str, frames: int = FRAMES, resume: bool = False) -> list[str]:
    outputs = ["--checkpoint", "c.npz", "--stats", "s.csv", "--dump", "d.extxyz", "--out", "m.mp4"]
    scene = ["candle", "--resume", "c.npz"] if resume else SCENE
    return [sys.executable, "-m", "sandbox", "run", *scene, *RUN, "--frames", str(frames), *outputs, *extra]


def start(folder: Path, *extra: str, **kw) -> subprocess.Popen:
    return subprocess.Popen(
        command(folder, *extra, **kw), cwd=folder, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True
    )


def finish(proc: subprocess.Popen) -> tuple[int, list[str]]:
    _, err = proc.communicate(timeout=300)
    return proc.returncode, [line for line in err.splitlines() if line.strip()]


def rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k not in UNTIMED} for row in csv.DictReader(f)]


def checkpoint_frame(folder: Path) -> int:
    try:
        return read_meta(folder / "c.npz")["frame"]
    except Exception:
        return 0


def wait_for(condition, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert proc.poll() is None, finish(proc)
        assert time.monotonic() < end, "the run did not get there in time"
        time.sleep(0.02)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("reference")
    code, err = finish(start(folder))
    assert code == 0, err
    return folder


def same_outputs(folder: Path, reference: Path) -> None:
    assert rows(folder / "s.csv") == rows(reference / "s.csv")
    assert (folder / "d.extxyz").read_bytes() == (reference / "d.extxyz").read_bytes()
    assert frame_digests(folder / "m.mp4") == frame_digests(reference / "m.mp4")
    assert not [p.name for p in folder.iterdir() if p.name.startswith(".")], "partial or lock files left behind"


@pytest.mark.parametrize("seed", [1, 2])
def test_kill_9_at_a_random_frame_then_resume_leaves_the_uninterrupted_files(reference, tmp_path, seed):
    """kill -9 after a random checkpoint (and a random part of the frames after it): the resume adopts the partial
    files the checkpoint recorded, truncates what came after it, removes the rest and continues every output."""
    rng = random.Random(seed)
    target = rng.randrange(EVERY, FRAMES - EVERY, EVERY)
    proc = start(tmp_path)
    wait_for(lambda: checkpoint_frame(tmp_path) >= target, proc)
    time.sleep(rng.uniform(0.0, 0.3))
    proc.kill()
    proc.wait()
    assert not (tmp_path / "s.csv").exists() and not (tmp_path / "m.mp4").exists()
    assert any(".partial" in p.name for p in tmp_path.iterdir())
    code, err = finish(start(tmp_path, resume=True))
    assert code == 0, err
    same_outputs(tmp_path, reference)


def test_a_finished_run_resumed_for_more_frames_continues_its_files(reference, tmp_path):
    """The issue's example: 16 frames with checkpoints, then the same outputs resumed to 24 frames: the CSV, dump
    and video hold all 24 frames, the first 16 as the first run wrote them."""
    code, err = finish(start(tmp_path, frames=16))
    assert code == 0, err
    code, err = finish(start(tmp_path, resume=True))
    assert code == 0, err
    same_outputs(tmp_path, reference)


def test_a_resume_whose_outputs_do_not_match_stops_unless_told_to_restart_them(tmp_path):
    code, err = finish(start(tmp_path, frames=8))
    assert code == 0, err
    with open(tmp_path / "s.csv", "r+") as f:  # someone edited the CSV: its first bytes are not the recorded ones
        f.write("x")
    code, err = finish(start(tmp_path, resume=True, frames=12))
    assert code == EXIT_BAD_INPUT and len(err) == 1, err
    assert "--stats s.csv" in err[0] and "--restart-outputs" in err[0]
    assert (tmp_path / "s.csv").read_text().startswith("x")  # untouched
    code, err = finish(start(tmp_path, "--restart-outputs", resume=True, frames=12))
    assert code == 0, err
    frames = [int(r["frame"]) for r in rows(tmp_path / "s.csv")]
    assert frames == list(range(8, 12))  # started over at the checkpoint's frame
    assert len(frame_digests(tmp_path / "m.mp4")) == 4


def test_sigterm_leaves_valid_files_and_exits_143(tmp_path):
    proc = start(tmp_path, frames=2000)
    wait_for(lambda: checkpoint_frame(tmp_path) >= EVERY, proc)
    proc.send_signal(signal.SIGTERM)
    code, err = finish(proc)
    assert code == 143, err
    assert err[-1] == "stopped by SIGTERM: the files written so far are complete and valid", err
    done = rows(tmp_path / "s.csv")
    assert len(done) >= EVERY and [int(r["frame"]) for r in done] == list(range(len(done)))
    assert len(frame_digests(tmp_path / "m.mp4")) == len(done)
    assert (tmp_path / "d.extxyz").read_text().count("Properties=") == len(done)
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_a_second_run_on_the_same_output_is_refused_and_the_first_completes(tmp_path):
    first = start(tmp_path, frames=2000)
    wait_for(lambda: (tmp_path / ".s.csv.lock").exists() and checkpoint_frame(tmp_path) >= EVERY, first)
    code, err = finish(start(tmp_path, frames=8))
    assert code == EXIT_BAD_INPUT and len(err) == 1, err
    assert f"(process {first.pid}) is writing it" in err[0]
    first.send_signal(signal.SIGINT)
    code, err = finish(first)
    assert code == 130, err
    done = rows(tmp_path / "s.csv")
    assert len(frame_digests(tmp_path / "m.mp4")) == len(done) >= EVERY


def test_a_full_disk_leaves_partials_and_no_broken_file_under_a_final_name(tmp_path):
    """The file-size limit of the running process (prlimit, as a full disk meets a writer): the write fails, the
    run says which file and which partial files hold what was written, exits 4, and no output takes its name."""
    proc = start(tmp_path, frames=2000)
    wait_for(lambda: checkpoint_frame(tmp_path) >= EVERY, proc)
    dump = next(tmp_path.glob(".d.extxyz.*.partial.extxyz"))
    limit = dump.stat().st_size + 100_000
    resource.prlimit(proc.pid, resource.RLIMIT_FSIZE, (limit, limit))
    code, err = finish(proc)
    assert code == 4 and len(err) == 2, err  # the run's first line, then one saying what went wrong
    assert err[1].startswith("error: could not write") and "File too large" in err[1], err
    assert "kept under partial names" in err[1]
    for name in ("s.csv", "d.extxyz", "m.mp4"):
        assert not (tmp_path / name).exists()
    kept = [p for p in tmp_path.iterdir() if ".partial" in p.name]
    assert kept and all(str(p.name) in err[1] for p in kept)


def test_an_output_that_is_an_input_is_refused(tmp_path, capsys):
    code, err = finish(start(tmp_path, frames=4))
    assert code == 0, err
    state = str(tmp_path / "c.npz")
    before = (tmp_path / "c.npz").read_bytes()
    for option in ("--stats", "--dump", "--out"):
        args = ["run", "candle", "--resume", state, "--headless", "--frames", "8", option, state]
        assert main(args) == EXIT_BAD_INPUT
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "is the --resume file this run reads" in err[0], err
    assert (tmp_path / "c.npz").read_bytes() == before
    scene = Path(__file__).parents[1] / "scenes" / "candle.toml"
    assert main(["run", str(scene), "--headless", "--frames", "2", "--stats", str(scene)]) == EXIT_BAD_INPUT
    assert "is the scene file" in capsys.readouterr().err


def test_partial_names_are_the_runs_own():
    from sandbox.files.claim import RUN_TOKEN, partial_name

    name = partial_name(Path("out/m.mp4")).name
    assert name.startswith(".m.mp4.") and name.endswith(".partial.mp4") and RUN_TOKEN in name
    assert str(os.getpid()) in RUN_TOKEN
    assert np.unique([partial_name(Path("a.csv"), f"seg{k}").name for k in range(3)]).size == 3


def test_a_signal_whose_exception_is_lost_still_stops_the_run_at_the_next_frame():
    """A signal's exception raised while Python runs a finalizer or a callback is printed and dropped; the stopper
    keeps the signal, and the next frame's held() block stops the run with it (a serial sweep once ran on for
    minutes after a SIGTERM that came at such a moment)."""
    import signal as signals

    from sandbox.app.signals import Signalled, Stopper

    with Stopper() as stopper:
        try:
            signals.raise_signal(signals.SIGTERM)
        except KeyboardInterrupt:
            pass  # lost, as in a finalizer
        with pytest.raises(Signalled) as stopped:
            with stopper.held():
                pass  # the next frame's outputs
    assert stopped.value.signum == signals.SIGTERM


def test_sigterm_to_the_run_and_its_ffmpeg_together_exits_143_resumable(tmp_path):
    """systemd, scancel or a `kill` of every process signal ffmpeg as well: the run ended with exit 4 "ffmpeg
    failed" and no named outputs (issue 72). Now 143, its outputs under partial names, and the resume from the last
    checkpoint finishes the same files as an uninterrupted run's."""
    import psutil

    proc = start(tmp_path, frames=FRAMES)
    wait_for(lambda: checkpoint_frame(tmp_path) >= EVERY, proc)
    encoders = [c for c in psutil.Process(proc.pid).children(recursive=True) if "ffmpeg" in c.name()]
    while not encoders:  # the next piece's ffmpeg starts with the first frame after the checkpoint
        assert proc.poll() is None, finish(proc)
        encoders = [c for c in psutil.Process(proc.pid).children(recursive=True) if "ffmpeg" in c.name()]
    for pid in [proc.pid, *(c.pid for c in encoders)]:
        os.kill(pid, signal.SIGTERM)
    code, err = finish(proc)
    assert code == 143, err
    assert err[-1].startswith("stopped by SIGTERM, which stopped ffmpeg too: the outputs are kept"), err
    assert not [line for line in err if line.startswith("error")], err
    code, err = finish(start(tmp_path, resume=True))
    assert code == 0, err
    assert len(rows(tmp_path / "s.csv")) == FRAMES and len(frame_digests(tmp_path / "m.mp4")) == FRAMES

"""`sandbox sweep`: the plan, runs on a local Dask cluster equal to the same runs one by one (through a worker that
dies mid-run), resume, and errors recorded without stopping the sweep."""

import csv
import json
import subprocess
import sys

import pytest

from sandbox.app.sweep import Variation, parse_vary, plan_runs, run_sweep, write_manifest
from sandbox.app.sweep_run import CRASH_HOOK
from sandbox.errors import SandboxError

from .conftest import SCENES

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)

SMALL = {"bodies.0.lo": [56.0, 0.0], "bodies.0.hi": [64.0, 6.0]}  # 48 particles


def _rows(path):
    """A stats CSV's rows without the wall-time column."""
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k != "step_seconds"} for row in csv.DictReader(f)]


def test_vary_reads_lists_and_spans_and_plans_products_or_zips():
    assert parse_vary("bodies.0.material=wax,chocolate") == Variation("bodies.0.material", ("wax", "chocolate"))
    assert parse_vary("heat.sources.0.temperature=100:200:3").values == (100.0, 150.0, 200.0)
    assert parse_vary("world.dt=0.001,2e-3").values == (0.001, 0.002)
    a, b = parse_vary("a=1,2"), parse_vary("b=x,y,z")
    assert plan_runs([a, b]) == [{"a": i, "b": s} for i in (1, 2) for s in "xyz"]
    assert plan_runs([a, parse_vary("b=x,y")], zipped=True) == [{"a": 1, "b": "x"}, {"a": 2, "b": "y"}]
    for bad, match in (("nokey", "expected KEY="), ("a=1:2:0", "COUNT from 1"), ("=1,2", "expected KEY=")):
        with pytest.raises(SandboxError, match=match):
            parse_vary(bad)
    with pytest.raises(SandboxError, match="equal lengths"):
        plan_runs([a, b], zipped=True)
    with pytest.raises(SandboxError, match="varied twice"):
        plan_runs([a, a])


@pytest.mark.slow  # a 2-worker Dask cluster
@pytest.mark.xdist_group("dask")  # cluster tests one at a time: two clusters at once overload the 2 cores
def test_a_local_cluster_sweep_equals_the_runs_one_by_one_and_resumes(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    base = [
        {**SMALL, "heat.sources.0.temperature": t, "bodies.0.material": m}
        for t in (150.0, 250.0)
        for m in ("wax", "chocolate")
    ]
    scene = SCENES / "melting_block.toml"
    serial = run_sweep(
        scene, base, tmp_path / "serial", frames=4, scheduler="serial", threads=1, log=lambda s: None, batch=False
    )
    marker = tmp_path / "crashed"
    monkeypatch.setenv(CRASH_HOOK, str(marker))  # the first run to reach mid-run kills its worker process
    said = []
    spread = run_sweep(  # each run alone on a worker (batch=False: else the runs, which differ in a world's keys
        # and their material, would run as two batches of two worlds in this process)
        scene,
        base,
        tmp_path / "dask",
        frames=4,
        scheduler="local",
        workers=2,
        threads=1,
        log=said.append,
        batch=False,
    )
    assert marker.exists()  # a worker did die ...
    assert [r["outcome"] for r in spread] == ["done"] * 4  # ... and its run was retried to completion
    assert not list((tmp_path / "dask").rglob(".*partial*"))  # leaving no half-written file
    for a, b in zip(serial, spread):
        assert a["overrides"] == b["overrides"]
        assert _rows(a["stats"]) == _rows(b["stats"])  # bit for bit: every measurement's printed digits
        assert len(_rows(b["stats"])) == 4
    molten = {
        (r["overrides"]["heat.sources.0.temperature"], r["overrides"]["bodies.0.material"]): r["final_molten_fraction"]
        for r in spread
    }
    assert molten[(250.0, "wax")] > molten[(150.0, "wax")]  # a hotter plate melts more
    records = {p: p.stat().st_mtime_ns for p in (tmp_path / "dask").glob("*/run.json")}
    said.clear()
    again = run_sweep(
        scene, base, tmp_path / "dask", frames=4, scheduler="local", workers=2, log=said.append, batch=False
    )
    assert said[0] == "4 of 4 runs already complete: skipped"
    assert {p: p.stat().st_mtime_ns for p in records} == records  # nothing ran again
    assert [r["outcome"] for r in again] == ["done"] * 4
    with open(tmp_path / "dask" / "manifest.csv", newline="") as f:
        manifest = list(csv.DictReader(f))
    assert [m["bodies.0.material"] for m in manifest] == ["wax", "chocolate", "wax", "chocolate"]
    assert manifest[0]["stats"] == "000_lo=-56.0--0.0-_hi=-64.0--6.0-_temperature=150_material=wax/stats.csv"


SUMMED_OVER_SPRINGS = ("spring_energy", "potential_energy", "total_energy", "pressure")


def test_runs_that_differ_in_a_worlds_keys_run_as_worlds_and_equal_their_runs_alone(tmp_path):
    """Eight runs (two materials x two plate temperatures x two starting temperatures): the four of each material
    differ only in what a world holds of its own, so they run as two simulations of four worlds; every run's
    readouts equal its run alone (a run of the same sweep with batch=False), each frame, to the printed digit (the
    sums over springs, which a world adds up in another order, to the rounding of their ninth digit)."""
    runs = [
        {**SMALL, "bodies.0.material": m, "heat.sources.0.temperature": t, "bodies.0.temperature": start}
        for m in ("wax", "chocolate")
        for t in (150.0, 300.0)
        for start in (20.0, 50.0)
    ]
    scene, said = SCENES / "melting_block.toml", []
    batched = run_sweep(scene, runs, tmp_path / "b", frames=6, scheduler="serial", threads=1, log=said.append)
    alone = run_sweep(
        scene, runs, tmp_path / "a", frames=6, scheduler="serial", threads=1, log=lambda s: None, batch=False
    )
    assert "runs 0 1 2 3: batched as 4 worlds of one simulation" in said
    assert "runs 4 5 6 7: batched as 4 worlds of one simulation" in said
    assert [r["batch"] for r in batched] == [[0, 1, 2, 3]] * 4 + [[4, 5, 6, 7]] * 4
    assert all("batch" not in r for r in alone)
    for b, a in zip(batched, alone):
        assert b["outcome"] == a["outcome"] == "done" and b["overrides"] == a["overrides"]
        rows_b, rows_a = _rows(b["stats"]), _rows(a["stats"])
        assert len(rows_b) == len(rows_a) == 6
        for row_b, row_a in zip(rows_b, rows_a):
            for column, value in row_a.items():
                if column in SUMMED_OVER_SPRINGS and value:
                    assert float(row_b[column]) == pytest.approx(float(value), rel=1e-7), column
                else:
                    assert row_b[column] == value, column
    finals = {tuple(r["overrides"][k] for k in ("bodies.0.material", "heat.sources.0.temperature")): r for r in batched}
    assert finals[("wax", 300.0)]["final_mean_temperature"] > finals[("wax", 150.0)]["final_mean_temperature"]
    with open(tmp_path / "b" / "manifest.csv", newline="") as f:
        assert [row["batch"] for row in csv.DictReader(f)] == ["0 1 2 3"] * 4 + ["4 5 6 7"] * 4


def test_an_invalid_value_is_recorded_and_the_rest_complete(tmp_path):
    runs = [{**SMALL, "bodies.0.material": m} for m in ("wax", "unobtainium", "chocolate")]
    records = run_sweep(SCENES / "melting_block.toml", runs, tmp_path, frames=2, scheduler="serial", log=lambda s: None)
    assert [r["outcome"] for r in records] == ["done", "error", "done"]
    assert "unknown material 'unobtainium'" in records[1]["message"]
    assert json.loads((tmp_path / records[1]["folder"].split("/")[-1] / "run.json").read_text())["outcome"] == "error"
    rows = list(csv.DictReader(open(tmp_path / "manifest.csv", newline="")))
    assert [r["outcome"] for r in rows] == ["done", "error", "done"] and rows[1]["frames"] == ""


def test_the_manifest_lists_runs_not_yet_complete_as_pending(tmp_path):
    folder = tmp_path / "000_a=1"
    records = write_manifest(tmp_path, [(0, {"a": 1}, folder)])
    assert records[0]["outcome"] == "pending"


def test_bad_sweep_arguments_end_in_one_line(tmp_path, capsys):
    from sandbox.app.cli import main

    out = str(tmp_path / "s")
    assert main(["sweep", "melting_block", "--vary", "world.dt", "--out", out]) == 2
    assert main(["sweep", "melting_block", "--vary", "a=1", "--out", out, "--scheduler", "locall"]) == 2
    assert main(["sweep", "melting_block", "--vary", "a=1", "--out", out, "--metric", "speed"]) == 2
    assert main(["sweep", "no_such_scene", "--vary", "a=1", "--out", out]) == 2
    err = capsys.readouterr().err
    assert "expected KEY=V1,V2" in err and "expected auto, local, serial" in err
    assert "unknown scene 'no_such_scene'" in err
    assert not (tmp_path / "s").exists()  # nothing written


def test_a_sweep_reruns_nothing_of_the_same_settings_and_refuses_other_settings_unless_redo(tmp_path):
    """run.json holds the run's identity (the scene with its overrides, frames, video, size, version): the same
    sweep skips its runs; a changed one into the same folder stops before running anything and says what differs;
    --redo runs it again."""
    scene, runs = SCENES / "melting_block.toml", [{**SMALL, "bodies.0.material": "wax"}]
    said = []
    first = run_sweep(scene, runs, tmp_path, frames=2, scheduler="serial", log=said.append)
    assert first[0]["outcome"] == "done" and first[0]["settings"]["frames"] == 2
    record = next(tmp_path.glob("*/run.json"))
    stamp = record.stat().st_mtime_ns
    said.clear()
    run_sweep(scene, runs, tmp_path, frames=2, scheduler="serial", log=said.append)
    assert said == ["1 of 1 runs already complete: skipped"] and record.stat().st_mtime_ns == stamp
    with pytest.raises(SandboxError, match=r"holds a run of other settings \(frames 2 -> 3\).*--redo"):
        run_sweep(scene, runs, tmp_path, frames=3, scheduler="serial", log=said.append)
    assert record.stat().st_mtime_ns == stamp  # nothing ran
    again = run_sweep(scene, runs, tmp_path, frames=3, scheduler="serial", log=said.append, redo=True)
    assert again[0]["frames"] == 3 and json.loads(record.read_text())["settings"]["frames"] == 3


def test_an_unknown_key_is_refused_before_anything_runs(tmp_path, capsys):
    from sandbox.app.cli import main

    out = tmp_path / "s"
    for vary, says in (("NOPE=1,2", "unknown key"), ("bodies.0.materal=wax", "did you mean 'material'?")):
        assert main(["sweep", "melting_block", "--vary", vary, "--out", str(out), "--scheduler", "serial"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"error: --vary {vary.split('=')[0]}:") and says in err[0], err
    assert main(["sweep", "melting_block", "--vary", "bodies.3.material=wax", "--out", str(out)]) == 2
    assert "not an index" in capsys.readouterr().err
    assert not out.exists()


def _sweep_process(tmp_path, *extra: str):
    import subprocess
    import sys

    args = ["sweep", "melting_block", "--vary", "bodies.0.material=wax,chocolate,butter", "--frames", "500000"]
    return subprocess.Popen(
        [sys.executable, "-m", "sandbox", *args, "--out", str(tmp_path), *extra],
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def _stop_when_running(proc, tmp_path, signum) -> list[str]:
    """Wait until a run writes its rows, send `signum` to the sweep's whole process group; its stderr lines."""
    import os
    import signal
    import subprocess
    import time

    end = time.monotonic() + 120
    while not list(tmp_path.glob("*/.stats.csv.*.partial.csv")) and time.monotonic() < end and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(1.0)
    os.killpg(proc.pid, signum)
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # not stopped: it would run its 500,000 frames on after the test
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise
    assert "Traceback" not in err, err
    return [line for line in err.splitlines() if line.strip()]


@pytest.mark.parametrize("signum, code", [(2, 130), (15, 143), (1, 129)], ids=["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_stops_a_serial_sweep_in_one_line_and_the_stopped_run_is_not_recorded_done(tmp_path, signum, code):
    """SIGINT, SIGTERM or SIGHUP during a serial sweep's first run: the project's exit code and one line, the run
    that was stopped has no run.json (so the next sweep runs it again) and the manifest calls it pending."""
    proc = _sweep_process(tmp_path, "--scheduler", "serial")
    lines = _stop_when_running(proc, tmp_path, signum)
    name = {2: "SIGINT", 15: "SIGTERM", 1: "SIGHUP"}[signum]
    assert proc.returncode == code, lines
    assert lines[-1].startswith(f"stopped by {name}: the completed runs are kept in"), lines
    assert not list(tmp_path.glob("*/run.json"))
    rows = list(csv.DictReader(open(tmp_path / "manifest.csv", newline="")))
    assert [r["outcome"] for r in rows] == ["pending"] * 3


def test_a_signal_that_lands_in_a_finalizer_stops_the_run_at_the_next_frame_without_a_traceback():
    """A signal that arrives while Python runs a finalizer or a weakref callback raises there, where Python drops the
    exception and printed it with a traceback (the serial sweep's signal test caught one in a WeakSet callback,
    twice in a clean CI run); now nothing is printed and the next held() block stops the run."""
    code = (
        "import os, signal\n"
        "from sandbox.app.signals import Signalled, Stopper\n"
        "class Dropper:\n"
        "    def __del__(self):\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "        for _ in range(100000): pass  # the handler runs here, inside the finalizer\n"
        "with Stopper() as stopper:\n"
        "    Dropper()\n"
        "    print('pending', stopper.pending)\n"
        "    try:\n"
        "        with stopper.held():\n"
        "            pass\n"
        "    except Signalled as exc:\n"
        "        print('stopped', exc)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stderr == "" and done.stdout.split() == ["pending", "2", "stopped", "SIGINT"], done


def test_a_vary_value_that_is_not_finite_is_refused_in_one_line(tmp_path, capsys):
    from sandbox.app.cli import main

    for vary in ("world.dt=1e308,nan", "world.dt=inf", "heat.ambient=-inf,20"):
        assert main(["sweep", "melting_block", "--vary", vary, "--out", str(tmp_path / "s")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "expected finite numbers" in err[0], err
    assert not (tmp_path / "s").exists()


@pytest.mark.slow  # a Dask cluster in another process
@pytest.mark.xdist_group("dask")
@pytest.mark.parametrize("signum, code", [(15, 143)], ids=["SIGTERM"])  # SIGINT: as SIGTERM, and the serial test's
def test_a_signal_stops_a_cluster_sweep_in_one_line(tmp_path, signum, code):
    """Ctrl-C at a terminal (or a scheduler's SIGTERM) signals the whole process group: the sweep, its nannies and
    workers."""
    pytest.importorskip("distributed")
    proc = _sweep_process(tmp_path, "--scheduler", "local", "--workers", "2")
    lines = _stop_when_running(proc, tmp_path, signum)
    assert proc.returncode == code, lines
    assert lines[-1].startswith("stopped by SIG") and "the completed runs are kept in" in lines[-1], lines
    assert (tmp_path / "manifest.csv").exists()

"""One run of a sweep, as a worker process executes it: the scene with its overrides, headless, into its own folder.

A run folder holds stats.csv, the optional video, and run.json, written last and atomically: a folder with a run.json
is a run that completed (done: all its frames; stopped by the guard; or refused by a scene error), and a second
invocation of the sweep skips it. A run stopped by a signal writes no run.json (the signal goes on up and stops the
sweep), so the next invocation runs it again. Everything else is written under temporary names first
(runner.run_headless), so a worker that dies mid-run leaves no file under a final name, and the retried run starts
its folder afresh.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
import signal
import time
from pathlib import Path

from ..config.scene import load_scene
from ..config.schema import toml_value
from ..core import runtime
from ..errors import SandboxError
from ..research.dask_pool import cpu_threads
from ..simulation import Simulation
from .runner import run_headless
from .signals import Signalled

RECORD = "run.json"
CRASH_HOOK = "SANDBOX_SWEEP_CRASH_ONCE"  # tests: a marker path; the first run to see it missing kills its process


def override_text(key: str, value) -> str:
    """key=value as --set takes it (the value in TOML syntax)."""

    return f"{key}={toml_value(value)}"


def identity(settings: dict) -> str:
    """A hash of a run's settings (sweep.run_settings): equal exactly when the runs are the same."""
    text = json.dumps(settings, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def summarise(rows: list[dict], conserves_energy: bool) -> dict:
    """Summary metrics of a run's stats rows (the CSV's columns as strings): final molten fraction, time to half
    molten (seconds; None if never), peak and final mean temperature (degrees), relative total-energy drift (only
    where the scene conserves energy: no heat sources, emitters or drag), frames and final time."""

    def column(name):
        return [float(r[name]) if r[name] != "" else math.nan for r in rows]

    if not rows:
        return {"frames": 0}
    t, molten, temp, energy = (
        column("time"),
        column("molten_fraction"),
        column("mean_temperature"),
        column("total_energy"),
    )
    half = next((ti for ti, m in zip(t, molten) if m >= 0.5), None)
    finite_temps = [x for x in temp if not math.isnan(x)]
    out = {
        "frames": len(rows),
        "final_time": t[-1],
        "final_molten_fraction": None if math.isnan(molten[-1]) else molten[-1],
        "time_to_half_molten": half,
        "peak_mean_temperature": max(finite_temps) if finite_temps else None,
        "final_mean_temperature": finite_temps[-1] if finite_temps else None,
        "energy_drift": None,
    }
    if conserves_energy and energy[0] != 0 and not math.isnan(energy[0]):
        out["energy_drift"] = abs(energy[-1] - energy[0]) / abs(energy[0])
    return out


def _write_json(path: Path, data: dict) -> None:
    partial = path.with_name(f".{path.name}.partial")
    partial.write_text(json.dumps(data, indent=1, allow_nan=False, default=str))
    os.replace(partial, path)


def execute_run(
    scene_path: str,
    overrides: dict,
    folder: str,
    frames: int | None,
    video: bool,
    width: int | None,
    height: int | None,
    threads: int,
    settings: dict | None = None,
) -> dict:
    """Run the scene at `scene_path` with `overrides` (dotted key -> value) headless into `folder` for `frames`
    frames (None: the scene's render.frames); `video`: also out.mp4 (width x height, default the scene's); `threads`:
    Taichi CPU threads for this run; `settings`: what identifies the run (sweep.run_settings), kept in the record with
    its hash so that a later sweep knows what ran. Returns the run's record (also written to folder/run.json)."""

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    record = {"overrides": overrides, "folder": str(folder), "stats": None, "video": None}
    if settings is not None:
        record.update(identity=identity(settings), settings=settings)
    start = time.perf_counter()
    with cpu_threads(threads):
        try:
            scene = load_scene(scene_path, [override_text(k, v) for k, v in overrides.items()])
            runtime.reset()  # the last run's fields go; its kernels come back from the offline cache (same field ids)
            sim = Simulation(scene, arch="cpu")
            n = frames or scene.render.frames
            crash_marker = os.environ.get(CRASH_HOOK)
            stats_path = folder / "stats.csv"
            video_path = folder / "out.mp4" if video else None

            def maybe_crash(frame, stats):
                if crash_marker and frame == n // 2 and not Path(crash_marker).exists():
                    Path(crash_marker).write_text(str(os.getpid()))
                    os._exit(17)  # a worker dying mid-run, its partial files left behind

            result = run_headless(
                sim, n, None, video_path, stats_path, width, height, progress=False, on_frame=maybe_crash
            )
            if result.interrupted:  # no record: the run is not complete, and the next sweep runs it again
                raise Signalled(result.signal or signal.SIGINT)
            with open(stats_path, newline="") as f:
                rows = list(csv.DictReader(f))
            conserves = not (scene.heat and scene.heat.sources) and not scene.emitters and not scene.world.drag
            record.update(summarise(rows, conserves))
            record["stats"] = str(stats_path)
            record["video"] = str(video_path) if video_path and video_path.exists() else None
            if result.stopped:
                record.update(outcome="stopped", message=result.stopped)
            elif result.frames == n:
                record.update(outcome="done", message="")
            else:  # cannot happen without a signal or the guard; never recorded as done
                raise SandboxError(f"{folder}: the run ended after {result.frames} of its {n} frames")
        except SandboxError as exc:
            record.update(outcome="error", message=str(exc))
    record["wall_seconds"] = time.perf_counter() - start
    _write_json(folder / RECORD, record)
    return record

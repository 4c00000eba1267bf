"""`sandbox sweep`: one scene run headless for every combination of overrides, spread over Dask workers.

    sandbox sweep melting_block --vary heat.sources.0.temperature=120:240:4 --vary bodies.0.material=wax,chocolate \\
        --frames 300 --out sweeps/melt

The plan is the cross product of the --vary lists (or, with --zip, their values side by side). Each run gets a
folder named by its index and overrides (sweep_run.py writes it); the manifest (manifest.csv) lists every run's
overrides, summary metrics, outcome and files; with matplotlib, sweep.png plots a metric against each varied key.

Where it runs: on a Dask cluster given by address (`--scheduler tcp://host:8786`), else on a local cluster of worker
processes on this machine (workers x Taichi threads no more than the cores), else, without the `sweep` extra (dask,
distributed), one run after another in this process. Runs are retried when their worker dies; a run that completed
(its run.json exists) is skipped by a second invocation, so an interrupted sweep resumes where it stopped.
"""

from __future__ import annotations

import copy
import csv
import itertools
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..config.resources import read_small_text
from ..config.scene import apply_override, parse_override, read_scene_table, scene_from_dict
from ..errors import SandboxError, SceneError
from ..research.dask_pool import choose_scheduler, dask_client, local_shape
from ..research.figures import key_label, legend_beside, metric_label, pyplot, save
from .sweep_batch import batches, execute_batch
from .sweep_run import RECORD, execute_run, identity

METRICS = (
    "final_molten_fraction",
    "time_to_half_molten",
    "peak_mean_temperature",
    "final_mean_temperature",
    "energy_drift",
    "wall_seconds",
)
MAX_RUNS = 10_000


@dataclass(frozen=True)
class Variation:
    """One --vary: a dotted scene key and the values it takes."""

    key: str
    values: tuple


def parse_vary(text: str) -> Variation:
    """KEY=V1,V2,... (each value read as TOML: numbers, true/false, bare words as strings) or KEY=START:STOP:COUNT
    (COUNT evenly spaced numbers from START to STOP)."""

    if "=" not in text:
        raise SandboxError(f"--vary {text}: expected KEY=V1,V2,... or KEY=START:STOP:COUNT")
    key, raw = (s.strip() for s in text.split("=", 1))
    if not key or not raw:
        raise SandboxError(f"--vary {text}: expected KEY=V1,V2,... or KEY=START:STOP:COUNT")
    span = re.fullmatch(r"([-+0-9.eE]+):([-+0-9.eE]+):(\d+)", raw)
    if span:
        try:
            start, stop, count = float(span[1]), float(span[2]), int(span[3])
        except ValueError as exc:
            raise SandboxError(f"--vary {text}: expected numbers START:STOP and a whole COUNT") from exc
        if not (1 <= count <= MAX_RUNS and np.isfinite(start) and np.isfinite(stop)):
            raise SandboxError(f"--vary {text}: expected finite START and STOP and COUNT from 1 to {MAX_RUNS:,}")
        values = tuple(float(v) for v in np.linspace(start, stop, count))
    else:
        values = tuple(parse_override(f"{key}={item}")[1] for item in raw.split(","))
    numbers = [v for v in values if isinstance(v, float)]
    if not all(math.isfinite(v) for v in numbers):
        raise SandboxError(f"--vary {text}: {raw} holds a value that is not a finite number; expected finite numbers")
    return Variation(key, values)


def plan_runs(variations: list[Variation], zipped: bool = False) -> list[dict]:
    """The runs' overrides (dotted key -> value), in order: the cross product of the variations, or with `zipped`
    their values side by side (all lists the same length)."""
    if not variations:
        raise SandboxError("sweep: expected at least one --vary KEY=VALUES")
    keys = [v.key for v in variations]
    if len(set(keys)) != len(keys):
        raise SandboxError(f"sweep: a key is varied twice in {keys}; expected each key once")
    if zipped:
        lengths = {len(v.values) for v in variations}
        if len(lengths) != 1:
            raise SandboxError(f"--zip: the --vary lists have {sorted(lengths)} values; expected equal lengths")
        combos = list(zip(*(v.values for v in variations)))
    else:
        combos = list(itertools.product(*(v.values for v in variations)))
    if len(combos) > MAX_RUNS:
        raise SandboxError(f"sweep: {len(combos):,} runs; expected at most {MAX_RUNS:,}")
    return [dict(zip(keys, combo)) for combo in combos]


def check_keys(scene_path: str | Path, variations: list[Variation]) -> None:
    """Every varied key names a setting of the scene (a SandboxError naming the nearest key otherwise), before any
    run starts; a value a key cannot take is left to its run, which records the error."""
    path = Path(scene_path)
    data = read_scene_table(path)
    for v in variations:
        trial = copy.deepcopy(data)
        try:
            apply_override(trial, v.key, v.values[0])
            scene_from_dict(trial, path)
        except SceneError as exc:
            if exc.key == v.key or "unknown key" in exc.expected or exc.file == "--set":
                raise SandboxError(f"--vary {v.key}: {exc.expected}") from None
        except SandboxError as exc:
            raise SandboxError(f"--vary {v.key}: {exc}") from None


def run_settings(table: dict, overrides: dict, frames, video: bool, width, height) -> dict:
    """What makes a run what it is: the scene `table` (as read, left unchanged) with the run's overrides applied,
    and the run's settings."""
    data = copy.deepcopy(table)
    for key, value in overrides.items():
        try:
            apply_override(data, key, value)
        except SandboxError:
            pass  # the run itself records the error
    return {"scene": data, "frames": frames, "video": video, "width": width, "height": height, "sandbox": __version__}


def differences(old: dict, new: dict) -> str:
    """What changed between two runs' settings, in words (the first few)."""
    if not isinstance(old, dict):
        return "it has no record of its settings"
    said = []
    for key in ("frames", "video", "width", "height", "sandbox"):
        if old.get(key) != new.get(key):
            said.append(f"{key} {old.get(key)} -> {new.get(key)}")
    if old.get("scene") != new.get("scene"):
        said.append("the scene or its overrides differ")
    return ", ".join(said) or "its settings differ"


def run_folder_name(index: int, overrides: dict) -> str:
    """`007_temperature=150_material=wax`: the index, then each key's last part and its value, safe as a name."""
    parts = [f"{index:03d}"]
    for key, value in overrides.items():
        short = key.split(".")[-1]
        text = f"{value:g}" if isinstance(value, float) else str(value)
        parts.append(re.sub(r"[^A-Za-z0-9.=+-]", "-", f"{short}={text}"))
    return "_".join(parts)[:120]


def run_sweep(
    scene_path: str | Path,
    runs: list[dict],
    out: str | Path,
    frames: int | None = None,
    video: bool = False,
    width: int | None = None,
    height: int | None = None,
    scheduler: str = "auto",
    workers: int | None = None,
    threads: int | None = None,
    log=print,
    redo: bool = False,
    batch: bool = True,
) -> list[dict]:
    """Run every override set in `runs` and write the manifest; returns the records in plan order.

    `scheduler`: "auto" (a local Dask cluster where the sweep extra is installed, else "serial"), "local", "serial"
    (one by one in this process) or a Dask scheduler address. `workers`, `threads`: local worker processes and Taichi
    threads per run (default: one worker per core, up to the runs, and the cores shared among them). A run whose
    folder holds a record of the same settings is skipped; one of other settings stops the sweep before anything
    runs (a SandboxError saying what differs), unless `redo`, which runs it again. `batch`: runs that differ only
    in what a world may hold of its own run as the worlds of one simulation, in this process (sweep_batch.py),
    before the rest."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scene_path = str(Path(scene_path).resolve())
    jobs = [(k, o, out / run_folder_name(k, o)) for k, o in enumerate(runs)]
    table = read_scene_table(Path(scene_path))  # read once for every run's settings
    settings = [run_settings(table, o, frames, video, width, height) for o in runs]
    todo = []
    for (k, o, f), wanted in zip(jobs, settings):
        record = _read_record(f / RECORD)
        if record is not None and record.get("identity") != identity(wanted) and not redo:
            raise SandboxError(
                f"{f}: holds a run of other settings ({differences(record.get('settings'), wanted)}); expected the "
                "same sweep in this folder, or --redo to run such runs again"
            )
        if record is None or record.get("identity") != identity(wanted):
            todo.append((k, o, f, wanted))
    if len(todo) < len(jobs):
        log(f"{len(jobs) - len(todo)} of {len(jobs)} runs already complete: skipped")
    groups, alone = batches(todo, video) if batch else ([], todo)
    workers, threads = local_shape(len(todo), workers, threads)  # as if none were batched: the runs' threads
    if alone:
        scheduler = choose_scheduler(scheduler, len(alone), log, "sweep")
    todo = alone
    args = (frames, video, width, height, threads)
    try:
        for group in groups:
            log(f"runs {' '.join(str(job[0]) for job in group)}: batched as {len(group)} worlds of one simulation")
            for record in execute_batch(scene_path, group, frames, threads, log):
                log(f"run {record['run']}: {record['outcome']} {record.get('message', '')}".rstrip())
        if not todo:
            pass
        elif scheduler == "serial":
            for k, overrides, folder, wanted in todo:
                record = execute_run(scene_path, overrides, str(folder), *args, settings=wanted)
                log(f"run {k}: {record['outcome']} {record.get('message', '')}".rstrip())
        else:
            _run_on_dask(scheduler, workers, threads, scene_path, todo, args, log)
    finally:
        records = write_manifest(out, jobs)
    return records


def _run_on_dask(scheduler, workers, threads, scene_path, todo, args, log) -> None:
    from distributed import as_completed

    with dask_client(scheduler, workers) as client:
        futures = {
            client.submit(
                execute_run, scene_path, o, str(f), *args, settings=s, pure=False, retries=3, key=f"run-{k}-{f.name}"
            ): k
            for k, o, f, s in todo
        }
        for future in as_completed(futures):
            record = future.result()
            log(f"run {futures[future]}: {record['outcome']} {record.get('message', '')}".rstrip())


def _read_record(path: Path) -> dict | None:
    """A run folder's run.json, or None when there is none (a damaged one reads as a run of unknown settings)."""
    if not path.exists():
        return None
    try:
        record = json.loads(read_small_text(path))
    except (OSError, ValueError, RecursionError):
        return {}
    return record if isinstance(record, dict) else {}


def write_manifest(out: Path, jobs: list) -> list[dict]:
    """manifest.csv: one row per planned run (its overrides, outcome, metrics and files; outcome "pending" for a
    run not complete), written atomically. Returns the records."""
    records = []
    for k, overrides, folder in jobs:
        record = _read_record(folder / RECORD)
        if not record or record.get("overrides") != overrides:
            record = {"overrides": overrides, "outcome": "pending"}
        record["run"] = k
        records.append(record)
    keys = list(jobs[0][1]) if jobs else []
    columns = ["run", *keys, "outcome", "message", "frames", *METRICS, "batch", "stats", "video", "folder"]
    partial = out / ".manifest.csv.partial"
    with open(partial, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for record in records:
            row = {c: record.get(c) for c in columns}
            for name in ("stats", "video", "folder"):  # paths relative to the sweep's folder
                if row[name]:
                    row[name] = os.path.relpath(row[name], out)
            row.update(record["overrides"])
            if record.get("batch"):  # the runs stepped as the worlds of one simulation with it
                row["batch"] = " ".join(str(k) for k in record["batch"])
            writer.writerow({c: ("" if v is None else v) for c, v in row.items()})
    os.replace(partial, out / "manifest.csv")
    return records


def plot_sweep(
    out: Path, records: list[dict], keys: list[str], metric: str, scene_table: dict | None = None
) -> Path | None:
    """sweep.png: `metric` against each varied key (one panel per key), or None without matplotlib. Axes in words
    with units (`scene_table` names the body or source a key belongs to); numbers as lines through the points,
    words (materials, integrators) as categories: bars for one series, points side by side for several; legends
    beside the axes."""
    plt = pyplot()
    if plt is None:
        return None
    done = [r for r in records if r.get("outcome") == "done" and r.get(metric) is not None]
    ylabel, factor = metric_label(metric)
    fig, axes = plt.subplots(1, len(keys), figsize=(5.2 * len(keys), 3.8), squeeze=False, layout="constrained")
    for ax, key in zip(axes[0], keys):
        others = [k for k in keys if k != key]
        groups: dict = {}
        for r in done:
            groups.setdefault(tuple(str(r["overrides"][k]) for k in others), []).append(r)
        categorical = any(isinstance(r["overrides"][key], str) for r in done)
        categories = list(dict.fromkeys(str(r["overrides"][key]) for r in done))
        width = 0.8 / max(len(groups), 1)
        for g, (label, group) in enumerate(groups.items()):
            name = ", ".join(label) or None
            if categorical:
                where = {c: k for k, c in enumerate(categories)}
                xs = [where[str(r["overrides"][key])] + (g - (len(groups) - 1) / 2) * width for r in group]
                ax.bar(xs, [r[metric] * factor for r in group], width=width * 0.9, label=name)
            else:
                group.sort(key=lambda r: r["overrides"][key])
                ax.plot([r["overrides"][key] for r in group], [r[metric] * factor for r in group], "o-", label=name)
        if categorical:
            ax.set_xticks(range(len(categories)), categories)
        ax.set(xlabel=key_label(key, scene_table), ylabel=ylabel)
        if others:
            legend_beside(ax, title=", ".join(key_label(k, scene_table) for k in others))
    return save(fig, out / "sweep.png")

"""A sweep's runs that differ only in what a world may hold of its own, run as the worlds of one simulation.

Runs whose overrides change only world_view.WORLD_KEYS (their bodies' temperatures and velocities, gravity, drag,
the air's and the heat sources' temperatures, the thermal walls' temperatures, the heater's power and the lid's
pressure) share everything else: `batches` groups them, and `execute_batch`
steps each group as one simulation of as many worlds (core/worlds.py), world k started from run k's scene, so that
each world is its run alone, bit for bit. Each run still gets its own folder: stats.csv (its world's readouts,
written through the same claimed, partial-then-renamed files as a lone run's) and run.json (its record, with the
runs it was batched with). A run that asks for a video, a scene that cannot run as worlds, or a group of one runs
alone (sweep_run.execute_run).
"""

from __future__ import annotations

import csv
import re
import time
from pathlib import Path

from ..config.scene import load_scene
from ..core import runtime
from ..core.cores import usable_cores
from ..errors import SandboxError, SimulationError
from ..research.dask_pool import cpu_threads
from ..simulation import Simulation
from ..world_view import WORLD_KEYS
from .run_outputs import RunOutputs
from .signals import Stopper
from .sweep_run import RECORD, _write_json, identity, override_text, summarise

MAX_BATCH = 64  # runs one simulation holds at most (a larger group is split)


def world_key(key: str) -> bool:
    """Whether a dotted scene key is one a world may hold of its own (WORLD_KEYS)."""
    return any(re.fullmatch(pattern, key) for pattern in WORLD_KEYS)


def batches(todo: list, video: bool) -> tuple[list[list], list]:
    """(groups of runs to run as worlds, runs to run alone) of `todo` ((index, overrides, folder, settings) each):
    runs whose overrides agree on every key but WORLD_KEYS form a group (at most MAX_BATCH); none with `video`."""
    if video:
        return [], list(todo)
    groups: dict = {}
    for job in todo:
        shared = tuple(sorted((k, repr(v)) for k, v in job[1].items() if not world_key(k)))
        groups.setdefault(shared, []).append(job)
    batched, alone = [], []
    for group in groups.values():
        chunks = [group[i : i + MAX_BATCH] for i in range(0, len(group), MAX_BATCH)]
        for chunk in chunks:
            (batched if len(chunk) > 1 else alone).append(chunk if len(chunk) > 1 else chunk[0])
    return batched, alone


def execute_batch(scene_path: str, group: list, frames: int | None, threads: int, log=print) -> list[dict]:
    """Run a group of runs (batches()) as the worlds of one simulation on every usable core; returns their records
    (also each folder's run.json; "run": the run's index), each world equal to its run alone on `threads` Taichi
    threads, as the sweep runs the runs it does not batch. A run whose values its scene refuses records its error
    alone; where the scene cannot run as worlds (SandboxError), every run of the group runs alone, and it is said."""
    from .sweep_run import execute_run

    def alone(job) -> dict:
        k, overrides, folder, settings = job
        record = execute_run(scene_path, overrides, str(folder), frames, False, None, None, threads, settings=settings)
        return dict(record, run=k)

    start = time.perf_counter()
    scenes, records, worlds = [], [], []
    for job in group:
        try:
            scenes.append(load_scene(scene_path, [override_text(k, v) for k, v in job[1].items()]))
            worlds.append(job)
        except SandboxError:  # a value its key cannot take: the run alone records the error
            records.append(alone(job))
    if len(worlds) < 2:
        return records + [alone(job) for job in worlds]
    with cpu_threads(usable_cores()):
        runtime.reset()
        try:
            sim = Simulation(scenes[0], arch="cpu", starts=scenes, alone_threads=threads)
        except SandboxError as exc:
            log(f"runs {' '.join(str(job[0]) for job in worlds)}: not batched ({exc}); each runs alone")
            return records + [alone(job) for job in worlds]
        batched = _run_worlds(sim, worlds, scenes, frames or scenes[0].render.frames)
    wall = time.perf_counter() - start
    for record, (_, _, folder, _) in zip(batched, worlds):
        record["wall_seconds"] = wall
        _write_json(Path(folder) / RECORD, record)
    return records + batched


def _run_worlds(sim: Simulation, group: list, scenes: list, frames: int) -> list[dict]:
    """Step every world `frames` frames, each world's readouts into its run's stats.csv; a world the blow-up guard
    stops is recorded stopped (the others step on: nothing crosses worlds). A signal stops the batch between frames:
    each run's rows so far take their names, as a stopped lone run's do, and no run.json is written (the next sweep
    runs them again)."""
    runs = [k for k, _, _, _ in group]
    records, outputs = [], []
    for k, overrides, folder, settings in group:
        Path(folder).mkdir(parents=True, exist_ok=True)
        stats = Path(folder) / "stats.csv"
        outputs.append(RunOutputs(sim, None, stats))
        record = {"run": k, "overrides": overrides, "folder": str(folder), "stats": str(stats), "video": None}
        record.update(identity=identity(settings), settings=settings, batch=runs, outcome="done", message="")
        records.append(record)
    live = list(range(len(group)))
    try:
        with Stopper() as stopper:
            for frame in range(frames):
                begun = time.perf_counter()
                steps = sim.advance_frame()
                seconds = (time.perf_counter() - begun) / (steps * len(group))  # a world's share of a step
                with stopper.held():
                    for k in list(live):
                        try:
                            stats = sim.stats(world=k)
                        except SimulationError as exc:
                            records[k].update(outcome="stopped", message=str(exc))
                            live.remove(k)
                            continue
                        outputs[k].frame(frame, stats, seconds, None)
                if not live:
                    break
    finally:  # the rows so far take their names, as a lone run's do when it is stopped
        for out in outputs:
            out.close(True)
    for record, scene in zip(records, scenes):
        with open(record["stats"], newline="") as f:
            rows = list(csv.DictReader(f))
        conserves = not (scene.heat and scene.heat.sources) and not scene.emitters and not scene.world.drag
        record.update(summarise(rows, conserves))
    return records

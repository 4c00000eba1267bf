"""Headless runs: advance a simulation frame by frame, draw each frame, write video and a stats CSV."""

from __future__ import annotations

import csv
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import taichi as ti

from ..errors import SimulationError
from ..measure.stats import stat_values
from ..render.raster import Renderer
from ..render.video import open_writer, partial_path, publish
from ..simulation import STAT_COLUMNS, Simulation, Stats


@dataclass
class RunResult:
    frames: int  # frames written (or run, without an output)
    sim_time: float
    wall_seconds: float
    last: Stats | None
    interrupted: bool = False
    stopped: str | None = None  # the blow-up guard's message when it stopped the run


def stats_row(frame: int, s: Stats, step_seconds: float) -> dict:
    """One CSV row (the STAT_COLUMNS) for frame `frame`; a measurement the scene does not have (the temperature of a
    scene without heat) is left empty."""
    row = stat_values(frame, s, step_seconds)
    return {k: (("" if math.isnan(v) else f"{v:.9g}") if isinstance(v, float) else v) for k, v in row.items()}


def _progress(total: int, enabled: bool, label: str):
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="frame", desc=label, file=sys.stderr, dynamic_ncols=True)


def run_headless(
    sim: Simulation,
    frames: int,
    substeps: int | None,
    out: str | Path | None,
    stats_path: str | Path | None = None,
    width: int | None = None,
    height: int | None = None,
    fps: float | None = None,
    still_frame: int | None = None,
    progress: bool = True,
    on_frame: Callable[[int, Stats], None] | None = None,
    first_frame: int = 0,
) -> RunResult:
    """Run `frames` frames of `substeps` steps each (None: the scene's, possibly "auto"); write frames to `out` (by
    extension) and stats to a CSV. `first_frame`: the frames run before (a resumed run numbers its rows on from it).

    Every frame is measured, and so checked by the blow-up guard, before its row and picture are written. Ctrl-C
    stops the run between steps (the result says `interrupted`); the guard stops it with a SimulationError (the
    result's `stopped` holds its message). Either way the video and CSV hold exactly the frames before, closed into
    valid files under the names asked for (a video with no frame is not written).
    """
    cfg = sim.scene.render
    width, height, fps = width or cfg.width, height or cfg.height, fps or cfg.fps
    renderer = Renderer(sim.model, sim.state, width, height, cfg, output="picture") if out is not None else None
    if renderer is not None:
        sim.state.carry(renderer.tails)  # its motion-blur tails move with the particles
    writer = open_writer(out, width, height, fps, still_frame) if out is not None else None
    csv_file = None
    if stats_path is not None:
        stats_path = Path(stats_path)
        stats_path.parent.mkdir(parents=True, exist_ok=True)
        csv_file = open(partial_path(stats_path), "w", newline="")  # noqa: SIM115 - closed in finally
        table = csv.DictWriter(csv_file, fieldnames=STAT_COLUMNS)
        table.writeheader()
    bar = _progress(frames, progress, sim.scene.name)
    start = time.perf_counter()
    last = None
    done = 0
    interrupted = False
    stopped = None
    try:
        for frame in range(first_frame, first_frame + frames):
            ti.sync()
            t0 = time.perf_counter()
            if renderer is not None:
                renderer.begin_frame()
            taken = sim.advance_frame(substeps, renderer.mid_frame if renderer is not None else None)
            ti.sync()
            step_seconds = (time.perf_counter() - t0) / taken
            last = sim.stats()
            if csv_file is not None:
                table.writerow(stats_row(frame, last, step_seconds))
            if writer is not None:
                renderer.record(last)
                writer.write(renderer.frame())
            if on_frame is not None:
                on_frame(frame, last)
            done += 1
            if bar is not None:
                bar.update(1)
    except KeyboardInterrupt:
        interrupted = True
    except SimulationError as exc:
        stopped = str(exc)
    finally:
        if bar is not None:
            bar.close()
        if writer is not None:
            writer.close()
        if csv_file is not None:
            csv_file.close()
            publish(partial_path(stats_path), stats_path, keep=True)
    written = writer.frames_written if writer is not None else done
    return RunResult(written, sim.time, time.perf_counter() - start, last, interrupted, stopped)

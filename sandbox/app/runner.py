"""Headless runs: advance a simulation frame by frame, draw each frame, write video and a stats CSV."""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import taichi as ti

from ..errors import OutputError, SimulationError
from ..render.matte import BLACK, WHITE, matte
from ..render.raster import Renderer
from ..simulation import Simulation, Stats
from .run_outputs import RunOutputs
from .signals import Stopper, exit_code


@dataclass
class RunResult:
    frames: int  # frames written (or run, without an output)
    sim_time: float
    wall_seconds: float
    last: Stats | None
    interrupted: bool = False
    stopped: str | None = None  # the blow-up guard's message when it stopped the run
    signal: int | None = None  # the signal that interrupted it (2: Ctrl-C, 15: SIGTERM, 1: SIGHUP)
    kept: list[Path] = dataclasses.field(default_factory=list)  # partial files kept (a signal stopped a writer too)


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
    outputs: RunOutputs | None = None,
    overlays: bool = True,
) -> RunResult:
    """Run `frames` frames of `substeps` steps each (None: the scene's, possibly "auto"); write frames to `out` (by
    extension) and stats to a CSV, or everything `outputs` holds (the command line's run: dump and checkpoints
    too). `first_frame`: the frames run before (a resumed run numbers its rows on from it). `overlays` False leaves
    the title, clock and legend out of the pictures (the scene's charts stay).

    Every frame is measured, and so checked by the blow-up guard, before its row and picture are written. Ctrl-C,
    SIGTERM or SIGHUP stop the run between steps (the result says `interrupted`, and `signal`); the guard stops it
    with a SimulationError (the result's `stopped` holds its message). Either way the outputs hold exactly the
    frames before, closed into valid files under the names asked for (a video with no frame is not written). A write
    that fails (a full disk) leaves them under partial names and raises an OutputError that lists them; where the
    signal that stopped the run stopped ffmpeg too, they are kept so, and the result lists them (`kept`).
    """
    cfg = _render_table(sim, overlays)
    width, height, fps = width or cfg.width, height or cfg.height, fps or cfg.fps
    if outputs is None:
        outputs = RunOutputs(sim, out, stats_path, size=(width, height, fps), still_frame=still_frame)
    alpha = outputs.pictures and outputs.codec is not None and outputs.codec.alpha
    if alpha:  # drawn over black and over white: their difference is each pixel's coverage (render/matte.py)
        renderer = _renderer(sim, width, height, dataclasses.replace(cfg, background=BLACK))
        over_white = _renderer(sim, width, height, dataclasses.replace(cfg, background=WHITE))
    else:
        renderer = _renderer(sim, width, height, cfg) if outputs.pictures else None

    def picture():
        renderer.record(last)
        if not alpha:
            return renderer.frame()
        over_white.record(last)
        return matte(np.array(renderer.frame(), copy=True), over_white.frame())

    bar = _progress(frames, progress, sim.scene.name)
    start, last, done = time.perf_counter(), None, 0
    interrupted, signum, stopped = False, None, None
    complete, kept = True, []
    with Stopper() as stopper:
        try:
            for frame in range(first_frame, first_frame + frames):
                last, step_seconds = _advance(sim, substeps, renderer)
                with stopper.held():
                    outputs.frame(frame, last, step_seconds, picture if renderer is not None else None)
                    done += 1  # its row and picture are written
                    if on_frame is not None:
                        on_frame(frame, last)
                if bar is not None:
                    bar.update(1)
        except KeyboardInterrupt as exc:
            interrupted, signum = True, exit_code(exc) - 128
        except SimulationError as exc:
            stopped = str(exc)
        except OutputError as exc:
            complete = False
            kept = outputs.close(complete=False)
            if stopper.pending is None:
                raise OutputError(exc.path, exc.reason, kept) from None
            # the signal that stops this run stopped a writer too (systemd, scancel or `kill` signal ffmpeg as well):
            # the outputs stay under partial names, continued by a resume from the last checkpoint
            interrupted, signum = True, stopper.pending
        except BaseException:
            complete = False
            outputs.close(complete=False)
            raise
        finally:
            if bar is not None:
                bar.close()
            if complete:
                finished = first_frame + done if done == frames and not (interrupted or stopped) else None
                with stopper.deferred():  # a signal now waits until every output has its name
                    kept = _close(outputs, finished, interrupted or stopper.pending is not None)
        if stopper.pending is not None and not interrupted:
            interrupted, signum = True, stopper.pending
    return RunResult(done, sim.time, time.perf_counter() - start, last, interrupted, stopped, signum, kept)


def _render_table(sim: Simulation, overlays: bool):
    """The scene's render table, without the title, clock and legend where `overlays` is False."""
    cfg = sim.scene.render
    return cfg if overlays else dataclasses.replace(cfg, title=False, clock=False, legend=False)


def _close(outputs: RunOutputs, finished: int | None, signalled: bool) -> list[Path]:
    """Give every output its name; the partial files kept instead when a signal that stopped the run stopped a
    writer too (an ffmpeg that received the same SIGTERM cannot finish its piece): a resume continues them."""
    try:
        outputs.close(complete=True, finished_frame=finished)
    except OutputError as exc:
        if not signalled:
            raise
        return exc.kept
    return []


def _renderer(sim: Simulation, width: int, height: int, cfg) -> Renderer:
    """The pictures' renderer at `width` x `height` with the render table `cfg`; its motion-blur tails move with the
    particles."""
    renderer = Renderer(sim.model, sim.state, width, height, cfg, output="picture")
    sim.state.carry(renderer.tails)
    return renderer


def _advance(sim: Simulation, substeps: int | None, renderer: Renderer | None) -> tuple[Stats, float]:
    """One frame's steps (the renderer told where its middle is, for curved streaks), then its measurements (the
    blow-up guard's check among them): (Stats, wall seconds per step)."""
    ti.sync()
    t0 = time.perf_counter()
    if renderer is not None:
        renderer.begin_frame()
    taken = sim.advance_frame(substeps, renderer.mid_frame if renderer is not None else None)
    ti.sync()
    step_seconds = (time.perf_counter() - t0) / taken
    return sim.stats(), step_seconds

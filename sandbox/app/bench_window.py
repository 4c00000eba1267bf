"""`sandbox bench`'s window figures: the window's frame on the 10,000-particle melting block at fixed substeps, split
into its parts, and (`sandbox bench --window`) the frame rate the window holds on every shipped scene with its
pacing on (FramePacer), with the substeps it ran and the simulated seconds per wall second."""

from __future__ import annotations

import statistics
import time

import taichi as ti

from ..config.scene import load_scene
from ..core import runtime
from ..errors import SandboxError
from ..render.raster import Renderer
from ..research.bench import INTERACTIVE_BLOCK, SCENES
from ..simulation import Simulation
from .window import FRAME_PARTS, run_window


def interactive_frame(arch: str, repeats: int) -> dict:
    """The window's frame on the 10,000-particle melting block at its default substeps, split into its parts: the
    window loop itself (sandbox.render.window.run_window, in a hidden GGUI window) timed part by part, from the
    simulation to handing the picture to GGUI and drawing the panel. GGUI presenting the frame on a screen is not
    included (a hidden window does not present; on a display that is the GPU's work). Without Vulkan the same parts
    are timed in a loop that stands in for the window (no GGUI: "display" is 0), and `window` says so."""

    sim = Simulation(load_scene(SCENES / "melting_block.toml", INTERACTIVE_BLOCK), arch=arch)
    frames, warm = max(repeats, 5) * 8, 10  # the first frames compile (or load) what the window runs: not timed
    timings: dict[str, list[float]] = {}
    try:
        run_window(sim, frames=warm + frames, show=False, timings=timings, steady=False)  # the scene's substeps
        timings = {part: seconds[warm:] for part, seconds in timings.items()}
        window = "hidden GGUI window"
    except SandboxError as exc:
        window = f"no window ({exc}): the window's parts in a plain loop"
        timings = {part: [] for part in (*FRAME_PARTS, "frame")}
        renderer = Renderer(sim.model, sim.state, 1280, 720, sim.scene.render)
        for k in range(frames):
            ti.sync()
            t0 = time.perf_counter()
            renderer.begin_frame()
            sim.advance_frame(midway=renderer.mid_frame)
            ti.sync()
            t1 = time.perf_counter()
            renderer.record(sim.stats(pair_energy=k % 10 == 0))
            t2 = time.perf_counter()
            renderer.render()
            ti.sync()
            t3 = time.perf_counter()
            for part, seconds in zip(FRAME_PARTS, (0.0, t1 - t0, t2 - t1, t3 - t2, 0.0)):
                timings[part].append(seconds)
            timings["frame"].append(t3 - t0)
    ms = {part: statistics.median(timings[part]) * 1e3 for part in FRAME_PARTS}
    frame_ms = statistics.median(timings["frame"]) * 1e3
    return {
        "particles": sim.model.built.count,
        "substeps": sim.scene.world.substeps,
        "window": window,
        "ms": ms,
        "frame_ms": frame_ms,
        "slowest_frame_ms": max(timings["frame"]) * 1e3,
        "fps": 1e3 / frame_ms,
        "window_overhead": 1.0 - ms["simulation"] / sum(ms.values()),
    }


def window_rates(arch: str, frames: int = 120, warm: int = 20) -> list[dict]:
    """Every shipped scene in a hidden window with pacing on: the median frame rate over `frames` frames after
    `warm` (compiling), the median substeps run and the wanted ones, and the simulated seconds per wall second."""

    rows = []
    for path in sorted(SCENES.glob("*.toml")):
        runtime.reset()
        sim = Simulation(load_scene(path), arch=arch)
        timings: dict[str, list[float]] = {}
        run_window(sim, frames=warm + frames, show=False, timings=timings)
        frame = statistics.median(timings["frame"][warm:])
        substeps = statistics.median(timings["substeps"][warm:])
        rows.append(
            {
                "scene": path.stem,
                "particles": int(sim.particles.n[None]),
                "fps": 1.0 / frame,
                "slowest_frame_ms": 1e3 * max(timings["frame"][warm:]),
                "substeps": substeps,
                "wanted_substeps": timings["wanted_substeps"][-1],
                "sim_seconds_per_second": substeps * sim.dt / frame,
            }
        )
    return rows


def print_window_rates(rows: list[dict]) -> None:
    print(f"{'scene':18s} {'particles':>9s} {'fps':>6s} {'slowest ms':>10s} {'substeps':>13s} {'sim s per s':>11s}")
    for r in rows:
        steps = f"{r['substeps']:g} of {r['wanted_substeps']:g}"
        print(
            f"{r['scene']:18s} {r['particles']:9d} {r['fps']:6.1f} {r['slowest_frame_ms']:10.1f} {steps:>13s} "
            f"{r['sim_seconds_per_second']:11.3g}"
        )

"""`sandbox bench --worlds K SCENE`: K worlds of a scene in one simulation against K simulations of it stepped in
turn in one process (what a classroom host does with K tabs), side by side in one command.

Each way is timed over the same frames (the scene's substeps each) after a warm-up frame that compiles: the batch
steps all its worlds a frame at a time, the separate runs each a frame in turn. Reported per way: the time to build
and compile (construction to the first frame done), particle-steps a second in total and per world, the field
memory (Simulation.memory_bytes) and the process's resident memory grown while it was built and run; and the ratios.
"""

from __future__ import annotations

import resource
import statistics
import time

import taichi as ti

from ..api import load


def _resident_mb() -> float:
    """The process's peak resident memory so far (MB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _timed_frames(step_frame, frames: int, repeats: int) -> list[float]:
    """Wall seconds of `repeats` runs of `frames` calls of step_frame(), synchronised with the device."""
    times = []
    for _ in range(repeats):
        ti.sync()
        start = time.perf_counter()
        for _ in range(frames):
            step_frame()
        ti.sync()
        times.append(time.perf_counter() - start)
    return times


def _way(sims_or_batch, frames: int, repeats: int, built: float) -> dict:
    """The figures of one way (a list of simulations stepped in turn, or one simulation of worlds); its
    particle-steps are counted by _count_steps."""
    sims = sims_or_batch if isinstance(sims_or_batch, list) else [sims_or_batch]

    def frame() -> None:
        for sim in sims:
            sim.advance_frame()

    times = _timed_frames(frame, frames, repeats)
    seconds = statistics.median(times)
    return {
        "ready_seconds": built,
        "frames_per_second_each": frames / seconds,
        "field_mb": sum(sum(sim.memory_bytes().values()) for sim in sims) / 2**20,
        "spread": (max(times) - min(times)) / seconds,
    }


def bench_worlds(worlds: int, scene: str, frames: int = 30, repeats: int = 3) -> dict:
    """K = `worlds` worlds of shipped scene `scene` in one simulation, then K separate simulations of it in this
    process (module docstring)."""
    start_mb = _resident_mb()
    start = time.perf_counter()
    batch = load(scene, worlds=worlds)
    batch.advance_frame()
    ti.sync()
    batch_ready = time.perf_counter() - start
    steps = batch.frame_substeps()[0]
    result = {"scene": scene, "worlds": worlds, "steps_per_frame": steps}
    result["batched"] = _way(batch, frames, repeats, batch_ready)
    result["batched"]["resident_mb_grown"] = _resident_mb() - start_mb
    # world 0's live particles now (a scene with emitters has as many as its timeline gives it at this frame)
    result["particles_per_world"] = particles = batch.state.particles.block(0)[1]
    del batch
    middle_mb = _resident_mb()
    start = time.perf_counter()
    sims = []
    for _ in range(worlds):
        sim = load(scene)
        sim.advance_frame()
        sims.append(sim)
    ti.sync()
    result["separate"] = _way(sims, frames, repeats, time.perf_counter() - start)
    result["separate"]["resident_mb_grown"] = _resident_mb() - middle_mb
    b, s = result["batched"], result["separate"]
    for way in (b, s):  # both ways step the same timeline: the same particles a world at each frame
        way["per_world"] = particles * steps * way["frames_per_second_each"]
        way["particle_steps_per_second"] = worlds * way["per_world"]
    result["speedup"] = b["frames_per_second_each"] / s["frames_per_second_each"]
    result["ready_ratio"] = s["ready_seconds"] / b["ready_seconds"]
    return result


def report(result: dict) -> str:
    """The benchmark's figures as a small table."""
    lines = [
        f"{result['worlds']} worlds of {result['scene']} ({result['particles_per_world']:,} particles, "
        f"{result['steps_per_frame']} steps a frame each)",
        f"{'':<10} {'ready s':>8} {'M p-steps/s':>12} {'per world':>10} {'frames/s':>9} {'fields MB':>10} "
        f"{'RSS+ MB':>8}",
    ]
    for way in ("batched", "separate"):
        r = result[way]
        lines.append(
            f"{way:<10} {r['ready_seconds']:>8.1f} {r['particle_steps_per_second'] / 1e6:>12.2f} "
            f"{r['per_world'] / 1e6:>10.3f} {r['frames_per_second_each']:>9.1f} {r['field_mb']:>10.1f} "
            f"{r['resident_mb_grown']:>8.0f}"
        )
    lines.append(
        f"batched / separate: {result['speedup']:.2f}x the particle-steps a second; ready {result['ready_ratio']:.1f}x "
        "sooner"
    )
    return "\n".join(lines)

"""The smoke projection two ways at several grid sizes (the figures behind physics/smoke.py's ONE_LAUNCH_CELLS):
in one launch on one thread, and CG driven from the host (three launches and three sums read back per iteration).

    python benchmarks/smoke_projection.py [--resolutions 64 128 256 400] [--rounds 3] [--frames 10]

Builds scenes/smoke_vortex.toml with `smoke.resolution=N`, runs 10 frames to warm up, then times `--frames` frames;
the two ways alternate, `--rounds` times each. Prints milliseconds a frame (3 steps) for each round.
"""

import argparse
import time

import taichi as ti
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

import sandbox.physics.smoke as smoke
from sandbox.config.scene import load_scene
from sandbox.core import runtime
from sandbox.research.bench import SCENES
from sandbox.simulation import Simulation


def frame_ms(resolution: int, one_launch: bool, frames: int) -> float:
    runtime.reset()
    smoke.ONE_LAUNCH_CELLS = 10**12 if one_launch else 0
    sim = Simulation(load_scene(SCENES / "smoke_vortex.toml", [f"smoke.resolution={resolution}"]))
    for _ in range(10):
        sim.advance_frame()
    ti.sync()
    t0 = time.perf_counter()
    for _ in range(frames):
        sim.advance_frame()
    ti.sync()
    return (time.perf_counter() - t0) / frames * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--resolutions", type=int, nargs="+", default=[64, 128, 256, 400])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--frames", type=int, default=10)
    args = parser.parse_args()
    for resolution in args.resolutions:
        times = {True: [], False: []}
        for _ in range(args.rounds):
            for one_launch in (True, False):
                times[one_launch].append(frame_ms(resolution, one_launch, args.frames))
        print(
            f"resolution {resolution}: one launch {', '.join(f'{t:.1f}' for t in times[True])} ms a frame; "
            f"CG from the host {', '.join(f'{t:.1f}' for t in times[False])}",
            flush=True,
        )


if __name__ == "__main__":
    main()

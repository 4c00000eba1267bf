"""Frames of a scene that take long, and when its neighbour lists widen (the stalls behind physics/neighbours.py's
choice of an ndarray for the lists).

    python benchmarks/slow_frames.py [--scene candle] [--frames 60] [--slow-ms 100]

Prints every frame slower than `--slow-ms` (the first frames compile) and every frame in which the lists widened,
with the list width and the particle count.
"""

import argparse
import time

import taichi as ti
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.config.scene import load_scene
from sandbox.research.bench import SCENES
from sandbox.simulation import Simulation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scene", default="candle")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--slow-ms", type=float, default=100.0)
    args = parser.parse_args()
    sim = Simulation(load_scene(SCENES / f"{args.scene}.toml"))
    lists = sim.neighbours
    if lists is None:
        raise SystemExit(f"{args.scene} keeps no neighbour lists")
    print(f"{args.scene}: lists {lists.width} wide, {sim.capacity} particle slots")
    grown = lists.grown
    for frame in range(args.frames):
        t0 = time.perf_counter()
        sim.advance_frame()
        ti.sync()
        ms = (time.perf_counter() - t0) * 1e3
        if lists.grown != grown or ms > args.slow_ms:
            widened = " (lists widened)" if lists.grown != grown else ""
            count = int(sim.particles.n[None])
            print(f"frame {frame}: {ms:.0f} ms, lists {lists.width} wide, {count} particles{widened}")
            grown = lists.grown


if __name__ == "__main__":
    main()

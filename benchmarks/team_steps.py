"""W1 (the periodic 2D LJ box) or the melting block (springs, heat, a hot plate) stepped three ways in one process,
batches alternating: as a team of threads (sandbox/step/team.py), many steps to a launch on one thread
(Simulation._fused_steps), and one launch per pass with parallel loops (the long way).

    python benchmarks/team_steps.py [--scene lj_box|melting_block] [--side 100] [--rounds 10] [--steps 100]

`--side`: particles per row (100: 10,000 particles). Prints the median and minimum microseconds per step of each
way. All three share the parallel storage layout (a buffer row per chunk of particles), so their trajectories are
the same bit for bit; the shipped single-thread path for small scenes keeps one buffer row and is a little faster
than the "one thread" figure here.
"""

import argparse
import statistics
import time

import taichi as ti
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.config.scene import load_scene
from sandbox.research.bench import SCENES, lj_box_sim, melting_block_of
from sandbox.simulation import Simulation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", choices=("lj_box", "melting_block"), default="lj_box")
    parser.add_argument("--side", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args()

    def build() -> Simulation:
        if args.scene == "lj_box":
            return lj_box_sim(args.side, "cpu")
        return Simulation(load_scene(SCENES / "melting_block.toml", melting_block_of(args.side)))

    ways = {name: build() for name in ("team", "one thread", "long way")}
    if ways["team"].plan.team is None:
        raise SystemExit("this size does not step as a team here (see sandbox/core/loops.py TEAM_FROM, threads >= 2)")
    ways["one thread"].plan.use_team(None)  # the same fused batches on the calling thread
    ways["long way"].plan.fuses = False
    times: dict[str, list[float]] = {name: [] for name in ways}
    for sim in ways.values():
        sim.step(args.steps)  # compile, and the first list builds
    for _ in range(args.rounds):
        for name, sim in ways.items():
            ti.sync()
            t0 = time.perf_counter()
            sim.step(args.steps)
            ti.sync()
            times[name].append((time.perf_counter() - t0) / args.steps * 1e6)
    n = ways["team"].model.built.count
    for name, ts in times.items():
        print(f"{name:>10}: median {statistics.median(ts):7.0f} us/step, min {min(ts):7.0f} ({n} particles)")


if __name__ == "__main__":
    main()

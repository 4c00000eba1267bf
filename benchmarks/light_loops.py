"""W1 3D on the CPU with the light loops' threshold as shipped (`new`) or as measured on 2 cores alone (`old`:
400,000 slots whatever the threads): `python benchmarks/light_loops.py new|old` prints the particle-steps per second
by size, medians of three runs of 40 steps (docs/performance.md, "Per CPU"). Run each in its own process."""

import statistics
import sys
import time

import taichi as ti

from sandbox.core import loops
from sandbox.research import bench

SIDES = (32, 48, 64, 80, 100)


def main(which: str) -> None:
    if which == "old":
        loops.light_parallel_from = lambda threads: loops.LIGHT_PARALLEL_FROM
    for side in SIDES:
        sim = bench.lj_box_3d_sim(side, "cpu")
        sim.step(10)
        ti.sync()
        rates = []
        for _ in range(3):
            start = time.perf_counter()
            sim.step(40)
            ti.sync()
            rates.append(side**3 * 40 / (time.perf_counter() - start))
        serial = sim.model.loops.serial_light
        print(f"{which} {side**3:9,d} atoms  {statistics.median(rates) / 1e6:6.2f} M/s  light loops serial: {serial}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "new")

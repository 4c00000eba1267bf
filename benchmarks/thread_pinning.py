"""Taichi's CPU worker threads free or pinned one per core: the time of one parallel loop over 10,000 items.

    python benchmarks/thread_pinning.py

Prints min, median and 90th percentile of 400 launches, alternating free and pinned three times in one process
(sandbox/threads.py pins them when a Simulation starts Taichi).
"""

import os
import time

import taichi as ti
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.core import threads

ti.init(arch=ti.cpu, log_level=ti.ERROR)
N = 10_000
x = ti.field(ti.f32, N)
y = ti.field(ti.f32, N)


@ti.kernel
def work(rounds: ti.i32):
    for i in range(N):
        s = x[i]
        for _ in range(rounds):
            s = ti.sin(s) + 0.5
        y[i] = s


def timings(label: str) -> None:
    work(8)
    ts = sorted(_timed() for _ in range(400))
    print(f"{label}: min {ts[0]:6.0f} us, median {ts[200]:6.0f} us, p90 {ts[360]:6.0f} us")


def _timed() -> float:
    t0 = time.perf_counter()
    work(8)
    return (time.perf_counter() - t0) * 1e6


if __name__ == "__main__":
    workers = threads.pin_workers(int(ti.cfg.cpu_max_num_threads))
    if not workers:
        raise SystemExit("no workers pinned (one core, not Linux, or SANDBOX_PIN_THREADS=0)")
    every_core = set(os.sched_getaffinity(0))
    for _ in range(3):
        for tid, _core in workers:
            os.sched_setaffinity(tid, every_core)
        timings("free  ")
        for tid, core in workers:
            os.sched_setaffinity(tid, {core})
        timings("pinned")

"""How much a parallel loop costs over a serialized one on Taichi's CPU backend (the figures behind sandbox/loops.py).

Run: `python benchmarks/loop_overhead.py [--threads N]`. Prints microseconds per kernel call (median of 7 batches of
500 calls) for a kernel of three loops of `x[i] += 1`, parallel and serialized, at several loop lengths, and an empty
kernel. `--threads 1`: Taichi on one CPU worker, as a classroom host runs (its pool still hands each parallel loop to
that worker: taichi_compat.serialize_loops_on_one_thread).
"""

import argparse
import statistics
import time

import taichi as ti

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--threads", type=int, default=None, help="Taichi's CPU worker threads (default: its own)")
ARGS = parser.parse_args()
ti.init(arch=ti.cpu, log_level=ti.WARN, **({"cpu_max_num_threads": ARGS.threads} if ARGS.threads else {}))
x = ti.field(ti.f32, shape=100_000)


@ti.kernel
def three_parallel(m: ti.i32):
    for i in range(m):
        x[i] += 1.0
    for i in range(m):
        x[i] += 1.0
    for i in range(m):
        x[i] += 1.0


@ti.kernel
def three_serial(m: ti.i32):
    ti.loop_config(serialize=True)
    for i in range(m):
        x[i] += 1.0
    ti.loop_config(serialize=True)
    for i in range(m):
        x[i] += 1.0
    ti.loop_config(serialize=True)
    for i in range(m):
        x[i] += 1.0


@ti.kernel
def empty():
    pass


def per_call_us(call, calls: int = 500, batches: int = 7) -> float:
    """Median over `batches` of the mean wall time of one call, in microseconds."""
    call()
    ti.sync()
    times = []
    for _ in range(batches):
        start = time.perf_counter()
        for _ in range(calls):
            call()
        ti.sync()
        times.append((time.perf_counter() - start) / calls * 1e6)
    return statistics.median(times)


def main() -> None:
    print(f"Taichi's CPU worker threads: {ti.cfg.cpu_max_num_threads}")
    print(f"{'items':>8} {'3 parallel loops':>18} {'3 serial loops':>16}")
    for m in (100, 1_000, 10_000, 100_000):
        parallel = per_call_us(lambda m=m: three_parallel(m))
        serial = per_call_us(lambda m=m: three_serial(m))
        print(f"{m:>8} {parallel:>15.1f} us {serial:>13.1f} us")
    print(f"empty kernel: {per_call_us(empty):.1f} us")


if __name__ == "__main__":
    main()

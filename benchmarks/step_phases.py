"""Where a W1 step's time goes: the LAMMPS comparison's workloads (2D W1 at 100,489 particles, W1-3D at 32,768)
timed whole and a phase at a time, each phase in a launch of its own over the same state.

    python benchmarks/step_phases.py [--3d] [--repeats 7]

Prints milliseconds (medians of `--repeats` batches): the whole step (velocity Verlet, as the bench runs it), the
half-list pair pass alone, the per-particle pass (the chunks' rows summed, with no update), a list build (the grid's
counting sort and the fill) and how many steps a list lasts, so a build's share of a step is build / steps per build.
The phases in launches of their own use the thread pool where the step runs them as a team, so their sum is a
little above the whole step.
"""

import argparse
import statistics
import time

import taichi as ti
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.core import runtime
from sandbox.core.loops import SPREAD_STRIDE, spread_item
from sandbox.research.bench import lj_box_3d_sim, lj_box_sim
from sandbox.simulation import timed_steps


def median_ms(run, repeats: int, calls: int = 20) -> float:
    """Milliseconds a call of `run` takes: the median of `repeats` batches of `calls` calls, after one unmeasured
    call (its compile), synchronised with the device."""
    run()
    ti.sync()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            run()
        ti.sync()
        times.append((time.perf_counter() - start) / calls)
    return 1e3 * statistics.median(times)


def whole_step(sim, repeats: int) -> tuple[float, float]:
    """(milliseconds a velocity Verlet step of `sim` takes, the median of `repeats` batches of 100 steps; steps per
    list build over them), after 50 steps unmeasured; the lists are left freshly built."""
    sim.set_integrator("velocity_verlet")
    lists = sim.hood.lists
    timed_steps(sim, 50)
    builds = lists.builds
    step = 1e3 * statistics.median(timed_steps(sim, 100) / 100 for _ in range(repeats))
    steps_per_build = 100 * repeats / max(lists.builds - builds, 1)
    lists.ensure_fresh(True)
    return step, steps_per_build


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--3d", dest="three_d", action="store_true", help="W1-3D (32,768) instead of W1 (100,489)")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    runtime.own_process()
    sim = lj_box_3d_sim(32, "cpu") if args.three_d else lj_box_sim(317, "cpu")
    step, steps_per_build = whole_step(sim, args.repeats)
    rates, lists = sim.rates, sim.hood.lists
    ids = lists.flat

    @ti.kernel
    def pair_pass(ids: ti.types.ndarray(dtype=ti.i32, ndim=1)):
        n = rates.state.particles.n[None]
        for u in range(rates.n_chunks * SPREAD_STRIDE):
            t = spread_item(u)
            if t >= 0:
                rates.half_rows_of_chunk(t, n, ids)

    @ti.kernel
    def particle_pass(ids: ti.types.ndarray(dtype=ti.i32, ndim=1)):
        for k in range(rates.state.particles.n[None]):
            rates.gather_particle(rates.hood.grid.sorted_ids[k], True, ids, None, 0.0, 0, False)

    print(f"{sim.model.built.count:,} particles, {sim.model.dim}D; milliseconds:")
    print(f"  whole step          {step:7.3f}")
    print(f"  pair pass           {median_ms(lambda: pair_pass(ids), args.repeats):7.3f}")
    print(f"  per-particle pass   {median_ms(lambda: particle_pass(ids), args.repeats):7.3f}")
    build = median_ms(lambda: lists._sort_and_fill(ids), args.repeats, calls=5)
    print(
        f"  list build          {build:7.3f}  every {steps_per_build:.1f} steps: {build / steps_per_build:.3f} a step"
    )


if __name__ == "__main__":
    main()

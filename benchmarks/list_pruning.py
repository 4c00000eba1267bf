"""Would pruning the neighbour lists pay (GROMACS's dynamic pruning, issue 77)? Over one state of W1-3D (or W1 in 2D):
the rates of a step (the pair pass and the per-particle gather) read from the lists as built (cutoff + skin 0.3),
a prune of those lists to the cutoff plus a smaller buffer, and the rates read from the pruned lists.

    python benchmarks/list_pruning.py [--arch cpu|cuda] [--side 32] [--2d] [--repeats 7]

Prints milliseconds (medians of `--repeats` batches of 20 launches) and the entries each list holds. A prune pays
when it costs less than the passes it makes cheaper: (pass - pruned pass) x the steps between prunes. Then, stepping
on from that state, how long a list pruned to each buffer lasts: exactly (until some particle has moved half the
buffer: no pair can be missing before), and, with SciPy, how many pairs within the cutoff it misses after so many
steps (a list kept past its exact life, as GROMACS's statistical buffer and LAMMPS's unchecked in.lj policy keep it).
"""

import argparse

import numpy as np
import taichi as ti
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)
from step_phases import median_ms, whole_step

from sandbox.core import runtime
from sandbox.research.bench import lj_box_3d_sim, lj_box_sim

BUFFERS = (0.2, 0.1, 0.05)
LIFE_STEPS = (2, 4, 6, 10, 20)  # steps after the prune at which the missed pairs are counted


def _pairs_within(x: np.ndarray, box: np.ndarray, r: float) -> set:
    """The pairs (i < j) of positions x (N, D) in a periodic box of sides `box` closer than r (SciPy's cKDTree)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(np.mod(x, box), boxsize=box)
    return set(map(tuple, tree.query_pairs(r, output_type="ndarray")))


def _lifetimes(sim, reach: float, live: int, buffers: tuple) -> None:
    """Step on one step at a time and print, for each of `buffers`, the steps a list pruned now stays exact, and
    (with SciPy) the pairs within `reach` it misses after LIFE_STEPS steps, of all pairs then within reach (the
    lists' own skin among the buffers: what a list built now and kept unchecked, as in.lj keeps it, misses)."""
    x = sim.rates.state.particles.x
    box = np.array([sim.rates.domain.box[a] for a in range(sim.model.dim)])
    x0 = x.to_numpy()[:live].astype(np.float64)
    try:
        listed = {b: _pairs_within(x0, box, reach + b) for b in buffers}
    except ImportError:
        listed = None
    exact = {b: None for b in buffers}
    missed = {b: [] for b in buffers}
    for step in range(1, max(LIFE_STEPS) + 1):
        sim.step(1)
        xs = x.to_numpy()[:live].astype(np.float64)
        d = xs - x0
        d -= box * np.round(d / box)
        moved = float(np.sqrt((d * d).sum(axis=1)).max())
        for b in buffers:
            if exact[b] is None and moved > 0.5 * b:
                exact[b] = step - 1
        if listed is not None and step in LIFE_STEPS:
            near = _pairs_within(xs, box, reach)
            for b in buffers:
                missed[b].append(f"{len(near - listed[b])}/{len(near):,}")
    for b in buffers:
        life = f"exact for {exact[b]} steps" if exact[b] is not None else f"exact past {max(LIFE_STEPS)} steps"
        counts = ", ".join(f"{s}: {m}" for s, m in zip(LIFE_STEPS, missed[b])) if listed is not None else "no SciPy"
        print(f"  buffer {b:<4g} {life}; pairs missed after so many steps {counts}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arch", default="cpu")
    parser.add_argument("--side", type=int, default=None, help="particles a side (3D: 32, 64, 100; 2D: 317)")
    parser.add_argument("--2d", dest="two_d", action="store_true", help="W1 in 2D instead of W1-3D")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--no-life", dest="life", action="store_false", help="skip the lifetimes (slow past 200k)")
    args = parser.parse_args()
    runtime.own_process()
    side = args.side or (317 if args.two_d else 32)
    sim = lj_box_sim(side, args.arch) if args.two_d else lj_box_3d_sim(side, args.arch)
    step, steps_per_build = whole_step(sim, args.repeats)
    rates, lists = sim.rates, sim.hood.lists
    ids = lists.flat
    capacity = lists.capacity
    pruned = runtime.ndarray(ti.i32, (capacity * lists.width,))
    pruned_count = ti.field(ti.i32, shape=capacity)
    x, domain, n = rates.state.particles.x, rates.domain, rates.state.particles.n

    @ti.kernel
    def prune(src: ti.types.ndarray(dtype=ti.i32, ndim=1), dst: ti.types.ndarray(dtype=ti.i32, ndim=1), r2: float):
        width = src.shape[0] // capacity
        for i in range(n[None]):
            xi = x[i]
            row = i * width
            c = 0
            for k in range(lists.count[i]):  # branch-free, as the list build: every entry written, kept if near
                j = src[row + k]
                d = domain.separation(xi, x[j])
                dst[row + c] = j
                c += ti.cast(d.dot(d) < r2, ti.i32)
            pruned_count[i] = c

    built = lists.count.to_numpy()
    live = int(n[None])
    print(f"{live:,} particles, {sim.model.dim}D, {args.arch}, {'half' if sim.hood.half else 'full'} lists; ms")
    build = median_ms(lambda: lists._sort_and_fill(ids), args.repeats)
    built_every = f"a list build {build:.3f}, every {steps_per_build:.1f} steps"
    print(f"  whole step (velocity Verlet)                {step:7.3f}  {built_every}")
    whole = median_ms(lambda: rates._rates(True, ids), args.repeats)
    print(f"  rates over the lists as built (buffer {lists.skin:g})  {whole:7.3f}  entries {built[:live].sum():,}")
    for buffer in BUFFERS:
        r2 = (lists.reach + buffer) ** 2
        cost = median_ms(lambda r2=r2: prune(ids, pruned, r2), args.repeats)
        prune(ids, pruned, r2)
        kept = pruned_count.to_numpy()
        lists.count.from_numpy(kept)
        rates_pruned = median_ms(lambda: rates._rates(True, pruned), args.repeats)
        lists.count.from_numpy(built)
        saved = whole - rates_pruned
        pays = f"pays if it lasts {cost / saved:.1f} steps" if saved > 0 else "never pays"
        entries = f"entries {kept[:live].sum():,}"
        print(f"  buffer {buffer:<4g} prune {cost:7.3f}, rates {rates_pruned:7.3f}, {entries}: {pays}")
    if args.life:
        _lifetimes(sim, lists.reach, live, (lists.skin, *BUFFERS))


if __name__ == "__main__":
    main()

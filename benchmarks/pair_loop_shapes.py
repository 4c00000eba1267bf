"""What bounds the pair loop on this CPU: the bench's ideal 2D pair loop (sandbox/research/peer_bench.py) timed as it
is, with a part taken out, and against two other loop shapes that could use the vector units.

    python benchmarks/pair_loop_shapes.py [--rounds 3] [--c]

Prints M pairs within the cutoff per second (each pair once; 32,768 particles at density 0.8, cutoff 2.5), the
medians of `--rounds` alternating rounds of about a second each, on the threads the sandbox would use:

- ideal: the half-list loop as the bench times it (a force row per chunk of particles, the other particle's share
  scattered into it);
- no division: 1/r^2 replaced by a product (wrong forces; what the one division a pair costs);
- no scatter: the other particle's share not written (wrong forces; what the half list's scatter costs);
- clusters 4x4: GROMACS's layout, particles in clusters of 4 (strips sorted along x), each pair of clusters within
  reach evaluated whole with the i-cluster as a 4-wide vector (the compiler vectorizes it), masked to the cutoff;
- ranges: storage in cell order and each particle's half neighbourhood as two contiguous ranges of it (no list of
  ids, no gathers), every candidate evaluated and masked.

The last two are checked against the ideal loop's forces first. `--c` also times the ideal loop written in C
(compiled with `cc -O3 -march=native -ffast-math`, one thread) beside the same loop as a serial Taichi kernel: the
compiler's share of the difference. Measured figures: docs/performance.md, "Per CPU".
"""

import argparse
import math
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import taichi as ti
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.core import runtime, taichi_compat
from sandbox.core.loops import SPREAD_STRIDE, spread_item
from sandbox.research import peer_bench

N, CLUSTER, CELL_DIVISIONS = 32768, 4, 3  # particles; cluster size; cells per reach along y (as the sandbox's grid)


def _rate(pairs: int, run, seconds: float = 1.0) -> float:
    """M pairs per second of `run()` (each call evaluates `pairs` pairs), over about `seconds`."""
    run()
    ti.sync()
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        run()
        calls += 1
    ti.sync()
    return pairs * calls / (time.perf_counter() - start) / 1e6


def _cluster_pairs(x: np.ndarray, cutoff: float, density: float):
    """(storage order, cluster pair starts, partner clusters): clusters of CLUSTER particles, strips about 2 particles
    wide sorted along x; pairs of clusters (J >= I) whose bounding boxes come within the cutoff, sorted by I."""
    strip = np.floor((x[:, 1] - x[:, 1].min()) / math.sqrt(CLUSTER / density)).astype(int)
    order = np.lexsort((x[:, 0], strip))
    boxes = x[order].reshape(-1, CLUSTER, 2)
    lo, hi = boxes.min(1), boxes.max(1)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    reach = cutoff + 2 * float(np.linalg.norm(half, axis=1).max())
    i, j = peer_bench._pairs_within(centre, reach)
    own = np.arange(len(centre))
    i, j = np.concatenate([i, own]), np.concatenate([j, own])
    gap = np.maximum(0.0, np.abs(centre[i] - centre[j]) - half[i] - half[j])
    keep = (gap**2).sum(1) < cutoff * cutoff
    i, j = i[keep], j[keep]
    by_i = np.lexsort((j, i))
    i, j = i[by_i], j[by_i]
    return order, np.searchsorted(i, np.arange(len(centre) + 1)).astype(np.int32), j.astype(np.int32)


def _ranges(x: np.ndarray, cutoff: float):
    """(storage order, ranges (N, 4)): cell order over columns a cutoff wide (cells a third of it along y); each
    particle's own column from the place after it and the next column, as [start, end) pairs of places."""
    lo, extent = x.min(0), np.ptp(x, 0)
    columns = max(1, int(extent[0] // cutoff))
    rows = max(1, int(extent[1] // (cutoff / CELL_DIVISIONS)))
    col = np.minimum(((x[:, 0] - lo[0]) / extent[0] * columns).astype(int), columns - 1)
    row = np.minimum(((x[:, 1] - lo[1]) / extent[1] * rows).astype(int), rows - 1)
    key = col * rows + row
    order = np.argsort(key, kind="stable")
    key, col, row = key[order], col[order], row[order]
    cell_start = np.searchsorted(key, np.arange(columns * rows + 1))
    top = np.minimum(row + CELL_DIVISIONS, rows - 1) + 1
    bottom = np.maximum(row - CELL_DIVISIONS, 0)
    ahead = col + 1 < columns
    nxt = np.minimum(col + 1, columns - 1) * rows
    ranges = np.zeros((len(x), 4), np.int32)
    ranges[:, 0] = np.arange(len(x)) + 1
    ranges[:, 1] = cell_start[col * rows + top]
    ranges[:, 2] = np.where(ahead, cell_start[nxt + bottom], 0)
    ranges[:, 3] = np.where(ahead, cell_start[nxt + top], 0)
    return order, ranges


@ti.data_oriented
class Shapes:
    """The loop shapes over one configuration of N particles (see the module docstring)."""

    def __init__(self, threads: int):
        s = peer_bench.SETTINGS[2]
        self.cutoff = s["cutoff"]
        self.ideal = peer_bench._IdealLoop(2, N, s["density"], self.cutoff, threads=threads)
        self.pairs = self.ideal.pairs
        self.chunks = self.ideal.chunks
        x = self.ideal.x.to_numpy().astype(np.float64)
        self.c_order, c_start, c_partner = _cluster_pairs(x, self.cutoff, s["density"])
        self.cluster_evaluations = len(c_partner) * CLUSTER * CLUSTER
        self.r_order, ranges = _ranges(x, self.cutoff)
        self.range_candidates = int((ranges[:, 1] - ranges[:, 0]).sum() + (ranges[:, 3] - ranges[:, 2]).sum())
        self.cx, self.cy, self.rx, self.ry = (ti.field(ti.f32, shape=N) for _ in range(4))
        self.fx, self.fy = (ti.field(ti.f32, shape=(self.chunks, N)) for _ in range(2))
        self.c_start = ti.field(ti.i32, shape=len(c_start))
        self.c_partner = ti.field(ti.i32, shape=len(c_partner))
        self.ranges = ti.field(ti.i32, shape=ranges.shape)
        for field, values in (
            (self.cx, x[self.c_order, 0]),
            (self.cy, x[self.c_order, 1]),
            (self.rx, x[self.r_order, 0]),
            (self.ry, x[self.r_order, 1]),
        ):
            field.from_numpy(values.astype(np.float32))
        self.c_start.from_numpy(c_start)
        self.c_partner.from_numpy(c_partner)
        self.ranges.from_numpy(ranges)

    @ti.func
    def _law(self, inv2):
        inv6 = inv2 * inv2 * inv2
        return 24.0 * inv2 * inv6 * (2.0 * inv6 - 1.0)

    @ti.kernel
    def ideal_without(self, division: ti.template(), scatter: ti.template()):
        """The ideal loop with the division or the scatter taken out (wrong forces: a cost, not a result)."""
        loop = self.ideal
        n = loop.x.shape[0]
        for u in range(self.chunks * SPREAD_STRIDE):
            t = spread_item(u)
            if t >= 0:
                for a in range(t * n // self.chunks, (t + 1) * n // self.chunks):
                    xa = loop.x[a]
                    fa = ti.Vector.zero(ti.f32, 2)
                    for k in range(loop.start[a], loop.start[a + 1]):
                        b = loop.neighbour[k]
                        d = xa - loop.x[b]
                        r2 = d.dot(d)
                        inv2 = 1.0 / r2 if ti.static(division) else 0.1 * r2  # without: a product in its place
                        fab = self._law(inv2) * d
                        fa += fab
                        if ti.static(scatter):
                            loop.rows[t, b] = loop.rows[t, b] - fab
                    loop.rows[t, a] = loop.rows[t, a] + fa

    @ti.kernel
    def clusters(self):
        """Every listed pair of clusters whole, the i-cluster as a CLUSTER-wide vector; forces into fx, fy."""
        cutoff2 = self.cutoff**2
        clusters = N // CLUSTER
        for u in range(self.chunks * SPREAD_STRIDE):
            t = spread_item(u)
            if t >= 0:
                for ci in range(t * clusters // self.chunks, (t + 1) * clusters // self.chunks):
                    xi = ti.Vector([self.cx[ci * CLUSTER + a] for a in ti.static(range(CLUSTER))])
                    yi = ti.Vector([self.cy[ci * CLUSTER + a] for a in ti.static(range(CLUSTER))])
                    fxi, fyi = ti.Vector.zero(ti.f32, CLUSTER), ti.Vector.zero(ti.f32, CLUSTER)
                    for k in range(self.c_start[ci], self.c_start[ci + 1]):
                        cj = self.c_partner[k]
                        for b in ti.static(range(CLUSTER)):
                            dx, dy = xi - self.cx[cj * CLUSTER + b], yi - self.cy[cj * CLUSTER + b]
                            r2 = dx * dx + dy * dy
                            inside = ti.Vector(
                                [(r2[a] < cutoff2) and (cj != ci or b > a) for a in ti.static(range(CLUSTER))]
                            )
                            g = ti.select(inside, self._law(1.0 / ti.select(inside, r2, 1.0)), 0.0)
                            fxi += g * dx
                            fyi += g * dy
                            self.fx[t, cj * CLUSTER + b] -= (g * dx).sum()
                            self.fy[t, cj * CLUSTER + b] -= (g * dy).sum()
                    for a in ti.static(range(CLUSTER)):
                        self.fx[t, ci * CLUSTER + a] += fxi[a]
                        self.fy[t, ci * CLUSTER + a] += fyi[a]

    @ti.func
    def _scan(self, t, xi, yi, start, end):
        cutoff2 = self.cutoff**2
        fx, fy = 0.0, 0.0
        for j in range(start, end):
            dx, dy = xi - self.rx[j], yi - self.ry[j]
            r2 = dx * dx + dy * dy
            inside = r2 < cutoff2
            g = ti.select(inside, self._law(1.0 / ti.select(inside, r2, 1.0)), 0.0)
            fx += g * dx
            fy += g * dy
            self.fx[t, j] -= g * dx
            self.fy[t, j] -= g * dy
        return fx, fy

    @ti.kernel
    def contiguous_ranges(self):
        """Each particle's two ranges of cell order, every candidate evaluated and masked; forces into fx, fy."""
        for u in range(self.chunks * SPREAD_STRIDE):
            t = spread_item(u)
            if t >= 0:
                for i in range(t * N // self.chunks, (t + 1) * N // self.chunks):
                    ax, ay = self._scan(t, self.rx[i], self.ry[i], self.ranges[i, 0], self.ranges[i, 1])
                    bx, by = self._scan(t, self.rx[i], self.ry[i], self.ranges[i, 2], self.ranges[i, 3])
                    self.fx[t, i] += ax + bx
                    self.fy[t, i] += ay + by

    def forces_of(self, kernel, order: np.ndarray) -> np.ndarray:
        """Forces (N, 2) in the ideal loop's particle order from one call of `kernel` (which writes fx, fy in the
        storage order `order`)."""
        self.fx.fill(0)
        self.fy.fill(0)
        kernel()
        f = np.zeros((N, 2))
        f[order] = np.stack([self.fx.to_numpy().sum(0), self.fy.to_numpy().sum(0)], 1)
        return f


_C_LOOP = r"""
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
int main(int argc, char **argv) {
  int n = atoi(argv[1]), pairs;
  float (*x)[2] = malloc(8L * n), (*rows)[2] = calloc(n, 8); int *start = malloc(4L * (n + 1)), *nb;
  FILE *f = fopen(argv[2], "rb"); fread(x, 8, n, f); fread(start, 4, n + 1, f); pairs = start[n];
  nb = malloc(4L * pairs); fread(nb, 4, pairs, f); fclose(f);
  double t0 = now(); long calls = 0;
  while (now() - t0 < 1.0) {
    for (int a = 0; a < n; a++) {
      float xa = x[a][0], ya = x[a][1], fx = 0, fy = 0;
      for (int k = start[a]; k < start[a + 1]; k++) {
        int b = nb[k]; float dx = xa - x[b][0], dy = ya - x[b][1];
        float inv2 = 1.0f / (dx * dx + dy * dy), inv6 = inv2 * inv2 * inv2;
        float g = 24.0f * inv2 * inv6 * (2.0f * inv6 - 1.0f);
        fx += g * dx; fy += g * dy; rows[b][0] -= g * dx; rows[b][1] -= g * dy;
      }
      rows[a][0] += fx; rows[a][1] += fy;
    }
    calls++;
  }
  printf("%f\n", (double)pairs * calls / (now() - t0) / 1e6);
  return rows[0][0] == 12345.0f;
}
"""


def _c_and_serial(shapes: Shapes, rounds: int) -> tuple[list[float], list[float]] | None:
    """The ideal loop in C and as a serial Taichi kernel, one thread each, alternating: M pairs/s of each, or None
    without a C compiler."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return None
    loop = shapes.ideal

    @ti.kernel
    def serial():
        n = loop.x.shape[0]
        ti.loop_config(serialize=True)
        for a in range(n):
            xa = loop.x[a]
            fa = ti.Vector.zero(ti.f32, 2)
            for k in range(loop.start[a], loop.start[a + 1]):
                b = loop.neighbour[k]
                d = xa - loop.x[b]
                fab = shapes._law(1.0 / d.dot(d)) * d
                fa += fab
                loop.rows[0, b] = loop.rows[0, b] - fab
            loop.rows[0, a] = loop.rows[0, a] + fa

    folder = Path(tempfile.mkdtemp(prefix="pair-loop-"))
    (folder / "loop.c").write_text(_C_LOOP)
    binary = folder / "loop"
    subprocess.run([cc, "-O3", "-march=native", "-ffast-math", "-o", str(binary), str(folder / "loop.c")], check=True)
    with open(folder / "data.bin", "wb") as out:
        for array in (loop.x.to_numpy(), loop.start.to_numpy(), loop.neighbour.to_numpy()):
            out.write(np.ascontiguousarray(array).tobytes())
    in_c, in_taichi = [], []
    for _ in range(rounds):
        run = subprocess.run([str(binary), str(N), str(folder / "data.bin")], capture_output=True, text=True)
        in_c.append(float(run.stdout))
        in_taichi.append(_rate(shapes.pairs, serial))
    shutil.rmtree(folder)
    return in_c, in_taichi


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--c", action="store_true", help="also the loop in C against a serial Taichi kernel")
    args = parser.parse_args()
    runtime.own_process()
    runtime.init("cpu", "f32")
    shapes = Shapes(taichi_compat.cpu_threads())
    reference = shapes.ideal.force()
    scale = float(np.abs(reference).max())
    for name, kernel, order in (
        ("clusters 4x4", shapes.clusters, shapes.c_order),
        ("ranges", shapes.contiguous_ranges, shapes.r_order),
    ):
        error = float(np.abs(shapes.forces_of(kernel, order) - reference).max())
        if error > 1e-4 * scale:
            raise SystemExit(f"{name}: forces differ from the ideal loop's by {error:.3g} (largest force {scale:.3g})")
    runs = {
        "ideal": shapes.ideal.forces,
        "no division": lambda: shapes.ideal_without(False, True),
        "no scatter": lambda: shapes.ideal_without(True, False),
        "clusters 4x4": shapes.clusters,
        "ranges": shapes.contiguous_ranges,
    }
    rates: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(args.rounds):
        for name, run in runs.items():
            rates[name].append(_rate(shapes.pairs, run))
    print(
        f"{N:,} particles, 2D, {taichi_compat.cpu_threads()} threads; {shapes.pairs:,} pairs within the cutoff; "
        f"M pairs within the cutoff per second, medians of {args.rounds} rounds (all rounds):"
    )
    useful = {
        "clusters 4x4": f"{shapes.pairs / shapes.cluster_evaluations:.0%} of {shapes.cluster_evaluations:,} evaluated",
        "ranges": f"{shapes.pairs / shapes.range_candidates:.0%} of {shapes.range_candidates:,} evaluated",
    }
    for name, values in rates.items():
        extra = f"  ({useful[name]} within the cutoff)" if name in useful else ""
        print(f"  {name:14s} {statistics.median(values):6.0f}   {', '.join(f'{v:.0f}' for v in values)}{extra}")
    if args.c:
        measured = _c_and_serial(shapes, args.rounds)
        if measured is None:
            print("  no C compiler (cc or gcc) on PATH: the C comparison is skipped")
        else:
            in_c, in_taichi = measured
            print(
                f"  one thread: C (cc -O3 -march=native -ffast-math) {statistics.median(in_c):.0f} "
                f"({', '.join(f'{v:.0f}' for v in in_c)}), serial Taichi kernel {statistics.median(in_taichi):.0f} "
                f"({', '.join(f'{v:.0f}' for v in in_taichi)})"
            )


if __name__ == "__main__":
    main()

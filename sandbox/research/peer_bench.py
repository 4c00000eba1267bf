"""The comparison with LAMMPS made reproducible, and each rate read against what the cores allow.

- `lammps_input(dim)`: LAMMPS's standard Lennard-Jones liquid input, written by the bench itself (so an installed
  sandbox runs the comparison without the repository's benchmarks/ folder), with the settings printed beside it.
- `CpuHog`: another CPU-bound process on the machine, for `sandbox bench --contended`.
- `ideal_pair_rate()`: the micro-benchmark: Lennard-Jones pair interactions per second (each pair once) of an ideal
  loop (the sandbox's half-list pass at its best: only pairs within the cutoff, in cache, no periodic images, no
  rebuilds, no integration) on the same cores; and
  `pair_rate(sim, ...)`: the pair interactions per second a workload reaches, so each figure reads as a fraction
  of what the hardware allows.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import time
from pathlib import Path

import numpy as np
import taichi as ti

from ..core.loops import SPREAD_STRIDE, spread_item
from ..step.rates import CHUNKS_PER_THREAD


def lammps_configs(cores: int) -> tuple[tuple[str, int, int], ...]:
    """LAMMPS's configurations tried on `cores` cores, as (accelerator suffix, MPI processes, OpenMP threads): plain
    and `-sf opt` with a process per core, `-sf omp` as one process of `cores` threads and as a process per core (the
    duplicates dropped on one core). The bench runs each and compares the sandbox with the fastest."""
    configs = (("plain", cores, 1), ("opt", cores, 1), ("omp", 1, cores), ("omp", cores, 1))
    return tuple(dict.fromkeys(configs))


# neighbour-list policies: the sandbox's (checked every step, rebuilt at half the skin) and in.lj's own (rebuilt
# every 20 steps, unchecked: faster, and wrong for a particle that moves more than half the skin in 20 steps)
LAMMPS_POLICIES = {"strict": ("1", "yes"), "in.lj": ("20", "no")}

SETTINGS = {  # LAMMPS's bench/in.lj liquid, and its 2D twin (the W1 box); both sides use these
    2: {"density": 0.8, "temperature": 1.0, "cutoff": 2.5, "skin": 0.3, "dt": 0.005, "lattice": "sq2"},
    3: {"density": 0.8442, "temperature": 1.44, "cutoff": 2.5, "skin": 0.3, "dt": 0.005, "lattice": "sc"},
}

_HEAD = """# LAMMPS's standard Lennard-Jones liquid ({dim}D), written by `sandbox bench --lammps`: density {density},
# T {temperature}, cutoff {cutoff}, skin {skin} (neighbour list checked every step, rebuilt when a particle has
# moved half the skin), velocity Verlet (fix nve), dt {dt}.
# {run}
units           lj
atom_style      atomic
"""
_BODY = """mass            1 1.0
velocity        all create {temperature} 87287 loop geom
pair_style      lj/cut {cutoff}
pair_coeff      1 1 1.0 1.0 {cutoff}
neighbor        {skin} bin
variable        every index 1
variable        check index yes
neigh_modify    every ${{every}} delay 0 check ${{check}}
fix             1 all nve
{enforce}timestep        {dt}
thermo          500
run             100
run             ${{steps}}
"""
_LATTICE = {
    2: """dimension       2
boundary        p p p
variable        nx index 71
variable        ny index 71
variable        steps index 1000
lattice         sq2 {density}
region          box block 0 ${{nx}} 0 ${{ny}} -0.5 0.5
create_box      1 box
create_atoms    1 box
""",
    3: """variable        n index 32
variable        steps index 500
lattice         sc {density}
region          box block 0 ${{n}} 0 ${{n}} 0 ${{n}}
create_box      1 box
create_atoms    1 box
""",
}
_RUN = {
    2: "Run: mpirun -np 2 lmp -in in.lj2d -var nx 224 -var ny 224 -var steps 1000  (N = 2 nx ny)",
    3: "Run: mpirun -np 2 lmp -in in.lj3d -var n 32 -var steps 500  (N = n^3)",
}


def lammps_input(dim: int) -> str:
    """The LAMMPS input of the W1 liquid in `dim` dimensions (2D variables nx, ny: sq2 cells per axis; 3D n: simple
    cubic cells per axis; steps)."""
    s = SETTINGS[dim]
    enforce = "fix             2 all enforce2d\n" if dim == 2 else ""
    return _HEAD.format(dim=dim, run=_RUN[dim], **s) + _LATTICE[dim].format(**s) + _BODY.format(enforce=enforce, **s)


def write_lammps_input(dim: int, folder: Path) -> Path:
    """Write lammps_input(dim) into `folder` (created) and return its path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"in.lj{dim}d"
    path.write_text(lammps_input(dim))
    return path


def describe(dim: int, particles: int, lammps: str | None = None) -> str:
    """The settings both sides run with, in one line (`lammps`: the LAMMPS configuration compared with)."""
    s = SETTINGS[dim]
    return (
        f"{dim}D LJ liquid, N = {particles}, density {s['density']}, T {s['temperature']}, cutoff {s['cutoff']}, "
        f"skin {s['skin']} (checked every step, rebuilt at half the skin), velocity Verlet, dt {s['dt']}; "
        f"LAMMPS ({lammps or 'not run'}) and the sandbox on the same cores"
    )


def _spin(stop) -> None:
    # A program of its own, as another user's work would be: Linux's autogroup shares the cores between sessions
    # first, and mpirun starts LAMMPS in a session of its own, so hogs left in the bench's session would crowd the
    # sandbox alone.
    if hasattr(os, "setsid"):
        with contextlib.suppress(OSError):
            os.setsid()
    x = 0.0
    while not stop.is_set():
        for _ in range(100_000):
            x = x * 0.999 + 1.0


class CpuHog:
    """`count` other CPU-bound processes for as long as the `with` block lasts (bench --contended [N])."""

    def __init__(self, count: int = 1) -> None:
        self.count = count

    def __enter__(self):
        context = multiprocessing.get_context("spawn")
        self.stop = context.Event()
        self.processes = [context.Process(target=_spin, args=(self.stop,), daemon=True) for _ in range(self.count)]
        for process in self.processes:
            process.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        for process in self.processes:
            process.join(5)
            if process.is_alive():
                process.kill()


def pair_count(sim) -> int:
    """Pairs of particles within the pair cutoff now (each pair once)."""
    x = sim.positions()
    lo, hi = np.asarray(sim.scene.world.lo, x.dtype), np.asarray(sim.scene.world.hi, float)
    i, _ = _pairs_within(x - lo, float(sim.scene.pair.cutoff), hi - lo)
    return len(i)


def pair_rate(sim, particle_steps_per_second: float) -> float:
    """Pair interactions per second of a workload stepping at `particle_steps_per_second` (pairs within the cutoff,
    each once, per step)."""
    n = max(int(sim.particles.n[None]), 1)
    return pair_count(sim) * particle_steps_per_second / n


@ti.data_oriented
class _IdealLoop:
    """N particles at `density` in an open box, each pair within the cutoff listed once (a sorted half list in one
    flat array, built once): no pairs in a skin shell to mask, no periodic images, no rebuilds, no integration. Each
    thread takes blocks of particles and writes what its pairs give to the other particle into its block's own
    force row (no atomics), as the sandbox's pair pass does; summing the rows is not part of the loop."""

    def __init__(self, dim: int, n: int, density: float, cutoff: float, seed: int = 1, threads: int = 2):
        rng = np.random.default_rng(seed)
        side = (n / density) ** (1 / dim)
        per_axis = math.ceil(n ** (1 / dim))
        grid = np.stack(np.meshgrid(*[np.arange(per_axis)] * dim, indexing="ij"), -1).reshape(-1, dim)[:n]
        x = (grid + 0.5) * side / per_axis + rng.normal(0, 0.05, (n, dim))
        i, j = _pairs_within(x, cutoff)
        self.pairs = len(i)
        self.chunks = CHUNKS_PER_THREAD * max(threads, 1)  # as the sandbox's pass on the thread pool
        self.x = ti.Vector.field(dim, ti.f32, shape=n)
        self.rows = ti.Vector.field(dim, ti.f32, shape=(self.chunks, n))
        self.start = ti.field(ti.i32, shape=n + 1)
        self.neighbour = ti.field(ti.i32, shape=max(len(j), 1))
        self.x.from_numpy(x.astype(np.float32))
        self.start.from_numpy(np.searchsorted(i, np.arange(n + 1)).astype(np.int32))
        self.neighbour.from_numpy(j.astype(np.int32))

    @ti.kernel
    def forces(self):
        """Every pair once: the force on a into row t at a, its opposite into row t at the neighbour."""
        n = self.x.shape[0]
        for u in range(self.chunks * SPREAD_STRIDE):
            t = spread_item(u)
            if t >= 0:
                for a in range(t * n // self.chunks, (t + 1) * n // self.chunks):
                    xa = self.x[a]
                    fa = ti.Vector.zero(ti.f32, self.x.n)
                    for k in range(self.start[a], self.start[a + 1]):
                        b = self.neighbour[k]
                        d = xa - self.x[b]
                        inv2 = 1.0 / d.dot(d)
                        inv6 = inv2 * inv2 * inv2
                        fab = 24.0 * inv2 * inv6 * (2.0 * inv6 - 1.0) * d
                        fa += fab
                        self.rows[t, b] = self.rows[t, b] - fab
                    self.rows[t, a] = self.rows[t, a] + fa

    def force(self) -> np.ndarray:
        """The force on each particle (the rows summed) after one forces() from cleared rows, (N, D)."""
        self.rows.fill(0)
        self.forces()
        return self.rows.to_numpy().sum(0)


def _pairs_within(x: np.ndarray, cutoff: float, box: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) with i < j for every pair of the points x (N, D) closer than cutoff, sorted by i then j: in an open box,
    or with `box` (its edges; x in [0, box)) by the minimum image in a periodic one. A cell at a time against the
    cells around it."""
    periodic = box is not None
    lo = np.zeros(x.shape[1]) if periodic else x.min(0)
    if periodic:
        cells = np.maximum((box // cutoff).astype(int), 1)
        key = np.floor((x - lo) / box * cells).astype(int) % cells
    else:
        cells = ((x.max(0) - lo) // cutoff).astype(int) + 1
        key = np.minimum(((x - lo) // cutoff).astype(int), cells - 1)
    flat = np.ravel_multi_index(key.T, cells)
    order = np.argsort(flat, kind="stable")
    starts = np.searchsorted(flat[order], np.arange(np.prod(cells) + 1))
    offsets = np.stack(np.meshgrid(*[(-1, 0, 1)] * x.shape[1], indexing="ij"), -1).reshape(-1, x.shape[1])
    found_i, found_j = [np.zeros(0, int)], [np.zeros(0, int)]
    for c in range(int(np.prod(cells))):
        mine = order[starts[c] : starts[c + 1]]
        if not len(mine):
            continue
        near = np.array(np.unravel_index(c, cells)) + offsets
        if periodic:
            near = np.unique(np.ravel_multi_index((near % cells).T, cells))  # few cells: an image may repeat
        else:
            near = np.ravel_multi_index(near[((near >= 0) & (near < cells)).all(1)].T, cells)
        others = np.concatenate([order[starts[k] : starts[k + 1]] for k in near])
        d = x[others][None, :, :] - x[mine][:, None, :]
        if periodic:
            d -= box * np.round(d / box)
        a, b = np.nonzero(((d**2).sum(-1) < cutoff * cutoff) & (mine[:, None] < others[None, :]))
        found_i.append(mine[a])
        found_j.append(others[b])
    i, j = np.concatenate(found_i), np.concatenate(found_j)
    sort = np.lexsort((j, i))
    return i[sort], j[sort]


IDEAL_PARTICLES = {2: 32768, 3: 16384}  # in cache on a 2 MB L2 share (positions, list and rows), yet a launch's
# fixed cost (20-40 us) is a few percent of its work


def ideal_pair_rate(dim: int = 2, seconds: float = 0.5) -> float:
    """Pair interactions per second (each pair once) of the ideal loop in `dim` dimensions on this runtime's CPU
    threads: the most the same cores reach on the force loop alone."""
    from ..core import taichi_compat

    s = SETTINGS[dim]
    loop = _IdealLoop(dim, IDEAL_PARTICLES[dim], s["density"], s["cutoff"], threads=taichi_compat.cpu_threads())
    loop.forces()
    ti.sync()
    repeats, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        loop.forces()
        repeats += 1
    ti.sync()
    return loop.pairs * repeats / (time.perf_counter() - t0)

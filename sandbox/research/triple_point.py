"""The molecular model's triple point, measured by direct three-phase coexistence (`sandbox study --triple`).

A periodic 3D box holds an fcc crystal slab, a liquid slab on it and vapour around both (the slabs span the box
across; the box is long along z). Run at constant energy, such a system settles where the three phases coexist:
if it is too warm part of the crystal melts and the latent heat it takes cools the rest; too cold, part of the
liquid freezes and warms it. With a vapour present the pressure is the (tiny) vapour pressure, so the temperature
it settles at is the melting point at that pressure: the triple point. Nothing is assigned: the temperature is the
atoms' kinetic temperature, the phases are counted from structure (physics/structure.py).

Steps:
  1. the crystal's lattice spacing at zero pressure near the expected temperature (a periodic crystal held at kT by
     stochastic velocity rescaling, its virial pressure at three spacings, interpolated), so the slab is not
     squeezed across;
  2. three-phase runs started at a few temperatures about it: each is held at its start temperature briefly (the
     liquid forms from a cubic lattice), then runs at constant energy; the triple temperature is the mean kinetic
     temperature of the constant-energy part's second half, kept only where crystal and liquid both remain
     (10-90% solid) — runs that melted or froze through say so;
  3. the estimate: the mean over the runs that kept coexistence, with the spread between them as its uncertainty.

Reduced units (epsilon = sigma = m = k = 1), the linear-force-shifted 12-6 potential at 2.5 sigma, velocity Verlet
at dt 0.005, f64.
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..config.scene import scene_from_dict
from ..measure.coexistence_curve import shipped_curve
from ..simulation import Simulation
from .coexistence import LFS_PAIR, Rescaler, block_average
from .study_runs import STUDY_PATH

ROOT2 = math.sqrt(2.0)
FCC_SITES = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]])
LIQUID_DENSITY = 0.8  # the liquid slab's starting density (it relaxes to the coexisting liquid's)
# The short-range models beside which the result is set (reduced units): the Lennard-Jones/spline potential (cut
# at 1.74 sigma) of Hafskjold et al., Mol. Phys. 117 (2019), arXiv:1907.07039; the full 12-6 potential's values
# are the widely quoted ones (triple point of Mastny and de Pablo, J. Chem. Phys. 127, 104504 (2007); critical
# point of Potoff and Panagiotopoulos, J. Chem. Phys. 109, 10914 (1998)).
PEERS = (
    ("Lennard-Jones/spline (cut at 1.74 sigma)", 0.547, 0.005, 0.885),
    ("full 12-6 Lennard-Jones", 0.694, 0.005, 1.312),
)


def fcc_positions(cells: tuple[int, int, int], cell: float, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The sites (N, 3) of an fcc crystal of `cells` cubic cells of edge `cell`, from `origin`; N = 4 x cells."""
    grid = np.stack(np.meshgrid(*[np.arange(c) for c in cells], indexing="ij"), axis=-1).reshape(-1, 1, 3)
    return ((grid + FCC_SITES[None]) * cell).reshape(-1, 3) + np.asarray(origin)


def _box_scene(name: str, box: np.ndarray, atoms: int, kt: float, seed: int) -> dict:
    """A periodic box `box` wide with a body of at least `atoms` atoms (its sites are replaced by the caller's)."""
    spacing = (box.prod() / (1.5 * atoms)) ** (1.0 / 3.0)  # the box clips its lattice: build more, keep N
    return {
        "scene": {"name": name},
        "world": {"dim": 3, "lo": [0.0, 0.0, 0.0], "hi": box.tolist(), "dt": 0.005, "periodic": True,
                  "precision": "f64", "integrator": "velocity_verlet"},
        "pair": dict(LFS_PAIR),
        "molecular": {},
        "bodies": [{"material": "lj", "shape": "box", "lattice": "cubic", "lo": [0.0, 0.0, 0.0], "hi": box.tolist(),
                    "spacing": spacing, "springs": False, "random_velocity": math.sqrt(kt), "seed": seed}],
    }  # fmt: skip


def simulation_of(name: str, box: np.ndarray, x: np.ndarray, kt: float, seed: int) -> Simulation:
    """A simulation of atoms at positions `x` (N, 3) in the periodic box `box`, with Maxwell velocities at `kt`
    about a centre of mass at rest."""
    sim = Simulation(scene_from_dict(_box_scene(name, box, len(x), kt, seed), STUDY_PATH))
    snap = sim.snapshot()
    n = len(x)
    if int(snap["particles.n"]) < n:
        raise RuntimeError(f"the scene built {int(snap['particles.n'])} atoms, fewer than the {n} needed")
    v = np.random.default_rng(seed).normal(0.0, math.sqrt(kt), (n, 3))
    snap["particles.x"][:n] = x % box
    snap["particles.v"][:n] = v - v.mean(axis=0)
    snap["particles.n"] = np.asarray(n, dtype=snap["particles.n"].dtype)
    sim.restore(snap)
    sim.mark_initial()
    return sim


def hold(sim: Simulation, rescaler: Rescaler | None, steps: int, batch: int = 10) -> None:
    """`steps` steps, rescaled toward the rescaler's temperature every `batch` steps (none: constant energy)."""
    for _ in range(steps // batch):
        sim.step(batch)
        if rescaler is not None:
            rescaler.apply(batch * sim.state.dt)


def crystal_pressure(spacing: float, kt: float, cells: int = 5, steps: int = 4000) -> float:
    """The mean virial pressure of a periodic fcc crystal of nearest-neighbour distance `spacing` held at `kt`
    (the second half of `steps` steps)."""
    cell = spacing * ROOT2
    box = np.full(3, cells * cell)
    sim = simulation_of("crystal", box, fcc_positions((cells,) * 3, cell, (0.25 * cell,) * 3), kt, 11)
    rescaler = Rescaler(sim, kt, tau=0.25, seed=12)
    hold(sim, rescaler, steps // 2)
    readings = []
    for _ in range(10):
        hold(sim, rescaler, steps // 20)
        readings.append(sim.stats().pressure)
    return float(np.mean(readings))


def zero_pressure_spacing(kt: float, spacings=(1.10, 1.12, 1.14), log=None) -> float:
    """The nearest-neighbour distance at which the crystal's pressure at `kt` is zero (a straight line through
    the pressures at `spacings`)."""
    pressures = [crystal_pressure(s, kt) for s in spacings]
    slope, intercept = np.polyfit(spacings, pressures, 1)
    spacing = float(-intercept / slope)
    if log:
        log(f"crystal at kT {kt:g}: pressure {', '.join(f'{p:+.3f}' for p in pressures)} at spacings "
            f"{', '.join(f'{s:g}' for s in spacings)}: zero at {spacing:.4f}")  # fmt: skip
    return spacing


@dataclass
class ThreePhaseRun:
    """One three-phase run (reduced units): its start, the settled temperature and how it got there."""

    start_temperature: float
    temperature: float  # the mean kinetic temperature of the second half (nan unless coexistence held)
    temperature_err: float  # its standard error from five block means
    solid_first: float  # the solid share when constant energy began
    solid_last: float  # ... at the end
    gas_last: float
    coexisted: bool  # 10-90% solid through the second half
    atoms: int
    steps: int
    seconds: float


def three_phase_positions(spacing: float, cells: int = 6, layers: int = 6, liquid_atoms: int | None = None,
                          vacuum: float = 12.0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(positions (N, 3), box (3,)): an fcc slab `cells` x `cells` x `layers` cells, then a liquid slab of
    `liquid_atoms` atoms (as many as the crystal by default) on a cubic lattice at LIQUID_DENSITY, then `vacuum`
    of empty space along z."""
    cell = spacing * ROOT2
    width = cells * cell
    crystal = fcc_positions((cells, cells, layers), cell, (0.25 * cell, 0.25 * cell, 0.0))
    liquid_atoms = liquid_atoms or len(crystal)
    across = int(round(width * LIQUID_DENSITY ** (1.0 / 3.0)))
    a = width / across
    dz = 1.0 / (LIQUID_DENSITY * a * a)
    stacks = math.ceil(liquid_atoms / across**2)
    # layer by layer from the crystal up (z the slowest index), so only the top layer is partly filled
    grid = np.stack(np.meshgrid(np.arange(stacks), np.arange(across), np.arange(across), indexing="ij"), axis=-1)
    grid = grid.reshape(-1, 3)[:liquid_atoms]
    bottom = crystal[:, 2].max() + 0.5 * (cell / 2 + dz)
    liquid = np.column_stack([(grid[:, 1] + 0.5) * a, (grid[:, 2] + 0.5) * a, bottom + grid[:, 0] * dz])
    x = np.concatenate([crystal, liquid])
    top = liquid[:, 2].max() + 0.5 * dz
    x[:, 2] += 0.5 * vacuum
    return x, np.array([width, width, top + vacuum])


def run_three_phase(spacing: float, start: float, equilibrate: int = 2000, settle: int = 60000, every: int = 500,
                    cells: int = 6, layers: int = 6, log=None) -> ThreePhaseRun:  # fmt: skip
    """One three-phase run: held at `start` for `equilibrate` steps, then `settle` steps at constant energy,
    sampled every `every` steps."""
    began = time.perf_counter()
    x, box = three_phase_positions(spacing, cells, layers)
    sim = simulation_of(f"triple_{start:g}", box, x, start, seed=int(1000 * start))
    hold(sim, Rescaler(sim, start, tau=0.1, seed=int(1000 * start) + 1), equilibrate)
    rows = []
    for _ in range(settle // every):
        hold(sim, None, every, batch=every)
        s = sim.stats()
        rows.append((s.motion_temperature, s.structure_solid, s.structure_gas))
    t, solid, gas = np.array(rows).T
    half = slice(len(t) // 2, None)
    coexisted = bool(np.all((solid[half] > 0.1) & (solid[half] < 0.9)))
    temperature, err = block_average(t[half]) if coexisted else (math.nan, math.nan)
    run = ThreePhaseRun(
        start, temperature, err,
        float(solid[0]), float(solid[-1]), float(gas[-1]), coexisted, len(x), equilibrate + settle,
        time.perf_counter() - began,
    )  # fmt: skip
    if log:
        log(said(run))
    return run


def said(run: ThreePhaseRun) -> str:
    """One three-phase run in a line."""
    how = (f"settled at kT {run.temperature:.4f} +- {run.temperature_err:.4f}" if run.coexisted
           else "did not keep crystal and liquid together (solid share left the 10-90% band)")  # fmt: skip
    return (f"start kT {run.start_temperature:g}: {how}; solid {run.solid_first:.0%} -> {run.solid_last:.0%}, "
            f"gas {run.gas_last:.0%} ({run.atoms} atoms, {run.steps} steps, {run.seconds:.0f} s)")  # fmt: skip


def triple_estimate(runs: list[ThreePhaseRun]) -> tuple[float, float]:
    """(the triple temperature, its uncertainty): the mean over the runs that kept coexistence, and the larger of
    their spread (standard deviation) and their mean standard error; (nan, nan) when none did."""
    kept = [r for r in runs if r.coexisted]
    if not kept:
        return math.nan, math.nan
    values = np.array([r.temperature for r in kept])
    spread = float(values.std(ddof=1)) if len(kept) > 1 else 0.0
    return float(values.mean()), max(spread, float(np.mean([r.temperature_err for r in kept])))


STARTS = (0.50, 0.53, 0.56, 0.59)  # the three-phase runs' start temperatures, about the expected triple point
GUESS = 0.55  # the temperature at which the crystal's zero-pressure spacing is found


def run_triple_study(out: Path, quick: bool = False, log=print) -> tuple[float, float]:
    """The triple point: the crystal's spacing, then three-phase runs from each of STARTS (`quick`: a smaller slab,
    two starts, a third of the length: about a minute, a check that the study runs, not the figure); writes
    out/triple_point.csv and .md and returns (kT, its uncertainty)."""
    spacing = zero_pressure_spacing(GUESS, spacings=(1.12, 1.14, 1.16), log=log)
    size = dict(cells=5, layers=4, settle=20000) if quick else dict(cells=6, layers=8, settle=60000)
    starts = (STARTS[0], STARTS[2]) if quick else STARTS  # (the quick slab's crystal melts through from 0.59)
    runs = [run_three_phase(spacing, start, log=log, **size) for start in starts]
    estimate = triple_estimate(runs)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "triple_point.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(asdict(runs[0])))
        writer.writeheader()
        writer.writerows(asdict(run) for run in runs)
    (out / "triple_point.md").write_text(report(runs, spacing, estimate))
    return estimate


def report(runs: list[ThreePhaseRun], spacing: float, estimate: tuple[float, float]) -> str:
    """The study's result in Markdown: each run, the estimate, and the peers' values."""
    kt, err = estimate
    lines = [
        "# Triple point of the molecular model",
        "",
        "Made by `sandbox study --triple`: an fcc crystal slab, a liquid slab and vapour in a periodic box, run at",
        f"constant energy (LJ force-shifted at 2.5 sigma; {runs[0].atoms} atoms; the crystal's nearest-neighbour",
        f"distance {spacing:.4f}, where its pressure is zero at kT {GUESS:g}). Reduced units.",
        "",
        "| start kT | settled kT | +- | solid at start | solid at end | gas at end | kept coexistence |",
        "|---|---|---|---|---|---|---|",
    ]
    for run in runs:
        lines.append(
            f"| {run.start_temperature:g} | {run.temperature:.4f} | {run.temperature_err:.4f} | {run.solid_first:.0%} "
            f"| {run.solid_last:.0%} | {run.gas_last:.0%} | {'yes' if run.coexisted else 'no'} |"
        )
    lines += ["", f"Triple point: kT = {kt:.3f} +- {err:.3f} (mean of the runs that kept crystal and liquid).", ""]
    curve = shipped_curve(3)
    critical = f"{curve.critical_temperature:.3f}" if curve is not None else "-"
    lines += ["| potential | triple point kT | critical point kT | ratio |", "|---|---|---|---|"]
    lines.append(f"| this model (force-shifted at 2.5 sigma) | {kt:.3f} +- {err:.3f} | {critical} | "
                 f"{kt / curve.critical_temperature if curve is not None else math.nan:.3f} |")  # fmt: skip
    lines += [f"| {name} | {t:.3f} +- {e:.3f} | {c:.3f} | {t / c:.3f} |" for name, t, e, c in PEERS]
    lines.append("")
    return "\n".join(lines)

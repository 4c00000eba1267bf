"""Liquid-vapour coexistence of the molecular model, measured by slab simulations and set beside NIST's tables.

A periodic 3D box, W x W x Lz with Lz = 4 W, holds a slab of liquid across its middle; atoms evaporate from both
faces until the vapour on either side is saturated. The run holds the temperature with Bussi, Donadio and
Parrinello's stochastic velocity rescaling (canonical, and it keeps the momentum: the velocities about the centre of
mass are scaled together), applied between short batches of velocity-Verlet steps. From snapshots of the production
part it measures, in reduced units (epsilon = sigma = m = k = 1):

    rho_l, rho_v   the mean density of the slab's middle and of the vapour far from it (the density profile about the
                   slab's centre of mass, |z| < D / 4 and |z| > D / 2 + 3 with D the slab's width)
    p_sat          the pressure of the bulk vapour, (sum m v_z^2 + sum_pairs z_ij F_ij,z) / V over its atoms and the
                   pairs whose midpoint lies in it (the Irving-Kirkwood normal pressure of that region); across a flat
                   interface at equilibrium the normal pressure is the same everywhere, and the whole box's P_zz
                   (reported beside it as p_zz) agrees within its much larger noise
    dH_vap         the enthalpy of vaporisation per atom, (u_v - u_l) + p_sat (1 / rho_v - 1 / rho_l), u the mean pair
                   energy per atom of each bulk region (the kinetic energy is the same on both sides)

each with its standard error from block averages (five blocks). The pair force is the linear-force-shifted 12-6
Lennard-Jones force at 2.5 sigma, the truncation of NIST's tables (Standard Reference Simulation Website, "LJ
fluid, linear-force shifted at 2.5 sigma", grand-canonical transition-matrix Monte Carlo): NIST_LFS_PSAT holds its
saturation pressures. The pair analysis runs on SciPy's cKDTree.
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..config.scene import scene_from_dict
from ..core.cores import usable_cores
from ..errors import SandboxError
from ..measure.coexistence_curve import BETA, CoexistenceCurve, fit_curve
from ..measure.units import REAL_SUBSTANCES, shown
from ..simulation import Simulation
from .dask_pool import fresh_job, run_jobs
from .figures import pyplot, save
from .study_runs import STUDY_PATH

CUTOFF = 2.5
# NIST SRSW, linear-force-shifted LJ at 2.5 sigma (TMMC, V = 512 sigma^3): saturation pressure p* by T*
NIST_LFS_PSAT = {0.65: 6.71090e-03, 0.70: 1.18932e-02, 0.75: 1.95405e-02, 0.80: 3.02538e-02, 0.85: 4.47539e-02,
                 0.90: 6.39698e-02}  # fmt: skip
ARGON = REAL_SUBSTANCES["argon"]  # the argon the reduced units stand for (measure/units.py)
LFS_PAIR = {"a": 8.0, "b": 14.0, "cutoff": CUTOFF, "force_shift": True}  # a scene's [pair]: LJ force-shifted at CUTOFF
F_CUT = 24.0 / CUTOFF**7 - 48.0 / CUTOFF**13  # the 12-6 force's attraction at the cutoff (unit masses)


def argon_pressure_kpa(p_reduced: float) -> float:
    """A reduced pressure p* in kPa for argon (epsilon / sigma^3 = 41.9 MPa)."""
    return p_reduced * shown("pressure", ["argon"], 3)[0]


def lfs_force_factor(r: np.ndarray) -> np.ndarray:
    """g(r) with F_i = g(r) (x_j - x_i) for the force-shifted LJ pair (unit masses): (F(r) - F(rc)) / r."""
    return 24.0 / r**8 - 48.0 / r**14 - F_CUT / r


def lfs_energy(r: np.ndarray) -> np.ndarray:
    """The force-shifted pair energy: U(r) - U(rc) - F(rc) (r - rc) with F the attraction along x_j - x_i."""
    u = lambda s: 4.0 * (s**-12.0 - s**-6.0)  # noqa: E731
    return u(r) - u(CUTOFF) - F_CUT * (r - CUTOFF)


@dataclass
class SlabPoint:
    """One temperature's measured coexistence, reduced units, each with its standard error."""

    temperature: float
    temperature_err: float
    rho_liquid: float
    rho_liquid_err: float
    rho_vapour: float
    rho_vapour_err: float
    p_sat: float
    p_sat_err: float
    p_zz: float
    p_zz_err: float
    dh_vap: float
    dh_vap_err: float
    atoms: int
    steps: int
    seconds: float


def slab_scene(temperature: float, width: float, rho: float = 0.8, thickness: float = 12.0, dim: int = 3) -> dict:
    """The scene table of a liquid slab (a square or cubic lattice at density `rho`, `thickness` thick) across a
    periodic box `width` wide and 4 `width` long along the last axis (the slab's normal), in `dim` dimensions."""
    lz = 4.0 * width
    spacing = rho ** (-1.0 / dim)
    across = [width] * (dim - 1)
    return {
        "scene": {"name": f"slab_{temperature:g}"},
        "world": {
            "dim": dim, "lo": [0.0] * dim, "hi": [*across, lz], "dt": 0.005, "periodic": True,
            "precision": "f64", "integrator": "velocity_verlet",
        },
        "pair": dict(LFS_PAIR),
        "molecular": {},
        "bodies": [{
            "material": "lj", "shape": "box", "lattice": "cubic" if dim == 3 else "square",
            "lo": [0.0] * (dim - 1) + [0.5 * (lz - thickness)], "hi": [*across, 0.5 * (lz + thickness)],
            "spacing": spacing, "springs": False,
            "random_velocity": math.sqrt(temperature), "seed": 1 + int(1000 * temperature),
        }],
    }  # fmt: skip


class Rescaler:
    """Bussi-Donadio-Parrinello stochastic velocity rescaling of `sim`'s atoms (those in slots `rows`: a world's, or
    every live one) toward kT = `temperature` with coupling time `tau`, about the centre of mass (so momentum is
    kept)."""

    def __init__(self, sim: Simulation, temperature: float, tau: float, seed: int, rows: slice | None = None) -> None:
        self.sim, self.kt, self.tau = sim, temperature, tau
        self.rng = np.random.default_rng(seed)
        self.rows = rows if rows is not None else slice(0, sim.state.live_count())
        self.dof = sim.dim * (self.rows.stop - self.rows.start - 1)

    def apply(self, elapsed: float) -> None:
        """Rescale after `elapsed` time units of dynamics."""
        field = self.sim.state.particles.v
        full = field.to_numpy()
        self.apply_to(full, elapsed)
        field.from_numpy(full)

    def apply_to(self, full: np.ndarray, elapsed: float) -> None:
        """Rescale this rescaler's rows of the velocities `full` (every slot's, (C, D)) in place."""
        v = full[self.rows]
        drift = v.mean(axis=0)
        ke = 0.5 * ((v - drift) ** 2).sum()
        target = 0.5 * self.dof * self.kt
        c = math.exp(-elapsed / self.tau)
        r1 = self.rng.normal()
        chi = self.rng.chisquare(self.dof - 1)
        new = (
            ke * c
            + target / self.dof * (1 - c) * (r1 * r1 + chi)
            + 2 * r1 * math.sqrt(c * (1 - c) * ke * target / self.dof)
        )
        full[self.rows] = drift + (v - drift) * math.sqrt(max(new, 0.0) / ke)


def slab_coordinate(x: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Each atom's coordinate along the last axis about the slab's centre of mass, in (-L/2, L/2]: the centre of a
    periodic coordinate taken by its mean direction."""
    axis = len(box) - 1
    lz = box[axis]
    angle = 2 * math.pi * x[:, axis] / lz
    centre = (math.atan2(np.sin(angle).mean(), np.cos(angle).mean()) % (2 * math.pi)) * lz / (2 * math.pi)
    return (x[:, axis] - centre + 0.5 * lz) % lz - 0.5 * lz


def measure_snapshot(
    x: np.ndarray, v: np.ndarray, box: np.ndarray, vapour_from: float = np.inf
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(z about the slab's centre of mass, each atom's pair energy, the whole box's P_zz, and the normal pressure of
    the region |z| > vapour_from) of one snapshot (unit masses); z is the last axis (y in 2D)."""
    try:
        from scipy.spatial import cKDTree
    except ImportError as missing:
        raise SandboxError("the coexistence study needs SciPy: pip install -e '.[study]'") from missing

    axis = len(box) - 1
    lz = box[axis]
    z = slab_coordinate(x, box)
    tree = cKDTree(x % box, boxsize=box)
    pairs = tree.query_pairs(CUTOFF, output_type="ndarray")
    d = x[pairs[:, 1]] - x[pairs[:, 0]]
    d -= box * np.round(d / box)
    r = np.linalg.norm(d, axis=1)
    u = lfs_energy(r)
    energy = np.zeros(len(x))
    np.add.at(energy, pairs[:, 0], 0.5 * u)
    np.add.at(energy, pairs[:, 1], 0.5 * u)
    pair_zz = -lfs_force_factor(r) * d[:, axis] ** 2
    p_zz = ((v[:, axis] ** 2).sum() + pair_zz.sum()) / box.prod()
    mid = (z[pairs[:, 0]] + 0.5 * d[:, axis] + 0.5 * lz) % lz - 0.5 * lz
    volume = box[:axis].prod() * (lz - 2 * vapour_from)
    p_vapour = math.nan
    if volume > 0:
        atoms, kept = np.abs(z) > vapour_from, np.abs(mid) > vapour_from
        p_vapour = float(((v[atoms, axis] ** 2).sum() + pair_zz[kept].sum()) / volume)
    return z, energy, p_zz, p_vapour


def block_average(values: np.ndarray, count: int = 5) -> tuple[float, float]:
    """(mean, standard error from `count` block means) of a correlated series."""
    blocks = np.array([b.mean() for b in np.array_split(np.asarray(values), count)])
    return float(blocks.mean()), float(blocks.std(ddof=1) / math.sqrt(count))


def run_slab(temperature: float, width: float | None = None, equilibrate: int = 20000, produce: int = 40000,
             every: int = 100, log=None, dim: int = 3) -> SlabPoint:  # fmt: skip
    """One slab run at reduced temperature `temperature` in `dim` dimensions (steps of dt 0.005; a snapshot every
    `every` steps); `width` across the slab (default 9 sigma in 3D, 30 in 2D)."""
    return run_slabs([temperature], width, equilibrate, produce, every, log, dim)[0]


def run_slabs(temperatures: list[float], width: float | None = None, equilibrate: int = 20000, produce: int = 40000,
              every: int = 100, log=None, dim: int = 3) -> list[SlabPoint]:  # fmt: skip
    """run_slab at each of `temperatures`, the slabs as the worlds of one simulation (core/worlds.py: each world the
    slab run alone, bit for bit, so each point is the lone run's); the points in the temperatures' order."""
    started = time.perf_counter()
    width = width or (9.0 if dim == 3 else 30.0)
    scenes = [scene_from_dict(slab_scene(t, width, dim=dim), STUDY_PATH) for t in temperatures]
    sim = Simulation(scenes[0], starts=scenes if len(scenes) > 1 else None)
    box = np.array(sim.scene.world.hi) - np.array(sim.scene.world.lo)
    n = sim.state.live_count() // len(temperatures)
    rows = [slice(k * n, (k + 1) * n) for k in range(len(temperatures))]
    rescalers = [Rescaler(sim, t, tau=0.5, seed=int(1000 * t), rows=r) for t, r in zip(temperatures, rows)]
    batch = 10
    dt = sim.state.dt

    def steps() -> None:
        sim.step(batch)
        field = sim.state.particles.v
        full = field.to_numpy()
        for rescaler in rescalers:
            rescaler.apply_to(full, batch * dt)
        field.from_numpy(full)

    for _ in range(equilibrate // batch):
        steps()
    snapshots = [[] for _ in temperatures]  # per slab, per snapshot: (kT, rho_l, rho_v, p_vapour, u_l, u_v, p_zz)
    thickness = [None] * len(temperatures)
    for k in range(produce // batch):
        steps()
        if (k + 1) * batch % every:
            continue
        x_all, v_all = sim.particles.x.to_numpy(), sim.particles.v.to_numpy()
        for w, r in enumerate(rows):
            row, thickness[w] = _snapshot(x_all[r], v_all[r], box, dim, thickness[w])
            snapshots[w].append(row)
    seconds = (time.perf_counter() - started) / len(temperatures)
    points = [_point(np.array(data), n, equilibrate + produce, seconds) for data in snapshots]
    for point in points if log else ():
        log(said(point))
    return points


def _snapshot(x: np.ndarray, v: np.ndarray, box: np.ndarray, dim: int, thickness: float | None) -> tuple:
    """One snapshot's row (kT, rho_l, rho_v, p_vapour, u_l, u_v, p_zz) of a slab's atoms at x, v, and the slab's
    width (measured from its own density profile at the first snapshot, where `thickness` is None)."""
    axis = dim - 1
    area = box[:axis].prod()
    if thickness is None:
        z = slab_coordinate(x, box)
        hist, edges = np.histogram(z, bins=int(box[axis] / 0.5), range=(-0.5 * box[axis], 0.5 * box[axis]))
        dens = hist / (area * 0.5)
        dense = edges[:-1][dens > 0.5 * dens.max()]
        thickness = float(dense.max() - dense.min() + 0.5)
    z, energy, p_zz, p_vapour = measure_snapshot(x, v, box, 0.5 * thickness + 3.0)
    liquid = np.abs(z) < 0.25 * thickness
    vapour = np.abs(z) > 0.5 * thickness + 3.0
    vapour_volume = area * (box[axis] - 2 * (0.5 * thickness + 3.0))
    drift = v.mean(axis=0)
    kt = ((v - drift) ** 2).sum() / (dim * (len(x) - 1))
    row = (
        kt,
        liquid.sum() / (area * 0.5 * thickness),
        vapour.sum() / vapour_volume,
        p_vapour,
        energy[liquid].mean(),
        energy[vapour].mean() if vapour.any() else np.nan,
        p_zz,
    )
    return row, thickness


def _point(data: np.ndarray, atoms: int, steps: int, seconds: float) -> SlabPoint:
    """The SlabPoint of a slab's snapshot rows (_snapshot), block-averaged."""
    kt, kt_err = block_average(data[:, 0])
    rho_l, rho_l_err = block_average(data[:, 1])
    rho_v, rho_v_err = block_average(data[:, 2])
    p, p_err = block_average(data[:, 3])
    p_zz, p_zz_err = block_average(data[:, 6])
    u_v_all = data[:, 5][np.isfinite(data[:, 5])]
    u_l, u_l_err = block_average(data[:, 4])
    u_v, u_v_err = block_average(u_v_all) if len(u_v_all) >= 5 else (float("nan"), float("nan"))
    dh = (u_v - u_l) + p * (1.0 / rho_v - 1.0 / rho_l)
    dh_err = math.sqrt(u_v_err**2 + u_l_err**2 + (p_err / rho_v) ** 2 + (p * rho_v_err / rho_v**2) ** 2)
    return SlabPoint(kt, kt_err, rho_l, rho_l_err, rho_v, rho_v_err, p, p_err, p_zz, p_zz_err, dh, dh_err, atoms,
                     steps, seconds)  # fmt: skip


def said(point: SlabPoint) -> str:
    """One slab run's result in a line."""
    return (
        f"T* {point.temperature:.3g}: rho_l {point.rho_liquid:.4f}, rho_v {point.rho_vapour:.5f}, p_sat "
        f"{point.p_sat:.5f}, dH_vap {point.dh_vap:.3f} ({point.atoms} atoms, {point.seconds:.0f} s)"
    )


DEFAULT_TEMPERATURES = {3: (0.70, 0.75, 0.80, 0.85), 2: (0.30, 0.33, 0.36, 0.39)}


def parse_temperatures(text: str | None, dim: int = 3) -> list[float]:
    """--temperatures: comma-separated reduced temperatures from 0.2 to 1.2 (default: DEFAULT_TEMPERATURES, below
    the critical point of this truncation); SandboxError naming the option for anything else."""
    if text is None:
        return list(DEFAULT_TEMPERATURES[dim])
    if not text.strip():
        raise SandboxError("--temperatures: empty; expected comma-separated reduced temperatures from 0.2 to 1.2")
    out = []
    for word in text.split(","):
        try:
            value = float(word)
        except ValueError:
            value = math.nan
        if not 0.2 <= value <= 1.2:
            raise SandboxError(f"--temperatures: {word.strip()!r}; expected reduced temperatures from 0.2 to 1.2")
        out.append(value)
    if len(out) > 12:
        raise SandboxError(f"--temperatures: {len(out)} of them; expected at most 12")
    twice = sorted({t for t in out if out.count(t) > 1})
    if twice:
        raise SandboxError(f"--temperatures: {', '.join(f'{t:g}' for t in twice)} given twice; expected each once")
    return out


def run_coexistence(
    out: Path, temperatures: list[float], quick: bool = False, log=print, dim: int = 3, scheduler: str = "auto",
    workers: int | None = None, threads: int | None = None,
) -> list[SlabPoint]:  # fmt: skip
    """Slab runs at `temperatures` (reduced) in `dim` dimensions, written to out/coexistence.csv and
    out/coexistence.md (3D: beside NIST's saturation pressures and in argon's units); `quick`: short runs (under a
    minute each, wide error bars). With `scheduler` "auto" the slabs run as the worlds of one simulation in this
    process, on every usable core (run_slabs: each the lone run, bit for bit); given another ("serial", "local" or
    a Dask scheduler's address), each runs alone there (research/dask_pool.py)."""
    steps = (4000, 6000) if quick else (20000, 60000)
    if scheduler == "auto" and len(temperatures) > 1:
        log(f"the {len(temperatures)} temperatures as the worlds of one simulation (--scheduler: each alone)")
        job = (temperatures, None, steps[0], steps[1], 100, None, dim)
        points = fresh_job(run_slabs, threads or usable_cores(), job)
    else:
        jobs = [(t, None, steps[0], steps[1], 100, None, dim) for t in temperatures]
        points = run_jobs(run_slab, jobs, scheduler, workers, threads, log, "coexistence study")
    for point in points:
        log(said(point))
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "coexistence.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(asdict(points[0])))
        writer.writeheader()
        for p in points:
            writer.writerow(asdict(p))
    (out / "coexistence.md").write_text(report(points, dim))
    plot(out / "coexistence.png", points, dim)
    return points


def plot(path: Path, points: list[SlabPoint], dim: int = 3) -> None:
    """Two panels: the coexisting densities against temperature (with the fitted critical point), and the
    saturation pressure against 1 / T on a log axis beside NIST's (3D); nothing where matplotlib is missing."""
    plt = pyplot()
    if plt is None:
        return
    t = np.array([p.temperature for p in points])
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
    for values, errors, label in (
        ([p.rho_liquid for p in points], [p.rho_liquid_err for p in points], "liquid"),
        ([p.rho_vapour for p in points], [p.rho_vapour_err for p in points], "vapour"),
    ):
        left.errorbar(values, t, xerr=errors, fmt="o", label=label)
    tc, rho_c = critical_point(points, dim)
    if math.isfinite(tc):
        left.plot([rho_c], [tc], "k*", label=f"critical point (fit), T* = {tc:.3f}")
    left.set(xlabel="density (reduced)", ylabel="temperature T* (reduced)", title="Coexisting densities")
    left.legend(fontsize=8)
    right.errorbar(1 / t, [p.p_sat for p in points], yerr=[p.p_sat_err for p in points], fmt="o", label="measured")
    if dim == 3:
        nist_t = np.array(sorted(NIST_LFS_PSAT))
        right.plot(1 / nist_t, [NIST_LFS_PSAT[k] for k in nist_t], "k+", markersize=10, label="NIST (TMMC, same cut)")
    right.set_yscale("log")
    right.set(xlabel="1 / T*", ylabel="saturation pressure (reduced)", title="Vapour pressure")
    right.legend(fontsize=8)
    save(fig, path)


ATMOSPHERE_KPA = 101.325


def curve(points: list[SlabPoint], dim: int = 3) -> CoexistenceCurve | None:
    """The fitted curve and critical point of the measured points (measure/coexistence_curve.py's fit, the one the
    phase diagram draws); None below two points."""
    if len(points) < 2:
        return None
    columns = zip(*((p.temperature, p.p_sat, p.p_sat_err, p.rho_liquid, p.rho_vapour) for p in points))
    return fit_curve(*columns, dim)


def critical_point(points: list[SlabPoint], dim: int = 3) -> tuple[float, float]:
    """(T_c, rho_c) of the fitted curve (reduced units; nan below two points)."""
    fitted = curve(points, dim)
    return (fitted.critical_temperature, fitted.critical_density) if fitted else (math.nan, math.nan)


def report(points: list[SlabPoint], dim: int = 3) -> str:
    """The table of measured points beside NIST's saturation pressures, in reduced units and as argon (3D); in 2D
    the measured points and the fitted critical temperature alone."""
    if dim == 2:
        lines = ["| T* | rho_l* | rho_v* | p_sat* (2D: eps / sigma^2) | dH_vap / eps |", "|---|---|---|---|---|"]
        lines += [
            f"| {p.temperature:.3f} ± {p.temperature_err:.3f} | {p.rho_liquid:.4f} ± {p.rho_liquid_err:.4f} "
            f"| {p.rho_vapour:.5f} ± {p.rho_vapour_err:.5f} | {p.p_sat:.5f} ± {p.p_sat_err:.5f} "
            f"| {p.dh_vap:.3f} ± {p.dh_vap_err:.3f} |"
            for p in points
        ]
        tc, rho_c = critical_point(points, 2)
        lines += ["", f"Critical point (fit with the 2D Ising exponent 1/8): T_c* = {tc:.3f}, rho_c* = {rho_c:.3f}."]
        return "\n".join(lines) + "\n"
    lines = [
        "| T* | rho_l* | rho_v* | p_sat* | NIST p_sat* | p_sat / NIST | P_zz* (whole box) | dH_vap / eps "
        "| T (K, argon) | p_sat (kPa, argon) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in points:
        nist = NIST_LFS_PSAT.get(round(p.temperature, 2)) or NIST_LFS_PSAT.get(round(p.temperature * 20) / 20)
        ratio = f"{p.p_sat / nist:.3f}" if nist else "-"
        lines.append(
            f"| {p.temperature:.3f} ± {p.temperature_err:.3f} | {p.rho_liquid:.4f} ± {p.rho_liquid_err:.4f} "
            f"| {p.rho_vapour:.5f} ± {p.rho_vapour_err:.5f} | {p.p_sat:.5f} ± {p.p_sat_err:.5f} "
            f"| {nist if nist else '-'} | {ratio} | {p.p_zz:.4f} ± {p.p_zz_err:.4f} "
            f"| {p.dh_vap:.3f} ± {p.dh_vap_err:.3f} "
            f"| {p.temperature * ARGON['epsilon_over_k']:.1f} | {argon_pressure_kpa(p.p_sat):.0f} |"
        )
    tc, rho_c = critical_point(points, 3)
    fitted = curve(points, 3)
    boil = fitted.boiling_temperature(ATMOSPHERE_KPA / argon_pressure_kpa(1.0)) if fitted else math.nan
    eps = ARGON["epsilon_over_k"]
    lines += [
        "",
        f"Critical point (fit of (rho_l - rho_v)^(1/{BETA[3]}) and the rectilinear diameter): T_c* = {tc:.3f} "
        f"({tc * eps:.0f} K as argon; argon 150.7 K), rho_c* = {rho_c:.3f}.",
        f"Normal boiling point (the fitted vapour curve ln p = a - b / T at 101.325 kPa, extrapolated): "
        f"T* = {boil:.3f} ({boil * eps:.1f} K as argon; argon 87.3 K).",
    ]
    return "\n".join(lines) + "\n"

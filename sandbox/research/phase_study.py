"""Validation of phase change: the one-phase Stefan problem and the heating curve.

Stefan: a periodic 2D slab of a pure material at its melting point Tm, with a band of particles in the middle held at
Tm + dT (a "fixed" heat source). Melt fronts run out both ways; by symmetry each is the one-phase Stefan problem
with the Dirichlet boundary at the outermost held particles, whose exact (Neumann) solution is

    s(t) = 2 lambda sqrt(alpha t),     lambda exp(lambda^2) erf(lambda) = St / sqrt(pi),    St = c dT / L

The numerical front is the melted volume (sum of melt fraction x particle volume, over the free particles) per unit
cross-section per side, plus the half spacing between the held particle and its own slab's edge.

Heating curve: a body heated at constant power P, insulated. Its mean temperature rises at P / (M c), holds at Tm
for L M / P while it melts, and rises again at P / (M c).
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config.scene import scene_from_dict
from ..core import runtime
from ..simulation import Simulation
from .figures import legend_beside, pyplot, save
from .study_runs import STUDY_PATH

STEFAN_LENGTH = 60.0  # slab length (periodic), in units where the coarsest spacing is 1
STEFAN_HEIGHT = 8.0  # slab height (periodic)
STEFAN_HELD = 4.0  # width of the held band in the middle


def stefan_lambda(stefan_number: float) -> float:
    """lambda solving lambda exp(lambda^2) erf(lambda) = St / sqrt(pi) (bisection; the left side increases)."""
    target = stefan_number / math.sqrt(math.pi)
    lo, hi = 0.0, 3.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if mid * math.exp(mid * mid) * math.erf(mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@dataclass
class StefanResult:
    spacing: float
    particles: int
    times: np.ndarray  # (K,)
    front: np.ndarray  # (K,) numerical front position s(t)
    exact: np.ndarray  # (K,) Neumann solution
    lam: float

    def every(self, points: int) -> slice:
        """A stride that keeps at most `points` of the samples (for the CSV and the plot; the error uses all)."""
        return slice(None, None, max(1, -(-len(self.times) // points)))

    @property
    def error(self) -> float:
        """Largest relative front error over the second half of the run (the front is a few spacings deep there)."""
        half = len(self.times) // 2
        return float(np.max(np.abs(self.front[half:] - self.exact[half:]) / self.exact[half:]))


def stefan_scene(spacing: float, superheat: float = 10.0, latent: float = 10.0) -> dict:
    """Scene table of the Stefan slab at particle spacing `spacing` (conductivity, density, c = 1; Tm = 0)."""
    dt = 0.05 * spacing**2  # explicit heat limit is about 0.11 h^2 for alpha = 1 and the default H = 2.5 h
    mid = STEFAN_LENGTH / 2
    return {
        "world": {
            "dim": 2,
            "lo": [0.0, 0.0],
            "hi": [STEFAN_LENGTH, STEFAN_HEIGHT],
            "dt": dt,
            "periodic": True,
            "precision": "f64",
        },
        "heat": {
            "ambient": 0.0,
            "refreeze": False,
            "sources": [
                {
                    "name": "held band",
                    "mode": "fixed",
                    "lo": [mid - STEFAN_HELD / 2, 0.0],
                    "hi": [mid + STEFAN_HELD / 2, STEFAN_HEIGHT],
                    "temperature": superheat,
                    "reach": 0.0,
                }
            ],
        },
        "materials": {
            "pcm": {
                "based_on": "jelly",
                "density": 1.0,
                "specific_heat": 1.0,
                "conductivity": 1.0,
                "melt_temperature": 0.0,
                "latent_heat": latent,
            }
        },
        "bodies": [
            {
                "material": "pcm",
                "shape": "box",
                "lo": [0.0, 0.0],
                "hi": [STEFAN_LENGTH, STEFAN_HEIGHT],
                "spacing": spacing,
                "springs": False,
                "temperature": 0.0,
            }
        ],
    }


def stefan_run(spacing: float, t_end: float = 60.0, superheat: float = 10.0) -> StefanResult:
    """Run the Stefan slab to t_end, measuring the front after every step; St = superheat / 10 (c = 1, L = 10). The
    front advances a particle column at a time and its error swings between columns, so the maximum error is taken
    over every step (every column's crossing included), not over samples that may fall between the swings'
    extremes."""
    latent = 10.0
    sim = Simulation(scene_from_dict(stefan_scene(spacing, superheat, latent), STUDY_PATH))
    x = sim.positions()[:, 0]
    mid = STEFAN_LENGTH / 2
    free = np.abs(x - mid) > STEFAN_HELD / 2
    per_side = spacing**2 / (2 * STEFAN_HEIGHT)  # a particle's area, over the two fronts' height
    times, melted = [], []
    for _ in range(round(t_end / sim.dt)):
        sim.step(1)
        times.append(sim.time)
        melted.append(float(sim.melt_fractions()[free].sum()) * per_side)
    lam = stefan_lambda(superheat / latent)
    times_a = np.array(times)
    # measured from the outermost held particle: the first free particle's slab starts half a spacing out
    front_a = np.array(melted) + 0.5 * spacing
    exact = 2 * lam * np.sqrt(times_a)
    return StefanResult(spacing, sim.model.built.count, times_a, front_a, exact, lam)


@dataclass
class HeatingCurve:
    times: np.ndarray  # (K,)
    mean_temperature: np.ndarray  # (K,)
    molten_fraction: np.ndarray  # (K,)
    power: float
    mass: float
    specific_heat: float
    latent_heat: float
    melt_temperature: float
    liquid_specific_heat: float | None = None  # None: the solid's

    @property
    def plateau(self) -> tuple[float, float]:
        """(start, end) times of the plateau: first sample with melt, first fully molten sample."""
        melting = np.flatnonzero(self.molten_fraction > 0)
        molten = np.flatnonzero(self.molten_fraction >= 1.0)
        if not len(melting) or not len(molten):
            raise ValueError("the run ended before the body melted through; run longer or heat harder")
        return float(self.times[melting[0]]), float(self.times[molten[0]])

    @property
    def expected_plateau(self) -> float:
        return self.latent_heat * self.mass / self.power


def heating_curve_run(
    power: float = 10000.0, t_end: float = 3.0, samples: int = 300, material: str = "ice", start: float = -20.0
) -> HeatingCurve:
    """Heat a small insulated block of `material` at constant total power; sample mean temperature and melt."""
    data = {
        "world": {"dim": 2, "lo": [0.0, 0.0], "hi": [16.0, 16.0], "dt": 0.0004, "precision": "f64"},
        "heat": {
            "ambient": start,
            "refreeze": False,
            "sources": [{"name": "heater", "mode": "power", "power": power, "lo": [0, 0], "hi": [16, 16]}],
        },
        "bodies": [{"material": material, "shape": "box", "lo": [4, 4], "hi": [12, 12], "temperature": start}],
    }
    sim = Simulation(scene_from_dict(data, STUDY_PATH))
    mat = sim.scene.materials[material]
    steps = max(1, round(t_end / samples / sim.dt))
    times, temps, melt = [], [], []
    for _ in range(samples):
        sim.step(steps)
        s = sim.stats()
        times.append(sim.time)
        temps.append(s.mean_temperature)
        melt.append(s.molten_fraction)
    return HeatingCurve(
        np.array(times),
        np.array(temps),
        np.array(melt),
        power,
        float(sim.model.built.mass.sum()),
        mat.specific_heat,
        mat.latent_heat,
        mat.melt_temperature,
        mat.liquid_specific_heat,
    )


def run_phase_study(out: Path, quick: bool = False, log=print) -> list[StefanResult]:
    """Write the phase-change validation to `out`: phase.md, stefan.csv (at most 1,200 of each run's steps),
    heating_curve.csv and (with matplotlib) stefan.png and heating_curve.png."""

    out.mkdir(parents=True, exist_ok=True)
    spacings = (1.0, 0.5) if quick else (1.0, 0.5, 0.25)
    results = []
    for spacing in spacings:
        runtime.reset()
        t0 = time.perf_counter()
        result = stefan_run(spacing)
        results.append(result)
        log(
            f"stefan h = {spacing:g}: {result.particles} particles, max relative front error {result.error:.4f} "
            f"({time.perf_counter() - t0:.1f} s)"
        )
    with open(out / "stefan.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["spacing", "time", "front", "exact"])
        for r in results:
            keep = r.every(1200)
            for t, s, e in zip(r.times[keep], r.front[keep], r.exact[keep]):
                w.writerow([r.spacing, f"{t:.6g}", f"{s:.6g}", f"{e:.6g}"])
    runtime.reset()
    curve = heating_curve_run()
    start, end = curve.plateau
    log(f"heating curve: plateau {end - start:.3f} s, expected L M / P = {curve.expected_plateau:.3f} s")
    with open(out / "heating_curve.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time", "mean_temperature", "molten_fraction"])
        for row in zip(curve.times, curve.mean_temperature, curve.molten_fraction):
            w.writerow([f"{v:.6g}" for v in row])
    _write_report(out, results, curve)
    _plot(out, results, curve)
    return results


def _write_report(out: Path, results: list[StefanResult], curve: HeatingCurve) -> None:
    start, end = curve.plateau
    lines = [
        "# Phase change validation",
        "",
        "Made by `sandbox study --phase`. Explicit heat, f64.",
        "",
        f"## One-phase Stefan problem (St = 1, lambda = {results[0].lam:.4f})",
        "",
        "| spacing | particles | max relative front error, second half of t in [0, 60] |",
        "|---|---|---|",
    ]
    lines += [f"| {r.spacing:g} | {r.particles} | {r.error:.4f} |" for r in results]
    lines += [
        "",
        "## Heating curve (ice, -20 C, constant power, insulated)",
        "",
        f"Plateau at {curve.melt_temperature:g} C from t = {start:.3f} to {end:.3f} s: {end - start:.3f} s; "
        f"L M / P = {curve.expected_plateau:.3f} s (sampled every {curve.times[1] - curve.times[0]:.3f} s).",
        "",
    ]
    (out / "phase.md").write_text("\n".join(lines))


def _plot(out: Path, results: list[StefanResult], curve: HeatingCurve) -> None:
    """stefan.png (the melt front against the Neumann solution) and heating_curve.png (temperature and melt at
    constant power, the plateau the latent heat predicts shaded); legends beside the axes."""
    plt = pyplot()
    if plt is None:
        return
    fig, ax = plt.subplots(figsize=(7.5, 4), layout="constrained")
    t = np.linspace(0, results[0].times[-1], 200)
    ax.plot(t, 2 * results[0].lam * np.sqrt(t), "k-", label="exact (Neumann) solution")
    for r, marker in zip(results, "os^"):
        keep = r.every(60)
        label = f"particles {r.spacing:g} mm apart (error {r.error:.1%})"
        ax.plot(r.times[keep], r.front[keep], marker, fillstyle="none", label=label)
    ax.set(xlabel="time (s)", ylabel="melt front position (mm)", title="Melting from a hot wall (Stefan number 1)")
    legend_beside(ax)
    save(fig, out / "stefan.png")
    fig, ax1 = plt.subplots(figsize=(7.5, 4), layout="constrained")
    ax1.plot(curve.times, curve.mean_temperature, "C3-", label="mean temperature")
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel("mean temperature (°C)", color="C3")
    ax2 = ax1.twinx()
    ax2.plot(curve.times, 100 * np.asarray(curve.molten_fraction), "C0--", label="melted")
    ax2.set_ylabel("melted (%)", color="C0")
    ax2.set_ylim(0, 100)
    start, _ = curve.plateau
    ax1.axvspan(start, start + curve.expected_plateau, color="0.9", label="plateau predicted: latent heat / power")
    ax1.set_title("Heating curve of ice at constant power")
    handles = ax1.get_legend_handles_labels()[0] + ax2.get_legend_handles_labels()[0]
    ax2.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.15, 1.0), borderaxespad=0.0, fontsize=8)
    save(fig, out / "heating_curve.png")

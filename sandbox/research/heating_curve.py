"""The molecular model's heating curve: a crystal under a lid heated evenly at constant power, measured through
melting and boiling (`sandbox study --heating`).

A 3D fcc crystal of Lennard-Jones atoms (force-shifted at 2.5 sigma) rests on the floor of a tall box under a lid
pressed down by a set outside pressure P; the molecular heater (physics/heater.py) gives the atoms a constant power,
keeping momentum. Nothing is assigned: the temperature is the atoms' kinetic temperature, the phases are counted from
structure, the heat is the heater's own sum Q. At constant power a phase change shows as a stretch of the curve T(Q)
where heat goes in and the temperature hardly rises: the latent heat, which comes from the pair energy of the atoms
pulled apart. From each run the study measures, in reduced units:

    slope dT/dQ of each stage (crystal, melting, liquid, boiling, vapour: stages by the measured shares) by least
                squares, so the plateaus are numbers, not impressions
    the boiling liquid's temperature (the kinetic temperature of the atoms counted solid or liquid, mean while
                20-80% of the atoms are gas) beside the boiling point the measured coexistence curve gives at the
                lid's pressure (measure/coexistence_curve.py): the heater warms the vapour too, and the dilute
                vapour passes its heat on slowly, so the whole's temperature rises above the liquid's
    the heat per atom taken while the gas share rose from 10% to 90%, beside the coexistence study's enthalpy of
                vaporisation

Two lid pressures show the plateau move with the pressure (a pressure cooker). Runs are single trajectories of a few
hundred atoms: the plateau is noisy (+-0.05) and heating at a finite rate superheats the liquid a little.
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config.scene import scene_from_dict
from ..measure.coexistence_curve import shipped_curve
from ..simulation import Simulation
from .coexistence import LFS_PAIR
from .dask_pool import run_jobs
from .figures import legend_beside, pyplot, save
from .study_runs import STUDY_PATH

FCC_CELL = 1.556  # the fcc cell's edge for nearest neighbours 1.10 sigma
STAGES = ("crystal", "melting", "liquid", "boiling", "vapour")


def heating_scene(pressure: float, power: float, cells: int = 5, height: float = 240.0, seed: int = 5) -> dict:
    """The scene table: an fcc crystal `cells` cells wide on the floor of a box `height` tall, under a lid pressed
    by `pressure`, heated at `power` (reduced units); `seed` draws the starting velocities."""
    side = cells * FCC_CELL
    top = cells * FCC_CELL + 0.3
    return {
        "scene": {"name": f"heating_{pressure:g}"},
        "world": {
            "dim": 3, "lo": [0.0, 0.0, 0.0], "hi": [side, height, side], "dt": 0.005, "precision": "f64",
            "integrator": "velocity_verlet", "restitution": 1.0, "friction": 0.0,
        },
        "pair": dict(LFS_PAIR),
        "molecular": {"lid": {"pressure": pressure, "mass": 50.0, "height": top + 0.6}, "heater": {"power": power}},
        "bodies": [{
            "material": "lj", "shape": "box", "lattice": "fcc", "lo": [0.0, 0.3, 0.0], "hi": [side, top, side],
            "spacing": 1.10, "springs": False, "random_velocity": 0.2, "seed": seed,
        }],
    }  # fmt: skip


@dataclass
class HeatingRun:
    """One heating run's record, a row every `every` steps (reduced units)."""

    pressure: float
    power: float
    atoms: int
    heat: np.ndarray  # (K,) the heater's sum Q
    temperature: np.ndarray  # (K,) kinetic temperature of all atoms
    liquid_temperature: np.ndarray  # (K,) ... of the atoms counted solid or liquid (nan without any)
    solid: np.ndarray  # (K,) share of atoms counted solid
    gas: np.ndarray  # (K,) share counted gas
    lid_height: np.ndarray  # (K,)
    seconds: float

    def stage(self, name: str) -> np.ndarray:
        """Rows of stage `name` (STAGES), by the measured shares."""
        solid, gas = self.solid, self.gas
        return {
            "crystal": solid >= 0.8,
            "melting": (solid > 0.2) & (solid < 0.6),
            "liquid": (solid < 0.05) & (gas < 0.05),
            "boiling": (gas > 0.2) & (gas < 0.8),
            "vapour": gas > 0.97,
        }[name]

    def slope(self, name: str) -> float:
        """dT/dQ over stage `name` (least squares; nan with under 4 rows)."""
        rows = self.stage(name)
        return float(np.polyfit(self.heat[rows], self.temperature[rows], 1)[0]) if rows.sum() >= 4 else math.nan

    def plateau(self, liquid: bool = True) -> float:
        """The mean kinetic temperature of the liquid (`liquid`), else of all atoms, while 20-80% of them are gas."""
        rows = self.stage("boiling")
        t = self.liquid_temperature if liquid else self.temperature
        return float(np.nanmean(t[rows])) if rows.any() else math.nan

    def vaporisation_heat(self) -> float:
        """Heat per atom taken while the gas share rose from 10% to 90% (first crossings), over the 80% that went."""
        start, end = np.argmax(self.gas >= 0.1), np.argmax(self.gas >= 0.9)
        if not (self.gas >= 0.9).any() or end <= start:
            return math.nan
        return float((self.heat[end] - self.heat[start]) / (0.8 * self.atoms))


def run_heating(pressure: float, power: float, cells: int = 5, steps: int = 600_000, every: int = 1000,
                log=None, seed: int = 5) -> HeatingRun:  # fmt: skip
    """Heat the crystal under a lid at `pressure` with `power` for at most `steps` steps, stopping once it has all
    been gas for 50 rows; a row every `every` steps; `seed` draws the starting velocities."""
    started = time.perf_counter()
    sim = Simulation(scene_from_dict(heating_scene(pressure, power, cells, seed=seed), STUDY_PATH))
    rows = []
    vapour_rows = 0
    for _ in range(steps // every):
        sim.step(every)
        s = sim.stats()
        rows.append((s.heater_heat, s.motion_temperature, s.condensed_temperature, s.structure_solid,
                     s.structure_gas, s.lid_height))  # fmt: skip
        vapour_rows += s.structure_gas > 0.97
        if vapour_rows >= 50:
            break
    q, t, liquid, solid, gas, lid = np.array(rows).T
    run = HeatingRun(pressure, power, sim.state.live_count(), q, t, liquid, solid, gas, lid,
                     time.perf_counter() - started)  # fmt: skip
    if log:
        log(said(run))
    return run


def said(run: HeatingRun) -> str:
    """One heating run's result in a line, saying when the "boiling liquid" was above the critical point."""
    return (f"lid pressure {run.pressure:g}: {run.atoms} atoms, boiling liquid's kT {run.plateau():.3f}, "
            f"{len(run.heat)} rows, {run.seconds:.0f} s{above_critical(run)}")  # fmt: skip


def above_critical(run: HeatingRun) -> str:
    """ "" when the run's boiling liquid was below the model's critical temperature (the measured coexistence
    curve's), else a clause saying that it was, and so is no boiling point: a crystal too small or heated too fast
    (--quick's 63 atoms at four times the power) turns into a fluid without boiling."""
    curve = shipped_curve(3)
    plateau = run.plateau()
    if curve is None or not plateau > curve.critical_temperature:
        return ""
    return (
        f" (above the model's critical point, kT {curve.critical_temperature:.2f}: no liquid boils there, so this is "
        "no boiling point and does not depend on the lid; run without --quick)"
    )


def run_heating_study(out: Path, pressures=(0.015, 0.03), power: float = 2.0, quick: bool = False, log=print,
                      scheduler: str = "auto", workers: int | None = None,
                      threads: int | None = None) -> list[HeatingRun]:  # fmt: skip
    """Heating runs at each lid pressure, written to out/heating_curve.csv, .md and .png; `quick`: a 63-atom crystal
    heated four times as fast (a minute: it checks that the study runs; its liquid turns fluid above the critical point
    instead of boiling, which the report says). The runs go to a Dask cluster where there is one."""
    cells, power = (3, 4.0 * power) if quick else (5, power)
    runs = run_jobs(
        run_heating, [(p, power, cells) for p in pressures], scheduler, workers, threads, log, "heating study"
    )
    for run in runs:
        log(said(run))
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "heating_curve.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["lid_pressure", "heat", "temperature", "liquid_temperature", "solid", "gas", "lid_height"])
        for run in runs:
            for row in zip(run.heat, run.temperature, run.liquid_temperature, run.solid, run.gas, run.lid_height):
                writer.writerow([f"{run.pressure:g}", *(f"{v:.6g}" for v in row)])
    (out / "heating_curve.md").write_text(report(runs))
    plot(out / "heating_curve.png", runs)
    return runs


def _boiling_points(runs: list[HeatingRun]) -> list[float]:
    """The measured coexistence curve's boiling temperature at each run's lid pressure (the runs' atom is the one
    the shipped 3D curve was measured for)."""
    curve = shipped_curve(3)
    return [curve.boiling_temperature(run.pressure) for run in runs]


def report(runs: list[HeatingRun]) -> str:
    """The study's table in Markdown."""
    boiling = _boiling_points(runs)
    lines = [
        "# Heating curve of the molecular model",
        "",
        f"Made by `sandbox study --heating`: an fcc crystal of {runs[0].atoms} atoms (LJ, force-shifted at 2.5 sigma)",
        f"under a lid, heated evenly at {runs[0].power:g} eps per time unit (momentum kept). Reduced units.",
        "",
        "| lid pressure | boiling liquid's kT (20-80% gas) | curve's boiling point | all atoms' kT then | "
        "heat per atom, 10-90% gas | " + " | ".join(f"dT/dQ {s}" for s in STAGES) + " |",
        "|---" * (5 + len(STAGES)) + "|",
    ]
    for run, tb in zip(runs, boiling):
        slopes = " | ".join(f"{run.slope(s) * run.atoms:.3g}" for s in STAGES)
        lines.append(
            f"| {run.pressure:g} | {run.plateau():.3f} | {tb:.3f} | {run.plateau(liquid=False):.3f} | "
            f"{run.vaporisation_heat():.2f} | {slopes} |"
        )
    notes = [(run.pressure, above_critical(run)) for run in runs]
    lines += [f"\nLid pressure {pressure:g}:{note}." for pressure, note in notes if note]
    lines += [
        "",
        "dT/dQ (of all atoms' kT) is given per atom (N dT/dQ, the inverse of the heat capacity per atom): small",
        "where heat goes into a phase change. The curve's boiling point comes from the coexistence study",
        "(assets/coexistence_lj_lfs25.csv). The heat per atom while the gas share rose from 10% to 90% includes",
        "what warmed the liquid and the vapour meanwhile, so it exceeds the enthalpy of vaporisation at the boiling",
        "point (the coexistence study's 3.6 at kT 0.80, 4.4 at 0.70).",
        "",
    ]
    return "\n".join(lines)


def plot(path: Path, runs: list[HeatingRun]) -> None:
    """T against Q per atom for each lid pressure, with the curve's boiling point at each pressure dashed."""
    plt = pyplot()
    if plt is None:
        return
    boiling = _boiling_points(runs)
    fig, ax = plt.subplots(figsize=(7.5, 4), layout="constrained")
    for k, (run, tb) in enumerate(zip(runs, boiling)):
        colour = f"C{k}"
        q = run.heat / run.atoms
        ax.plot(q, run.temperature, "-", color=colour, lw=1, label=f"all atoms, lid pressure {run.pressure:g}")
        condensed = np.where(run.gas < 0.9, run.liquid_temperature, np.nan)  # (the last few atoms: noise)
        ax.plot(q, condensed, ":", color=colour, lw=1, label=f"solid and liquid, {run.pressure:g}")
        ax.axhline(tb, color=colour, ls="--", lw=0.8, label=f"boiling point of the measured curve at {run.pressure:g}")
    ax.set(xlabel="heat from the heater per atom (eps)", ylabel="kinetic temperature kT (eps)",
           title="Heating curve: a crystal under a lid, heated evenly")  # fmt: skip
    legend_beside(ax)
    save(fig, path)

"""Problem 4 of the study: a Gaussian heat pulse, for the explicit and the implicit heat steppers.

Errors: against the analytic Gaussian (total: space and time) and against the same particles and stepper at a
step 64x smaller (time alone). The explicit stepper's largest stable step is measured by bisection and compared
with linear stability theory, dt_max = 2 / lambda_max of C^-1 L (the heat operator, built densely in NumPy).
"""

from __future__ import annotations

import math

import numpy as np

from ..config.scene import scene_from_dict
from ..physics.heat import lattice_correction, wendland_grad_factor
from ..simulation import Simulation, timed_steps
from .study_runs import STUDY_PATH, Run

SIDE = 25
CENTRE = SIDE / 2
KAPPA = 1.0
T0 = 1.5


def pulse_sim(stepper: str, dt: float) -> Simulation:
    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [SIDE, SIDE], "dt": dt, "precision": "f64"},
        "heat": {"ambient": 0.0, "radius": 2.5, "stepper": stepper},
        "materials": {"cond": {"based_on": "jelly", "conductivity": KAPPA, "particle_mass": 1.0}},
        "bodies": [{"material": "cond", "shape": "box", "lo": [0, 0], "hi": [SIDE, SIDE], "springs": False}],
    }
    sim = Simulation(scene_from_dict(data, STUDY_PATH))
    sim.set_temperatures(gaussian(sim.positions(), T0))
    sim.mark_initial()
    return sim


def gaussian(x: np.ndarray, t: float, amount: float = 100.0) -> np.ndarray:
    r2 = ((x - CENTRE) ** 2).sum(axis=1)
    return amount * np.exp(-r2 / (4 * KAPPA * t)) / (4 * math.pi * KAPPA * t)


def theory_explicit_limit(sim: Simulation) -> float:
    """2 / lambda_max of the explicit heat operator C^-1 L on these particles (dense NumPy eigenvalues)."""
    x = sim.positions()
    n = len(x)
    h = sim.terms.heat.support
    vol = np.ones(n)  # unit density and mass: V = 1
    r = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    g = np.zeros_like(r)
    near = (r > 0) & (r < h)
    grad = np.vectorize(lambda v: wendland_grad_factor(v, h, 2))(r[near])
    correction = lattice_correction(x, vol, h)
    g[near] = 2 * KAPPA * grad / correction
    lap = np.diag(g.sum(axis=1)) - g  # C = 1
    return 2.0 / float(np.linalg.eigvalsh(lap).max())


def measured_explicit_limit(sim: Simulation, steps: int = 200) -> float:
    """Largest dt at which a random temperature field does not grow under the explicit stepper (bisection)."""
    rng = np.random.default_rng(0)
    noise = rng.uniform(-1, 1, sim.model.built.count)
    lo, hi = 0.0, 1.0
    for _ in range(16):
        mid = 0.5 * (lo + hi)
        sim.reset()
        sim.set_temperatures(noise)
        sim.dt = mid
        sim.step(steps)
        grew = not np.all(np.isfinite(sim.temperatures())) or np.abs(sim.temperatures()).max() > 1.0
        lo, hi = (lo, mid) if grew else (mid, hi)
    return 0.5 * (lo + hi)


def heat_runs(quick: bool) -> tuple[list[Run], dict]:
    end = 0.64 if quick else 2.56  # a whole number of steps for every dt in the ladders
    dts = [0.08, 0.04, 0.02] if quick else [0.16, 0.08, 0.04, 0.02, 0.01, 0.005]
    runs, notes = [], {}
    for stepper in ("explicit", "implicit"):
        sim = pulse_sim(stepper, dts[0])
        n = sim.model.built.count
        ref_dt = min(dts) / 64
        sim.dt = ref_dt
        sim.step(round(end / ref_dt))
        reference = sim.temperatures().copy()
        exact = gaussian(sim.positions(), T0 + end)
        for dt in dts:
            sim.reset()
            sim.dt = dt
            steps = round(end / dt)
            wall = timed_steps(sim, steps)
            temp = sim.temperatures()
            stable = bool(np.all(np.isfinite(temp)) and np.abs(temp).max() < 1e3)
            total = float(np.linalg.norm(temp - exact) / np.linalg.norm(exact)) if stable else math.inf
            time_err = float(np.linalg.norm(temp - reference) / np.linalg.norm(reference)) if stable else math.inf
            runs.append(
                Run(
                    "heat_pulse_time",
                    stepper,
                    dt,
                    steps,
                    time_err,
                    total,
                    wall,
                    n * steps / wall,
                    stable,
                    "error: against dt/64 (time error); energy_error column: against the analytic Gaussian",
                )
            )
    sim = pulse_sim("explicit", 0.01)
    theory = theory_explicit_limit(sim)
    measured = measured_explicit_limit(sim)
    notes["heat_explicit_dt_limit_measured"] = measured
    notes["heat_explicit_dt_limit_theory"] = theory
    notes["heat_explicit_limit_as_c_in_dt_le_c_h2_over_kappa"] = measured * KAPPA / 1.0**2
    return runs, notes

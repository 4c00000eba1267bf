"""The stability part of the integrator study, on a bank of independent undamped springs (one simulation, each spring
its own stiffness): the largest stable h*w of each integrator, refined around the first unstable spring; forward
Euler and midpoint have none and get their amplitude growth per period instead, next to the theory. The oscillator
problem (study_problems.py) uses the same bank.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.scene import scene_from_dict
from ..integrators import REGISTRY
from ..simulation import Simulation
from .study_runs import STUDY_PATH


# ---------------------------------------------------------------------------- problem 1 and stability: springs
def spring_bank(
    h_omegas: np.ndarray | list[float],
    dt: float,
    integrator: str = "symplectic_euler",
    amplitude: float = 0.1,
    damping: float = 0.0,
) -> Simulation:
    """Independent two-particle springs (unit masses, rest length 1), spring m stiff enough that h w_m equals
    h_omegas[m] at step dt (w = sqrt(2k/m) for the pair's relative motion); each starts stretched by `amplitude`."""
    h_omegas = np.asarray(h_omegas, dtype=float)
    m = len(h_omegas)
    data = {  # walls far away in x: an unstable spring must be free to grow, not be caught by a wall
        "world": {
            "dim": 2,
            "lo": [-1e12, 0],
            "hi": [1e12, 3 * m + 3],
            "dt": dt,
            "precision": "f64",
            "integrator": integrator,
            "substeps": 1,
        },
        "materials": {"spring": {"based_on": "jelly", "damping": damping, "particle_mass": 1.0}},
        "bodies": [
            {"material": "spring", "shape": "box", "lo": [2, 1 + 3 * k], "hi": [4, 2 + 3 * k], "spring_radius": 1.0}
            for k in range(m)
        ],
    }
    sim = Simulation(scene_from_dict(data, STUDY_PATH))
    set_bank_stiffness(sim, h_omegas, dt)
    x = sim.particles.x.to_numpy()
    x[1 : 2 * m : 2, 0] += amplitude
    sim.particles.x.from_numpy(x)
    sim.mark_initial()
    return sim


def set_bank_stiffness(sim: Simulation, h_omegas: np.ndarray, dt: float) -> np.ndarray:
    """Give spring m the stiffness k = (h_omegas[m] / dt)^2 / 2 (unit masses); returns k."""
    k = (np.asarray(h_omegas, dtype=float) / dt) ** 2 / 2
    sim.state.springs.ks.from_numpy(k)
    sim.dt = dt
    return k


def bank_energy(sim: Simulation, k: np.ndarray) -> np.ndarray:
    """Energy of each spring's relative motion: 1/2 mu v_rel^2 + 1/2 k ext^2 (mu = 1/2)."""
    x, v = sim.positions(), sim.velocities()
    ext = np.linalg.norm(x[1::2] - x[0::2], axis=1) - 1.0
    vrel = v[1::2] - v[0::2]
    return 0.25 * (vrel**2).sum(axis=1) + 0.5 * k * ext**2


def bank_growth(sim: Simulation, h_omegas: np.ndarray, steps: int) -> np.ndarray:
    """Energy ratio E(steps)/E(0) of each spring of the bank after `steps` steps from its initial state."""
    sim.reset()
    k = set_bank_stiffness(sim, h_omegas, sim.dt)
    e0 = bank_energy(sim, k)
    sim.step(steps)
    with np.errstate(over="ignore", invalid="ignore"):
        ratio = bank_energy(sim, k) / e0
    return np.where(np.isfinite(ratio), ratio, np.inf)


BANK_SIZE = 120
# Growth runs start each spring 1e-6 from rest: even a 1e4-fold amplitude growth keeps it far below its rest
# length, where a spring is a linear oscillator (squeezed through zero length it is not, and growth saturates).
LINEAR_AMPLITUDE = 1e-6


def amplification(sim: Simulation, h_omegas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trace and determinant of each bank spring's one-step map of (extension, dt x relative velocity), measured by
    stepping the integrator once from two states: stretched at rest, and unstretched and moving. The springs lie
    along the first axis and move along it, where a spring is exactly linear, so the map is the method's own
    amplification matrix (to round-off, about 1e-13 at the bank's amplitude of 0.01)."""
    columns = []
    dt = sim.dt
    for stretched in (True, False):
        sim.reset()
        set_bank_stiffness(sim, h_omegas, dt)
        x0 = sim.positions()
        a = np.linalg.norm(x0[1::2] - x0[0::2], axis=1) - 1.0  # the bank's initial stretch
        if not stretched:
            x = sim.particles.x.to_numpy()
            v = np.zeros_like(sim.particles.v.to_numpy())
            x[1 : 2 * len(a) : 2, 0] -= a  # back to rest length ...
            v[1 : 2 * len(a) : 2, 0] = a / dt  # ... moving apart at a/dt
            sim.particles.x.from_numpy(x)
            sim.particles.v.from_numpy(v)
        sim.step(1)
        x, v = sim.positions(), sim.velocities()
        ext = (x[1::2, 0] - x[0::2, 0] - 1.0) / a
        vel = (v[1::2, 0] - v[0::2, 0]) * dt / a
        columns.append((ext, vel))
    (m11, m21), (m12, m22) = columns
    return m11 + m22, m11 * m22 - m12 * m21


def stable_limit(
    integrator: str,
    sim: Simulation | None = None,
    top: float = 4.0,
    refinements: int = 3,
    tolerance: float = 1e-9,
) -> dict:
    """Largest stable h*w on the undamped spring: a bank of springs up to h*w = `top` is scanned and the bracket
    around the first unstable one refined (each pass narrows it BANK_SIZE-fold). Unstable: the one-step map has an
    eigenvalue outside the unit circle by more than `tolerance`, i.e. the amplitude grows at all (Schur-Cohn for a
    2 x 2 map: |det| <= 1 and |trace| <= 1 + det). `sim`: a spring_bank of BANK_SIZE springs to reuse."""
    lo, hi = 0.0, top
    grid = np.linspace(lo, hi, BANK_SIZE + 1)[1:]
    sim = sim or spring_bank(grid, 0.01, integrator, amplitude=0.01)
    sim.set_integrator(integrator)
    for _ in range(refinements):
        trace, det = amplification(sim, grid)
        grows = (np.abs(det) > 1 + tolerance) | (np.abs(trace) > 1 + det + tolerance) | ~np.isfinite(trace * det)
        unstable = np.flatnonzero(grows)
        if len(unstable) == 0:
            return {"integrator": integrator, "h_omega_limit": math.inf, "searched_up_to": float(grid[-1])}
        first = unstable[0]
        if first == 0 and lo == 0.0:
            return {"integrator": integrator, "h_omega_limit": 0.0, "searched_up_to": float(grid[-1])}
        lo, hi = (grid[first - 1], grid[first]) if first > 0 else (lo, grid[0])
        grid = np.linspace(lo, hi, len(grid) + 1)[1:]
    return {"integrator": integrator, "h_omega_limit": float(0.5 * (lo + hi)), "searched_up_to": top}


def unconditional_check(integrator: str, h_omegas=(1.0, 10.0, 100.0, 1000.0), steps: int = 10) -> dict:
    """For an unconditionally stable method: the energy ratio after `steps` steps at large h*w, one spring at a
    time (CG's residual is relative to the whole right-hand side, so springs of very different stiffness in one
    solve would not each be solved to the tolerance), with backward Euler's theory (1 + (h w)^2)^-steps beside
    it: its numerical damping."""
    sim = spring_bank([1.0], 0.01, integrator, amplitude=LINEAR_AMPLITUDE)
    sim.integrator.tolerance = 1e-12
    row = {"integrator": integrator, "h_omega_limit": math.inf, "searched_up_to": float(max(h_omegas))}
    for hw in h_omegas:
        row[f"energy_ratio_after_{steps}_steps_at_{hw:g}"] = float(bank_growth(sim, np.array([hw]), steps)[0])
        row[f"theory_energy_ratio_after_{steps}_steps_at_{hw:g}"] = (1 + hw**2) ** -steps
    return row


def growth_per_period(integrator: str, h_omega: float, periods: int = 1, sim: Simulation | None = None) -> float:
    """Measured amplitude factor per oscillation period at h*w, from the energy ratio after a whole number of
    periods (E scales as amplitude^2 for these methods: each step is a scaled rotation). Few periods, so the
    spring's extension stays well below its rest length (a spring squeezed through zero length is not linear)."""
    sim = sim or spring_bank([h_omega], 0.01, integrator, amplitude=LINEAR_AMPLITUDE)
    sim.set_integrator(integrator)
    steps = round(periods * 2 * math.pi / h_omega)
    bank = np.full(len(sim.state.springs.ks.to_numpy()), h_omega)
    ratio = float(bank_growth(sim, bank, steps)[0])
    return ratio ** (0.5 / (steps * h_omega / (2 * math.pi)))


def theory_growth_per_period(integrator: str, h_omega: float) -> float:
    """|amplification per step|^(steps per period) for the explicit methods on the undamped oscillator."""
    per_step = {"forward_euler": math.sqrt(1 + h_omega**2), "midpoint": math.sqrt(1 + h_omega**4 / 4)}[integrator]
    return per_step ** (2 * math.pi / h_omega)


def stability_rows(integrators, quick: bool) -> list[dict]:
    """Each integrator on the undamped spring: its largest stable h*w (stable_limit), or for an unconditionally
    stable method its damping at large h*w, or for forward Euler and midpoint their growth per period; with the
    theory beside each. One spring bank is shared by the integrators."""
    bank = single = None
    rows = []
    for name in integrators:
        if REGISTRY[name].stable_h_omega == 0:
            row = {"integrator": name, "h_omega_limit": 0.0, "searched_up_to": 0.0}
        elif math.isinf(REGISTRY[name].stable_h_omega):
            row = unconditional_check(name)
        else:
            bank = bank or spring_bank(np.linspace(0, 4, BANK_SIZE + 1)[1:], 0.01, amplitude=0.01)
            row = stable_limit(name, bank, refinements=2 if quick else 3)
        row["theory"] = REGISTRY[name].stable_h_omega
        if name in ("forward_euler", "midpoint"):
            single = single or spring_bank([0.1], 0.01, amplitude=LINEAR_AMPLITUDE)
            for hw in (0.1, 0.5):
                row[f"growth_per_period_at_{hw}"] = growth_per_period(name, hw, sim=single)
                row[f"theory_growth_per_period_at_{hw}"] = theory_growth_per_period(name, hw)
        rows.append(row)
    return rows

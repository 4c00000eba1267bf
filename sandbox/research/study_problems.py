"""The integrator study's reference problems, each run for one integrator at a time (study.py plans and runs them).
Each problem's reference is not the method under test:

1. oscillator     one undamped spring: the analytic solution (position error at T, and energy error)
2. lattice        a damped spring lattice falling and spinning under gravity: RK4 at a step 64x smaller than the
                  smallest tested (its own error estimated by Richardson from a run at twice that step, and
                  reported). Not velocity Verlet: with velocity-dependent (damping) forces both Verlet methods
                  evaluate the damper with a velocity half a step old and drop to first order.
3. lj_cluster     a 2D Lennard-Jones droplet: energy drift per unit time over a long run (no reference needed)
4. heat_pulse     a Gaussian heat pulse: the analytic solution (total error) and the same particles at a step 64x
                  smaller (time error alone), for the explicit and the implicit heat stepper (heat_study.py)
5. melting        the melting block (small): molten fraction and centre of mass against a converged run

Stability (study_stability.py): the largest stable h*w of each integrator on the undamped spring, on a bank of
independent springs.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..config.resources import SCENES_DIR
from ..config.scene import load_scene, scene_from_dict
from ..simulation import Simulation, timed_steps
from .study_runs import STUDY_PATH, Run
from .study_stability import bank_energy, set_bank_stiffness, spring_bank


def oscillator_runs(integrators, h_omegas, periods: float = 2.125) -> list[Run]:
    """Problem 1: one spring with w = 2 pi (period 1) for `periods` periods at each h*w; error against the analytic
    extension A cos(w t), energy error |E - E0| / E0. The end is not at an extremum of cos, so both phase and
    amplitude errors show."""
    omega, amplitude = 2 * math.pi, 0.1
    sim = spring_bank([0.1], 0.1 / omega)
    runs = []
    for name in integrators:
        warmed(sim, name)
        for hw in h_omegas:
            dt = hw / omega
            steps = round(periods * 2 * math.pi / hw)
            sim.reset()
            k = set_bank_stiffness(sim, [hw], dt)
            e0 = bank_energy(sim, k)[0]
            wall = timed_steps(sim, steps)
            x = sim.positions()
            ext = np.linalg.norm(x[1] - x[0]) - 1.0
            err = abs(ext - amplitude * math.cos(omega * sim.time))
            e_err = abs(bank_energy(sim, k)[0] - e0) / e0
            runs.append(
                Run(
                    "oscillator",
                    name,
                    dt,
                    steps,
                    float(err),
                    float(e_err),
                    wall,
                    2 * steps / wall,
                    bool(np.isfinite(err) and err < 10 * amplitude),
                )
            )
    return runs


def warmed(sim: Simulation, name: str) -> Simulation:
    """Switch to integrator `name` and compile its kernels with one step, then reset: timed runs exclude compiling."""
    sim.set_integrator(name)
    sim.step(1)
    sim.reset()
    return sim


def fitted_order(dts, errors, last: int = 3) -> float:
    """Least-squares slope of log(error) against log(dt) over the `last` smallest steps (the asymptotic range)."""
    dts, errors = np.asarray(dts, float), np.asarray(errors, float)
    order = np.argsort(dts)[:last]
    dts, errors = dts[order], errors[order]
    keep = np.isfinite(errors) & (errors > 0)
    if keep.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(dts[keep]), np.log(errors[keep]), 1)[0])


# ---------------------------------------------------------------------------- problem 2: damped lattice
def lattice_sim(integrator: str, dt: float) -> Simulation:
    """A 6 x 6 damped spring lattice, spinning and falling under gravity in a large box (no wall contact)."""
    data = {
        "world": {
            "dim": 2,
            "lo": [0, 0],
            "hi": [60, 60],
            "dt": dt,
            "precision": "f64",
            "gravity": [0, -9.8],
            "integrator": integrator,
            "implicit_tolerance": 1e-10,
        },
        "materials": {"gel": {"based_on": "jelly", "stiffness": 400.0, "damping": 2.0}},
        "bodies": [{"material": "gel", "shape": "box", "lo": [27, 40], "hi": [33, 46], "jitter": 0.1, "seed": 7}],
    }
    sim = Simulation(scene_from_dict(data, STUDY_PATH))
    x = sim.positions()
    centre = x.mean(axis=0)
    v = np.zeros_like(sim.particles.v.to_numpy())
    r = x - centre
    v[: len(x)] = 3.0 * np.stack([-r[:, 1], r[:, 0]], axis=1)  # spin at 3 rad/s
    sim.particles.v.from_numpy(v)
    sim.mark_initial()
    return sim


def lattice_reference(dts, end_time: float) -> tuple[np.ndarray, dict]:
    """The lattice's positions at `end_time` by RK4 at the smallest of `dts` / 64 ((n, 2) array), and notes with
    that step and its error estimated by Richardson extrapolation from a run at twice the step."""
    dt_ref = min(dts) / 64
    sim = lattice_sim("rk4", dt_ref)
    sim.step(round(end_time / dt_ref))
    ref = sim.positions()
    sim.reset()
    sim.dt = 2 * dt_ref
    sim.step(round(end_time / (2 * dt_ref)))
    ref_error = float(np.sqrt(((sim.positions() - ref) ** 2).sum(axis=1).mean()) / 15)  # Richardson, order 4
    return ref, {"lattice_reference (rk4) dt": dt_ref, "lattice_reference_error (Richardson)": ref_error}


def lattice_runs(integrators, dts, end_time: float, ref: np.ndarray) -> list[Run]:
    """Problem 2 for each of `integrators` at each of `dts`: RMS position error at `end_time` against `ref`."""
    sim = lattice_sim(integrators[0], max(dts))
    runs = []
    n = sim.model.built.count
    for name in integrators:
        warmed(sim, name)
        for dt in dts:
            sim.reset()
            sim.dt = dt
            steps = round(end_time / dt)
            wall = timed_steps(sim, steps)
            err = float(np.sqrt(((sim.positions() - ref) ** 2).sum(axis=1).mean()))
            runs.append(
                Run(
                    "lattice",
                    name,
                    dt,
                    steps,
                    err,
                    float("nan"),
                    wall,
                    n * steps / wall,
                    bool(np.isfinite(err) and err < 10),
                )
            )
    return runs


# ---------------------------------------------------------------------------- problem 3: LJ droplet
def lj_cluster_runs(integrators, dts, end_time: float) -> list[Run]:
    """Energy drift of a 2D LJ droplet: the error is max |E(t) - E0| / |E0| over the run, and the note gives the
    fitted drift per unit time."""
    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [40, 40], "dt": dts[0], "precision": "f64", "neighbor_list": True},
        "pair": {"a": 8.0, "b": 14.0, "cutoff": 2.5},
        "bodies": [
            {
                "material": "lj",
                "shape": "disk",
                "lattice": "hex",
                "center": [20, 20],
                "radius": 4.5,
                "spacing": 1.1225,
                "springs": False,
                "random_velocity": 0.3,
                "seed": 11,
            }
        ],
    }
    sim = Simulation(scene_from_dict(data, STUDY_PATH))
    n = sim.model.built.count
    runs = []
    for name in integrators:
        warmed(sim, name)
        for dt in dts:
            sim.reset()
            sim.dt = dt
            e0 = sim.stats().total_energy
            samples, times = [e0], [0.0]
            steps = round(end_time / dt)
            chunk = max(1, steps // 50)
            t0 = time.perf_counter()
            done = 0
            stable = True
            while done < steps:
                sim.step(min(chunk, steps - done))
                done += min(chunk, steps - done)
                try:
                    samples.append(sim.stats().total_energy)
                except Exception:  # a blow-up is a result here, not a failure
                    stable = False
                    break
                times.append(sim.time)
            wall = time.perf_counter() - t0
            e = np.asarray(samples)
            err = float(np.max(np.abs(e - e0)) / abs(e0)) if stable else float("inf")
            drift = float(np.polyfit(times, e, 1)[0] / abs(e0)) if stable and len(times) > 2 else float("nan")
            runs.append(
                Run(
                    "lj_cluster",
                    name,
                    dt,
                    done,
                    err,
                    err,
                    wall,
                    n * done / max(wall, 1e-9),
                    stable,
                    f"drift per unit time {drift:.3g}",
                )
            )
    return runs


# ---------------------------------------------------------------------------- problem 5: melting block
def melting_sim(integrator: str, dt: float) -> Simulation:
    """The melting block cut to 16 x 12 particles, in double precision."""

    over = ["bodies.0.lo=[56.0, 0.0]", "bodies.0.hi=[72.0, 12.0]", "world.precision='f64'"]
    over += [f"world.integrator='{integrator}'", f"world.dt={dt}"]
    return Simulation(load_scene(SCENES_DIR / "melting_block.toml", over))


def melting_reference(dts, end_time: float) -> tuple[tuple[float, np.ndarray], dict]:
    """The small melting block's molten fraction and centre of mass at `end_time` by velocity Verlet at the
    smallest of `dts` / 16, and notes naming that step and fraction."""
    dt_ref = min(dts) / 16
    ref = melting_sim("velocity_verlet", dt_ref)
    ref.step(round(end_time / dt_ref))
    molten = ref.stats().molten_fraction
    notes = {"melting_reference_dt": dt_ref, "melting_reference_molten_fraction": molten}
    return (molten, ref.positions().mean(axis=0)), notes


def melting_runs(integrators, dts, end_time: float, ref: tuple[float, np.ndarray]) -> list[Run]:
    """Problem 5 for each of `integrators` at each of `dts`: centre-of-mass distance and molten-fraction difference
    at `end_time` against `ref` (from melting_reference)."""
    ref_molten, ref_com = ref
    sim = melting_sim("symplectic_euler", dts[0])
    runs = []
    for name in integrators:
        warmed(sim, name)
        for dt in dts:
            sim.reset()
            sim.dt = dt
            steps = round(end_time / dt)
            t0 = time.perf_counter()
            stable = True
            try:
                sim.step(steps)
                s = sim.stats()
            except Exception:
                stable = False
            wall = time.perf_counter() - t0
            if stable:
                err = float(np.linalg.norm(sim.positions().mean(axis=0) - ref_com))
                molten = abs(s.molten_fraction - ref_molten)
            else:
                err, molten = float("inf"), float("inf")
            runs.append(
                Run(
                    "melting",
                    name,
                    dt,
                    steps,
                    err,
                    molten,
                    wall,
                    sim.model.built.count * steps / wall,
                    stable,
                    "error: centre of mass distance; energy_error column: molten fraction difference",
                )
            )
    return runs


# ---------------------------------------------------------------------------- stiff sweep
def stiff_sweep(integrators, stiffnesses, substeps_list, frame_time: float = 1 / 60, frames: int = 20) -> list[dict]:
    """For k/m over many decades at a fixed frame rate, the fewest substeps per frame (from `substeps_list`) at which
    each integrator keeps a damped lattice bounded (one simulation: a lattice per stiffness, independent)."""
    m = len(stiffnesses)
    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [10 * m + 10, 20], "dt": frame_time, "precision": "f64"},
        "materials": {"gel": {"based_on": "jelly", "damping": 0.0, "particle_mass": 1.0}},
        "bodies": [
            {"material": "gel", "shape": "box", "lo": [5 + 10 * k, 5], "hi": [9 + 10 * k, 9], "jitter": 0.2, "seed": k}
            for k in range(m)
        ],
    }
    sim = Simulation(scene_from_dict(data, STUDY_PATH))
    per_body = sim.model.built.count // m
    springs_per_body = sim.state.springs.count // m
    ks = np.repeat(np.asarray(stiffnesses, float), springs_per_body)
    x0 = sim.positions()
    v = sim.particles.v.to_numpy()
    v[: len(x0)] = np.random.default_rng(3).normal(0, 0.05, x0.shape)  # a small kick into every mode
    sim.particles.v.from_numpy(v)
    sim.state.springs.ks.from_numpy(ks)
    sim.mark_initial()
    rows = []
    for name in integrators:
        warmed(sim, name)
        needed = {k: None for k in stiffnesses}
        for sub in substeps_list:
            if all(v is not None for v in needed.values()):
                break  # bounded at every stiffness; more substeps stay bounded
            sim.reset()
            sim.dt = frame_time / sub
            sim.step(frames * sub)
            x = sim.positions()
            disp = np.linalg.norm(x - x0, axis=1).reshape(m, per_body).max(axis=1)
            ok = np.isfinite(disp) & (disp < 1.0)
            for k, good in zip(stiffnesses, ok):
                if good and needed[k] is None:
                    needed[k] = sub
        for k in stiffnesses:
            rows.append(
                {
                    "integrator": name,
                    "k_over_m": k,
                    "min_substeps": needed[k],
                    "h_omega_at_that": (frame_time / needed[k]) * math.sqrt(2 * k * 8) if needed[k] else None,
                }
            )
    return rows

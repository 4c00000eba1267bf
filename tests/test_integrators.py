"""Every integrator: convergence orders, stability limits against theory, energy behaviour, stiff and extreme cases."""

import math

import numpy as np
import pytest

from sandbox.errors import SimulationError
from sandbox.integrators import REGISTRY
from sandbox.research import study, study_problems, study_report, study_stability
from sandbox.simulation import Simulation

from .conftest import make_scene, scene_dict

pytestmark = [pytest.mark.xdist_group("study"), pytest.mark.long]  # one worker builds the session fixture, once

ALL = study.INTEGRATORS


@pytest.fixture(scope="session")
def quick(tmp_path_factory):
    """`sandbox study --quick` once for the module: its numbers are what these tests hold."""
    out = tmp_path_factory.mktemp("study")
    return out, study.run_study(out, quick=True, log=lambda line: None)


@pytest.mark.slow  # the quick study (session fixture)
@pytest.mark.parametrize("name", ALL)
def test_convergence_order_on_the_undamped_spring(quick, name):
    runs = [r for r in quick[1].runs if r.problem == "oscillator" and r.integrator == name]
    order = study_problems.fitted_order([r.dt for r in runs], [r.error for r in runs])
    assert abs(order - REGISTRY[name].order) <= 0.15, order


@pytest.mark.slow  # the quick study (session fixture)
@pytest.mark.parametrize("name", ALL)
def test_convergence_order_on_the_damped_lattice(quick, name):
    runs = [r for r in quick[1].runs if r.problem == "lattice" and r.integrator == name]
    order = study_problems.fitted_order([r.dt for r in runs], [r.error for r in runs])
    assert abs(order - study_report.theory_order("lattice", name)) <= 0.2, order
    assert quick[1].notes["lattice_reference_error (Richardson)"] < 1e-3 * min(r.error for r in runs)


@pytest.mark.slow  # the quick study (session fixture)
@pytest.mark.parametrize(
    "name, theory", [("symplectic_euler", 2.0), ("verlet", 2.0), ("velocity_verlet", 2.0), ("rk4", 2 * math.sqrt(2))]
)
def test_largest_stable_step_matches_theory(quick, name, theory):
    """The limit is where the amplitude starts to grow at all: to the quick study's bracket (4 / 120^2)."""
    row = next(r for r in quick[1].stability if r["integrator"] == name)
    assert row["h_omega_limit"] == pytest.approx(theory, abs=4 / 120**2)


@pytest.mark.slow  # the quick study (session fixture)
@pytest.mark.parametrize("name", ["forward_euler", "midpoint"])
def test_explicit_euler_and_midpoint_grow_at_every_step_as_theory_says(quick, name):
    row = next(r for r in quick[1].stability if r["integrator"] == name)
    assert row["h_omega_limit"] == 0.0
    for hw in (0.1, 0.5):
        measured = row[f"growth_per_period_at_{hw}"]
        assert measured > 1.0
        assert measured == pytest.approx(study_stability.theory_growth_per_period(name, hw), rel=1e-6)


def test_implicit_euler_is_stable_at_any_step_with_the_theoretical_damping():
    row = study_stability.unconditional_check("implicit_euler", h_omegas=(0.5, 10.0, 1000.0), steps=10)
    for hw in (0.5, 10.0, 1000.0):
        ratio = row[f"energy_ratio_after_10_steps_at_{hw:g}"]
        # backward Euler multiplies the oscillator's energy by 1 / (1 + (h w)^2) each step: excess damping
        assert ratio == pytest.approx((1 + hw**2) ** -10, rel=1e-3)


def long_run_energy(name, periods, hw=1.9, amplitude=0.01):
    """Relative energy error of one undamped spring over `periods` periods, sampled 50 times. h w = 1.9 (near the
    limit 2, about 3.3 steps per period) keeps 10^4 periods to 33,000 steps."""
    sim = study_stability.spring_bank([hw], 0.01, name, amplitude=amplitude)
    k = study_stability.set_bank_stiffness(sim, [hw], 0.01)
    e0 = study_stability.bank_energy(sim, k)[0]
    steps = round(periods * 2 * math.pi / hw)
    worst = []
    for _ in range(50):
        sim.step(steps // 50)
        worst.append(abs(study_stability.bank_energy(sim, k)[0] - e0) / e0)
    return np.array(worst)


@pytest.mark.parametrize("name, periods", [("symplectic_euler", 10_000), ("verlet", 2_000), ("velocity_verlet", 2_000)])
def test_symplectic_energy_error_stays_bounded_over_thousands_of_periods(name, periods):
    # 10^4 periods for symplectic Euler; 2,000 for the Verlets, whose steps cost 1.3-1.7x more (suite time)
    err = long_run_energy(name, periods)
    # bounded: the energy swings (a symplectic map keeps a modified energy, not the true one) but the swing over
    # the last 2,000 periods is no larger than over the first 2,000: no drift
    assert np.all(np.isfinite(err))
    assert err[-10:].max() <= 1.05 * err[:10].max()


def test_forward_euler_energy_grows():
    err = long_run_energy("forward_euler", 5, hw=0.5, amplitude=1e-6)
    assert np.all(np.diff(err) > 0) and err[-1] > 1e4  # energy x 1.25 per step at h w = 0.5, 50 steps


@pytest.mark.slow  # the quick study (session fixture)
def test_heat_steppers_are_first_order_in_time_and_the_explicit_limit_matches_theory(quick):
    res = quick[1]
    for stepper in ("explicit", "implicit"):
        mine = [r for r in res.runs if r.problem == "heat_pulse_time" and r.integrator == stepper]
        order = study_problems.fitted_order([r.dt for r in mine], [r.error for r in mine])
        assert abs(order - 1.0) <= 0.15, (stepper, order)
        assert all(r.energy_error < 0.03 for r in mine)  # total error against the analytic Gaussian
    measured, theory = res.notes["heat_explicit_dt_limit_measured"], res.notes["heat_explicit_dt_limit_theory"]
    assert measured == pytest.approx(theory, rel=0.02)


@pytest.mark.slow  # the quick study (session fixture)
def test_quick_study_writes_its_report(quick):
    out, res = quick
    for name in ("runs.csv", "stability.csv", "stiff.csv", "report.md"):
        assert (out / name).stat().st_size > 100
    report = (out / "report.md").read_text()
    assert "## Convergence orders" in report and "| rk4 |" in report
    rows = (out / "runs.csv").read_text().splitlines()
    assert rows[0].startswith("problem,integrator,dt,steps,error,energy_error,wall_seconds,particle_steps_per_second")
    assert len(rows) - 1 == len(res.runs)
    stiff = {(r["integrator"], r["k_over_m"]): r["min_substeps"] for r in res.stiff}
    assert stiff[("implicit_euler", 1e8)] == 1  # stays bounded at one step per frame at any stiffness
    assert stiff[("symplectic_euler", 1e8)] is None or stiff[("symplectic_euler", 1e8)] >= 64
    drift = {r.integrator: r.error for r in res.runs if r.problem == "lj_cluster"}
    assert drift["velocity_verlet"] < drift["forward_euler"]


def test_integrators_switch_live_and_keep_the_state():
    sim = study_stability.spring_bank([0.1, 0.2], 0.01)
    x0 = sim.positions().copy()
    for name in ALL:
        sim.set_integrator(name)
        assert sim.integrator.name == name
        assert np.allclose(sim.positions(), x0)


# ------------------------------------------------------------------------------ stability guard and auto substeps
def stiff_lattice(integrator="symplectic_euler", substeps=1, stiffness=1e6, **world):
    w = {
        "dim": 2,
        "lo": [0, 0],
        "hi": [20, 20],
        "dt": 1 / 60,
        "substeps": substeps,
        "integrator": integrator,
        "frame_time": 1 / 60,
    }
    w.update(world)
    data = scene_dict(
        world=w,
        materials={"stiff": {"based_on": "jelly", "stiffness": stiffness, "damping": 0.0}},
        bodies=[
            {"material": "stiff", "shape": "box", "lo": [5, 5], "hi": [9, 9], "jitter": 0.2, "random_velocity": 0.05}
        ],
    )
    return Simulation(make_scene(data))


def test_guard_names_the_limit_for_each_integrator():
    sim = stiff_lattice()
    with pytest.raises(SimulationError, match=r"above the stable limit .* symplectic_euler"):
        for _ in range(50):
            sim.advance_frame()
            sim.stats()
    fe = stiff_lattice("forward_euler")
    with pytest.raises(SimulationError, match="forward_euler is unstable on undamped springs at any step"):
        for _ in range(50):
            fe.advance_frame()
            fe.stats()


def test_auto_substeps_keep_a_stiff_lattice_stable():
    sim = stiff_lattice(substeps="auto")
    n, h = sim.frame_substeps()
    assert h * sim.terms.springs.omega_max() <= 1.0 + 1e-9  # half the symplectic Euler limit
    assert n == math.ceil((1 / 60) * sim.terms.springs.omega_max() / 1.0)
    x0 = sim.positions()
    for _ in range(20):
        sim.advance_frame()
        sim.stats()
    assert np.abs(sim.positions() - x0).max() < 0.5
    assert sim.time == pytest.approx(20 / 60)
    implicit = stiff_lattice("implicit_euler", substeps="auto")
    assert implicit.frame_substeps()[0] == 1  # unconditionally stable: only the speed bound and dt remain


# ------------------------------------------------------------------------------ extreme cases
def test_extreme_temperatures_stay_finite():
    for temperature in (0.0, 1e6):
        data = scene_dict(
            world={"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.002, "gravity": [0, -9.8]},
            pair={"a": 8.0, "b": 14.0},
            heat={"ambient": temperature},
            bodies=[{"material": "wax", "shape": "box", "lo": [10, 0], "hi": [18, 6], "temperature": temperature}],
        )
        sim = Simulation(make_scene(data))
        sim.step(200)
        s = sim.stats()
        assert np.isfinite(s.total_energy) and np.all(np.isfinite(sim.temperatures()))
        assert s.molten_fraction == (1.0 if temperature > 60 else 0.0)


def test_a_spring_stretched_a_thousandfold_breaks_instead_of_exploding():
    data = scene_dict(
        world={"dim": 2, "lo": [0, 0], "hi": [3000, 30], "dt": 0.001},
        bodies=[{"material": "jelly", "shape": "box", "lo": [10, 10], "hi": [12, 11], "spring_radius": 1.0}],
    )
    sim = Simulation(make_scene(data))
    x = sim.particles.x.to_numpy()
    x[1, 0] = x[0, 0] + 1000.0
    sim.particles.x.from_numpy(x)
    sim.step(1)
    assert sim.state.springs.alive.to_numpy()[0] == 0
    assert np.all(np.isfinite(sim.velocities())) and np.abs(sim.velocities()).max() < 1e-6


def test_a_body_hitting_a_wall_at_high_speed_stays_inside_and_finite():
    data = scene_dict(
        world={"dim": 2, "lo": [0, 0], "hi": [40, 20], "dt": 0.001, "restitution": 0.5},
        bodies=[{"material": "jelly", "shape": "box", "lo": [10, 5], "hi": [16, 11], "velocity": [-5000.0, 0.0]}],
    )
    sim = Simulation(make_scene(data))
    try:
        for _ in range(20):
            sim.step(5)
            sim.stats()
    except SimulationError as err:  # acceptable: a named error, not garbage
        assert "step" in str(err) and "particle" in str(err)
        return
    x = sim.positions()
    assert np.all(np.isfinite(x)) and x[:, 0].min() >= 0.5 - 1e-5 and x[:, 0].max() <= 39.5 + 1e-5


def _textbook_velocity_verlet(x, v, k, dt, steps):
    """Velocity Verlet on one undamped spring of rest length 1 between unit masses, in NumPy, the textbook way."""

    def accel(x):
        d = x[1] - x[0]
        r = np.linalg.norm(d)
        f0 = k * (r - 1.0) * d / r
        return np.array([f0, -f0])

    a = accel(x)
    for _ in range(steps):
        v = v + 0.5 * dt * a
        x = x + dt * v
        a = accel(x)
        v = v + 0.5 * dt * a
    return x, v


def test_velocity_verlet_as_leapfrog_is_the_textbook_method_and_its_velocities_are_synchronised():
    """One force evaluation a step (leapfrog), yet the positions and the velocities read after any step() are those
    of the textbook velocity Verlet (to round-off); how the steps are split into calls changes nothing, bit for bit;
    a velocity written between calls is taken as the velocity at that instant."""
    sim = study_stability.spring_bank([0.3], 0.01, "velocity_verlet", amplitude=0.1)
    k = study_stability.set_bank_stiffness(sim, [0.3], 0.01)[0]
    x0, v0 = sim.positions().copy(), sim.velocities().copy()
    sim.step(500)
    x, v = _textbook_velocity_verlet(x0, v0, k, 0.01, 500)
    assert np.abs(sim.positions() - x).max() < 1e-12 and np.abs(sim.velocities() - v).max() < 1e-12
    at_once = sim.positions().copy(), sim.velocities().copy()
    sim.reset()
    study_stability.set_bank_stiffness(sim, [0.3], 0.01)
    for _ in range(50):
        sim.step(10)
    assert np.array_equal(sim.positions(), at_once[0]) and np.array_equal(sim.velocities(), at_once[1])
    kicked = sim.particles.v.to_numpy()
    kicked[0] += [0.0, 0.25]  # a tool's push between two calls
    sim.particles.v.from_numpy(kicked)
    x1, v1 = sim.positions().copy(), sim.velocities().copy()
    sim.step(100)
    x, v = _textbook_velocity_verlet(x1, v1, k, 0.01, 100)
    assert np.abs(sim.positions() - x).max() < 1e-12 and np.abs(sim.velocities() - v).max() < 1e-12


def test_position_verlet_as_leapfrog_is_the_textbook_method():
    """Drift-kick-drift with the half drifts of neighbouring steps merged: the positions and velocities read after
    any step() are the textbook method's (to round-off), however the steps are split into calls."""
    sim = study_stability.spring_bank([0.3], 0.01, "verlet", amplitude=0.1)
    k = study_stability.set_bank_stiffness(sim, [0.3], 0.01)[0]
    x, v = sim.positions().copy(), sim.velocities().copy()
    for _ in range(500):
        x = x + 0.005 * v
        d = x[1] - x[0]
        f0 = k * (np.linalg.norm(d) - 1.0) * d / np.linalg.norm(d)
        v = v + 0.01 * np.array([f0, -f0])
        x = x + 0.005 * v
    sim.step(500)
    assert np.abs(sim.positions() - x).max() < 1e-12 and np.abs(sim.velocities() - v).max() < 1e-11
    at_once = sim.positions().copy(), sim.velocities().copy()
    sim.reset()
    study_stability.set_bank_stiffness(sim, [0.3], 0.01)
    for _ in range(25):
        sim.step(20)
    assert np.array_equal(sim.positions(), at_once[0]) and np.array_equal(sim.velocities(), at_once[1])

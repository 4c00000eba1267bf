"""The coexistence study's measurements (research/coexistence.py) against the engine's own, and its command line."""

import dataclasses

import numpy as np
import pytest

from sandbox.app.cli import main
from sandbox.config.scene import scene_from_dict
from sandbox.research.coexistence import (
    NIST_LFS_PSAT,
    Rescaler,
    argon_pressure_kpa,
    measure_snapshot,
    slab_scene,
)
from sandbox.research.study_runs import STUDY_PATH
from sandbox.simulation import Simulation

from .conftest import ROOT

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)


def test_the_slab_analysis_agrees_with_the_engine_and_the_rescaler_holds_the_temperature_and_momentum():
    sim = Simulation(scene_from_dict(slab_scene(0.8, width=7.5, thickness=6.0), STUDY_PATH))
    box = np.array(sim.scene.world.hi)
    p0 = sim.velocities().sum(axis=0)
    rescale = Rescaler(sim, 0.8, tau=0.1, seed=1)
    temps = []
    for k in range(150):
        sim.step(10)
        rescale.apply(10 * sim.state.dt)
        if k >= 50:
            temps.append(sim.stats().motion_temperature)
    assert np.mean(temps) == pytest.approx(0.8, rel=0.03)
    assert np.abs(sim.velocities().sum(axis=0) - p0).max() < 1e-9  # scaled about the centre of mass
    z, energy, p_zz, p_vapour = measure_snapshot(sim.positions(), sim.velocities(), box, 1.0)
    s = sim.stats()
    assert energy.sum() == pytest.approx(s.pair_energy, rel=1e-9)  # the same pairs and the same force-shifted law
    assert np.all(np.abs(z) <= box[2] / 2)
    assert np.isfinite(p_zz) and np.isfinite(p_vapour)


def test_the_slabs_as_worlds_are_the_slabs_run_alone():
    """run_slabs runs its temperatures as the worlds of one simulation: every measured number equals the lone run's."""
    from sandbox.core import runtime
    from sandbox.research.coexistence import run_slab, run_slabs

    temperatures = [0.7, 0.85]
    together = run_slabs(temperatures, equilibrate=200, produce=600, every=100, dim=2)
    for temperature, point in zip(temperatures, together):
        runtime.reset()
        alone = run_slab(temperature, equilibrate=200, produce=600, every=100, dim=2)
        assert dataclasses.replace(point, seconds=0.0) == dataclasses.replace(alone, seconds=0.0)
    assert together[0].rho_vapour < together[1].rho_vapour  # the hotter slab's vapour is denser


def test_argon_units_and_the_nist_table():
    assert argon_pressure_kpa(1.0) == pytest.approx(41_900, rel=0.01)  # epsilon / sigma^3 for argon: 41.9 MPa
    assert sorted(NIST_LFS_PSAT) == [0.65, 0.70, 0.75, 0.80, 0.85, 0.90]
    assert all(a < b for a, b in zip(NIST_LFS_PSAT.values(), list(NIST_LFS_PSAT.values())[1:]))


@pytest.mark.parametrize("text", ["0.8,hot", "0.1", "2.0", "nan"])
def test_bad_temperatures_get_one_line_and_a_nonzero_exit(text, tmp_path, capsys):
    code = main(["study", "--coexistence", "--temperatures", text, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code != 0 and "--temperatures" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "coexistence.md").exists()


# NIST's LAMMPS-MD equation of state of the linear-force-shifted LJ fluid at 2.5 sigma (N = 10,000, Nose-Hoover):
# (kT, density) -> (pressure, its error, energy per atom)
NIST_LFS_EOS = {(1.00, 0.010): (9.677e-03, 5.384e-07, -6.727e-02), (0.75, 0.010): (7.068e-03, 8.143e-07, -8.455e-02)}


@pytest.mark.parametrize("kt, density", sorted(NIST_LFS_EOS))
def test_a_dilute_gas_matches_nists_equation_of_state_for_the_same_truncation(kt, density):
    """The pressure and pair energy per atom of the molecular model at a state point NIST tabulates for the same
    force-shifted potential; the gas's non-ideality (p / (rho kT) - 1: -3% at kT 1, -6% at kT 0.75) is what is
    tested, so the tolerance is a small part of it. The pair energy of a dilute gas is its few dimers': one run's
    mean wanders by about 5% (kT 1: -0.0598 to -0.0677 over four thermostat seeds, while its own block averages
    claimed 2%), so three independent runs are averaged (each the thermostat's own seed, from the same start)."""
    spacing = density ** (-1 / 3)
    side = 8 * spacing  # 8^3 = 512 atoms on a simple cubic lattice filling the periodic box
    data = slab_scene(kt, width=side, thickness=side)
    data["world"]["hi"] = [side] * 3
    data["bodies"][0].update(lo=[0.0] * 3, hi=[side] * 3, spacing=spacing)
    sim = Simulation(scene_from_dict(data, STUDY_PATH))
    assert sim.state.live_count() == 512
    runs = []
    for seed in (3, 4, 5):
        sim.reset()
        rescale = Rescaler(sim, kt, tau=0.5, seed=seed)
        pressures, energies = [], []
        for k in range(2000):
            sim.step(10)
            rescale.apply(10 * sim.state.dt)
            if k >= 400 and k % 5 == 0:
                s = sim.stats()
                pressures.append(s.pressure)
                energies.append(s.pair_energy / s.particles)
        runs.append((np.mean(pressures), np.mean(energies)))
    pressure, energy = np.mean(runs, axis=0)
    assert len({u for _, u in runs}) == 3  # three trajectories, not one thrice
    p_nist, _, u_nist = NIST_LFS_EOS[(kt, density)]
    ideal = density * kt
    assert pressure - ideal == pytest.approx(p_nist - ideal, rel=0.25)  # the non-ideal part
    assert pressure == pytest.approx(p_nist, rel=0.01)
    assert energy == pytest.approx(u_nist, rel=0.1)


def test_the_measured_phase_diagram_places_its_dot_at_the_measured_state_on_the_studys_own_curve():
    from types import SimpleNamespace

    from sandbox.config.scene import load_scene
    from sandbox.measure.coexistence_curve import curve_of
    from sandbox.render.measured_phase_plot import MeasuredPhasePlot
    from sandbox.simulation import Simulation as Sim

    sim = Sim(load_scene(ROOT / "scenes" / "pressure_cooker.toml"))
    curve = curve_of(sim.model)
    assert curve is not None
    # the fitted line passes through the study's points within 10% and ends at the fitted critical point
    for t, p in zip(curve.temperatures, curve.pressures):
        assert float(curve.vapour_pressure(t)) == pytest.approx(p, rel=0.1)
    assert 0.85 < curve.critical_temperature < 1.0 and np.isnan(curve.vapour_pressure(1.2))
    assert (
        curve.region(0.7, 0.05) == "liquid" and curve.region(0.8, 0.01) == "gas" and curve.region(1.1, 0.1) == "fluid"
    )
    plot = MeasuredPhasePlot(curve, (0, 600, 0, 200), 14)
    states = [(0.70 + 0.01 * k, 0.02 + 0.001 * k) for k in range(10)]
    for t, p in states:
        plot.record(SimpleNamespace(motion_temperature=t, lid_pressure=p, wall_pressure=float("nan"), pressure=9.0))
    t, p = plot.dot()
    assert (t, p) == pytest.approx(tuple(np.mean(states, axis=0)))  # the measured means, the lid's gauge first
    assert plot.dot_region() == curve.region(t, p)
    image = np.zeros((200, 600, 3), np.uint8)
    plot.label(image)
    assert (image == [255, 70, 40]).all(axis=2).any()  # the dot is drawn


def test_a_scene_of_another_pair_law_has_no_measured_curve():
    from sandbox.measure.coexistence_curve import curve_of

    data = slab_scene(0.8, width=9.5, thickness=6.0)
    data["pair"]["cutoff"] = 3.0
    assert curve_of(Simulation(scene_from_dict(data, STUDY_PATH)).model) is None
    data["pair"]["cutoff"] = 2.5
    assert curve_of(Simulation(scene_from_dict(data, STUDY_PATH)).model) is not None

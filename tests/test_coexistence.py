"""The coexistence study's measurements (research/coexistence.py) against the engine's own, and its command line."""

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


def test_argon_units_and_the_nist_table():
    assert argon_pressure_kpa(1.0) == pytest.approx(41_900, rel=0.01)  # epsilon / sigma^3 for argon: 41.9 MPa
    assert sorted(NIST_LFS_PSAT) == [0.65, 0.70, 0.75, 0.80, 0.85, 0.90]
    assert all(a < b for a, b in zip(NIST_LFS_PSAT.values(), list(NIST_LFS_PSAT.values())[1:]))


@pytest.mark.parametrize("text", ["0.8,hot", "0.3", "2.0", "nan"])
def test_bad_temperatures_get_one_line_and_a_nonzero_exit(text, tmp_path, capsys):
    code = main(["study", "--coexistence", "--temperatures", text, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code != 0 and "--temperatures" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "coexistence.md").exists()

"""The melting block end to end: heat melts it, no heat keeps it solid, in 2D and 3D."""

import numpy as np
import pytest

from sandbox.config.scene import load_scene
from sandbox.simulation import Simulation

from .conftest import SCENES

SMALL_2D = ["bodies.0.lo=[56.0, 0.0]", "bodies.0.hi=[72.0, 12.0]"]  # 16 x 12 instead of 40 x 30: same physics
SMALL_3D = ["bodies.0.lo=[21.0, 0.0, 21.0]", "bodies.0.hi=[27.0, 5.0, 27.0]"]


def run_frames(sim, frames):
    history = []
    for _ in range(frames):
        sim.step(sim.scene.world.substeps)
        history.append(sim.stats())
    return history


def test_melting_block_melts_and_spreads():
    sim = Simulation(load_scene(SCENES / "melting_block.toml", SMALL_2D))
    x0 = sim.positions()
    width0 = np.ptp(x0[:, 0])
    first = sim.stats()
    assert first.molten_fraction == 0.0 and first.broken_springs == 0
    history = run_frames(sim, 120)
    molten = [s.molten_fraction for s in history]
    assert molten[-1] > 0.9
    assert molten[10] < 0.5  # it takes time: the heat has to diffuse up from the plate
    assert history[-1].broken_springs == sim.state.springs.built_count  # all of them, and none refroze on the plate
    x = sim.positions()
    # it slumps: wider and lower (this small block stays a cohesive blob; the full-size one spreads out)
    assert np.ptp(x[:, 0]) > width0 + 1.5
    assert x[:, 1].mean() < 0.85 * x0[:, 1].mean()
    assert all(np.isfinite(s.total_energy) for s in history)


def test_melting_block_without_heating_stays_solid():
    sim = Simulation(load_scene(SCENES / "melting_block.toml", SMALL_2D + ["heat.sources.0.temperature=20.0"]))
    x0 = sim.positions()
    history = run_frames(sim, 60)
    assert all(s.molten_fraction == 0.0 and s.broken_springs == 0 for s in history)
    assert np.allclose(sim.temperatures(), 20.0, atol=1e-3)
    assert np.ptp(sim.positions()[:, 0]) < np.ptp(x0[:, 0]) + 1.0  # it keeps its shape


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_melting_block_3d_melts():
    sim = Simulation(load_scene(SCENES / "melting_block_3d.toml", SMALL_3D))
    assert sim.dim == 3
    history = run_frames(sim, 40)
    assert history[0].molten_fraction < 0.5 < history[-1].molten_fraction
    assert history[-1].mean_temperature > history[0].mean_temperature


def test_plateau_finds_the_longest_level_stretch_of_a_heating_curve():
    import sandbox

    t = np.linspace(0.0, 10.0, 501)
    wiggle = 0.3 * np.sin(7.0 * t)
    curve = np.where(t < 2.0, -15.0 + 7.5 * t, np.where(t < 6.0, 0.0 + wiggle, 10.0 * (t - 6.0)))
    found = sandbox.plateau(t, curve, tolerance=0.5)
    assert found.start == pytest.approx(2.0, abs=0.15) and found.end == pytest.approx(6.0, abs=0.15)  # 1 °C of slope
    assert abs(found.level) < 0.1 and found.duration == pytest.approx(4.0, abs=0.3)
    assert str(found).startswith("level at ")
    assert sandbox.plateau(t, 5.0 * t, tolerance=0.01) is None or sandbox.plateau(t, 5.0 * t, 0.01).duration < 0.05
    with pytest.raises(ValueError, match="1D arrays of one length"):
        sandbox.plateau(t, curve[:-1])

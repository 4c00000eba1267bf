"""The blow-up guard stops an unstable run from its first frame, with the cause named, keeping only sane frames."""

import csv
import math
import re

import numpy as np
import pytest

from sandbox.app.cli import EXIT_STOPPED, main
from sandbox.app.tools import Tools
from sandbox.config.scene import load_scene
from sandbox.config.schema import ABSOLUTE_ZERO
from sandbox.errors import SimulationError
from sandbox.measure.guard import RUNAWAY_FACTOR
from sandbox.simulation import Simulation
from tests.conftest import SCENES, make_scene, scene_dict

SMALL = ["--headless", "--quiet", "--width", "64", "--height", "48"]


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_a_blow_up_in_the_first_frames_stops_with_the_cause_and_keeps_only_the_frames_before(tmp_path, capsys):
    frames, stats = tmp_path / "frames", tmp_path / "stats.csv"
    args = ["run", "spring_lattice", *SMALL, "--frames", "6", "--set", "world.dt=0.05"]
    code = main([*args, "--out", str(frames), "--stats", str(stats)])
    err = capsys.readouterr().err
    assert code == EXIT_STOPPED
    warning = err.index("warning: dt 0.05 is above the springs' stable limit")
    started = err.index("spring_lattice: 432 particles")
    assert warning < started  # the same warning as `sandbox check`, before the run starts
    assert "error: the blow-up guard stopped the run" in err and "above the stable limit 0.0204" in err
    assert "at step 16" in err  # the second frame of 8 steps: the first was still drawable
    rows = _rows(stats)
    pictures = sorted(frames.glob("*.png"))
    assert len(rows) == len(pictures) == 1  # exactly the frames before the stop, each with its row
    sim = Simulation(load_scene(SCENES / "spring_lattice.toml", ["world.dt=0.05"]))
    limit = RUNAWAY_FACTOR * sim.guard.limits.energy_scale(float(np.sum(sim.model.built.mass)))
    for row in rows:
        assert row["mean_temperature"] == row["heat_content"] == ""  # no heat in this scene: not measured
        values = [float(v) for v in row.values() if v != ""]
        assert all(math.isfinite(v) for v in values)
        assert float(row["kinetic_energy"]) < limit


def test_a_blow_up_in_the_first_frame_writes_no_video(tmp_path, capsys):
    video, stats = tmp_path / "jelly.mp4", tmp_path / "stats.csv"
    args = ["run", "spring_lattice", *SMALL, "--frames", "4", "--set", "materials.jelly.stiffness=1e8"]
    assert main([*args, "--out", str(video), "--stats", str(stats)]) == EXIT_STOPPED
    err = capsys.readouterr().err
    assert "stable limit 5e-05" in err and "no frame was drawn" in err
    assert not video.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stats.csv"]  # no partial file left behind
    assert _rows(stats) == []  # the header only


def test_a_heat_blow_up_is_named_before_any_row_goes_below_absolute_zero(tmp_path, capsys):
    stats = tmp_path / "stats.csv"
    over = ["--set", "world.dt=0.05", "--set", "world.integrator='implicit_euler'"]  # springs stable, heat not
    code = main(["run", "melting_block", *SMALL, "--frames", "3", *over, "--stats", str(stats)])
    err = capsys.readouterr().err
    assert code == EXIT_STOPPED
    assert "below absolute zero" in err and "above the explicit heat limit" in err
    coldest = re.search(r"temperature (\S+) C, below absolute zero .* \(at (\S+) C\)", err)
    assert coldest and coldest.group(1) == coldest.group(2)  # the particle named is the coldest
    assert all(float(r["mean_temperature"]) >= ABSOLUTE_ZERO for r in _rows(stats))


def test_the_limits_come_from_the_scene_not_from_a_measured_frame():
    sim = Simulation(load_scene(SCENES / "spring_lattice.toml"))
    b = sim.model.built
    kinetic = 0.5 * np.sum(b.mass * np.sum(b.v**2, axis=1))
    springs = 0.5 * np.sum(b.stiffness * b.rest_length**2)
    assert sim.guard.limits.fixed_energy == pytest.approx(kinetic + springs, rel=1e-12)
    size, g = 96.0, 9.8
    assert sim.guard.limits.specific_energy == pytest.approx(g * size + 0.5 * 6.0**2, rel=1e-12)
    assert sim.guard.limits.step_travel == 27.0  # half the domain's smaller side
    before = vars(sim.guard.limits).copy()
    sim.advance_frame()
    sim.stats()
    assert vars(sim.guard.limits) == before  # measuring never moves the limits


def test_tools_put_energy_in_without_tripping_the_guard_and_cooling_stops_at_absolute_zero():
    sim = Simulation(make_scene(scene_dict(heat={"ambient": 20.0})))
    tools = Tools(sim)
    centre = [6.5, 6.5]
    tools.apply("cool", centre, 5.0, dt=10.0)  # 4,000 degrees of cooling asked for
    assert sim.particles.T.to_numpy()[: sim.model.built.count].min() == pytest.approx(ABSOLUTE_ZERO, abs=1e-3)
    mass = float(np.sum(sim.model.built.mass))
    allowed = RUNAWAY_FACTOR * sim.guard.limits.energy_scale(mass)
    sim.stats()
    for _ in range(3):  # a hard push: far more kinetic energy than the scene allowed
        tools.apply("impulse", centre, 5.0, dt=0.01, strength=50.0)
    assert sim.stats().kinetic_energy > 10 * allowed
    sim.advance_frame()
    sim.stats()  # and accepted as part of the scene from then on


def test_a_non_finite_state_is_named_at_once():
    sim = Simulation(make_scene(scene_dict()))
    v = sim.particles.v.to_numpy()
    v[3] = [np.nan, 0.0]
    sim.particles.v.from_numpy(v)
    with pytest.raises(SimulationError, match="non-finite state at step 0 .* in particle 3"):
        sim.stats()


def test_after_a_blow_up_particles_warn_and_save_refuses_until_a_restore(tmp_path):
    """particles() after the guard stopped the run says the values are not physical; save() writes nothing (a state
    file of NaN would be refused on load anyway); reset() brings back a state that saves."""
    sim = Simulation(make_scene(scene_dict()))
    v = sim.particles.v.to_numpy()
    v[3] = [np.inf, 0.0]
    sim.particles.v.from_numpy(v)
    with pytest.raises(SimulationError):
        sim.stats()
    with pytest.warns(UserWarning, match="past a blow-up"):
        assert not np.isfinite(sim.particles()["velocity"]).all()
    with pytest.raises(SimulationError, match="not saved: the state is past a blow-up"):
        sim.save(tmp_path / "broken.npz")
    assert not list(tmp_path.iterdir())
    sim.broken = None  # even unmeasured, a non-finite state is not written
    with pytest.raises(SimulationError, match="not saved: .*particles.v holds a value that is not finite"):
        sim.save(tmp_path / "broken.npz")
    assert not list(tmp_path.iterdir())
    sim.reset()
    assert sim.save(tmp_path / "good.npz").exists()


def test_save_into_an_unwritable_place_is_one_clear_error(tmp_path):
    from sandbox.errors import OutputError

    sim = Simulation(make_scene(scene_dict()))
    with pytest.raises(OutputError, match=r"could not write /proc/x.npz: .*expected a writable folder"):
        sim.save("/proc/x.npz")

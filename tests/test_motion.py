"""Free fall against 1/2 g t^2, walls, and the stability guard."""

import numpy as np
import pytest

from sandbox.config.scene_tables import INTEGRATORS
from sandbox.errors import SimulationError
from sandbox.integrators import REGISTRY
from sandbox.simulation import Simulation

from .conftest import make_scene, scene_dict

G = 9.8


def falling(integrator, dt, precision="f64", **world):
    w = {
        "dim": 2,
        "lo": [0, 0],
        "hi": [10, 1000],
        "dt": dt,
        "gravity": [0, -G],
        "integrator": integrator,
        "precision": precision,
    }
    w.update(world)
    data = scene_dict(
        world=w, bodies=[{"material": "jelly", "shape": "box", "lo": [4, 900], "hi": [5, 901], "springs": False}]
    )
    return Simulation(make_scene(data))


@pytest.mark.parametrize("integrator, sign", [("symplectic_euler", -1), ("forward_euler", +1)])
def test_free_fall_first_order_error_is_exactly_half_g_dt_t(integrator, sign):
    # Symplectic Euler: y_n = y0 - g t^2/2 - g dt t/2; forward Euler: ... + g dt t/2.
    errors = []
    for dt in (0.02, 0.01):
        sim = falling(integrator, dt)
        y0 = sim.positions()[0, 1]
        sim.step(round(1.0 / dt))
        t = sim.time
        err = sim.positions()[0, 1] - (y0 - 0.5 * G * t * t)
        assert err == pytest.approx(sign * 0.5 * G * dt * t, rel=1e-9)
        errors.append(abs(err))
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=1e-6)  # first order


def test_velocity_verlet_free_fall_is_exact():
    sim = falling("velocity_verlet", 0.05)
    y0 = sim.positions()[0, 1]
    sim.step(20)
    assert sim.positions()[0, 1] == pytest.approx(y0 - 0.5 * G * sim.time**2, abs=1e-9)
    assert sim.velocities()[0, 1] == pytest.approx(-G * sim.time, abs=1e-9)


def test_every_listed_integrator_is_registered():
    assert set(INTEGRATORS) == set(REGISTRY)


def test_wall_bounce_keeps_restitution_and_stays_inside():
    sim = falling("symplectic_euler", 0.001, precision="f32", restitution=0.5, hi=[10, 1000])
    v = sim.particles.v.to_numpy()
    v[0] = [0.0, -50.0]
    sim.particles.v.from_numpy(v)
    x = sim.particles.x.to_numpy()
    x[0] = [4.5, 1.0]
    sim.particles.x.from_numpy(x)
    sim.step(30)  # hits the floor within 0.01 s and rebounds
    assert sim.positions()[0, 1] >= 0.5 - 1e-6
    assert sim.velocities()[0, 1] == pytest.approx(25.0 - G * 0.03, rel=0.02)


def test_extreme_speed_is_clamped_by_the_walls():
    sim = falling("symplectic_euler", 0.01, precision="f32")
    v = sim.particles.v.to_numpy()
    v[0] = [1e6, 0.0]  # crosses the domain many times over in one step
    sim.particles.v.from_numpy(v)
    sim.step(3)
    x = sim.positions()[0]
    assert np.all(np.isfinite(x)) and 0.5 - 1e-6 <= x[0] <= 9.5 + 1e-6


def test_blow_up_stops_with_a_named_error():
    data = scene_dict(
        world={"dim": 2, "lo": [0, 0], "hi": [20, 20], "dt": 0.05},
        materials={"stiff": {"based_on": "jelly", "stiffness": 1e7, "damping": 0.0}},
        bodies=[{"material": "stiff", "shape": "box", "lo": [5, 5], "hi": [9, 9], "jitter": 0.2}],
    )
    sim = Simulation(make_scene(data))
    assert sim.stable_dt() < 0.05
    with pytest.raises(SimulationError, match=r"dt 0.05 is above the stable limit .* symplectic_euler"):
        for _ in range(100):
            sim.step(1)
            sim.stats()

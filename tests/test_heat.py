"""Heat diffusion: exact conservation with insulated walls, the analytic Gaussian, sources and the ambient."""

import numpy as np
import pytest

from sandbox.simulation import Simulation

from .conftest import make_scene, scene_dict

L = 41


def lattice_scene(precision="f32", dt=0.02, heat=None, **extra):
    data = scene_dict(
        world={"dim": 2, "lo": [0, 0], "hi": [L, L], "dt": dt, "precision": precision},
        heat=heat or {"ambient": 0.0, "radius": 2.5},
        materials={"cond": {"based_on": "jelly", "conductivity": 1.0}},
        bodies=[{"material": "cond", "shape": "box", "lo": [0, 0], "hi": [L, L], "springs": False}],
    )
    data.update(extra)
    return Simulation(make_scene(data))


def gaussian(r2, t, kappa=1.0, amount=100.0):
    """Heat kernel in 2D: a pulse of total `amount` (in T x area) after time t."""
    return amount * np.exp(-r2 / (4 * kappa * t)) / (4 * np.pi * kappa * t)


def test_heat_pulse_spreads_like_the_analytic_gaussian():
    # 41 x 41 unit lattice, kappa = k / (rho c) = 1, kernel support 2.5 spacings, dt = 0.02 (limit ~0.34).
    # Started as the exact solution at t0 = 2, compared at t = 4 and 6 in the relative L2 norm over all particles.
    # Measured: 1.5% and 1.4% (the kernel's spatial smoothing; the time error is below 0.1%). Bound: 2.5%.
    sim = lattice_scene(precision="f64")
    x = sim.positions()
    r2 = ((x - 20.5) ** 2).sum(axis=1)
    sim.set_temperatures(gaussian(r2, 2.0))
    for _ in range(2):
        sim.step(100)
        exact = gaussian(r2, 2.0 + sim.time)
        err = np.linalg.norm(sim.temperatures() - exact) / np.linalg.norm(exact)
        assert err < 0.025, err
    # without the lattice correction the same run is 3.4% too slow in diffusivity, which this bound catches
    assert 1.03 < 1 / sim.terms.heat.correction < 1.04


def pulse_error(spacing: float, heat: dict, side: float = 16.0) -> float:
    """Relative L2 error of a Gaussian pulse (kappa = 1) carried from t = 1 to t = 2 at `spacing`, dt = 0.02 h^2."""
    dt = 0.02 * spacing**2
    data = scene_dict(
        world={"dim": 2, "lo": [0, 0], "hi": [side, side], "dt": dt, "precision": "f64"},
        heat={"ambient": 0.0, **heat},
        materials={"cond": {"based_on": "jelly", "conductivity": 1.0}},
        bodies=[{"material": "cond", "shape": "box", "lo": [0, 0], "hi": [side, side], "springs": False}],
    )
    data["bodies"][0]["spacing"] = spacing
    sim = Simulation(make_scene(data))
    r2 = ((sim.positions() - side / 2) ** 2).sum(axis=1)
    sim.set_temperatures(gaussian(r2, 1.0))
    sim.step(round(1.0 / dt))
    exact = gaussian(r2, 2.0)
    return float(np.linalg.norm(sim.temperatures() - exact) / np.linalg.norm(exact))


@pytest.mark.long  # a convergence study: `python3 -m pytest -m long`
def test_heat_pulse_refinement_converges_at_order_two_with_the_default_radius():
    # heat.radius is in particle spacings, so halving the spacing halves the kernel: measured 3.08%, 0.755%, 0.189%
    # (orders 2.03, 2.00). Given as a fixed length instead, the kernel's smoothing stays: 3.31% at spacing 0.5.
    errors = [pulse_error(h, {}) for h in (1.0, 0.5, 0.25)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.9) & (orders < 2.1)), (errors, orders)
    assert errors[-1] < 0.0025
    fixed = pulse_error(0.5, {"radius_length": 2.5})
    assert fixed > 0.9 * errors[0], (fixed, errors)


def test_heat_is_conserved_to_round_off_with_insulated_walls():
    sim = lattice_scene(precision="f64", dt=0.05)
    rng = np.random.default_rng(1)
    sim.set_temperatures(rng.uniform(0, 500, sim.model.built.count))
    before = sim.temperatures().sum()
    sim.step(200)
    after = sim.temperatures()
    assert abs(after.sum() - before) < 1e-11 * before
    assert after.std() < 0.2 * 500 / np.sqrt(12)  # and it did diffuse


def test_heat_conserved_in_a_moving_liquid_f32():
    data = scene_dict(
        world={"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.002, "gravity": [0, -9.8]},
        pair={"a": 8.0, "b": 14.0, "cutoff": 2.5},
        heat={"ambient": 20.0},
        bodies=[
            {"material": "wax", "shape": "box", "lo": [5, 5], "hi": [20, 15], "springs": False, "random_velocity": 1.0}
        ],
    )
    sim = Simulation(make_scene(data))
    rng = np.random.default_rng(2)
    sim.set_temperatures(rng.uniform(20, 200, sim.model.built.count))  # some solid, some melting, some liquid
    before = sim.stats().heat_content  # sum of m h, latent heat included
    assert 0.5 < sim.stats().molten_fraction < 1
    assert np.isclose(before, float(sim.model.built.mass @ (2.5 * sim.temperatures() + 200.0 * sim.melt_fractions())))
    sim.step(300)
    after = sim.stats().heat_content
    assert abs(after - before) < 2e-6 * before


def test_plate_heats_only_what_touches_it_and_ambient_pulls_back():
    heat = {
        "ambient": 20.0,
        "radius": 2.5,
        "sources": [{"lo": [0, 0], "hi": [L, 0.5], "temperature": 100.0, "conductance": 5.0, "reach": 0.0}],
    }
    sim = lattice_scene(heat=heat, dt=0.01)
    sim.set_temperatures(np.full(sim.model.built.count, 20.0))
    sim.step(10)
    T, y = sim.temperatures(), sim.positions()[:, 1]
    assert T[y < 0.6].min() > 20.5  # the bottom row touches the plate
    assert np.all(T[y > 10] < 20.0 + 1e-4)  # far rows are still cold
    sim.step(2000)
    assert np.isclose(sim.temperatures().max(), 100.0, atol=5.0)
    cool = lattice_scene(heat={"ambient": 20.0, "ambient_exchange": 2.0}, dt=0.01)
    cool.set_temperatures(np.full(cool.model.built.count, 80.0))
    cool.step(100)  # dT/dt = -2 (T - 20) / (m c): after t = 1, 60 e^-2 above ambient
    assert np.allclose(cool.temperatures(), 20 + 60 * np.exp(-2.0), rtol=0.01)


def test_only_what_the_scene_uses_is_built():
    sim = lattice_scene()
    assert (
        sim.terms.heat is not None
        and sim.terms.pair is None
        and sim.state.springs is None
        and sim.hood.grid is not None
    )
    assert hasattr(sim.particles, "T")
    no_heat = Simulation(make_scene(scene_dict()))
    assert (
        no_heat.terms.heat is None
        and no_heat.hood is None
        and no_heat.terms.pair is None
        and no_heat.state.springs is not None
    )
    assert not hasattr(no_heat.particles, "T")
    with pytest.raises(AttributeError):
        no_heat.temperatures()


@pytest.mark.parametrize("half", [True, False], ids=["half_lists", "full_lists"])
def test_heat_rates_between_two_materials_follow_the_harmonic_mean_conductance(half):
    """Two materials of different conductivity and density side by side: every particle's enthalpy rate is the sum
    over its neighbours of G_ij (T_j - T_i) / m_i, G_ij = 2 k_i k_j / (k_i + k_j) * W(r) * V_i V_j (V = m / density),
    evaluated here in NumPy; the rates conserve heat (sum of m dh/dt is 0)."""
    data = scene_dict(
        world={"dim": 2, "lo": [0, 0], "hi": [20, 10], "dt": 0.01, "precision": "f64"},
        heat={"ambient": 0.0, "radius": 2.5},
        materials={
            "poor": {"based_on": "jelly", "conductivity": 1.0, "density": 1.0},
            "good": {"based_on": "jelly", "conductivity": 4.0, "density": 2.5},
        },
        bodies=[
            {"material": "poor", "shape": "box", "lo": [2, 2], "hi": [10, 8], "springs": False},
            {"material": "good", "shape": "box", "lo": [10, 2], "hi": [18, 8], "springs": False},
        ],
    )
    sim = Simulation(make_scene(data), half_lists=half)
    assert sim.rates.half == half and not sim.terms.heat.single_material
    n = sim.model.built.count
    rng = np.random.default_rng(3)
    sim.set_temperatures(rng.uniform(0.0, 100.0, n))
    sim.rates.evaluate()
    x, t = sim.positions(), sim.temperatures()
    mass, mat = sim.particles.mass.to_numpy()[:n], sim.particles.material.to_numpy()[:n]
    k = sim.model.materials.host["conductivity"][mat]
    volume = mass / sim.model.materials.host["density"][mat]
    h = sim.terms.heat.support
    r = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    w = np.where((r > 0) & (r < h), (1 - r / h) ** 3, 0.0)
    g = 2 * k[:, None] * k[None, :] / (k[:, None] + k[None, :]) * sim.terms.heat.norm * 40.0 / h**2 * w
    expected = (g * volume[:, None] * volume[None, :] * (t[None, :] - t[:, None])).sum(axis=1) / mass
    rates = sim.rates.heat_rate.to_numpy()[:n]
    assert np.abs(rates - expected).max() <= 1e-9 * np.abs(expected).max()
    assert abs((mass * rates).sum()) <= 1e-12 * (mass * np.abs(rates)).sum()
    assert len(set(mat)) == 2


def test_heat_lengths_are_in_the_scenes_finest_particle_spacing():
    bodies = [
        {"material": "jelly", "shape": "box", "lo": [2, 2], "hi": [8, 8], "spacing": 0.5},
        {"material": "jelly", "shape": "box", "lo": [10, 2], "hi": [18, 8], "spacing": 2.0},
    ]
    scene = make_scene(scene_dict(heat={"radius": 3.0, "refreeze_radius": 2.0}, bodies=bodies))
    assert scene.spacing == 0.5 and scene.heat_radius == 1.5 and scene.refreeze_radius == 1.0
    absolute = make_scene(scene_dict(heat={"radius_length": 2.5}, bodies=bodies))
    assert absolute.heat_radius == 2.5 and absolute.refreeze_radius == 0.75
    assert make_scene(scene_dict(heat={}, bodies=[], scene={"palette": ["wax"]})).spacing == 1.0

"""Phase change: the enthalpy law, the heating curve, the Stefan problem, conservation and the freeze-thaw cycle."""

import numpy as np
import pytest

from sandbox.app.tools import Tools
from sandbox.config.materials import load_library
from sandbox.config.scene import load_scene
from sandbox.core import runtime
from sandbox.physics.phase import ENTHALPY_LAW, enthalpy_np, melt_fraction_np, temperature_np
from sandbox.research.phase_study import heating_curve_run, stefan_lambda, stefan_run
from sandbox.simulation import Simulation

from .conftest import SCENES, make_scene


def test_enthalpy_law_inverts_and_holds_the_temperature_while_melting():
    lib = load_library()
    for name in ("ice", "wax", "glass", "lava", "solder", "chocolate", "butter"):
        m = lib[name]
        args = [getattr(m, key) for key in ENTHALPY_LAW]  # ice: its own specific heat in each phase
        T = np.linspace(m.melt_temperature - 50, m.liquidus_temperature + 150, 801)
        h = enthalpy_np(T, *args)
        assert np.all(np.diff(h) > 0)  # enthalpy rises with temperature
        back, phi = temperature_np(h, *args)
        assert np.allclose(back, T, atol=1e-9)
        assert np.allclose(phi, melt_fraction_np(T, m.melt_temperature, m.liquidus_temperature))
        # across the band (just below the solidus to just above the liquidus) h gains the latent heat beyond c dT
        lo, hi = m.melt_temperature - 1e-6, m.liquidus_temperature + 1e-6
        band = enthalpy_np(hi, *args) - enthalpy_np(lo, *args)
        warming = m.specific_heat * (m.liquidus_temperature - lo) + m.liquid_specific_heat * (
            hi - m.liquidus_temperature
        )
        assert np.isclose(band, warming + m.latent_heat, rtol=1e-12, atol=1e-9)
        if m.boils:  # and across the boiling point the vaporization heat beyond the liquid's and vapour's warming
            lo, hi = m.boil_temperature - 1.0, m.boil_temperature + 1.0
            band = enthalpy_np(hi, *args) - enthalpy_np(lo, *args)
            warming = m.liquid_specific_heat + m.gas_specific_heat
            assert np.isclose(band, warming + m.vaporization_heat, rtol=1e-12)
    ice = lib["ice"]
    plateau = np.linspace(0.0, ice.latent_heat, 11)  # every enthalpy across the latent heat is at 0 C
    T, phi = temperature_np(plateau, ice.specific_heat, 0.0, 0.0, ice.latent_heat)
    assert np.all(T == 0.0) and np.allclose(phi, np.linspace(0, 1, 11))


def test_a_material_based_on_another_keeps_one_specific_heat_or_its_phases_own():
    """A material with one specific heat for every phase keeps one when a scene changes it; ice's liquid and vapour
    keep their own (water 4.18, steam 2.0) when a scene changes the ice's."""
    from sandbox.config.materials import resolve_materials

    made = resolve_materials(
        {"warm_wax": {"based_on": "wax", "specific_heat": 3.0}, "warm_ice": {"based_on": "ice", "specific_heat": 2.2}},
        "scene.toml",
    )
    wax, ice = made["warm_wax"], made["warm_ice"]
    assert (wax.specific_heat, wax.liquid_specific_heat, wax.gas_specific_heat) == (3.0, 3.0, 3.0)
    assert (ice.specific_heat, ice.liquid_specific_heat, ice.gas_specific_heat) == (2.2, 4.18, 2.0)
    steam = resolve_materials({"s": {"based_on": "wax", "liquid_specific_heat": 4.0}}, "scene.toml")["s"]
    assert (steam.specific_heat, steam.liquid_specific_heat, steam.gas_specific_heat) == (2.5, 4.0, 4.0)


def test_every_library_material_has_a_source_note_and_melts_sensibly():
    lib = load_library()
    for name in ("wax", "ice", "chocolate", "butter", "solder", "glass", "lava"):
        m = lib[name]
        assert m.note and m.melts and m.liquidus_temperature >= m.melt_temperature
        assert m.soften_temperature <= m.melt_temperature
    assert lib["glass"].latent_heat == 0 and lib["glass"].liquidus_temperature - lib["glass"].melt_temperature > 200
    assert lib["ice"].latent_heat / lib["ice"].specific_heat > lib["wax"].latent_heat / lib["wax"].specific_heat


def test_heating_curve_plateau_lasts_latent_heat_times_mass_over_power():
    runtime.reset()
    curve = heating_curve_run()
    start, end = curve.plateau
    assert abs((end - start) - curve.expected_plateau) < 0.015 * curve.expected_plateau
    rate = curve.power / curve.mass  # degrees per second when not melting, times the phase's specific heat
    t, T = curve.times, curve.mean_temperature
    before = t < start - 0.02
    after = t > end + 0.02
    assert np.allclose(np.diff(T[before]) / np.diff(t[before]), rate / curve.specific_heat, rtol=1e-3)  # ice
    assert np.allclose(np.diff(T[after]) / np.diff(t[after]), rate / curve.liquid_specific_heat, rtol=1e-3)  # water
    melting = (t > start + 0.02) & (t < end - 0.02)
    assert melting.sum() > 100 and np.all(np.abs(T[melting] - curve.melt_temperature) < 1e-9)


@pytest.mark.long  # a convergence study: `python3 -m pytest -m long`
def test_stefan_front_follows_the_neumann_solution_and_converges():
    assert abs(stefan_lambda(1.0) - 0.6201) < 1e-4  # tabulated: St = 1 gives lambda = 0.620
    runtime.reset()
    coarse = stefan_run(1.0, t_end=60.0)
    runtime.reset()
    fine = stefan_run(0.5, t_end=60.0)
    assert len(coarse.times) == 1200 and len(fine.times) == 4800  # every step (dt = 0.05 h^2): every crossing
    assert coarse.front[-1] > 9.0  # the front ran nine coarse spacings
    assert coarse.error < 0.015, coarse.error
    assert fine.error < 0.6 * coarse.error, (fine.error, coarse.error)


def _wax_scene(**heat):
    return {
        "world": {
            "dim": 2,
            "lo": [0, 0],
            "hi": [30, 16],
            "dt": 0.002,
            "gravity": [0, -9.8],
            "restitution": 0.1,
            "friction": 0.5,
        },
        "pair": {"a": 8.0, "b": 14.0, "cutoff": 2.5},
        "heat": {"ambient": 20.0, **heat},
    }


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_enthalpy_is_conserved_through_melting_and_refreezing():
    runtime.reset()
    data = _wax_scene()
    data["world"]["precision"] = "f64"
    data["bodies"] = [
        {"material": "wax", "shape": "box", "lo": [8, 0], "hi": [22, 4], "temperature": -20.0},
        {"material": "wax", "shape": "box", "lo": [10, 4.2], "hi": [20, 7.2], "springs": False, "temperature": 90.0},
    ]
    sim = Simulation(make_scene(data))
    before = sim.stats()
    assert 0.2 < before.molten_fraction < 0.5
    for _ in range(15):
        sim.step(50)
        now = sim.stats()
        assert abs(now.heat_content - before.heat_content) < 1e-10 * abs(before.heat_content)
    assert now.molten_fraction < 0.5 * before.molten_fraction  # the melt froze onto the cold block ...
    assert int(sim.state.springs.created[None]) > sim.state.springs.built_count + 30  # ... by making new bonds


def _components(n, i, j):
    parent = list(range(n))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in zip(i, j):
        parent[find(a)] = find(b)
    return len({find(a) for a in range(n)})


def _spring_graph(sim):
    alive = sim.state.springs.alive.to_numpy().astype(bool)
    return sim.state.springs.i.to_numpy()[alive], sim.state.springs.j.to_numpy()[alive]


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_freeze_thaw_cycles_make_one_solid_each_time_and_lose_nothing():
    runtime.reset()
    data = _wax_scene(
        sources=[
            {
                "name": "plate",
                "lo": [0, 0],
                "hi": [30, 0.5],
                "reach": 0.6,
                "temperature": 20.0,
                "conductance": 150.0,
                "schedule_times": [0.0, 2.0],
                "schedule_values": [0.0, 120.0],  # cold for 2 s, hot for 2 s, repeating
                "schedule_period": 4.0,
            }
        ]
    )
    data["bodies"] = [
        {"material": "wax", "shape": "box", "lo": [9, 0], "hi": [21, 4], "springs": False, "temperature": 90}
    ]
    sim = Simulation(make_scene(data))
    n = sim.model.built.count
    liquid_before = sim.particles.liquid.to_numpy()[:n].copy()
    assert liquid_before.all()  # a puddle at 90 C
    toggles = np.zeros(n, dtype=int)
    checks = {}
    for _frame in range(300):  # 6 s: cold, hot, cold
        sim.step(10)
        liquid = sim.particles.liquid.to_numpy()[:n]
        toggles += liquid != liquid_before
        liquid_before = liquid.copy()
        t = round(sim.time, 6)
        if t in (2.0, 4.0, 6.0):
            checks[t] = (sim.stats(), _components(n, *_spring_graph(sim)), liquid.sum())
    for t in (2.0, 6.0):  # cooled: one connected solid, nothing liquid
        stats, components, liquid_count = checks[t]
        assert stats.molten_fraction == 0.0 and liquid_count == 0 and components == 1, (t, checks[t])
        assert stats.particles == n and np.isfinite(stats.total_energy)
    stats, components, liquid_count = checks[4.0]  # heated: all molten, every bond broken
    assert stats.molten_fraction == 1.0 and liquid_count == n and components == n
    assert toggles.max() <= 3  # froze, melted, froze: no particle flickered between phases
    # the refrozen puddle is one piece: a hand grabbing its middle and rising lifts all of it off the plate
    tools = Tools(sim)
    x = sim.positions()
    grab = np.array([x[:, 0].mean(), x[:, 1].max()])
    for frame in range(120):
        tools.drag(grab + [0.0, 0.06 * frame], 3.0, 400.0, 0.02)
        sim.step(10)
    lifted = sim.positions()[:, 1]
    assert lifted.min() > 1.0 and lifted.mean() > x[:, 1].mean() + 4.0, (lifted.min(), lifted.mean())


def test_ice_cube_scene_holds_at_zero_while_it_melts():
    runtime.reset()
    sim = Simulation(load_scene(SCENES / "ice_cube.toml"))
    history = []
    for _ in range(120):  # 2.4 s: warming, then melting
        sim.advance_frame()
        history.append(sim.stats())
    melting = [s for s in history if 0.05 < s.molten_fraction < 0.95]
    assert len(melting) > 60 and history[-1].molten_fraction > history[0].molten_fraction
    assert history[0].mean_temperature < -10  # it starts frozen well below 0 ...
    assert all(-0.5 < s.mean_temperature < 1.0 for s in melting)  # ... and holds near 0 C while ice remains

"""Boiling (issue 46, item 2): a liquid hot enough leaves as vapour. While it boils its temperature holds at the
boiling point, as melting holds it at the melting point, for as long as the vaporization heat takes: L_v M / P at
power P; the vapour feels no attraction, so with the thermostat it flies apart and fills its box."""

import numpy as np
import pytest

import sandbox

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)

POWER = 400_000.0  # heat per second (mg kJ/kg per s = mJ/s) shared by mass among every particle


def pot(power: float = POWER):
    """400 water particles at 98 °C in a closed 30 x 30 box, heated at constant power everywhere, the motion coupled
    to the temperature (so the vapour moves)."""
    return sandbox.load(
        {
            "world": {"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.001, "substeps": 20},
            "pair": {"a": 8.0, "b": 14.0, "cutoff": 2.5},
            "heat": {
                "ambient": 20.0,
                "refreeze": False,
                "agitation_time": 0.005,
                "agitation_scale": 0.003,
                "sources": [{"mode": "power", "power": power, "lo": [0, 0], "hi": [30, 30], "visible": False}],
            },
            "bodies": [
                {"material": "ice", "shape": "box", "lo": [5, 0], "hi": [25, 20], "springs": False, "temperature": 98.0}
            ],
        }
    )


def test_boiling_holds_the_temperature_at_the_boiling_point_for_the_vaporization_heat():
    sim = pot()
    mass = float(sim.state.particles.mass.to_numpy()[: sim.model.built.count].sum())
    rows = sim.run(160)
    t, temperature, gas = (np.asarray(rows[k], float) for k in ("time", "mean_temperature", "gas_fraction"))
    start, end = np.argmax(gas >= 0.05), np.argmax(gas >= 0.95)
    assert 0 < start < end, (gas[0], gas[-1])
    boiling = slice(start, end + 1)
    assert temperature[boiling] == pytest.approx(100.0, abs=0.5)  # held at the boiling point
    expected = 0.9 * 2257.0 * mass / POWER  # from 5% to 95% of the vaporization heat
    assert t[end] - t[start] == pytest.approx(expected, rel=0.05)
    assert temperature[-1] > 100.5  # all vapour: it warms again


def test_vapour_fills_its_box_and_is_counted():
    sim = pot()
    sim.run(160)
    x = sim.positions()
    assert sim.stats().gas_fraction == pytest.approx(1.0)
    # the liquid sat below 20; the vapour spreads up through the box (measured: top 23.4, mean height 11.8, and
    # still rising: 26.0 and 12.9 after as long again)
    assert x[:, 1].max() > 22.0 and x[:, 1].mean() > 10.0
    liquid = sandbox.load("ice_cube")
    assert liquid.stats().gas_fraction == 0.0
    # drawn by phase, vapour is the legend's "ice vapour" colour
    from sandbox.render.look import VAPOUR_COLOR
    from sandbox.render.raster import Renderer

    ren = Renderer(sim.model, sim.state, 320, 320, sim.scene.render.__class__(color_by="phase", title=False))
    img = ren.frame().astype(int)
    centres = ren.plan.pixels(sim.state.particles.x.to_numpy()[: int(sim.state.particles.n[None])])
    under = np.array([img[int(r), int(c)] for c, r in centres if 0 <= r < 320 and 0 <= c < 320])
    vapour = np.round(np.asarray(VAPOUR_COLOR) * 255)
    assert (np.abs(under - vapour).max(axis=1) <= 3).mean() > 0.8


@pytest.mark.parametrize("temperature, attraction", [(50.0, 1.0), (150.0, 0.0)])
def test_the_pair_energy_counts_only_the_liquid_shares_attraction(temperature, attraction):
    """The pair energy reported follows the force: between vapour particles (150 C: all boiled) the attraction is
    gone from the energy too (only the shifted repulsion is left); between liquid ones (50 C) it is whole. Checked
    against a NumPy sum of the pair potential over every pair within the cutoff."""
    from sandbox.physics.pair import pair_energy

    drop = dict(material="ice", shape="box", lo=[4, 4], hi=[11.2, 11.2], spacing=1.2, springs=False)
    world = {"dim": 2, "lo": [0, 0], "hi": [20, 20]}
    pair_law = {"a": 8.0, "b": 14.0, "cutoff": 2.5}
    body = dict(drop, temperature=temperature)
    sim = sandbox.load({"world": world, "pair": pair_law, "heat": {"refreeze": False}, "bodies": [body]})
    pair = sim.terms.pair
    x = sim.positions()
    mass = sim.state.particles.mass.to_numpy()[: len(x)]
    alpha, beta, eps = pair.alpha_np[0, 0] * attraction, pair.beta_np[0, 0], pair.eps_np[0, 0]
    expected = 0.0
    for i in range(len(x)):
        for j in range(i + 1, len(x)):
            r = float(np.linalg.norm(x[i] - x[j]))
            if r < pair.cutoff:
                expected += mass[i] * mass[j] * pair_energy(r, alpha, beta, eps, pair.a, pair.b, pair.cutoff)
    assert sim.stats().gas_fraction == (1.0 if temperature > 100 else 0.0)
    assert sim.stats().pair_energy == pytest.approx(expected, rel=1e-4, abs=1e-6)


def test_ice_water_and_steam_each_warm_at_their_own_specific_heat():
    """Heated evenly at constant power P, a phase warms at dT/dt = P / (M c) with its own c: ice 2.1, liquid water
    4.18, steam 2.0 kJ/kg K (handbook values; before, one c served all three), measured from the run's mean
    temperature while the whole mass is in that phase."""
    power = 20_000.0
    sim = sandbox.load(
        {
            "world": {"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.001, "substeps": 20, "gravity": [0, 0]},
            "heat": {
                "ambient": 20.0,
                "refreeze": False,
                "sources": [{"mode": "power", "power": power, "lo": [0, 0], "hi": [30, 30], "visible": False}],
            },
            "bodies": [
                {
                    "material": "ice",
                    "shape": "box",
                    "lo": [10, 10],
                    "hi": [20, 20],
                    "springs": False,
                    "temperature": -50,
                }
            ],
        }
    )
    mass = float(sim.state.particles.mass.to_numpy()[: sim.model.built.count].sum())
    rows = sim.run(760)  # 15.2 s: 3.3 kJ/kg into 92 mg of ice at -50 C, about 190 C at the end
    t, temperature, melt, gas = (
        np.asarray(rows[k], float) for k in ("time", "mean_temperature", "molten_fraction", "gas_fraction")
    )
    phases = {"ice": (melt == 0.0, 2.1), "water": ((melt == 1.0) & (gas == 0.0), 4.18), "steam": (gas == 1.0, 2.0)}
    for name, (inside, c) in phases.items():
        assert inside.sum() >= 10, name
        slope = np.polyfit(t[inside], temperature[inside], 1)[0]
        assert slope == pytest.approx(power / (mass * c), rel=0.01), name

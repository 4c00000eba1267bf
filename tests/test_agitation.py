"""Temperature as motion (issue 46, item 1; pairwise since issue 57): the thermostat keeps free particles' agitation
at their temperature (equipartition, with and without pair forces), a dilute gas presses as n k T / V, a drop keeps
its momentum, the energy moved is counted, runs repeat bit for bit, and scenes that do not ask for it do not build
it."""

import numpy as np
import pytest

import sandbox
from sandbox.physics.agitation import GAS_WEIGHT, KELVIN

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)

SCALE = 0.01  # pJ per kelvin


def gas(
    temperature: float,
    periodic: bool = True,
    pair: bool = False,
    box: float = 40.0,
    velocity=(0.0, 0.0),
    tau: float = 0.05,
    shape: str = "box",
):
    """400 free (molten) wax particles at `temperature` in a `box` x `box` domain, every one held there (no heat
    sources, no conduction differences), coupled to it in `tau` s."""
    lo = (box - 20) / 2
    scene = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [box, box], "periodic": periodic, "dt": 0.002, "substeps": 10},
        "heat": {
            "ambient": temperature,
            "agitation_time": tau,
            "agitation_scale": SCALE,
            "refreeze": False,
        },
        "bodies": [
            {
                "material": "wax",
                "shape": shape,
                "lo": [lo, lo],
                "hi": [lo + 20, lo + 20],
                **({"center": [box / 2, box / 2], "radius": 11.5} if shape == "disk" else {}),
                "springs": False,
                "temperature": temperature,
                "velocity": list(velocity),
            }
        ],
    }
    if pair:
        scene["pair"] = {"a": 8.0, "b": 14.0, "cutoff": 2.5}
    if not periodic:
        scene["world"]["restitution"] = 1.0
        scene["world"]["friction"] = 0.0
    return sandbox.load(scene)


def kinetic_per_component(sim, frames: int = 40) -> float:
    """The mean of m v_a^2 over particles, components and `frames` frames (pJ): kT at equipartition."""
    values = []
    for _ in range(frames):
        sim.run(1)
        parts = sim.particles()
        mass = sim.state.particles.mass.to_numpy()[: len(parts["id"])]
        values.append(np.mean(mass[:, None] * sim.velocities() ** 2))
    return float(np.mean(values))


@pytest.mark.parametrize("temperature", [100.0, 400.0])
def test_free_particles_move_as_fast_as_their_temperature_says(temperature):
    """Equipartition: <m v_x^2> = kT = scale (T + 273.15), within statistical error (400 particles, 40 frames a
    few coupling times apart: about 1%); hot liquid moves faster than cool liquid."""
    sim = gas(temperature)
    sim.run(10)  # several coupling times: the Maxwell distribution
    kt = SCALE * (temperature + KELVIN)
    assert kinetic_per_component(sim) == pytest.approx(kt, rel=0.04)
    assert sim.temperatures() == pytest.approx(temperature, abs=1e-3)  # the heat is not visibly changed
    # the motion's thermometer (stats, CSV, panel, charts) reads the heat's temperature, in kelvin within 4%
    motion = np.mean([sim.run(1)["kinetic_temperature"][-1] for _ in range(20)])
    assert motion + KELVIN == pytest.approx(temperature + KELVIN, rel=0.04)


def test_a_dilute_gas_presses_as_n_k_t_over_v():
    """In a walled box the gas fills, the virial pressure (kinetic only: no pair force) is N kT / V within a few
    percent. (The walls' momentum gauge reads 15-50% high while the thermostat runs: a hard wall reflects the discrete
    kicks a particle in contact gets toward it; docs/physics.md.)"""
    sim = gas(200.0, periodic=False, box=20.0)
    sim.run(10)
    kt = SCALE * (200.0 + KELVIN)
    n, area = 400, 20.0 * 20.0
    virial = [sim.run(1)["pressure"][-1] for _ in range(40)]
    assert np.mean(virial) == pytest.approx(n * kt / area, rel=0.04)


def test_the_thermostat_keeps_the_flow_and_agitates_about_it():
    """A liquid drifting at U keeps drifting: the thermostat acts on motion relative to the neighbours, so it is no
    drag (a drag would leave e^-10 of the drift after ten coupling times). Its agitation about the drift is still
    there (coupled in 50 ms the wax's viscosity holds it under kT)."""
    sim = gas(150.0, pair=True, velocity=(3.0, 0.0))
    sim.run(25)  # half a second: ten coupling times
    v = sim.velocities()
    assert 1.5 < v[:, 0].mean() < 4.5 and abs(v[:, 1].mean()) < 1.5
    assert v[:, 0].std() > 0.5 * np.sqrt(SCALE * (150.0 + KELVIN) / 0.9)  # agitated, not frozen into the flow


def test_the_energy_given_to_the_motion_is_counted_and_runs_repeat_bit_for_bit(tmp_path):
    sim = gas(100.0)
    thermostat = sim.terms.agitation
    ke0 = sim.stats().kinetic_energy
    sim.run(5)
    assert thermostat.moved[None] == pytest.approx(sim.stats().kinetic_energy - ke0, rel=1e-3)
    again = gas(100.0)
    again.run(5)
    assert np.array_equal(sim.velocities(), again.velocities())  # the noise is a hash of particle id and step
    sim.save(tmp_path / "gas.npz")
    sim.run(5)
    resumed = sandbox.resume(tmp_path / "gas.npz")
    resumed.run(5)
    assert np.array_equal(sim.velocities(), resumed.velocities())


def test_scenes_that_do_not_ask_for_it_do_not_build_it():
    sim = sandbox.load("melting_block")
    assert sim.terms.agitation is None and not any("thermostat" in line for line in sim.pipeline())
    assert np.isnan(sim.stats().kinetic_temperature)


def test_hot_and_cold_the_hot_puddle_jiggles_as_its_absolute_temperature_says():
    """The lesson of scenes/hot_and_cold.toml: the mean kinetic energy of the particles' jiggling (their motion
    about their puddle's own centre of mass) grows with the absolute temperature, 1.7 times from 70 °C to 300 °C, and
    the speed by about 1.3 times; each puddle's says its temperature in kelvin within 10% (the wax's own damping
    takes part of it), and so does the motion's thermometer (relative to the local flow, its scatter allowed for)."""
    from .conftest import SCENES

    sim = sandbox.load(SCENES / "hot_and_cold.toml")
    sim.run(30)
    warm, hot, thermometer = [], [], []
    for _ in range(20):
        thermometer.append(sim.run(3)["kinetic_temperature"][-1])
        n = int(sim.state.particles.n[None])
        p = sim.state.particles
        v, mass, group = p.v.to_numpy()[:n], p.mass.to_numpy()[:n], p.group.to_numpy()[:n]
        for puddle, out in ((0, warm), (1, hot)):
            mine = group == puddle
            drift = (mass[mine, None] * v[mine]).sum(axis=0) / mass[mine].sum()
            out.append((mass[mine] * ((v[mine] - drift) ** 2).sum(axis=1)).mean())
    ratio = np.mean(hot) / np.mean(warm)
    assert ratio == pytest.approx((300.0 + KELVIN) / (70.0 + KELVIN), rel=0.1)
    scale = sim.scene.heat.agitation_scale
    for energy, temperature in ((warm, 70.0), (hot, 300.0)):
        assert np.mean(energy) / (2 * scale) == pytest.approx(temperature + KELVIN, rel=0.1)
    assert sim.temperatures().min() == pytest.approx(70.0, abs=0.01)  # each puddle keeps its heat
    mean_kelvin = (np.mean(warm) + np.mean(hot)) / 2 / (2 * scale)  # the two puddles are about the same size
    assert np.mean(thermometer) + KELVIN == pytest.approx(mean_kelvin, rel=0.1)


def test_with_pair_forces_a_drop_keeps_its_momentum_and_its_motion_says_its_temperature():
    """The pairwise thermostat: a liquid drop drifting in a periodic box keeps its momentum to 1e-5, as without the
    thermostat (each pair's impulses cancel; a gas particle, held about its flow with a noise of its own, would
    not), and its particles' motion about the
    drift has <m v_a^2> = kT per component (equipartition with pair forces on; the wax's viscosity given its noise)
    within 10%, coupled as the lesson scenes are (in 5 ms). Measured 7% low at this step (2 ms): the explicit step of
    a strongly damped motion, which the noise's correction (agitation.py) allows for only roughly."""
    sim = gas(100.0, pair=True, velocity=(3.0, -1.0), tau=0.005, shape="disk")
    thermostat = sim.terms.agitation
    n = sim.model.built.count
    mass = sim.state.particles.mass.to_numpy()[:n]
    momentum0 = (mass[:, None] * sim.velocities()).sum(axis=0)
    energies = []
    for _ in range(30):
        sim.run(1)
        assert thermostat.weight.to_numpy()[:n].min() >= GAS_WEIGHT  # no particle is (partly) a gas
        v = sim.velocities()
        momentum = (mass[:, None] * v).sum(axis=0)
        assert np.abs(momentum - momentum0).max() < 1e-5 * np.abs(momentum0).max()
        energies.append(np.mean(mass[:, None] * (v - momentum / mass.sum()) ** 2))
    assert np.mean(energies[10:]) == pytest.approx(SCALE * (100.0 + KELVIN), rel=0.1)
    again = gas(100.0, pair=True, velocity=(3.0, -1.0), tau=0.005, shape="disk")
    again.run(30)
    assert np.array_equal(again.velocities(), sim.velocities())  # the pairs' noise: hashes of both ids and the step

"""The molecular model (scenes with [molecular]): temperature is the atoms' motion and obeys equipartition and the
Maxwell distribution with the pair forces on; momentum is kept; thermal walls bring a gas to their temperature and
the energy they move closes the energy balance; phases are counted from structure; the linear-force-shifted pair
force falls continuously to zero at the cutoff."""

import math

import numpy as np
import pytest
from scipy import stats as scistats

from sandbox.errors import SandboxError, SceneError
from sandbox.physics.structure import LEGENDRE6
from sandbox.simulation import Simulation

from .conftest import make_scene

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)

CUTOFF = 2.5


def atoms(dim: int, side: float, lo, hi, spacing: float, kt: float, lattice: str = "square", periodic=True, **more):
    """A [molecular] Lennard-Jones scene (reduced units, velocity Verlet, double precision) with one block of atoms."""
    data = {
        "world": {
            "dim": dim, "lo": [0.0] * dim, "hi": [side] * dim, "dt": 0.005, "substeps": 10, "periodic": periodic,
            "precision": "f64", "integrator": "velocity_verlet", "restitution": 1.0, "friction": 0.0,
        },
        "pair": {"a": 8.0, "b": 14.0, "cutoff": CUTOFF, "force_shift": True},
        "molecular": more.pop("molecular", {}),
        "bodies": [
            {
                "material": "lj", "shape": "box", "lattice": lattice, "lo": list(lo), "hi": list(hi),
                "spacing": spacing, "springs": False, "random_velocity": kt, "seed": 11,
            }
        ],
    }  # fmt: skip
    box = more.pop("box", None)
    data["world"].update(more)
    if box is not None:  # a box that is not a cube
        data["world"]["hi"] = list(box)
    return Simulation(make_scene(data))


def set_velocities(sim: Simulation, v: np.ndarray) -> None:
    full = sim.state.particles.v.to_numpy()
    full[: len(v)] = v
    sim.state.particles.v.from_numpy(full)


def lj_liquid_2d() -> Simulation:
    """400 atoms of a periodic 2D liquid (density 0.69, kT about 1), all starting at one speed in random directions: a
    distribution far from Maxwell's, which only the pair forces can make Maxwellian (there is no thermostat)."""
    side = 24.0
    sim = atoms(2, side, (0, 0), (side, side), 1.2, 0.0)
    n = sim.state.live_count()
    angle = np.random.default_rng(3).uniform(0, 2 * math.pi, n)
    v = 1.5 * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    set_velocities(sim, v - v.mean(axis=0))
    return sim


def test_with_the_pair_forces_on_the_motion_becomes_maxwellian_with_equipartition_and_momentum_is_kept():
    sim = lj_liquid_2d()
    start = sim.velocities()
    p0 = start.sum(axis=0)
    kt0 = (start**2).mean()
    # the start is one speed: far from Maxwell (its KS distance from a Gaussian of its own variance is large)
    assert scistats.kstest(start[:, 0] / math.sqrt(kt0), "norm").statistic > 0.05
    sim.step(2000)  # 10 time units: many collisions per atom
    samples, temps = [], []
    for _ in range(20):
        sim.step(100)
        samples.append(sim.velocities())
        temps.append(sim.stats().motion_temperature)
    v = np.concatenate(samples)
    kt = float(np.mean(temps))
    # equipartition: each direction carries kT / 2 per atom (unit masses), as the kinetic temperature says
    assert (v[:, 0] ** 2).mean() == pytest.approx(kt, rel=0.04)
    assert (v[:, 1] ** 2).mean() == pytest.approx(kt, rel=0.04)
    # Maxwell: each component normal with variance kT / m; speeds follow the 2D (Rayleigh) law
    assert scistats.kstest(v.ravel() / math.sqrt(kt), "norm").statistic < 0.02
    speed = np.linalg.norm(v, axis=1)
    assert scistats.kstest(speed / math.sqrt(kt), "rayleigh").statistic < 0.025
    # no thermostat and periodic walls: momentum is kept to round-off
    p = sim.velocities().sum(axis=0)
    assert np.abs(p - p0).max() < 1e-9 * len(v)
    assert 0.5 < kt < 1.5  # part of the start's kinetic energy went into the pair energy


def test_thermal_walls_bring_a_gas_to_their_temperature_and_the_energy_they_move_closes_the_balance():
    side = 20.0
    walls = [{"name": f"w{k}", "side": s, "temperature": 0.8} for k, s in enumerate(["left", "right", "bottom", "top"])]
    # dt 0.0025: a wall re-draws the half-step velocity of the leapfrog form of velocity Verlet, which costs the
    # balance an error that falls with dt as the integrator's own drift does (2.8% of the heat moved at dt 0.005)
    sim = atoms(2, side, (1, 1), (19, 19), 2.2, 0.3, periodic=False, molecular={"walls": walls}, dt=0.0025)
    e0 = sim.stats().total_energy
    assert sim.stats().motion_temperature < 0.4  # cool at the start
    sim.step(40000)  # 100 time units: each atom has met the walls several times
    temps = []
    for _ in range(100):
        sim.step(400)
        temps.append(sim.stats().motion_temperature)
    assert np.mean(temps) == pytest.approx(0.8, rel=0.05)
    s = sim.stats()
    moved = sum(sim.terms.thermal_walls.energy_moved())
    assert s.wall_heat == pytest.approx(moved)
    assert moved > 0  # the walls warmed the gas
    assert s.total_energy - e0 == pytest.approx(moved, rel=0.02)


def test_a_hot_floor_and_a_cold_lid_carry_heat_through_the_atoms_and_are_set_live():
    walls = [
        {"name": "floor", "side": "bottom", "temperature": 1.5},
        {"name": "lid", "side": "top", "temperature": 0.1},
    ]
    sim = atoms(
        2, 16.0, (0.6, 0.6), (15.4, 15.4), 1.12, 0.6, periodic=False, molecular={"walls": walls}
    )  # fills the box
    sim.step(6000)
    floor0, lid0 = sim.terms.thermal_walls.energy_moved()
    sim.step(6000)
    floor, lid = sim.terms.thermal_walls.energy_moved()
    assert floor - floor0 > 0 > lid - lid0  # in steady flow: heat in at the floor, out at the lid
    sim.controls.set({"thermal_walls.floor": 2.0})
    assert sim.terms.thermal_walls.temperatures() == [2.0, 0.1]
    with pytest.raises(ValueError):
        sim.terms.thermal_walls.set_temperatures([-1.0, 0.1])


@pytest.mark.parametrize(
    "dim, side, lo, hi, spacing, kt, lattice, periodic, expected",
    [
        (2, 40.0, (10, 10), (30, 30), 1.09, 0.1, "hex", False, "solid"),  # a cold crystal
        (2, 24.0, (0, 0), (24, 24), 1.2, 1.4, "square", True, "liquid"),  # hot, dense and disordered
        (2, 60.0, (0, 0), (60, 60), 5.0, 1.0, "square", False, "gas"),  # far apart (density 0.04)
        (3, 16.0, (4, 4, 4), (12, 12, 12), 1.09, 0.1, "fcc", False, "solid"),
        (3, 9.5, (0, 0, 0), (9.5, 9.5, 9.5), 1.077, 1.6, "cubic", True, "liquid"),
    ],
)
def test_phases_are_counted_from_structure(dim, side, lo, hi, spacing, kt, lattice, periodic, expected):
    sim = atoms(dim, side, lo, hi, spacing, kt, lattice, periodic)
    sim.step(1000)
    s = sim.stats()
    shares = {"solid": s.structure_solid, "liquid": s.structure_liquid, "gas": s.structure_gas}
    assert sum(shares.values()) == pytest.approx(1.0)
    least = {"solid": 0.85, "liquid": 0.85, "gas": 0.95}[expected]  # a cluster's surface atoms are not in order
    assert shares[expected] >= least, shares
    kinds = sim.state.particles.kind.to_numpy()[: s.particles]
    assert np.mean(kinds == {"gas": 0, "liquid": 1, "solid": 2}[expected]) == pytest.approx(shares[expected])


def test_the_3d_bond_order_is_steinhardts_q6():
    """q_i . q_j from the stored harmonics equals the addition theorem's (4 pi / 13) sum_m Y6m(a) Y6m*(b)."""
    special = pytest.importorskip("scipy.special")
    rng = np.random.default_rng(1)
    d = rng.normal(size=(6, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]

    def stored(v):
        w = complex(v[0], v[1])
        out = [np.polyval(poly, v[2]) * weight * w**m for m, (weight, poly) in enumerate(LEGENDRE6)]
        return np.array([out[0].real] + [part for c in out[1:] for part in (c.real, c.imag)])

    theta, phi = np.arccos(d[:, 2]), np.arctan2(d[:, 1], d[:, 0])
    for a in range(6):
        for b in range(6):
            ya = special.sph_harm_y(6, np.arange(-6, 7), theta[a], phi[a])
            yb = special.sph_harm_y(6, np.arange(-6, 7), theta[b], phi[b])
            expected = 4 * math.pi / 13 * (ya * np.conj(yb)).sum().real
            assert stored(d[a]) @ stored(d[b]) == pytest.approx(expected, abs=1e-9)


def test_the_force_shifted_pair_force_falls_to_zero_at_the_cutoff_and_its_energy_is_its_integral():
    sim = atoms(2, 20.0, (5, 5), (9, 7), 2.0, 0.0, periodic=False)  # two atoms
    assert sim.state.live_count() == 2

    def lj_force(r):  # magnitude along d (attraction positive): 24 / r^7 - 48 / r^13
        return 24.0 / r**7 - 48.0 / r**13

    def lfs_energy(r):
        u = lambda s: 4.0 * (s**-12 - s**-6)  # noqa: E731
        return u(r) - u(CUTOFF) - lj_force(CUTOFF) * (r - CUTOFF)

    r_curve, f_curve = sim.terms.pair.curve()
    assert f_curve[-1] == pytest.approx(0.0, abs=1e-12) and r_curve[-1] == CUTOFF
    for r in (1.0, 1.5, 2.2, 2.49):
        x = sim.state.particles.x.to_numpy()
        x[1] = x[0] + np.array([r, 0.0])
        sim.state.particles.x.from_numpy(x)
        assert sim.stats().pair_energy == pytest.approx(lfs_energy(r), rel=1e-9, abs=1e-12)
    assert lfs_energy(CUTOFF - 1e-9) == pytest.approx(0.0, abs=1e-8)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"heat": {}}, "expected [molecular] or [heat], not both"),
        ({"molecular": {"walls": [{"side": "front", "temperature": 1.0}]}}, "3D box only"),
        ({"molecular": {"walls": [{"side": "top", "temperature": 1.0}] * 2}}, "named twice"),
        ({"molecular": {"phase_radius": 3.0}}, "at most the pair cutoff"),
        ({"molecular": {"walls": [{"side": "top", "temperature": 0.0}]}}, "temperature"),
    ],
)
def test_a_molecular_scene_that_cannot_be_built_is_refused_with_the_key_named(change, message):
    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [10, 10]},
        "pair": {"a": 8.0, "b": 14.0, "cutoff": CUTOFF},
        "molecular": {},
        "bodies": [{"material": "lj", "shape": "box", "lo": [2, 2], "hi": [5, 5], "springs": False}],
    }
    data.update(change)
    with pytest.raises(SceneError, match=message.replace("[", r"\[")):
        make_scene(data)


def test_the_atoms_scene_offers_its_floor_temperature_as_a_setting_and_its_phases_in_the_panel():
    from sandbox.app.controller import Controller, open_scene
    from sandbox.app.panel import readouts

    control = Controller(open_scene("atoms", "cpu"))
    keys = {s.key: s for s in control.settings()}
    assert "wall0" in keys and keys["wall0"].words == "floor temperature"
    control.set("wall0", 0.9)
    assert control.sim.terms.thermal_walls.temperatures() == [pytest.approx(0.9, rel=1e-6)]  # f32 scene
    rows = {r.key: r for r in readouts(control.sim, control.sim.stats())}
    assert {"motion", "solid", "liquid", "gas", "wall_heat"} <= set(rows)
    assert rows["solid"].value > 90  # it starts as a crystal, measured so
    said = control.summary(control.sim.stats())  # the screen reader's sentence: the measured shares and kT
    assert said["key"] == "summary_atoms" and said["solid"] > 90 and said["solid"] + said["molten"] + said["gas"] >= 99


def test_a_lid_under_an_outside_pressure_finds_the_height_of_the_ideal_gas_law(pressure=0.06):
    """A dilute gas in a box of thermal walls under a lid: the lid settles where the gas pushes on it with the outside
    pressure. For atoms of radius r between the floor and the lid, P L (h - 2 r) = N kT (2D): doubling P halves the
    gas's height (the gas is dilute: its non-ideality is a few %; 0.12 gave the same within 8% too)."""
    walls = [{"name": side, "side": side, "temperature": 1.0} for side in ("bottom", "left", "right")]
    lid = {"pressure": pressure, "mass": 20.0, "height": 3.0 + 80 / (pressure * 50.0) * 1.2}  # 20% above its rest
    # dt 0.01: a dilute gas at kT 1 steps stably at twice the liquid's step (the long way runs the lid: launch-bound)
    sim = atoms(2, 50.0, (1, 1), (49, 18), 3.0, 1.0, periodic=False, molecular={"walls": walls, "lid": lid}, dt=0.01)
    n = sim.state.live_count()
    assert n == 80
    radius = float(sim.state.particles.radius.to_numpy()[0])
    sim.step(15000)
    heights, temps = [], []
    for _ in range(150):
        sim.step(100)
        heights.append(sim.stats().lid_height)
        temps.append(sim.stats().motion_temperature)
    assert 0.85 < np.mean(temps) < 1.15  # about the walls' temperature (80 atoms: slow swings of a few %)
    assert np.mean(heights) - 2 * radius == pytest.approx(n * np.mean(temps) / (pressure * 50.0), rel=0.08)


def test_the_lids_pressure_follows_its_schedule_until_set_by_hand_and_a_state_keeps_it():
    """A lid scheduled at pressure 0.06 for 30 time units and 0.24 after (a pressure cooker's lid made heavier, issue
    75): the pressure in force is the schedule's, the gas is pressed down by the heavier lid (it settles at about a
    quarter of the height above the atoms), a state's record keeps following the schedule and a slider's value stops
    it; a negative scheduled pressure is refused by name."""
    walls = [{"name": side, "side": side, "temperature": 1.0} for side in ("bottom", "left", "right")]
    lid = {"pressure": 0.06, "mass": 20.0, "height": 30.0}
    lid.update(schedule_times=[0.0, 30.0], schedule_values=[0.06, 0.24])
    sim = atoms(2, 50.0, (1, 1), (49, 18), 3.0, 1.0, periodic=False, molecular={"walls": walls, "lid": lid}, dt=0.01)
    sim.step(2900)
    light = sim.stats().lid_height
    assert sim.controls.values()["lid.pressure"] == 0.06 and sim.controls.values()["lid.scheduled"] == 1.0
    saved = sim.controls.values()
    sim.step(3000)
    assert sim.controls.values()["lid.pressure"] == 0.24
    heavy = sim.stats().lid_height
    assert heavy < 0.5 * light  # measured in the ideal gas law's test: height - 2 r = N kT / (P L)
    sim.controls.set({"lid.pressure": 0.1})  # by hand: the schedule stops
    sim.step(100)
    assert sim.controls.values()["lid.pressure"] == 0.1 and sim.controls.values()["lid.scheduled"] == 0.0
    sim.controls.set(saved)  # a state's record: the schedule applies again (at this time, 0.24)
    sim.step(1)
    assert sim.controls.values()["lid.pressure"] == 0.24
    with pytest.raises(SceneError, match=r"molecular.lid.schedule_values\[1\]"):
        negative = {**lid, "schedule_values": [0.06, -1.0]}
        atoms(2, 50.0, (1, 1), (49, 18), 3.0, 1.0, periodic=False, molecular={"lid": negative})


def test_the_lid_keeps_the_energy_of_atoms_and_lid_with_the_work_of_the_outside_pressure():
    """Without thermal walls, E_atoms + M u^2 / 2 + P A h is conserved (the lid's hits are elastic collisions)."""
    lid = {"pressure": 0.08, "mass": 20.0, "height": 30.0}
    sim = atoms(2, 50.0, (1, 1), (49, 20), 4.0, 1.0, periodic=False, molecular={"lid": lid})
    term = sim.terms.lid

    def enthalpy():
        u, h = float(term.speed.to_numpy()), float(term.height.to_numpy())
        return sim.stats().total_energy + 0.5 * term.mass * u * u + 0.08 * 50.0 * h

    start = enthalpy()
    kinetic = sim.stats().kinetic_energy
    sim.step(20000)
    assert enthalpy() - start == pytest.approx(0.0, abs=0.01 * kinetic)
    assert abs(float(term.height.to_numpy()) - 30.0) > 1.0  # it moved
    sim.controls.set({"lid.pressure": 0.02})
    assert term.pressure == 0.02


def test_melting_takes_latent_heat_the_temperature_rises_slower_per_heat_while_the_crystal_melts():
    """A 2D crystal on a hot floor: the temperature rise per unit of heat taken in (dT / dQ, both measured: the
    atoms' kinetic temperature and the floor's energy sum) is several times smaller while the measured solid share
    falls than while it is still a crystal: the heat goes into breaking the order (latent heat), which nothing
    assigns."""
    walls = [{"name": "floor", "side": "bottom", "temperature": 0.7}]
    sim = atoms(2, 30.0, (3, 0.6), (27, 10), 1.09, 0.1, lattice="hex", periodic=False, molecular={"walls": walls},
                gravity=[0.0, -0.02])  # fmt: skip
    rows = []
    for _ in range(120):
        sim.step(500)
        s = sim.stats()
        rows.append((s.wall_heat, s.motion_temperature, s.structure_solid))
    q, t, solid = np.array(rows).T
    crystal, melting = solid >= 0.85, (solid >= 0.15) & (solid <= 0.7)
    assert crystal.sum() >= 6 and melting.sum() >= 20
    slope_crystal = np.polyfit(q[crystal], t[crystal], 1)[0]
    slope_melting = np.polyfit(q[melting], t[melting], 1)[0]
    assert slope_crystal > 0 and slope_melting < 0.5 * slope_crystal


def test_a_drop_cools_as_its_fastest_atoms_evaporate_while_the_total_energy_is_kept():
    """A hot 3D drop in a large empty periodic box, no thermostat: atoms leave it, the vapour they make is hotter
    than the drop (the fast ones escape), and the drop's own temperature falls while the total energy stays."""
    sim = atoms(3, 30.0, (11, 11, 11), (19, 19, 19), 1.09, 1.6, lattice="fcc", periodic=True)
    sim.step(2000)  # the crystal melts at once; the drop settles
    e0 = sim.stats().total_energy
    rows = []
    for _ in range(18):
        sim.step(1000)
        s = sim.stats()
        rows.append((s.total_energy, s.condensed_temperature, s.gas_temperature, s.structure_gas, s.kinetic_energy))
    energy, drop, vapour, gas, kinetic = np.array(rows).T
    assert np.abs(energy - e0).max() < 0.02 * kinetic.mean()
    assert drop[-5:].mean() < 0.92 * drop[:5].mean()  # evaporative cooling, measured
    assert vapour.mean() > drop.mean()
    assert gas[-5:].mean() > gas[:5].mean()


@pytest.mark.parametrize("pressure, boils", [(0.015, True), (0.045, False)])
def test_a_heavier_lid_raises_the_boiling_point_along_the_measured_curve(pressure, boils):
    """A pressure cooker: 384 atoms of liquid in a box of thermal walls at kT 0.79 under a lid. The measured curve
    (assets/coexistence_lj_lfs25.csv) boils the liquid at 0.724 under a lid pressure of 0.015 and at 0.849 under
    0.045: at 0.79 the light lid is pushed up by the vapour the liquid makes (it boils away), the heavy one stays on
    the liquid. The lid's height is averaged over windows (it bobs by 2-3 sigma about its course): over six velocity
    seeds the light lid's mean over steps 27,000-36,000 was 33.6-42.9 sigma, 6-13 above its mean over 9,000-18,000;
    the heavy lid's 17.1-19.1, within 3 of it."""
    from sandbox.measure.coexistence_curve import curve_of

    walls = [{"name": s, "side": s, "temperature": 0.79} for s in ("bottom", "left", "right", "back", "front")]
    molecular = {"walls": walls, "lid": {"pressure": pressure, "mass": 20.0, "height": 9.0}}
    sim = atoms(3, 9.0, (0, 0.6, 0), (9, 7.5, 9), 1.10, 0.89, lattice="cubic", periodic=False, molecular=molecular,
                box=(9.0, 90.0, 9.0))  # fmt: skip
    curve = curve_of(sim.model)
    assert (curve.boiling_temperature(pressure) < 0.79) == boils
    heights = []
    for _ in range(24):
        sim.step(1500)
        heights.append(sim.stats().lid_height)
    middle, late = np.mean(heights[5:12]), np.mean(heights[17:])  # steps 9,000-18,000 and 27,000-36,000
    if boils:  # the light lid rises on: the liquid is boiling away
        assert late > 27.0 and late - middle > 3.0
    else:  # the heavy lid stays on the liquid (which started 7 sigma deep)
        assert late < 23.0 and late - middle < 3.0


def test_the_lid_is_drawn_at_its_height_in_3d():
    """The pressure cooker's picture shows the lid's outline (a light grey line) where the lid is, and moves it with
    the lid: raised by 10 sigma, the outline's rows move up the picture."""
    from sandbox.app.controller import open_scene
    from sandbox.render.raster import Renderer

    sim = open_scene("pressure_cooker", "cpu")
    renderer = Renderer(sim.model, sim.state, 640, 360, sim.scene.render, output="picture")

    def outline_rows():
        renderer.render()
        picture = renderer.frame()
        lid = np.all(np.abs(picture.astype(int) - [217, 217, 230]) <= 2, axis=2)  # the outline's colour
        return np.flatnonzero(lid.any(axis=1))

    low = outline_rows()
    sim.terms.lid.height.from_numpy(np.array(22.0, dtype=np.float32))
    high = outline_rows()
    assert len(low) and len(high) and high.mean() < low.mean() - 5  # picture rows count down from the top


def test_the_lid_is_drawn_at_its_height_in_2d_and_the_page_gets_pictures():
    """In 2D the lid's underside is a light line across the box at its height, with the box above it tinted: raised
    by 4 sigma, the line moves up 4 sigma's pixels (the whole picture is composited while a lid moves). A classroom
    page cannot draw it from particle frames, so such a scene is sent as pictures."""
    from sandbox.render.particle_frame import unsupported
    from sandbox.render.raster import Renderer
    from sandbox.render.style import LID_COLOR

    lid = {"pressure": 0.06, "mass": 20.0, "height": 21.0}
    sim = atoms(2, 50.0, (1, 1), (49, 18), 3.0, 1.0, periodic=False, molecular={"lid": lid})
    renderer = Renderer(sim.model, sim.state, 640, 400, sim.scene.render, output="picture")
    colour = np.round(np.asarray(LID_COLOR) * 255)

    def line_rows():
        picture = renderer.frame()
        return np.flatnonzero(np.all(np.abs(picture.astype(int) - colour) <= 1, axis=2).sum(axis=1) > 500)

    low = line_rows()
    sim.terms.lid.height[None] = 25.0
    high = line_rows()
    assert len(low) == len(high) >= 2  # a line 2 to 3 pixels thick across the box
    assert low.mean() - high.mean() == pytest.approx(4.0 * renderer.painter.px_per_unit, abs=1.0)
    assert unsupported(renderer) == "a moving lid"


def heated_liquid(power: float, **schedule) -> Simulation:
    """400 atoms of a periodic 2D liquid at kT about 1 under the molecular heater at `power` (energy per time)."""
    side = 24.0
    sim = atoms(2, side, (0, 0), (side, side), 1.2, 0.0, molecular={"heater": {"power": power, **schedule}})
    v = np.random.default_rng(3).normal(0.0, 1.0, (sim.state.live_count(), 2))
    set_velocities(sim, v - v.mean(axis=0))
    return sim


def test_the_heater_shares_its_power_among_the_atoms_keeping_momentum_and_the_energy_closes():
    """The even heater gives the atoms P dt a step by scaling their motion about the centre of mass: over 2,000 steps
    at P = +-4 its sum is P t to round-off, the total energy changes by that sum within the integrator's drift
    (measured 0.1 of 40; the unheated run drifts 0.1), momentum is kept to round-off, the heated liquid ends hotter
    than the unheated one and the cooled one colder; cooling harder than the motion holds stops at rest, not below;
    a run repeats bit for bit; a power that is not a number is refused."""
    runs = {}
    for power in (0.0, 4.0, -4.0):
        sim = heated_liquid(power)
        n = sim.state.live_count()
        mass = sim.state.particles.mass.to_numpy()[:n, None]
        start, momentum = sim.stats(), (mass * sim.state.particles.v.to_numpy()[:n]).sum(axis=0)
        sim.step(2000)
        end = sim.stats()
        assert end.heater_heat == pytest.approx(power * 2000 * sim.dt, rel=1e-12, abs=1e-12)
        assert end.total_energy - start.total_energy == pytest.approx(end.heater_heat, abs=0.3)
        assert np.abs((mass * sim.state.particles.v.to_numpy()[:n]).sum(axis=0) - momentum).max() < 1e-10
        runs[power] = (end.motion_temperature, sim.positions())
    assert runs[4.0][0] > runs[0.0][0] + 0.03 and runs[-4.0][0] < runs[0.0][0] - 0.03  # measured +0.046, -0.145
    again = heated_liquid(4.0)
    again.step(2000)
    assert np.array_equal(again.positions(), runs[4.0][1])
    frozen = heated_liquid(-400.0)  # 2 eps a step: the motion's 399 eps in 200 steps, then all there is each step
    frozen.step(500)
    stats = frozen.stats()
    assert stats.kinetic_energy < 0.01 and math.isfinite(stats.total_energy)  # measured 0.003: near rest, not below
    assert -stats.heater_heat < 0.5 * 400.0 * 500 * frozen.dt  # it took what there was (446), not what was asked
    with pytest.raises(SandboxError, match="heater.power"):
        frozen.controls.set({"heater.power": float("nan")})


def test_the_heater_follows_its_schedule_until_set_by_hand_and_a_state_keeps_it():
    """A heater scheduled to heat at 4 for 5 time units then cool at -4 has given the atoms 4 x 5 after 1,000 steps
    and nothing net after 2,000; its state saved mid-schedule and put back follows the schedule on; set by hand (the
    slider) it keeps the hand's power."""
    sim = heated_liquid(0.0, schedule_times=[0.0, 5.0], schedule_values=[4.0, -4.0])
    sim.step(1000)
    assert sim.stats().heater_heat == pytest.approx(20.0, rel=1e-9)
    saved = sim.controls.values()
    assert saved["heater.scheduled"] == 1.0
    sim.step(1000)
    # the clock adds dt step by step, so the change may land a step late (a step at 4 and one fewer at -4)
    step = 4.0 * sim.dt
    assert sim.stats().heater_heat == pytest.approx(0.0, abs=2 * step + 1e-9)
    after_schedule = sim.stats().heater_heat
    sim.controls.set({"heater.power": 1.0})  # by hand: the schedule stops
    sim.step(1000)
    assert sim.stats().heater_heat - after_schedule == pytest.approx(5.0, rel=1e-9)
    sim.controls.set(saved)  # a state's record: the schedule applies again (at this time, -4)
    sim.step(200)
    assert sim.stats().heater_heat - after_schedule == pytest.approx(5.0 - 200 * step, rel=1e-9)


def test_an_argon_scene_computes_as_reduced_units_and_is_shown_in_kelvin_and_kilopascals():
    """The material "argon" is the reduced Lennard-Jones atom shown in argon's units (epsilon / k = 119.8 K,
    sigma = 0.3405 nm, m = 39.95 u): the same trajectory bit for bit as "lj", its readouts, chart and sliders in K,
    kPa, zJ and ps, and a slider moved in kPa sets the reduced pressure it stands for."""
    from sandbox.api import load
    from sandbox.app.controller import Controller
    from sandbox.app.panel import readouts
    from sandbox.render.chart import Chart

    sims = {m: load("pressure_cooker", set={"bodies.0.material": m}) for m in ("lj", "argon")}
    for sim in sims.values():
        sim.step(100)
    assert np.array_equal(sims["lj"].positions(), sims["argon"].positions())
    rows = {m: {r.key: r for r in readouts(sim, sim.stats())} for m, sim in sims.items()}
    kt, kelvin = rows["lj"]["motion"], rows["argon"]["motion"]
    assert (kt.unit, kelvin.unit) == ("eps", "K") and kelvin.value == pytest.approx(119.8 * kt.value, rel=1e-12)
    assert rows["argon"]["energy"].unit == "zJ" and rows["argon"]["time"].unit == "ps"
    # epsilon = 119.8 k = 1.654 zJ, epsilon / sigma^3 = 41.9 MPa, tau = sigma sqrt(m / epsilon) = 2.156 ps
    assert rows["argon"]["energy"].value == pytest.approx(1.6540 * rows["lj"]["energy"].value, rel=1e-4)
    assert rows["argon"]["time"].value == pytest.approx(2.1564 * rows["lj"]["time"].value, rel=1e-4)
    control = Controller(sims["argon"])
    lid = {s.key: s for s in control.settings()}["lid"]
    assert lid.unit == "kPa" and lid.value == pytest.approx(0.02 * 41897.6, rel=1e-5)
    control.set("lid", 2513.85)  # kPa
    assert sims["argon"].terms.lid.pressure == pytest.approx(0.06, rel=1e-5)
    chart = Chart(("motion_temperature",), (0, 400, 0, 120), 12, ["argon"], 3)
    chart.record(sims["argon"].stats())
    assert chart.words[0][1] == "K" and chart.history[0][0] == pytest.approx(kelvin.value, rel=1e-9)


def test_the_heated_crystal_lesson_offers_its_heater_and_lid_and_follows_its_schedule():
    """states_of_matter_atoms: a crystal (measured so) under a lid, with the heater and the lid's weight as sliders;
    its heater follows the scene's schedule (3 eps per time unit at first) until the slider takes it over, and the
    panel shows the heat it has given."""
    from sandbox.app.controller import Controller, open_scene
    from sandbox.app.panel import readouts

    control = Controller(open_scene("states_of_matter_atoms", "cpu"))
    sim = control.sim
    keys = {s.key: s for s in control.settings()}
    assert keys["heater"].value == 3.0 and keys["heater"].unit == "eps/s" and "lid" in keys
    assert sim.stats().structure_solid > 0.8
    sim.step(200)
    rows = {r.key: r for r in readouts(sim, sim.stats())}
    assert rows["heater_heat"].value == pytest.approx(3.0 * 200 * sim.dt, rel=1e-9)
    control.set("heater", -1.0)  # by hand: the schedule stops
    sim.step(200)
    assert sim.stats().heater_heat == pytest.approx((3.0 - 1.0) * 200 * sim.dt, rel=1e-9)

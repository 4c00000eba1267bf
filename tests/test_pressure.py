"""The virial pressure against an independent evaluation and against the momentum an ideal gas gives its walls;
energies per particle; the pair energy's cutoff shift (pair.shift) and what turning it off changes."""

import numpy as np
import pytest

from sandbox.simulation import Simulation

from .conftest import make_scene

CUTOFF = 2.5


def lj_fluid(side: float = 14.0, shift: bool = True) -> Simulation:
    """A periodic 2D LJ fluid at density 0.8 and kT about 1, in double precision (about 150 particles)."""
    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [side, side], "dt": 0.005, "periodic": True, "precision": "f64"},
        "pair": {"a": 8.0, "b": 14.0, "cutoff": CUTOFF, "shift": shift},
        "bodies": [
            {
                "material": "lj",
                "shape": "box",
                "lo": [0, 0],
                "hi": [side, side],
                "spacing": 1.1180339887,
                "springs": False,
                "random_velocity": 1.0,
                "seed": 5,
            }
        ],
    }
    return Simulation(make_scene(data))


def lj_pairs(x: np.ndarray, side: float) -> tuple[np.ndarray, np.ndarray]:
    """Every pair closer than the cutoff by the minimum image: (d = x_j - x_i for i < j, r)."""
    d = x[None, :, :] - x[:, None, :]
    d -= side * np.round(d / side)
    i, j = np.triu_indices(len(x), 1)
    d = d[i, j]
    r = np.linalg.norm(d, axis=1)
    keep = r < CUTOFF
    return d[keep], r[keep]


def test_the_virial_pressure_equals_an_independent_evaluation_on_the_lj_fluid():
    side = 14.0
    sim = lj_fluid(side)
    sim.step(200)  # off the lattice: a disordered fluid
    s = sim.stats()
    x, v = sim.positions(), sim.velocities()
    d, r = lj_pairs(x, side)
    force_on_i = (24.0 / r**8 - 48.0 / r**14)[:, None] * d  # 12-6 LJ, unit masses: F_i = g(r) d
    virial = -(d * force_on_i).sum()  # sum of r_ij . F_ij with r_ij = x_i - x_j = -d
    expected = ((v**2).sum() + virial) / (2 * side**2)
    assert s.pressure == pytest.approx(expected, rel=1e-6)
    assert 0.5 < s.pressure < 3.0  # LJ at density 0.8, kT ~ 1 (P ~ 1.4 in reduced units in 2D)
    n = s.particles
    assert s.kinetic_energy_per_particle == s.kinetic_energy / n
    assert s.total_energy_per_particle == s.total_energy / n
    assert s.potential_energy_per_particle == s.potential_energy / n


def test_without_the_cutoff_shift_the_pair_energy_drops_by_u_at_the_cutoff_per_pair_and_motion_is_unchanged():
    shifted, plain = lj_fluid(shift=True), lj_fluid(shift=False)
    shifted.step(50)
    plain.step(50)
    assert np.array_equal(shifted.positions(), plain.positions())  # the forces do not depend on the shift
    a, b = shifted.stats(), plain.stats()
    _, r = lj_pairs(plain.positions(), 14.0)
    u_cut = 4 * (CUTOFF**-12 - CUTOFF**-6)  # -0.0163: LJ at 2.5 sigma
    assert b.pair_energy - a.pair_energy == pytest.approx(len(r) * u_cut, rel=1e-9)
    assert b.pressure == a.pressure


def test_an_ideal_gas_pushes_its_walls_with_the_virial_pressure():
    """No pair forces and elastic walls: the momentum the particles give the walls per unit time and length is the
    pressure. The centres reach only L - 2 r of each side L, so the walls feel L / (L - 2 r) times the virial
    pressure, which uses the box's volume. The walls' gauge (stats().wall_pressure) reads it too."""
    side = 24.0
    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [side, side], "dt": 0.05, "restitution": 1.0, "friction": 0.0},
        "bodies": [
            {
                "material": "lj",
                "shape": "box",
                "lo": [2, 2],
                "hi": [22, 22],
                "spacing": 1.0,
                "springs": False,
                "random_velocity": 1.0,
                "seed": 3,
            }
        ],
    }
    sim = Simulation(make_scene(data))
    pressure = sim.stats().pressure
    m = sim.particles.mass.to_numpy()[: sim.model.built.count]
    radius = float(sim.particles.radius.to_numpy()[0])
    v = sim.velocities()
    assert pressure == pytest.approx((m[:, None] * v**2).sum() / (2 * side**2), rel=1e-9)  # only the kinetic term
    impulse = np.zeros(2)
    chunk, chunks = 20, 200  # 1 time unit per chunk: no particle crosses the box (and bounces twice) within one
    for _ in range(chunks):
        sim.step(chunk)
        after = sim.velocities()
        flipped = np.sign(after) != np.sign(v)
        impulse += (2 * m[:, None] * np.abs(v) * flipped).sum(axis=0)
        v = after
    duration = chunk * chunks * 0.05
    wall_pressure = impulse / (2 * duration * side)  # per wall: half the impulse on each of its axis's two walls
    measured = wall_pressure.mean() * (side - 2 * radius) / side
    assert measured == pytest.approx(pressure, rel=0.05)
    gauge = sim.stats().wall_pressure  # the walls' own count over the whole run (no frame restarted it)
    assert gauge == pytest.approx(wall_pressure.mean(), rel=0.01)
    assert gauge * (side - 2 * radius) / side == pytest.approx(pressure, rel=0.05)


def test_the_wall_gauge_counts_each_bounce_as_its_momentum_over_time_and_wall_area():
    """One particle at speed 3 across a 20 x 10 box with elastic walls: the walls take 2 m u per bounce, and the gauge
    reads that over the elapsed time and the walls' length (60); a frame restarts it; a periodic box has no walls."""
    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [20, 10], "dt": 0.01, "restitution": 1.0, "precision": "f64"},
        "bodies": [
            {
                "material": "lj",
                "shape": "box",
                "lo": [9.5, 4.5],
                "hi": [10.5, 5.5],
                "springs": False,
                "velocity": [3, 0],
            },
        ],
    }
    sim = Simulation(make_scene(data))
    assert sim.model.built.count == 1 and sim.model.domain.wall_area == 60.0
    assert np.isnan(sim.stats().wall_pressure)  # no time has passed
    m = float(sim.particles.mass.to_numpy()[0])
    sim.step(1800)  # from x = 10: bounces at x = 19.5 (t = 3.17), 0.5 (t = 9.5) and 19.5 (t = 15.83); at 13 by t = 18
    bounces = 3
    assert sim.positions()[0, 0] == pytest.approx(13.0, abs=0.1)  # a hit clamps to the wall within a step
    assert sim.velocities()[0, 0] == pytest.approx(-3.0)
    assert sim.stats().wall_pressure == pytest.approx(bounces * 2 * m * 3.0 / (sim.time * 60.0), rel=1e-9)
    sim.advance_frame(substeps=100)  # 1 time unit, no bounce (the particle crosses the middle)
    assert sim.stats().wall_pressure == 0.0
    assert np.isnan(lj_fluid().stats().wall_pressure) and lj_fluid().model.domain.wall_area == 0.0

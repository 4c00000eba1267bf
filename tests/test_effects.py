"""Particle effects: seeding uniformity, emission counts, lifetimes, velocity fields and kinematic advection."""

import math

import numpy as np
import pytest

from sandbox.physics import smoke as smoke_module
from sandbox.simulation import Simulation

from .conftest import make_scene

CHI2_999 = {15: 37.7, 31: 61.1}  # chi-square critical values at p = 0.001 for 15 and 31 degrees of freedom


def emitter_scene(dim=2, emitters=(), fields=(), **world):
    size = 40.0
    return {
        "world": {"dim": dim, "lo": [0.0] * dim, "hi": [size] * dim, "dt": 0.01, **world},
        "emitters": list(emitters),
        "fields": list(fields),
    }


def chi_square(counts: np.ndarray) -> float:
    expected = counts.sum() / len(counts)
    return float(((counts - expected) ** 2 / expected).sum())


def seeded(emitter: dict, dim=2) -> np.ndarray:
    sim = Simulation(make_scene(emitter_scene(dim, [{"material": "jelly", **emitter}])))
    return sim.positions()


def test_disk_volume_seeding_is_uniform_by_area():
    x = seeded({"shape": "disk", "center": [20, 20], "size": 10, "count": 6400, "particle_radius": 0.05}) - 20
    r, angle = np.linalg.norm(x, axis=1), np.arctan2(x[:, 1], x[:, 0])
    assert r.max() <= 10 + 1e-5
    ring = np.minimum((r / 10) ** 2 * 4, 3.999).astype(int)  # four rings of equal area
    sector = ((angle + math.pi) / (2 * math.pi) * 8).astype(int) % 8
    counts = np.bincount(ring * 8 + sector, minlength=32)
    assert chi_square(counts) < CHI2_999[31]
    # a sampler uniform in radius (not area) fails the same test
    wrong = np.minimum(r / 10 * 4, 3.999).astype(int)
    assert chi_square(np.bincount(wrong * 8 + sector, minlength=32)) > 10 * CHI2_999[31]


def test_box_volume_and_sphere_volume_seeding_are_uniform():
    x = seeded({"shape": "box", "lo": [5, 10], "hi": [25, 20], "count": 6400, "particle_radius": 0.05})
    cells = ((x[:, 0] - 5) / 5).astype(int) * 4 + ((x[:, 1] - 10) / 2.5).astype(int)
    assert chi_square(np.bincount(cells, minlength=16)) < CHI2_999[15]
    x = seeded({"shape": "sphere", "center": [20, 20, 20], "size": 8, "count": 6400, "particle_radius": 0.05}, 3)
    x -= 20
    r = np.linalg.norm(x, axis=1)
    shell = np.minimum((r / 8) ** 3 * 4, 3.999).astype(int)  # four shells of equal volume
    octant = (x[:, 0] > 0) * 4 + (x[:, 1] > 0) * 2 + (x[:, 2] > 0)
    assert chi_square(np.bincount(shell * 8 + octant, minlength=32)) < CHI2_999[31]


def test_surface_seeding_is_uniform_by_arc_length_and_area():
    x = seeded({"shape": "disk", "surface": True, "center": [20, 20], "size": 10, "count": 3200}) - 20
    assert np.allclose(np.linalg.norm(x, axis=1), 10, atol=1e-4)
    angle = np.arctan2(x[:, 1], x[:, 0])
    counts = np.bincount(((angle + math.pi) / (2 * math.pi) * 16).astype(int) % 16, minlength=16)
    assert chi_square(counts) < CHI2_999[15]
    # a 20 x 5 box: the long sides get 4x the particles of the short ones, evenly along their length
    x = seeded({"shape": "box", "surface": True, "lo": [10, 10], "hi": [30, 15], "count": 5000})
    on_long = np.isclose(x[:, 1], 10, atol=1e-4) | np.isclose(x[:, 1], 15, atol=1e-4)
    on_short = np.isclose(x[:, 0], 10, atol=1e-4) | np.isclose(x[:, 0], 30, atol=1e-4)
    assert np.all(on_long | on_short)
    assert abs(on_long.sum() / on_short.sum() - 4.0) < 0.4
    along = np.bincount(((x[on_long, 0] - 10) / 20 * 16).astype(int).clip(0, 15), minlength=16)
    assert chi_square(along) < CHI2_999[15]


def test_emission_follows_the_rate_to_within_one_particle_and_bursts_are_exact():
    scene = emitter_scene(
        emitters=[
            {"material": "jelly", "shape": "point", "center": [20, 20], "rate": 250.0},  # 2.5 per step of 0.01
            {"material": "jelly", "shape": "point", "center": [10, 10], "bursts": [0.1, 0.255], "burst_count": 7},
        ]
    )
    sim = Simulation(make_scene(scene))
    for step in range(1, 41):
        sim.step(1)
        assert abs(sim.terms.emitters.emitted[0] - 250.0 * sim.time) <= 1.0
        if step % 2 == 0:
            assert sim.terms.emitters.emitted[0] == 5 * step // 2  # 2.5 per step gives 5 every 2 steps
    assert sim.terms.emitters.emitted[1] == 14 and sim.particles.n[None] == 100 + 14


def test_lifetimes_retire_exactly_the_expired_and_memory_stays_bounded():
    scene = emitter_scene(
        emitters=[
            {
                "material": "jelly",
                "count": 500,
                "shape": "point",
                "center": [20, 20],
                "lifetime": 1.0,
                "lifetime_spread": 0.5,
            }
        ],
        precision="f64",
    )
    sim = Simulation(make_scene(scene))
    born = np.sort(sim.particles.lifetime.to_numpy()[:500])
    assert 0.5 <= born.min() and born.max() <= 1.5 and born.std() > 0.2
    for _ in range(12):
        sim.step(10)
        alive = np.sort(sim.particles.lifetime.to_numpy()[: sim.particles.n[None]])
        assert np.array_equal(alive, born[born > sim.particles.age.to_numpy()[0] + 1e-12] if len(alive) else alive)
    # a fountain: 100 particles per step living 5 steps, for 1,000 steps
    fountain = emitter_scene(
        emitters=[
            {
                "material": "jelly",
                "rate": 10000.0,
                "shape": "disk",
                "center": [20, 20],
                "size": 3,
                "lifetime": 0.05,
                "radial_speed": 5.0,
            }
        ]
    )
    sim = Simulation(make_scene(fountain))
    capacity = sim.capacity
    most = 0
    for _ in range(100):
        sim.step(10)
        most = max(most, int(sim.particles.n[None]))
    assert sum(sim.terms.emitters.emitted) >= 100_000 - 1  # (the carried fraction may still owe one)
    assert most <= 600 and sim.capacity == capacity


def test_kinematic_particles_move_exactly_with_a_uniform_wind():
    data = emitter_scene(fields=[{"kind": "wind", "velocity": [1.5, -0.5]}], gravity=[0, -9.8], precision="f64")
    data["bodies"] = [{"material": "jelly", "shape": "box", "lo": [10, 20], "hi": [12, 22], "field": "kinematic"}]
    sim = Simulation(make_scene(data))
    x0 = sim.positions()
    sim.step(100)  # t = 1: springs, gravity and the integrator do not move them; the wind does
    assert np.allclose(sim.positions() - x0, [1.5, -0.5], atol=1e-12)


def test_drag_coupling_relaxes_to_the_field_velocity():
    data = emitter_scene(fields=[{"kind": "wind", "velocity": [4.0, 0.0]}], dt=0.001, precision="f64")
    data["bodies"] = [
        {
            "material": "jelly",
            "shape": "box",
            "lo": [10, 20],
            "hi": [11, 21],
            "field": "drag",
            "field_drag": 2.0,
            "springs": False,
        }
    ]
    sim = Simulation(make_scene(data))
    sim.step(500)  # t = 0.5: v = w (1 - exp(-k t))
    assert abs(sim.velocities()[0, 0] - 4.0 * (1 - math.exp(-1.0))) < 0.01


def test_vortex_speed_profile_matches_its_formula():
    gamma, core, falloff = 30.0, 2.0, 12.0
    data = emitter_scene(
        fields=[{"kind": "vortex", "center": [20, 20], "strength": gamma, "radius": core, "falloff": falloff}]
    )
    data["bodies"] = [{"material": "jelly", "shape": "box", "lo": [1, 1], "hi": [2, 2]}]
    sim = Simulation(make_scene(data))
    r = np.linspace(0.5, 15, 30)
    pts = np.stack([20 + r, np.full_like(r, 20)], axis=1)
    v = sim.terms.fields.sample(pts, 0.0)
    expected = gamma / (2 * np.pi * r) * (1 - np.exp(-(r**2) / core**2)) * np.exp(-(r**2) / falloff**2)
    assert np.allclose(v[:, 1], expected, rtol=1e-4, atol=1e-6) and np.allclose(v[:, 0], 0, atol=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_curl_noise_is_divergence_free(dim):
    data = emitter_scene(dim, fields=[{"kind": "noise", "strength": 2.0, "scale": 6.0, "seed": 3}])
    data["bodies"] = [{"material": "jelly", "shape": "box", "lo": [1] * dim, "hi": [2] * dim}]
    sim = Simulation(make_scene(data))
    rng = np.random.default_rng(0)
    pts = rng.uniform(5, 35, (200, dim))
    delta = 0.02
    div = np.zeros(len(pts))
    grad_scale = np.zeros(len(pts))
    for a in range(dim):
        e = np.zeros(dim)
        e[a] = delta
        dv = (sim.terms.fields.sample(pts + e, 0.3) - sim.terms.fields.sample(pts - e, 0.3)) / (2 * delta)
        div += dv[:, a]
        grad_scale += np.abs(dv).sum(axis=1)
    speed = np.linalg.norm(sim.terms.fields.sample(pts, 0.3), axis=1)
    assert speed.mean() > 0.3  # it does swirl
    assert np.mean(np.abs(div)) < 0.02 * np.mean(grad_scale)  # but neither converges nor diverges


def test_rotation_forward_euler_spirals_out_and_midpoint_much_less():
    # inside a Lamb-Oseen core of radius 1000 the flow is a rigid rotation: omega = gamma / (2 pi rc^2)
    gamma, rc = 2 * math.pi * 1000.0**2, 1000.0  # omega = 1
    growth = {}
    for scheme in ("euler", "midpoint"):
        data = emitter_scene(
            fields=[{"kind": "vortex", "center": [20, 20], "strength": gamma, "radius": rc}],
            dt=0.05,
            precision="f64",
            advection=scheme,
        )
        data["bodies"] = [
            {"material": "jelly", "shape": "box", "lo": [29.5, 19.5], "hi": [30.5, 20.5], "field": "kinematic"}
        ]
        sim = Simulation(make_scene(data))
        steps = round(2 * math.pi / 0.05)  # one turn
        sim.step(steps)
        growth[scheme] = np.linalg.norm(sim.positions()[0] - 20) / 10.0 - 1
    # forward Euler multiplies the radius by sqrt(1 + (omega dt)^2) every step
    assert abs(growth["euler"] - ((1 + 0.05**2) ** (steps / 2) - 1)) < 0.02 * growth["euler"]
    assert 0 <= growth["midpoint"] < 0.01 * growth["euler"]


def smoke_scene(dim: int) -> dict:
    """A hot source low in a 24^dim box of smoke, and a kinematic particle above it."""
    lo, hi = [0.0] * dim, [24.0] * dim
    src_lo, src_hi = [10.0] * dim, [14.0] * dim
    src_lo[1], src_hi[1] = 1.0, 3.0
    data = emitter_scene(dim, gravity=[0.0, -9.8] + [0.0] * (dim - 2), dt=0.02, precision="f64")
    data["world"]["lo"], data["world"]["hi"] = lo, hi
    data["smoke"] = {
        "resolution": 24 if dim == 2 else 12,
        "buoyancy": 1.0,
        "tolerance": 1e-6,
        "sources": [{"lo": src_lo, "hi": src_hi, "temperature": 120.0}],
    }
    centre = [12.0] * dim
    centre[1] = 4.0
    data["bodies"] = [
        {
            "material": "jelly",
            "shape": "box",
            "lo": [c - 0.5 for c in centre],
            "hi": [c + 0.5 for c in centre],
            "field": "kinematic",
        }
    ]
    return data


@pytest.mark.parametrize("one_launch", [True, False], ids=["one_launch", "host_driven_cg"])
@pytest.mark.parametrize("dim", [2, pytest.param(3, marks=[pytest.mark.slow, pytest.mark.long])])  # 3D: `-m long`
def test_smoke_grid_projects_to_divergence_free_and_hot_air_rises(dim, one_launch, monkeypatch):
    """Both ways of projecting: the whole solve in one launch on one thread (small grids on the CPU) and CG driven
    from the host, a launch per stage (large grids, GPUs)."""
    monkeypatch.setattr(smoke_module, "ONE_LAUNCH_CELLS", 10**9 if one_launch else 0)
    sim = Simulation(make_scene(smoke_scene(dim)))
    assert sim.terms.smoke.grid.one_launch == one_launch
    y0 = sim.positions()[0, 1]
    for _ in range(25):
        sim.step(1)
        smoke = sim.terms.smoke.grid
        assert smoke.last.relative_residual <= 1e-6
        # what is left of the divergence is the solver's residual: a millionth of what the projection removed
        assert smoke.divergence_norm() <= 1.01e-6 * smoke.divergence_before + 1e-12
    above = np.array([[12.0] * dim])
    above[0, 1] = 8.0
    assert sim.terms.fields.sample(above, sim.time)[0, 1] > 0.5  # the plume rises ...
    assert sim.positions()[0, 1] > y0 + 1.0  # ... and carries the particle up with it


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_both_ways_of_projecting_the_smoke_give_the_same_flow(monkeypatch):
    """The one-launch projection iterates as solvers.pcg does: the same iterations and, to round-off (the sums
    are taken in another order), the same velocities after 10 steps."""
    results = []
    for cells in (10**9, 0):
        monkeypatch.setattr(smoke_module, "ONE_LAUNCH_CELLS", cells)
        sim = Simulation(make_scene(smoke_scene(2)))
        iterations = []
        for _ in range(10):
            sim.step(1)
            iterations.append(sim.terms.smoke.grid.last.iterations)
        results.append((iterations, [u.to_numpy() for u in sim.terms.smoke.grid.u]))
    (its_one, u_one), (its_host, u_host) = results
    assert sum(its_one) > 50 and abs(sum(its_one) - sum(its_host)) <= 2
    for a, b in zip(u_one, u_host):
        assert np.abs(a - b).max() <= 1e-8 * np.abs(b).max()


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_candle_melts_at_the_top_drips_and_refreezes_under_a_bounded_flame():
    from sandbox.config.scene import load_scene

    from .conftest import SCENES

    sim = Simulation(load_scene(SCENES / "candle.toml"))
    wax = sim.model.built.count
    top0 = sim.positions()[:, 1].max()
    most_flame = 0
    for _ in range(200):  # 4 s
        sim.advance_frame()
        most_flame = max(most_flame, int(sim.particles.n[None]) - wax)
    stats = sim.stats()
    x = sim.positions()[:wax]
    assert sim.particles.n[None] - wax > 100 and most_flame < 300  # the flame: 300/s living 0.7 s (+-50%)
    assert stats.molten_fraction > 0.1 and stats.broken_springs > 100  # the top melted ...
    assert x[:, 1].max() < top0 - 2  # ... and sank
    outside = (x[:, 0] < 58) | (x[:, 0] > 70)
    assert np.sum(outside & (x[:, 1] < top0 - 6)) > 5  # the melt ran over the sides and drips down them
    assert np.all(np.isfinite(sim.temperatures()))


def test_refill_tops_up_each_cell_to_the_target_density_and_no_more():
    from sandbox.app.tools import Tools

    data = emitter_scene(
        emitters=[
            {
                "material": "jelly",
                "shape": "box",
                "lo": [10, 10],
                "hi": [30, 20],
                "refill_density": 1.0,
                "particle_radius": 0.2,
            }
        ]
    )
    sim, again = Simulation(make_scene(data)), Simulation(make_scene(data))
    sim.step(1)
    again.step(1)
    n = int(sim.particles.n[None])
    assert n == 200  # 50 cells of 2 x 2, four each: 1 per unit area
    # each its own id (they were all 0), and the same particles in every run (the cells took their serial numbers,
    # and so their random places, in the order their threads reached them)
    assert np.array_equal(np.sort(sim.particles.ident.to_numpy()[:n]), np.arange(n))
    assert np.array_equal(sim.positions(), again.positions())
    x = sim.positions()
    cells = ((x[:, 0] - 10) // 2).astype(int) * 5 + ((x[:, 1] - 10) // 2).astype(int)
    assert np.all(np.bincount(cells, minlength=50) == 4)
    sim.step(5)
    assert sim.particles.n[None] == 200  # full: nothing more
    removed = Tools(sim).erase([15.0, 15.0], 4.0)
    assert removed > 20
    sim.step(1)
    assert sim.particles.n[None] >= 200  # topped up again where the hole was
    ids = sim.particles.ident.to_numpy()[: int(sim.particles.n[None])]
    assert len(np.unique(ids)) == len(ids) and ids.max() == 200 + removed - 1  # the new ones numbered on
    x = sim.positions()
    inside = (x[:, 0] >= 10) & (x[:, 0] < 30) & (x[:, 1] >= 10) & (x[:, 1] < 20)
    cells = ((x[inside, 0] - 10) // 2).astype(int) * 5 + ((x[inside, 1] - 10) // 2).astype(int)
    assert np.all(np.bincount(cells, minlength=50) >= 4)


def test_mask_seeding_is_uniform_over_the_masked_area_and_colour_is_the_emitters():
    from sandbox.config.build import load_mask

    from .conftest import ROOT

    image = load_mask(str(ROOT / "assets" / "masks" / "heart.png"))  # (W, H) bool
    emitter = {
        "shape": "mask",
        "mask": "masks/heart.png",
        "lo": [4, 4],
        "hi": [36, 36],
        "count": 4000,
        "color": [0.2, 0.9, 0.4],
        "particle_radius": 0.05,
    }
    sim = Simulation(make_scene(emitter_scene(2, [{"material": "jelly", **emitter}])))
    x = sim.positions()
    w, h = image.shape
    px = ((x[:, 0] - 4) / 32 * w).astype(int)
    py = ((x[:, 1] - 4) / 32 * h).astype(int)
    assert np.all(image[px, py])  # every particle on an inside pixel
    # counts in a 4 x 4 grid of blocks against each block's share of the inside pixels
    block = (px * 4 // w) * 4 + (py * 4 // h)
    share = np.array(
        [image[i * w // 4 : (i + 1) * w // 4, j * h // 4 : (j + 1) * h // 4].sum() for i in range(4) for j in range(4)],
        dtype=float,
    )
    used = share > 0
    expected = share[used] / share.sum() * len(x)
    counts = np.bincount(block, minlength=16)[used]
    assert ((counts - expected) ** 2 / expected).sum() < 40  # p = 0.001 for up to 15 degrees of freedom: 37.7
    assert np.allclose(sim.particles.color.to_numpy()[0], [0.2, 0.9, 0.4])

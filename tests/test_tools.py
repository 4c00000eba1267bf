"""The sandbox tools act where the brush is and nowhere else; erase, spawn and reset keep the state consistent."""

import numpy as np
import pytest

from sandbox.app.tools import Tools
from sandbox.config.scene import load_scene
from sandbox.errors import SandboxError
from sandbox.simulation import Simulation

from .conftest import SCENES

SMALL = ["bodies.0.lo=[56.0, 0.0]", "bodies.0.hi=[72.0, 12.0]"]


@pytest.fixture
def melt():
    sim = Simulation(load_scene(SCENES / "melting_block.toml", SMALL))
    return sim, Tools(sim)


def test_heat_brush_warms_only_inside_the_brush(melt):
    sim, tools = melt
    x, t0 = sim.positions(), sim.temperatures().copy()
    centre = np.array([64.5, 6.5])
    tools.heat(centre, 3.0, rate=100.0, dt=0.1)
    r = np.linalg.norm(x - centre, axis=1)
    dt = sim.temperatures() - t0
    assert dt[r < 0.5].min() > 8.0  # ~10 degrees at the centre
    assert np.all(dt[r >= 3.0] == 0.0)  # nothing outside the brush
    assert np.all(np.diff(dt[np.argsort(r)][r[np.argsort(r)] < 3.0]) <= 1e-4)  # falls off with distance
    tools.heat(centre, 3.0, rate=-100.0, dt=0.1)
    assert np.allclose(sim.temperatures(), t0, atol=1e-4)


def test_erase_removes_exactly_the_particles_in_the_brush_and_their_springs(melt):
    sim, tools = melt
    x = sim.positions()
    centre = np.array([60.0, 6.0])
    inside = np.linalg.norm(x - centre, axis=1) <= 2.5
    survivors = x[~inside]
    removed = tools.erase(centre, 2.5)
    assert removed == inside.sum() > 0
    assert sim.particles.n[None] == len(x) - removed
    assert np.allclose(np.sort(sim.positions(), axis=0), np.sort(survivors, axis=0))
    # every live spring joins two surviving particles at about its rest length; the bond table matches
    s = sim.state.springs
    alive = s.alive.to_numpy().astype(bool)
    i, j = s.i.to_numpy()[alive], s.j.to_numpy()[alive]
    n = sim.particles.n[None]
    assert i.max() < n and j.max() < n
    length = np.linalg.norm(sim.positions()[j] - sim.positions()[i], axis=1)
    assert np.allclose(length, s.rest.to_numpy()[alive], atol=1e-4)
    assert (s.bonds.to_numpy()[:n] >= 0).sum() == 2 * alive.sum()
    sim.step(20)  # and it keeps running
    assert np.isfinite(sim.stats().total_energy)


def test_spawn_adds_the_material_without_overlap(melt):
    sim, tools = melt
    n0 = sim.particles.n[None]
    added = tools.spawn("wax", [64.0, 15.0], 3.0)  # overlapping the block's top (y up to 12)
    assert added > 10
    assert sim.particles.n[None] == n0 + added
    x = sim.positions()
    new, old = x[n0:], x[:n0]
    d = np.linalg.norm(new[:, None, :] - old[None, :, :], axis=2).min()
    assert d >= 0.9 - 1e-6
    assert np.all(sim.particles.material.to_numpy()[n0 : n0 + added] == 0)
    with pytest.raises(SandboxError, match="not in this scene"):
        tools.spawn("unobtainium", [64.0, 30.0], 2.0)


def test_impulse_pushes_outward(melt):
    sim, tools = melt
    centre = np.array([64.0, 12.0])
    tools.impulse(centre, 4.0, speed=10.0)
    x, v = sim.positions(), sim.velocities()
    r = x - centre
    inside = (np.linalg.norm(r, axis=1) < 4.0) & (np.linalg.norm(r, axis=1) > 0.1)
    assert np.all((v[inside] * r[inside]).sum(axis=1) > 0)
    assert np.all(v[~inside] == 0)


def test_reset_restores_the_initial_state_exactly(melt):
    sim, tools = melt
    before = sim.snapshot()
    tools.erase([60.0, 6.0], 2.5)
    tools.spawn("wax", [64.0, 20.0], 2.0)
    tools.heat([64.0, 6.0], 4.0, 500.0, 0.1)
    sim.step(30)
    sim.reset()
    after = sim.snapshot()
    for key, value in before.items():
        assert np.array_equal(np.asarray(value), np.asarray(after[key])), key
    sim.step(5)  # runs again after the reset
    assert np.isfinite(sim.stats().total_energy)


def test_empty_sandbox_spawns_palette_materials_and_cold_wax_freezes_into_one_solid():
    from sandbox.app.cli import _scene_path
    from sandbox.app.window_state import make_state

    path = _scene_path("sandbox")  # a shipped scene, not the package folder of the same name
    assert path == SCENES / "sandbox.toml"
    sim = Simulation(load_scene(path))
    assert sim.particles.n[None] == 0 and sim.material_names == ["wax", "ice", "jelly"]
    state = make_state(sim, None)
    assert state.material == "wax"
    state.handle_key("m")
    assert state.material == "ice"
    tools = Tools(sim)
    made = tools.spawn("wax", [64.0, 20.0], 4.0)
    assert made > 40 and sim.particles.n[None] == made
    assert set(sim.particles.group.to_numpy()[:made]) == {len(sim.scene.groups)}  # the spawn tool's own group
    sim.step(20)  # two refreezing passes: cold (20 C) wax bonds into a solid
    alive = sim.state.springs.alive.to_numpy().astype(bool)
    i, j = sim.state.springs.i.to_numpy()[alive], sim.state.springs.j.to_numpy()[alive]
    assert len(i) > 2 * made  # about four bonds per particle
    assert np.all(np.bincount(np.concatenate([i, j]), minlength=made)[:made] > 0)
    with pytest.raises(SandboxError, match="not in this scene"):
        tools.spawn("lava", [64.0, 40.0], 2.0)


def _slots(sim, first: int, last: int) -> dict:
    p = sim.particles
    return {name: getattr(p, name).to_numpy()[first:last] for name in p.names()}


def test_a_spawn_after_retirement_gives_fresh_values_in_every_field():
    """Fireworks retires dead sparks by compaction; the spawn tool then wrote its hand-kept list of fields and left
    the rest as the dead had them: 258 of 512 spawned particles inherited a dead spark's age and lifetime (issue 73),
    and died at once. Every field of a spawned slot is what the tool gives or the field's declared default."""
    from sandbox.core.particles import PER_PARTICLE

    sim = Simulation(load_scene(SCENES / "fireworks.toml"))
    tools = Tools(sim)
    for _ in range(60):  # bursts, and sparks retired (lifetimes 2.2 s +- 40%)
        sim.run(5)
        if int(sim.particles.n[None]) < sim.particles.ident.to_numpy().max():
            break
    p = sim.particles
    n = int(p.n[None])
    assert p.next_ident > n, "no spark was retired: the test needs freed slots"
    stale = _slots(sim, n, sim.capacity)
    assert not np.any(stale["lifetime"]) and not np.any(stale["age"]), "freed slots kept a dead spark's values"
    added = tools.spawn(sim.material_names[0], [80.0, 40.0], 6.0)
    assert added > 20
    new = _slots(sim, n, n + added)
    given = {"x", "v", "mass", "radius", "material", "color", "group", "ident"}
    for field in PER_PARTICLE:
        if field.name in new and field.name not in given:
            assert np.all(new[field.name] == field.default), field.name
    spawned = set(new["ident"].tolist())
    sim.run(5)  # none dies at once: they live for ever (lifetime 0), as the tool's particles do in any scene
    assert spawned <= set(p.ident.to_numpy()[: int(p.n[None])].tolist())


def test_erased_slots_hold_their_declared_defaults(melt):
    sim, tools = melt
    n = int(sim.particles.n[None])
    removed = tools.erase([60.0, 6.0], 2.5)
    assert removed > 0
    freed = _slots(sim, n - removed, n)
    assert not np.any(freed["x"]) and not np.any(freed["mass"]) and not np.any(freed["T"])

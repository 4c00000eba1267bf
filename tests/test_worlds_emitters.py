"""Worlds of scenes whose particle counts change (core/worlds.py, gaps): emitters seed each world on its own clock and
with its own random stream, lifetimes retire each world's dead by compacting its own block, and each world is the
scene run alone, bit for bit.

A world's particles are compared by id (`sim.world(k).positions()` is by id; a lone run's storage is reordered by
its compaction, so the lone run's are sorted by id here).
"""

from pathlib import Path

import numpy as np
import pytest

import sandbox

pytestmark = pytest.mark.xdist_group("worlds")
ROOT = Path(__file__).resolve().parent.parent


def _by_id(sim, name: str = "x") -> np.ndarray:
    """A lone run's per-particle field `name` of its live particles, by id."""
    n = sim.state.live_count()
    order = np.argsort(sim.particles.ident.to_numpy()[:n], kind="stable")
    return getattr(sim.particles, name).to_numpy()[:n][order]


def _restarted(scene: str, worlds: int, frames: int, k: int, steps: int = 0, values: dict | None = None) -> tuple:
    """(lone run, batch of `worlds`, fresh lone run) of `scene` (with `values` set): the first two run `frames`
    frames and `steps` steps, then world k of the batch starts again, as the fresh run starts."""
    lone, batch = sandbox.load(scene, set=values), sandbox.load(scene, set=values, worlds=worlds)
    for _ in range(frames):
        lone.advance_frame()
        batch.advance_frame()
    if steps:
        lone.step(steps)
        batch.step(steps)
    batch.world(k).reset()
    return lone, batch, sandbox.load(scene, set=values)


def _assert_world_is(lone, world, fields=("x", "v")) -> None:
    for name in fields:
        mine, alone = world.field(name), _by_id(lone, name)
        assert mine.shape == alone.shape, name
        assert np.array_equal(mine, alone), name


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_fireworks_is_its_lone_run_through_bursts_and_retirements():
    """Three emitters' bursts (at 0.1, 0.6 and 1.2 s) and sparks of 1.8-2.2 s lifetimes (spread 40%): by frame 70
    (1.4 s) the first burst's sparks have begun to die, so each world has emitted into its block and compacted it."""
    lone = sandbox.load("fireworks")
    batch = sandbox.load("fireworks", worlds=3)
    assert batch.state.live_count() == 3 * batch.state.particles.world_size  # every world's block, none live yet
    for _ in range(70):
        lone.advance_frame()
        batch.advance_frame()
    emitted = sum(lone.terms.emitters.emitted)
    assert 0 < lone.state.live_count() < emitted  # sparks were born and some retired
    for k in range(3):
        world = batch.world(k)
        _assert_world_is(lone, world)
        assert world.stats() == lone.stats()
        assert batch.terms.emitters.emitted[k] == lone.terms.emitters.emitted


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_fireworks_world_started_again_bursts_on_its_own_clock_and_the_others_run_on(tmp_path):
    """World 1 starts again at 0.5 s: its first burst comes at its own 0.1 s, and it equals a lone run started then;
    worlds 0 and 2 equal the uninterrupted run. A world's state file resumes alone as that run; a world taken out
    has the last one move into its place."""
    lone, batch, fresh = _restarted("fireworks", 3, 25, 1)
    assert batch.world(1).positions().shape == (0, 2) and batch.world(1).time == 0.0
    for _ in range(20):
        for sim in (lone, batch, fresh):
            sim.advance_frame()
    for k, alone in ((0, lone), (1, fresh), (2, lone)):
        _assert_world_is(alone, batch.world(k))
    assert lone.state.live_count() != fresh.state.live_count()  # the restarted world is really younger
    path = batch.world(1).save(tmp_path / "world1.npz")
    resumed = sandbox.resume(path)
    batch.world(0).remove()  # world 2 (the uninterrupted run) moves into index 0
    for _ in range(10):
        for sim in (lone, batch, fresh, resumed):
            sim.advance_frame()
    _assert_world_is(lone, batch.world(0))
    _assert_world_is(fresh, batch.world(1))
    _assert_world_is(fresh, type("View", (), {"field": lambda self, name: _by_id(resumed, name)})())


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_a_candle_is_its_lone_run_to_the_bit():
    """The candle: a flame emitter (300 a second, 0.7 s lifetimes) carried by a wind and curl noise that drifts in
    time (kinematic particles, sampled at each world's clock), over wax that melts, breaks its bonds and refreezes
    (springs, the pair force, heat, a heat source): positions, velocities and temperatures equal the lone run's. A
    third world started again after 10 frames is a lone run started then (its noise drifting on its own clock), to
    the bit, temperatures too: its neighbour lists are rebuilt where its own particles are seeded or retired (or have
    moved half the skin), not where the other worlds' are, so its heat flows are summed in its lone run's order."""
    lone, batch, fresh = _restarted("candle", 3, 10, 2)
    for _ in range(40):
        for sim in (lone, batch, fresh):
            sim.advance_frame()
    alone = lone.stats()
    assert alone.broken_springs > 0 and sum(lone.terms.emitters.emitted) > lone.state.live_count() - 336
    _assert_world_is(fresh, batch.world(2), ("x", "v", "T"))
    assert not np.array_equal(_by_id(fresh)[:336], _by_id(lone)[:336])  # the young world's wax is its own
    for k in range(2):
        _assert_world_is(lone, batch.world(k), ("x", "v", "T"))
        mine = batch.world(k).stats()
        assert (mine.particles, mine.broken_springs, mine.molten_fraction) == (
            alone.particles,
            alone.broken_springs,
            alone.molten_fraction,
        )
        assert mine.kinetic_energy == alone.kinetic_energy
        # summed over springs: a world's refrozen bonds sit in other slots than its lone run's
        assert mine.spring_energy == pytest.approx(alone.spring_energy, rel=1e-6)


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_smoke_vortex_has_its_own_smoke_grid_and_is_its_lone_run():
    """smoke_vortex: a chimney's puffs carried by a stable-fluids smoke grid (buoyant hot air, its CG projection),
    a vortex and curl noise. Each world has its own grid, stepped every 3 of its own steps: world 1, started again
    one step past a frame (so its grid steps on other steps of the simulation than world 0's), is a lone run started
    then, its grid and puffs to the bit, while world 0 stays the uninterrupted run."""
    lone, batch, fresh = _restarted("smoke_vortex", 2, 8, 1, steps=1)
    for _ in range(12):
        for sim in (lone, batch, fresh):
            sim.advance_frame()
    _assert_world_is(lone, batch.world(0))
    _assert_world_is(fresh, batch.world(1))
    grids = batch.terms.smoke.grid
    for alone, k in ((lone, 0), (fresh, 1)):
        grid = alone.terms.smoke.grid
        assert np.array_equal(grids.T.to_numpy()[k], grid.T.to_numpy())
        assert all(np.array_equal(grids.u[a].to_numpy()[k], grid.u[a].to_numpy()) for a in range(2))
    assert not np.array_equal(grids.T.to_numpy()[0], grids.T.to_numpy()[1])  # two grids, each its own


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
@pytest.mark.parametrize("integrator", ["velocity_verlet", "verlet"])
def test_each_world_of_fireworks_stepped_by_a_leapfrog_is_its_lone_run(integrator):
    """A leapfrog integrator keeps each particle's staggered state between calls (integrators/leapfrog.py): a world
    whose particles are seeded and retired in its block steps as its lone run does, to the bit (it was refused)."""
    values = {"world.integrator": integrator}
    lone, batch = sandbox.load("fireworks", set=values), sandbox.load("fireworks", set=values, worlds=2)
    for _ in range(70):
        lone.advance_frame()
        batch.advance_frame()
    assert 0 < lone.state.live_count() < sum(lone.terms.emitters.emitted)  # sparks were born and some retired
    for k in range(2):
        _assert_world_is(lone, batch.world(k))


def _dripping_cooker(folder) -> str:
    """pressure_cooker (a lid, a heater, velocity Verlet) at 40 steps a frame, with an emitter dripping atoms from
    above the lid (20 a time unit, lifetimes 1-2 time units): a scene file in `folder`."""
    shipped = (ROOT / "scenes" / "pressure_cooker.toml").read_text()
    world = shipped[shipped.index("[world]") :].replace("substeps = 400 ", "substeps = 40  ")
    drip = (
        '[[emitters]]\nname = "drip"\nmaterial = "lj"\nshape = "box"\nlo = [2.0, 20.0, 2.0]\nhi = [13.0, 24.0, 13.0]\n'
        "rate = 20.0\nvelocity = [0.0, -1.0, 0.0]\nlifetime = 1.5\nlifetime_spread = 0.5\nseed = 3\n"
    )
    path = folder / "cooker_drip.toml"
    path.write_text('[scene]\nname = "cooker_drip"\n\n' + world + "\n" + drip)
    return str(path)


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_a_lidded_heated_cooker_with_an_emitter_is_its_lone_run(tmp_path):
    """The lid and the heater of a world whose atoms are seeded and retired sum its live atoms alone (an emitter's
    world has empty slots after them: Particles.world_slots): atoms, the lid's height and the heater's heat equal
    the lone run's, and a world started again after 10 frames equals a lone run started then (it was refused)."""
    lone, batch, fresh = _restarted(_dripping_cooker(tmp_path), 3, 10, 1)
    # what an empty slot of world 0's block holds (the last hit of an atom retired from it) moves no lid, as a lone
    # run never reads past its live atoms (the whole block summed, world 0's lid rose to 48.0 in a frame, the lone
    # run's to 30.0)
    first, live = batch.state.particles.block(0)
    batch.terms.lid.hit[first + live] = 1e3
    lone.terms.lid.hit[lone.state.live_count()] = 1e3
    for sim in (lone, batch, fresh):
        sim.advance_frame()
    assert batch.world(0).stats().lid_height == lone.stats().lid_height
    for _ in range(14):
        for sim in (lone, batch, fresh):
            sim.advance_frame()
    assert lone.terms.emitters.emitted[0] > lone.state.live_count() - 432 > 0  # dripped atoms were born and retired
    for k, alone in ((0, lone), (1, fresh), (2, lone)):
        _assert_world_is(alone, batch.world(k))
        mine, theirs = batch.world(k).stats(), alone.stats()
        assert (mine.lid_height, mine.heater_heat) == (theirs.lid_height, theirs.heater_heat)
    assert lone.stats().lid_height != fresh.stats().lid_height  # the restarted world's lid is its own


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_a_refill_emitter_is_its_lone_run_and_refills_its_own_region():
    """The candle's flame emitter given a refill density (it keeps its region topped up as the flame rises out of
    it): each world counts its own particles in the region and seeds its deficit with its own serial numbers and
    ids, cell by cell in a lone run's order; a world started again after 10 frames is a lone run started then."""
    refill = {"emitters.0.refill_density": 2.0}
    lone, batch, fresh = _restarted("candle", 3, 10, 2, values=refill)
    plain = sandbox.load("candle")  # its rate alone
    for _ in range(20):
        for sim in (lone, batch, fresh):
            sim.advance_frame()
    for _ in range(30):
        plain.advance_frame()
    assert lone.terms.emitters.emitted[0] > plain.terms.emitters.emitted[0] + 30  # the refill seeded too
    for k, alone in ((0, lone), (1, lone), (2, fresh)):
        _assert_world_is(alone, batch.world(k), ("x", "v", "T"))
        assert batch.terms.emitters.emitted[k] == alone.terms.emitters.emitted
        assert batch.particles.next_ident[k] == alone.particles.next_ident


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_bench_worlds_counts_a_scene_with_emitters_by_its_live_particles():
    """`sandbox bench --worlds K fireworks` counts each world's live sparks, not the slots of its block (4,672 a
    world, the few hundred thousand particle-steps a second it would have claimed)."""
    from sandbox.research.worlds_bench import bench_worlds

    result = bench_worlds(2, "fireworks", frames=4, repeats=1)  # 1 + 4 x 2 frames: past the first shell (frame 4)
    assert result["particles_per_world"] == 700
    batched = result["batched"]
    assert batched["per_world"] == pytest.approx(700 * result["steps_per_frame"] * batched["frames_per_second_each"])
    assert result["speedup"] > 0.0

"""Worlds (core/worlds.py): K copies of a scene in one simulation, each the trajectory of the scene run alone.

Every world starts on the same coordinates as the others, so a pair, a heat flow or a neighbour found across two
worlds would put two particles at distance 0 (a blow-up, not a rounding): bit-for-bit equality with the lone run is
also the proof that nothing crosses worlds.
"""

import dataclasses
import math

import numpy as np
import pytest

import sandbox
from sandbox.errors import SandboxError

pytestmark = pytest.mark.xdist_group("worlds")

# a 12 x 12 wax block near its melting point on a 400-degree plate: it melts, its bonds break and (refreeze) new ones
# form within the steps run here; springs, the pair force, heat, a heat source, walls and refreezing all act
SMALL_BLOCK = {
    "bodies.0.lo": [44.0, 0.0],
    "bodies.0.hi": [56.0, 12.0],
    "bodies.0.temperature": 52.0,
    "heat.sources.0.temperature": 400.0,
}
# a periodic Lennard-Jones box of 20 x 20 atoms at density 0.8: pairs across its seams
SMALL_LJ = {"world.hi": [22.36067977, 22.36067977], "bodies.0.hi": [22.36067977, 22.36067977]}


def _state(view) -> tuple:
    return view.positions(), view.velocities()


def _assert_same(lone, world) -> None:
    for a, b in zip(_state(lone), _state(world)):
        assert a.shape == b.shape
        assert np.array_equal(a, b)


def test_each_world_of_a_melting_block_is_its_lone_run_to_the_bit():
    lone = sandbox.load("melting_block", set=SMALL_BLOCK)
    batch = sandbox.load("melting_block", set=SMALL_BLOCK, worlds=3)
    assert batch.worlds == 3 and batch.state.live_count() == 3 * lone.state.live_count()
    for _ in range(16):
        lone.advance_frame()
        batch.advance_frame()
    alone = lone.stats()
    assert alone.molten_fraction > 0.05 and alone.broken_springs > 0  # the run melts, breaks bonds
    for k in range(3):
        world = batch.world(k)
        _assert_same(lone, world)
        assert np.array_equal(lone.temperatures(), world.temperatures())
        _assert_readouts_alike(world.stats(), alone)


def _assert_readouts_alike(stats, alone) -> None:
    """Each world's readouts are its own sums, as the lone run's (a sum over all worlds would be 3 times as much):
    the particles' sums to the bit, those over springs (a world's refrozen bonds sit in other slots than its lone
    run's) and the walls' gauge (added up atomically per world) to the rounding of their sums."""
    rounded = {"spring_energy", "potential_energy", "total_energy", "pressure", "wall_pressure"}
    rounded.add("time")  # a restarted world's clock: the time now less the time it started
    for name, value in dataclasses.asdict(alone).items():
        mine = getattr(stats, name)
        if isinstance(value, float) and math.isnan(value):
            assert math.isnan(mine), name
        elif any(word in name for word in rounded):
            assert mine == pytest.approx(value, rel=1e-6, abs=1e-9), name
        else:
            assert mine == value, name


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_a_periodic_lj_box_is_its_lone_run_to_the_bit():
    """World 1 is heated hard (its atoms sped up 3 times), so its neighbour lists are rebuilt on other steps than
    world 0's: world 0 still sums its forces in the lone run's order (its rows rebuilt only when its own atoms have
    moved half the skin), and world 1 is the lone run given the same kick."""
    lone = sandbox.load("lj_box", set=SMALL_LJ)
    kicked = sandbox.load("lj_box", set=SMALL_LJ)
    batch = sandbox.load("lj_box", set=SMALL_LJ, worlds=2)
    v = batch.particles.v.to_numpy()
    n = lone.state.live_count()
    v[n : 2 * n] *= 3.0
    batch.particles.v.from_numpy(v)
    kicked.particles.v.from_numpy(kicked.particles.v.to_numpy() * 3.0)
    for _ in range(6):
        for sim in (lone, kicked, batch):
            sim.advance_frame()
    assert batch.hood.lists.builds > lone.hood.lists.builds  # world 1 rebuilt more often than world 0 would
    start = sandbox.load("lj_box", set=SMALL_LJ).positions()
    assert np.abs(lone.positions() - start).max() > 5.0  # some atom wrapped across a seam
    for k, alone in enumerate((lone, kicked)):
        _assert_same(alone, batch.world(k))
        assert batch.world(k).stats().pair_energy == alone.stats().pair_energy


def _crowded(sim, way, tmp_path):
    """`sim` stepping as on a crowded machine (another program wants a core), by `way` (step/crowd.py)."""
    from sandbox.core.threads import LoadWatch

    loadavg = tmp_path / f"loadavg-{way}"
    loadavg.write_text("0.5 0.5 0.5 9/80 1234\n")
    sim.plan.load = LoadWatch(2, str(loadavg), cores=2, machine=2)
    sim.plan.load.others, sim.plan.load.last = 9.0, -1.0
    sim.plan.crowd.choose = lambda: way
    return sim


@pytest.mark.long
def test_worlds_step_as_a_team_where_their_lone_runs_do_and_each_is_its_lone_run_to_the_bit(tmp_path):
    """A whole melting block (1,200 particles) runs alone as a team of threads (step/team.py), and so do its worlds:
    many steps a launch, every world's pair chunks shared out among the workers. World 0's plate is at 400 C, world
    1's at 20 C (a block that only settles), and the lists are narrowed so that a build overflows and they widen
    while running: the rebuild after the widening rebuilds the rows of the worlds that build was for (world 0's),
    so world 1's lists are still those its lone run built, on its lone run's steps (their reference positions equal
    the lone run's), and each world is its lone run to the bit; so are the worlds of a crowded machine, stepped on
    one thread (the team's kernel, one worker) or the long way."""
    from sandbox.step.crowd import ALONE, LONG

    hot = {"bodies.0.temperature": 52.0, "heat.sources.0.temperature": 400.0}
    lone = sandbox.load("melting_block", set=hot)
    if lone.plan.team is None:
        pytest.skip("one CPU thread here: no team of threads to step as")
    cold = sandbox.load("melting_block", set={**hot, "heat.sources.0.temperature": 20.0})
    batch, alone, long_way = (sandbox.load("melting_block", set=hot, worlds=2) for _ in range(3))
    for sim in (batch, alone, long_way):
        sim.world(1).controls.set({"heat.sources": [20.0]})
    assert batch.plan.team is not None and batch.plan.fuses
    sims = (lone, cold, batch, _crowded(alone, ALONE, tmp_path), _crowded(long_way, LONG, tmp_path))
    for sim in sims:  # lists narrower than the melt needs, built again from the next step on
        sim.advance_frame()
        sim.plan.lists._allocate(19)
        sim.plan.lists.invalidate()
    for _ in range(26):
        for sim in sims:
            sim.advance_frame()
    assert [sim.plan.lists.grown for sim in sims] == [1, 0, 1, 1, 1]  # world 0 widened the batches' lists
    assert batch.plan.fused_batches > 0 and lone.stats().broken_springs > 0
    assert alone.plan.crowded_steps == long_way.plan.crowded_steps == 27 * 8 and batch.plan.crowded_steps == 0
    n = lone.state.live_count()
    for worlds in (batch, alone, long_way):
        kept = worlds.plan.lists.x_ref.to_numpy()
        for k, run in enumerate((lone, cold)):
            _assert_same(run, worlds.world(k))
            assert np.array_equal(run.temperatures(), worlds.world(k).temperatures())
            assert np.array_equal(kept[k * n : (k + 1) * n], run.plan.lists.x_ref.to_numpy()[:n])


@pytest.mark.long
@pytest.mark.parametrize("scene", ["boiling_pot", "states_of_matter"])
def test_each_world_of_a_thermostatted_melt_is_its_lone_run_to_the_bit(scene):
    """The agitation kicks each free particle with noise hashed from its id and the step: a world's ids are its lone
    run's, so it draws the same noise, and its thermostat's gauge is its own. states_of_matter's burner is a power
    source, shared among the particles over it by mass: each world's among its own."""
    lone = sandbox.load(scene)
    batch = sandbox.load(scene, worlds=2)
    for _ in range(3):
        lone.advance_frame()
        batch.advance_frame()
    thermostat = lone.terms.agitation
    if scene == "boiling_pot":  # its water starts liquid: the noise acts from the first step (the ice starts solid)
        assert thermostat.moved[None] != 0.0
    for k in range(2):
        _assert_same(lone, batch.world(k))
        assert np.array_equal(lone.temperatures(), batch.world(k).temperatures())
        assert batch.terms.agitation.moved[k] == pytest.approx(thermostat.moved[None], rel=1e-9)


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_atoms_on_a_thermal_floor_is_its_lone_run_and_keeps_its_own_floor():
    """atoms: phases from structure (a cell grid of its own, per world too) over a thermal floor whose noise is hashed
    from each atom's id and hit count; world 1's floor is made hotter, as a lone run's is."""
    plain, hot = sandbox.load("atoms"), sandbox.load("atoms")
    batch = sandbox.load("atoms", worlds=2)
    hot.controls.set({"thermal_walls.floor": 0.6})
    batch.world(1).controls.set({"thermal_walls.floor": 0.6})
    for _ in range(6):  # the solid's bottom reaches the floor in its fifth frame
        for sim in (plain, hot, batch):
            sim.advance_frame()
    assert hot.stats().kinetic_energy > plain.stats().kinetic_energy  # the hotter floor gave the atoms more
    for k, alone in enumerate((plain, hot)):
        _assert_same(alone, batch.world(k))
        assert batch.world(k).stats() == alone.stats()  # no springs: every readout to the bit
        assert batch.world(k).controls.values() == alone.controls.values()


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_control_set_in_one_world_is_that_worlds_alone():
    """World 1's gravity and world 2's hot plate, air and pair law are set halfway: world 0 stays the unchanged lone
    run, and worlds 1 and 2 are the lone runs given the same change at the same step; a control set for all applies
    to every world."""
    plain = sandbox.load("melting_block", set=SMALL_BLOCK)
    tilted = sandbox.load("melting_block", set=SMALL_BLOCK)
    cooler = sandbox.load("melting_block", set=SMALL_BLOCK)
    batch = sandbox.load("melting_block", set=SMALL_BLOCK, worlds=3)
    for frame in range(8):
        if frame == 3:
            tilted.controls.set({"world.gravity": [2.0, -5.0]})
            batch.world(1).controls.set({"world.gravity": [2.0, -5.0]})
            cooler.controls.set({"heat.sources": [60.0], "heat.ambient": 10.0, "pair.scale": [1.5, 0.8]})
            batch.world(2).controls.set({"heat.sources": [60.0], "heat.ambient": 10.0, "pair.scale": [1.5, 0.8]})
        for sim in (plain, tilted, cooler, batch):
            sim.advance_frame()
    for k, lone in enumerate((plain, tilted, cooler)):
        _assert_same(lone, batch.world(k))
        assert np.array_equal(lone.temperatures(), batch.world(k).temperatures())
        assert batch.world(k).controls.values() == lone.controls.values()
    assert not np.array_equal(plain.positions(), tilted.positions())
    batch.controls.set({"world.drag": 0.5})
    assert [batch.world(k).controls.values()["world.drag"] for k in range(3)] == [0.5] * 3


def test_worlds_refuse_what_they_cannot_do_in_one_line():
    for bad in (0, -1, True, 2.5, "3", 10**6):
        with pytest.raises(SandboxError, match="worlds = .*expected a whole number from 1 to 4096"):
            sandbox.load("lj_box", set=SMALL_LJ, worlds=bad)
    with pytest.raises(SandboxError, match="sandbox: worlds = 2 needs a scene with particles or emitters; this one is"):
        sandbox.load("sandbox", worlds=2)  # the empty scene: was a ZeroDivisionError
    batch = sandbox.load("melting_block", set=SMALL_BLOCK, worlds=2)
    with pytest.raises(SandboxError, match="world 2: expected a whole number from 0 to 1"):
        batch.world(2)
    with pytest.raises(SandboxError, match="a state file holds one world; this simulation has 2"):
        batch.save("never.npz")
    for draw in (batch.picture, batch.particles, lambda: batch.write_cache("never.vtp", 1)):
        with pytest.raises(SandboxError, match="of a simulation of 2 worlds would draw them over each other"):
            draw()


def test_a_sweep_batches_the_runs_that_differ_only_in_a_worlds_keys():
    from sandbox.app.sweep_batch import MAX_BATCH, batches, world_key

    assert world_key("heat.sources.2.temperature") and world_key("bodies.0.velocity") and world_key("world.gravity")
    assert world_key("molecular.lid.pressure") and world_key("molecular.walls.1.temperature")
    assert not world_key("bodies.0.material") and not world_key("world.dt") and not world_key("heat.sources.0.lo")
    jobs = [
        (k, {"bodies.0.material": m, "heat.ambient": a}, f"f{k}", {})
        for k, (m, a) in enumerate((m, a) for m in ("wax", "ice") for a in (10.0, 20.0, 30.0))
    ]
    lone = (6, {"bodies.0.material": "gel", "heat.ambient": 10.0}, "f6", {})
    groups, alone = batches([*jobs, lone], video=False)
    assert [[job[0] for job in group] for group in groups] == [[0, 1, 2], [3, 4, 5]] and alone == [lone]
    assert batches(jobs, video=True) == ([], jobs)  # a video is drawn from one world: every run alone
    many = [(k, {"heat.ambient": float(k)}, f"f{k}", {}) for k in range(MAX_BATCH + 2)]
    groups, alone = batches(many, video=False)
    assert [len(g) for g in groups] == [MAX_BATCH, 2] and alone == []


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_worlds_started_from_other_scenes_take_their_lid_heater_and_wall_settings():
    """A sweep's worlds start from their runs' scenes: a lid pressure, a heater power and a thermal wall's
    temperature are a world's own (world 1 is its run alone; the heater's schedule, which starts at 0, is one for
    all worlds)."""
    from sandbox.config.resources import shipped_scene
    from sandbox.config.scene import load_scene
    from sandbox.simulation import Simulation

    path = shipped_scene("states_of_matter_atoms")
    weights = ["molecular.lid.pressure=0.1", "molecular.heater.power=1.5"]
    starts = [load_scene(path), load_scene(path, weights)]
    batch = Simulation(starts[0], starts=starts)
    heavy = Simulation(starts[1])
    for sim in (batch, heavy):
        sim.advance_frame()
    assert batch.world(1).controls.values() == heavy.controls.values()
    assert batch.world(1).controls.values()["lid.pressure"] == 0.1 != batch.world(0).controls.values()["lid.pressure"]
    _assert_same(heavy, batch.world(1))
    floor = shipped_scene("atoms")
    warm = Simulation(
        load_scene(floor), starts=[load_scene(floor), load_scene(floor, ["molecular.walls.0.temperature=0.6"])]
    )
    assert [warm.world(k).controls.values()["thermal_walls.floor"] for k in (0, 1)] == pytest.approx([0.25, 0.6])


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_world_started_again_is_a_fresh_lone_run_and_the_others_run_on():
    """World 1 starts again after 5 frames (40 steps: the refreezing pass, every 10 steps, keeps its phase): 10
    frames later it equals a lone run of 10 frames, its own plate schedule (hot for 0.25 s, then off) timed from its
    restart, while worlds 0 and 2 equal the uninterrupted lone run, whose plate went off at 0.25 s."""
    scheduled = {
        **SMALL_BLOCK,
        "heat.sources.0.schedule_times": [0.0, 0.25],
        "heat.sources.0.schedule_values": [400.0, 0.0],
    }
    lone = sandbox.load("melting_block", set=scheduled)
    batch = sandbox.load("melting_block", set=scheduled, worlds=3)
    for _ in range(5):
        lone.advance_frame()
        batch.advance_frame()
    batch.world(1).reset()
    assert batch.world(1).time == 0.0 and batch.world(0).time == lone.time
    fresh = sandbox.load("melting_block", set=scheduled)
    for _ in range(10):
        for sim in (lone, batch, fresh):
            sim.advance_frame()
    assert batch.world(1).controls.values()["heat.sources"] == [400.0]  # its plate still on at its own 0.2 s ...
    assert batch.world(0).controls.values()["heat.sources"] == [0.0]  # ... the others' off since 0.25 s
    for k, alone in ((0, lone), (1, fresh), (2, lone)):
        _assert_same(alone, batch.world(k))
        assert np.array_equal(alone.temperatures(), batch.world(k).temperatures())
        _assert_readouts_alike(batch.world(k).stats(), alone.stats())
    assert fresh.stats().broken_springs != lone.stats().broken_springs  # the restarted world is really younger


def test_bench_worlds_refuses_bad_arguments_in_one_line(capsys):
    from sandbox.app.cli import main

    for args, said in (
        (["0", "melting_block"], "--worlds: expected a number of worlds from 1 to 4096, got '0'"),
        (["many", "melting_block"], "--worlds: expected a number of worlds from 1 to 4096, got 'many'"),
        (["3", "no_such_scene"], "--worlds: no shipped scene 'no_such_scene'; expected one of"),
    ):
        assert main(["bench", "--worlds", *args]) == 2
        err = capsys.readouterr().err
        assert said in err and "Traceback" not in err


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_each_world_of_a_pressure_cooker_has_its_own_lid_and_heater_and_is_its_lone_run():
    """pressure_cooker (3D): a lid the atoms push up and a heater sharing its power among them, both following the
    scene's schedules. World 1's lid is made heavier and its heater weaker, as a second lone run's are: each world is
    its lone run to the bit (the lid's momentum summed in the atoms' order, the heater's sums over its own atoms),
    also after world 0's lists were widened (world 1's rows kept, not rebuilt on a step its lone run does not). World
    1 taken out and back in starts as a fresh run, its schedules on its own clock."""
    soon = {"molecular.heater.schedule_times": [0.0, 5.0], "molecular.heater.schedule_values": [2.4, -1.0]}
    light, heavy = sandbox.load("pressure_cooker", set=soon), sandbox.load("pressure_cooker", set=soon)
    batch = sandbox.load("pressure_cooker", set=soon, worlds=2)
    weights = {"lid.pressure": 0.3, "heater.power": 2.0, "pair.scale": [1.1, 1.0]}
    heavy.controls.set(weights)
    batch.world(1).controls.set(weights)
    for _ in range(3):
        for sim in (light, heavy, batch):
            sim.advance_frame()
    assert batch.hood.lists.grown > heavy.hood.lists.grown  # world 0's rows widened the table
    assert light.stats().lid_height > heavy.stats().lid_height + 2.0  # the light lid rose higher
    for k, alone in enumerate((light, heavy)):
        world = batch.world(k)
        _assert_same(alone, world)
        assert world.stats() == alone.stats()  # its lid's height and gauge, the heat its heater gave
        assert world.controls.values() == alone.controls.values()
    assert batch.world(1).controls.values()["lid.scheduled"] == 0.0  # set by hand: its schedule stopped
    # taken out and back in, world 1 starts with the scene's controls, its pair law's scales among them
    batch.world(1).remove()
    assert batch.add_world().index == 1
    fresh = sandbox.load("pressure_cooker", set=soon)
    for sim in (light, batch, fresh):
        sim.advance_frame()
    for k, alone in enumerate((light, fresh)):
        _assert_same(alone, batch.world(k))
        assert batch.world(k).controls.values() == alone.controls.values()  # its schedules, on its own clock
    assert light.controls.values()["heater.power"] == -1.0  # the first world cools since its 5th time unit ...
    assert batch.world(1).controls.values()["heater.power"] == 2.4  # ... the young one heats, 2 time units old


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_stroke_a_slider_undo_and_a_load_in_one_world_change_nothing_in_the_others(tmp_path):
    """World 1's controller (a classroom tab's) heats its block, cools its plate and undoes the stroke; world 2's
    loads world 0's state file: world 0 stays the uninterrupted lone run to the bit all along, world 1 is back to
    the state before its stroke, and world 2 becomes world 0 and steps on as it does."""
    from sandbox.app.controller import Controller

    plain = sandbox.load("melting_block", set=SMALL_BLOCK)
    batch = sandbox.load("melting_block", set=SMALL_BLOCK, worlds=3)
    tab, other = Controller(batch, world=1), Controller(batch, world=2)
    assert "erase" not in tab.tool_names() and "spawn" not in tab.tool_names()  # a world keeps its particle count
    assert "dt_scale" not in {s.key for s in tab.settings()}  # one step size for all worlds
    for _ in range(4):
        plain.advance_frame()
        batch.advance_frame()
    before = (batch.world(1).positions(), batch.world(1).temperatures(), batch.world(1).time)
    tab.press("heat", (50.0, 6.0), 4.0)
    for _ in range(2):
        assert tab.advance() == 0  # the stroke acts; the simulation's holder steps the worlds
        plain.advance_frame()
        batch.advance_frame()
    tab.release()
    tab.set("source0", 20.0)
    assert batch.world(1).controls.values()["heat.sources"] == [20.0]
    assert [batch.world(k).controls.values()["heat.sources"] for k in (0, 2)] == [[400.0], [400.0]]
    n = plain.state.live_count()
    warmer = batch.world(1).field("h") - plain.particles.h.to_numpy()[:n]  # its heat: a melt holds its temperature
    assert warmer.max() > 20.0 and warmer.sum() > 300.0  # the stroke heated world 1 ...
    for k in (0, 2):  # ... and nothing else
        _assert_same(plain, batch.world(k))
        assert np.array_equal(plain.temperatures(), batch.world(k).temperatures())
    assert tab.undo().key == "undone"
    after = (batch.world(1).positions(), batch.world(1).temperatures(), batch.world(1).time)
    for was, now in zip(before, after):
        assert np.array_equal(was, now)
    saved = batch.world(0).save(tmp_path / "world0")
    other.load(saved)
    _assert_same(batch.world(0), batch.world(2))
    for _ in range(3):
        plain.advance_frame()
        batch.advance_frame()
    for k in (0, 2):
        _assert_same(plain, batch.world(k))
        assert np.array_equal(plain.temperatures(), batch.world(k).temperatures())
    with pytest.raises(SandboxError, match="this scene has no erase tool"):
        tab.press("erase", (50.0, 6.0), 4.0)
    with pytest.raises(SandboxError, match="erase changes a world's particle count"):
        tab.tools.erase((50.0, 6.0), 4.0)


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_worlds_state_file_resumes_alone_and_a_bad_one_is_refused_in_one_line(tmp_path):
    """World 1's file opens as a lone run that steps on as world 1 does; a lone run's file loads into a world; a file
    of another scene is refused before anything changes; a file's pair scale is the world's own."""
    batch = sandbox.load("melting_block", set=SMALL_BLOCK, worlds=2)
    batch.world(1).controls.set({"heat.sources": [300.0]})
    scaled = sandbox.load("melting_block", set=SMALL_BLOCK)
    scaled.controls.set({"pair.scale": [2.0, 1.0]})
    for _ in range(4):
        batch.advance_frame()
        scaled.advance_frame()
    alone = sandbox.resume(batch.world(1).save(tmp_path / "w1.npz"))
    assert alone.time == batch.world(1).time and alone.controls.values()["heat.sources"] == [300.0]
    for _ in range(3):
        alone.advance_frame()
        batch.advance_frame()
        scaled.advance_frame()
    _assert_same(alone, batch.world(1))
    assert np.array_equal(alone.temperatures(), batch.world(1).temperatures())
    batch.world(0).load(alone.save(tmp_path / "lone.npz"))  # a lone run's whole file: its lists are not taken
    _assert_same(alone, batch.world(0))
    other = sandbox.load("lj_box", set=SMALL_LJ)
    before = batch.world(0).positions()
    said = "saved from the scene 'lj_box' as it was then; expected one saved from this 'melting_block'"
    with pytest.raises(SandboxError, match=said):
        batch.world(0).load(other.save(tmp_path / "bad.npz"))
    assert np.array_equal(before, batch.world(0).positions())
    batch.world(0).load(scaled.save(tmp_path / "scaled.npz"))
    assert [batch.world(k).controls.values()["pair.scale"] for k in (0, 1)] == [[2.0, 1.0], [1.0, 1.0]]
    _assert_same(scaled, batch.world(0))
    again = sandbox.resume(batch.world(0).save(tmp_path / "w0.npz"))  # its lists built again, as the world's are
    assert again.controls.values()["pair.scale"] == [2.0, 1.0]
    for _ in range(2):
        for sim in (again, alone, batch):
            sim.advance_frame()
    _assert_same(again, batch.world(0))
    _assert_same(alone, batch.world(1))


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_world_started_again_keeps_the_bonds_another_world_made_in_its_slots():
    """World 1's plate is made cold, so its melt refreezes into the first free spring slots, among them the slots of
    world 0's broken built bonds. World 0 starting again puts its built bonds back elsewhere: world 1 steps on as in
    a simulation where world 0 was not started again, and world 0 as a fresh lone run."""

    def history():
        batch = sandbox.load("melting_block", set=SMALL_BLOCK, worlds=2)
        for frame in range(14):
            if frame == 12:
                batch.world(1).controls.set({"heat.sources": [-100.0], "heat.ambient": -100.0})
            batch.advance_frame()
        return batch

    restarted, kept = history(), history()
    springs, each = restarted.state.springs, restarted.state.live_count() // 2
    block = springs.built_count // 2
    ends, alive = springs.i.to_numpy()[:block], springs.alive.to_numpy()[:block]
    assert np.count_nonzero((alive == 1) & (ends >= each)) > 0  # world 1's new bonds sit in world 0's slots
    restarted.world(0).reset()
    fresh = sandbox.load("melting_block", set=SMALL_BLOCK)
    for _ in range(6):
        for sim in (restarted, kept, fresh):
            sim.advance_frame()
    _assert_same(kept.world(1), restarted.world(1))
    assert np.array_equal(kept.world(1).temperatures(), restarted.world(1).temperatures())
    assert kept.world(1).stats().broken_springs == restarted.world(1).stats().broken_springs
    _assert_same(fresh, restarted.world(0))


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_worlds_added_and_removed_while_running_leave_the_others_as_they_were():
    """A simulation holding 4 worlds runs 2 of them; a third is taken into use after 5 frames and is then a fresh
    lone run, while the first two stay the uninterrupted one; world 0 is taken out and the last world (the young
    one) takes its index, its state and clock moved with it."""
    plain = sandbox.load("melting_block", set=SMALL_BLOCK)
    batch = sandbox.load("melting_block", set=SMALL_BLOCK, worlds=4)
    batch.world(3).remove()
    batch.world(2).remove()
    assert batch.live_worlds == 2 and batch.state.live_count() == 2 * plain.state.live_count()
    with pytest.raises(SandboxError, match="world 2: expected a whole number from 0 to 1"):
        batch.world(2)
    for _ in range(5):
        plain.advance_frame()
        batch.advance_frame()
    young = batch.add_world()
    assert young.index == 2 and young.time == 0.0
    fresh = sandbox.load("melting_block", set=SMALL_BLOCK)
    for _ in range(5):
        for sim in (plain, batch, fresh):
            sim.advance_frame()
    for k, alone in ((0, plain), (1, plain), (2, fresh)):
        _assert_same(alone, batch.world(k))
        assert np.array_equal(alone.temperatures(), batch.world(k).temperatures())
        assert batch.world(k).stats().broken_springs == alone.stats().broken_springs
    batch.world(0).remove()
    assert batch.live_worlds == 2 and batch.world(0).time == pytest.approx(fresh.time)
    for _ in range(3):
        for sim in (plain, batch, fresh):
            sim.advance_frame()
    _assert_same(fresh, batch.world(0))
    _assert_same(plain, batch.world(1))
    batch.add_world()
    batch.add_world()
    with pytest.raises(SandboxError, match="all 4 worlds of this simulation are in use"):
        batch.add_world()
    lone = sandbox.load("melting_block", set=SMALL_BLOCK)
    with pytest.raises(SandboxError, match="this simulation holds one world; expected one built with room for more"):
        lone.add_world()

"""The performance paths change no physics: half neighbour lists, storage sorted into cell order."""

import os

import numpy as np
import pytest

from sandbox.config.scene import load_scene
from sandbox.core import runtime
from sandbox.research.bench import melting_block_of
from sandbox.simulation import Simulation

from .conftest import SCENES, make_scene, scene_dict

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)


def lj_box(side: float = 20.0, reorder: int = 0, half: bool = True, neighbor_list: bool = True, seed: int = 5):
    """A periodic 2D LJ liquid (W1 in miniature), f64, ~320 particles."""
    data = scene_dict(
        world={
            "dim": 2,
            "lo": [0, 0],
            "hi": [side, side],
            "dt": 0.005,
            "periodic": True,
            "precision": "f64",
            "reorder": reorder,
            "neighbor_list": neighbor_list,
        },
        pair={"a": 8.0, "b": 14.0, "cutoff": 2.5},
        bodies=[
            {
                "material": "lj",
                "shape": "box",
                "lo": [0, 0],
                "hi": [side, side],
                "spacing": 1.118,
                "springs": False,
                "random_velocity": 1.0,
                "seed": seed,
            }
        ],
    )
    return Simulation(make_scene(data), half_lists=half)


def _wax_refreezing_data() -> dict:
    """Cold wax (-20 C) under a hot molten slab (90 C, no springs): the melt freezes onto it and makes new springs."""
    from .test_phase import _wax_scene

    data = _wax_scene()
    data["world"]["precision"] = "f64"
    data["bodies"] = [
        {"material": "wax", "shape": "box", "lo": [8, 0], "hi": [22, 4], "temperature": -20.0},
        {"material": "wax", "shape": "box", "lo": [10, 4.2], "hi": [20, 7.2], "springs": False, "temperature": 90.0},
    ]
    return data


def listed_pairs(sim) -> set:
    n = int(sim.particles.n[None])
    count, ids = sim.hood.lists.count.to_numpy()[:n], sim.hood.lists.ids.to_numpy()
    return {(min(i, int(j)), max(i, int(j))) for i in range(n) for j in ids[i, : count[i]]}


@pytest.mark.parametrize("side", [20.0, 8.5])  # 8.5: three cells per axis, every neighbour cell a periodic image
def test_a_half_list_holds_each_pair_of_the_full_list_once(side):
    full, half = lj_box(side, half=False), lj_box(side, half=True)
    for sim in (full, half):
        sim.rates.evaluate()
    n = full.model.built.count
    full_pairs = listed_pairs(full)
    assert len(full_pairs) * 2 == int(full.hood.lists.count.to_numpy()[:n].sum())  # listed from both ends
    assert int(half.hood.lists.count.to_numpy()[:n].sum()) == len(full_pairs)  # once
    assert listed_pairs(half) == full_pairs


def _packed_box(dim: int, side: float, periodic: bool, half: bool):
    """A jittered LJ packing of a box `side` wide in `dim` dimensions, f64, periodic or walled."""
    data = scene_dict(
        world={"dim": dim, "lo": [0] * dim, "hi": [side] * dim, "dt": 0.005, "periodic": periodic, "precision": "f64"},
        pair={"a": 8.0, "b": 14.0, "cutoff": 2.5},
        bodies=[
            {
                "material": "lj",
                "shape": "box",
                "lo": [0.3] * dim,
                "hi": [side - 0.3] * dim,
                "spacing": 1.118,
                "springs": False,
                "random_velocity": 1.0,
                "seed": 3,
            }
        ],
    )
    sim = Simulation(make_scene(data), half_lists=half)
    sim.step(40)  # off the lattice: cell boundaries and the periodic seams crossed at odd places
    sim.hood.lists.invalidate()
    sim.rates.evaluate()  # the lists built for the positions now
    return sim


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("periodic", [True, False])
def test_the_half_lists_hold_every_pair_within_reach_and_skin_once(periodic, dim, side=8.5):
    """Against a brute-force search over every pair (minimum image in a periodic box): the half rows, built a row
    of cells at a time and each row trimmed to the cells within reach of the particle, list each pair within reach +
    skin exactly once and no pair twice. The box is 8.5 wide: three cells across the leading axes; walled, its cells
    were narrower than the reach and missed pairs."""
    sim = _packed_box(dim, side, periodic, half=True)
    lists = sim.hood.lists
    n = int(sim.particles.n[None])
    x = sim.positions()
    d = x[None, :, :] - x[:, None, :]
    if periodic:
        d -= side * np.round(d / side)
    r2 = (d**2).sum(-1)
    near = (r2 < (lists.reach + lists.skin) ** 2) & np.triu(np.ones((n, n), bool), 1)
    count, ids = lists.count.to_numpy()[:n], lists.ids.to_numpy()
    within = [
        (min(i, int(j)), max(i, int(j))) for i in range(n) for j in ids[i, : count[i]] if near[min(i, j), max(i, j)]
    ]
    assert len(within) == len(set(within))  # no pair twice
    assert set(within) == set(zip(*np.nonzero(near)))


@pytest.mark.parametrize(
    "cpuinfo, chosen, expected",
    [
        ("vendor_id\t: GenuineIntel\nflags\t\t: fpu avx2 avx512f avx512dq\n", "", True),
        ("vendor_id\t: AuthenticAMD\nflags\t\t: fpu avx2 avx512f avx512dq\n", "", False),
        ("vendor_id\t: GenuineIntel\nflags\t\t: fpu avx2\n", "", False),
        ("", "", False),
        ("vendor_id\t: AuthenticAMD\nflags\t\t: fpu avx512f\n", "1", True),
        ("vendor_id\t: GenuineIntel\nflags\t\t: fpu avx512f\n", "0", False),
    ],
)
def test_rows_are_blocked_where_the_cpus_gathers_pay_or_where_asked(monkeypatch, cpuinfo, chosen, expected):
    """Vectorized pair blocks on Intel CPUs with AVX-512 only (AMD's gathers made the 3D pass slower), unless
    SANDBOX_PAIR_BLOCKS says otherwise."""
    monkeypatch.setattr(runtime, "_cpuinfo", lambda: cpuinfo)
    monkeypatch.setenv("SANDBOX_PAIR_BLOCKS", chosen)
    runtime.vector_gathers_pay.cache_clear()
    try:
        assert runtime.vector_gathers_pay() is expected
    finally:
        runtime.vector_gathers_pay.cache_clear()


@pytest.mark.parametrize("blocks", [True, False])
def test_3d_half_rows_give_the_forces_of_full_lists(monkeypatch, blocks):
    """A periodic 3D liquid of pair forces alone, 38 pairs a half row, computed in vectorized blocks or one pair at a
    time (Rates.blocked_rows, as the CPU decides: both chosen here): every particle's force agrees with the full
    lists' gather to round-off (f64)."""
    monkeypatch.setattr(runtime, "vector_gathers_pay", lambda: blocks)
    sims = [_packed_box(3, 8.5, True, half=h) for h in (True, False)]
    assert sims[0].rates.blocked_rows == blocks and not sims[1].rates.half
    f_half, f_full = (s.forces() for s in sims)
    assert np.abs(f_half - f_full).max() <= 1e-9 * np.abs(f_full).max()


def test_half_lists_give_the_forces_and_heat_rates_of_full_lists():
    """The melting block (springs, viscosity, heat, a hot plate) part-way through melting: every particle's force and
    enthalpy rate agree to round-off whichever way the pairs are visited."""
    over = ["world.precision=f64", "heat.sources.0.temperature=400.0"]
    sims = [Simulation(load_scene(SCENES / "melting_block.toml", over), half_lists=h) for h in (False, True)]
    for sim in sims:
        sim.step(400)
        sim.rates.evaluate()
    assert 0 < sims[0].state.springs.alive.to_numpy().sum() < sims[0].model.built.spring_count  # some bonds broke
    f0, f1 = (s.forces() for s in sims)
    h0, h1 = (s.rates.heat_rate.to_numpy()[: s.model.built.count] for s in sims)
    assert np.abs(f0 - f1).max() <= 1e-9 * np.abs(f0).max()
    assert np.abs(h0 - h1).max() <= 1e-9 * np.abs(h0).max()
    assert sims[1].rates.half and not sims[0].rates.half


def test_a_bond_that_breaks_between_list_builds_brings_back_its_pair_force():
    """Half lists mark bonded pairs so the pair pass skips their pair force; a spring that breaks while the list is
    still in use must give its pair the pair force at once, as the full lists (which subtract it per bond) do."""
    over = ["world.precision=f64", "heat.sources.0.temperature=400.0"]
    sims = [Simulation(load_scene(SCENES / "melting_block.toml", over), half_lists=h) for h in (False, True)]
    for sim in sims:
        sim.step(150)
        sim.rates.evaluate()
    half = sims[1]
    n = half.model.built.count
    ids, count = half.hood.lists.ids.to_numpy(), half.hood.lists.count.to_numpy()
    marked = [int(-e - 1) for i in range(n) for e in ids[i, : count[i]] if e < 0]
    assert len(marked) > 1000 and half.rates.marks_bonds  # bonded pairs are marked in the list
    alive = sims[0].state.springs.alive.to_numpy()
    doomed = [s for s in marked[::3] if alive[s]]
    assert len(doomed) > 300
    builds = half.hood.lists.builds
    for sim in sims:  # break every third marked spring by hand, without moving anything
        a = sim.state.springs.alive.to_numpy()
        a[doomed] = 0
        sim.state.springs.alive.from_numpy(a)
        sim.rates.evaluate()
    assert half.hood.lists.builds == builds  # the list was not rebuilt: the marks are stale
    f0, f1 = (s.forces() for s in sims)
    assert np.abs(f0 - f1).max() <= 1e-9 * np.abs(f0).max()


def test_springs_made_by_refreezing_are_marked_before_the_next_step():
    """Refreezing makes new springs (possibly in reused slots): the half list is rebuilt, and forces stay equal."""
    data = _wax_refreezing_data()
    sims = [Simulation(make_scene(data), half_lists=h) for h in (False, True)]
    for sim in sims:
        sim.step(400)
        sim.rates.evaluate()
    assert (
        int(sims[1].state.springs.created[None]) > sims[1].state.springs.built_count + 10
    )  # springs made by refreezing
    f0, f1 = (s.forces() for s in sims)
    assert np.abs(f0 - f1).max() <= 1e-9 * np.abs(f0).max()


@pytest.mark.parametrize("fused", [False, True], ids=["one_step_a_launch", "fused_batches"])
def test_sorting_the_storage_keeps_every_trajectory_and_orders_particles_by_cell(fused):
    plain, sorted_ = lj_box(reorder=0), lj_box(reorder=1)
    for sim in (plain, sorted_):
        sim.plan.fuses = fused
        sim.step(300)
    assert sorted_.hood.order.applied >= 3
    assert (sorted_.plan.fused_batches > 0) == fused  # fused: sorted between batches
    ident = sorted_.particles.ident.to_numpy()[: sorted_.model.built.count]
    assert sorted(ident) == list(range(sorted_.model.built.count))  # a permutation: no particle lost or doubled
    assert not np.array_equal(ident, np.arange(len(ident)))  # the storage did move
    x_plain, x_sorted = plain.positions(), sorted_.positions()
    assert np.abs(x_sorted - x_plain[ident]).max() < 1e-9
    assert np.abs(sorted_.velocities() - plain.velocities()[ident]).max() < 1e-9
    sorted_.hood.order.apply()  # right after a sort the storage runs cell by cell
    cells = sorted_.hood.grid.particle_cell.to_numpy()[: sorted_.model.built.count]
    sorted_.hood.grid.rebuild()
    cells = sorted_.hood.grid.particle_cell.to_numpy()[: sorted_.model.built.count]
    assert np.all(np.diff(cells) >= 0)


def test_sorting_keeps_springs_between_the_same_particles():
    over = ["world.reorder=1", "world.precision=f64"]
    sim = Simulation(load_scene(SCENES / "melting_block.toml", over))
    ident0 = sim.particles.ident.to_numpy()
    i0, j0 = sim.state.springs.i.to_numpy(), sim.state.springs.j.to_numpy()
    before = {frozenset((ident0[a], ident0[b])) for a, b in zip(i0, j0)}
    sim.hood.order.apply()
    ident = sim.particles.ident.to_numpy()
    i, j = sim.state.springs.i.to_numpy(), sim.state.springs.j.to_numpy()
    assert {frozenset((ident[a], ident[b])) for a, b in zip(i, j)} == before
    bonds = sim.state.springs.bonds.to_numpy()
    for p in (0, 17, sim.model.built.count - 1):  # each particle's bond list names springs that touch it
        for s in bonds[p][bonds[p] >= 0]:
            assert p in (i[s], j[s])


def rdf(x: np.ndarray, side: float, bins: np.ndarray) -> np.ndarray:
    d = x[:, None, :] - x[None, :, :]
    d -= side * np.round(d / side)
    r = np.sqrt((d**2).sum(-1))[np.triu_indices(len(x), 1)]
    hist, _ = np.histogram(r, bins)
    shell = np.pi * (bins[1:] ** 2 - bins[:-1] ** 2)
    return hist / shell / (len(x) * (len(x) - 1) / 2 / side**2)


def test_the_optimised_step_keeps_the_energy_drift_and_the_radial_distribution():
    """W1 in miniature, 1,000 steps: half lists + sorting against a plain cell-grid scan (no lists, no sorting)."""
    fast, plain = lj_box(reorder=1, half=True), lj_box(reorder=0, half=False, neighbor_list=False)
    energies = {}
    for name, sim in (("fast", fast), ("plain", plain)):
        e0 = sim.stats().total_energy
        sim.step(1000)
        energies[name] = (sim.stats().total_energy - e0) / abs(e0)
    assert abs(energies["fast"]) < 2e-3 and abs(energies["plain"]) < 2e-3
    assert abs(energies["fast"] - energies["plain"]) < 1e-3
    bins = np.linspace(0.8, 3.0, 23)
    g_fast, g_plain = rdf(fast.positions(), 20.0, bins), rdf(plain.positions(), 20.0, bins)
    assert g_fast.max() > 1.5  # a liquid's first shell
    assert np.abs(g_fast - g_plain).max() < 0.35


def _wax_refreezing_scene():
    return Simulation(make_scene(_wax_refreezing_data()))


def _state(sim) -> list[np.ndarray]:
    out = [sim.positions(), sim.velocities()]
    if sim.terms.heat is not None:
        out.append(sim.temperatures())
    if sim.state.springs is not None:
        out.append(sim.state.springs.alive.to_numpy())
    return out


def assert_same_states(a: list[np.ndarray], b: list[np.ndarray]) -> None:
    """Bit for bit: every array of one _state() equal to the other's."""
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)


SMALL_BLOCK = melting_block_of(30)  # 900 particles: under the size that steps as a team (loops.py)


@pytest.mark.parametrize(
    "make, refreezes",
    [
        (lambda: lj_box(), False),
        (lambda: Simulation(load_scene(SCENES / "melting_block.toml", [*SMALL_BLOCK, "world.precision=f64"])), False),
        (_wax_refreezing_scene, True),
    ],
    ids=["lj_box", "melting_block_900", "refreezing_wax"],
)
def test_many_steps_to_a_launch_give_the_trajectory_of_one_step_at_a_time(make, refreezes):
    """A small scene runs a whole batch of steps in one kernel launch (the list rebuild decided on the device):
    bit for bit the states, clock, list builds and refreezing of launching each pass of each step from the host."""
    one_by_one, fused = make(), make()
    one_by_one.plan.fuses = False
    assert fused.plan.fuses
    for n in (1, 7, 64, 228):
        one_by_one.step(n)
        fused.step(n)
    assert fused.plan.fused_batches >= 4 and one_by_one.plan.fused_batches == 0
    assert_same_states(_state(one_by_one), _state(fused))
    assert (fused.time, fused.step_count) == (one_by_one.time, one_by_one.step_count)
    assert fused.hood.lists.builds == one_by_one.hood.lists.builds > 2
    if refreezes:
        assert (
            int(fused.state.springs.created[None])
            == int(one_by_one.state.springs.created[None])
            > fused.state.springs.built_count
        )


@pytest.mark.parametrize("make", [lambda: lj_box(), lambda: team_box()], ids=["one_thread", "team"])
def test_a_list_build_that_overflows_inside_a_batch_grows_the_list_and_goes_on(make):
    """Lists made too narrow: the batch (fused on one thread, or a team's) stops before the forces of the step whose
    build overflowed, the host widens the lists and the next batch builds them again (no step the long way, whose
    kernels would have to be compiled: a stall of seconds with a cold cache); the trajectory is that of the long
    way."""
    one_by_one, fused = make(), make()
    one_by_one.plan.fuses = False
    for sim in (one_by_one, fused):
        sim.hood.lists._allocate(4)
        sim.hood.lists.invalidate()
        sim.step(50)
    assert fused.hood.lists.grown == one_by_one.hood.lists.grown == 1
    assert fused.plan.fused_batches == 2  # the batch that stopped at its first build, then the rest
    assert fused.hood.lists.host_builds == 0 and one_by_one.hood.lists.host_builds > 0
    assert_same_states(_state(one_by_one), _state(fused))


def test_each_pass_says_why_a_scene_steps_the_long_way():
    """The stepping plan asks each pass (step/plan.py): the reasons name the passes the scene uses, and `sandbox check`
    (pipeline) prints them."""
    from sandbox.step.plan import can_step_as_a_team, host_work_reasons

    block = SCENES / "melting_block.toml"
    assert host_work_reasons(load_scene(block)) == [] and can_step_as_a_team(load_scene(block))
    assert host_work_reasons(load_scene(SCENES / "fireworks.toml")) == ["emitters seed particles between steps"]
    smoke = host_work_reasons(load_scene(SCENES / "smoke_vortex.toml"))
    assert smoke == ["emitters seed particles between steps", "the smoke grid steps between particle steps"] + [
        "particles follow a velocity field sampled at each step"
    ]
    implicit = load_scene(block, ['heat.stepper="implicit"'])
    assert host_work_reasons(implicit) == ["the implicit heat solve iterates from the host"]
    power = load_scene(block, ['heat.sources.0.mode="power"', "heat.sources.0.power=500.0"])
    assert host_work_reasons(power) == [] and not can_step_as_a_team(power)
    sim = Simulation(load_scene(SCENES / "fireworks.toml"))
    assert "launch: one launch per pass, one step at a time: emitters seed particles between steps" in sim.pipeline()


def test_a_step_the_long_way_runs_the_host_passes_that_the_pipeline_lists_in_its_order():
    """pipeline() is printed from the plan that the long way runs: the smoke scene's host passes (emitters, smoke,
    kinematic start; then advection, ageing) each run once a step, in the printed order."""
    sim = Simulation(load_scene(SCENES / "smoke_vortex.toml"))
    plan, ran = sim.plan, []
    for when, terms in (("before_step", plan.before), ("after_step", plan.after)):
        for term in terms:
            hook = getattr(term, when)
            setattr(term, when, lambda state, hook=hook, key=(when, term.key): (ran.append(key), hook(state)))
    sim.step(2)
    order = [("before_step", t.key) for t in plan.before] + [("after_step", t.key) for t in plan.after]
    assert ran == order * 2 and len(order) == 5
    lines = sim.pipeline()
    before = [line for t in plan.before for line in t.words("before")]
    after = [line for t in plan.after for line in t.words("after")]
    described = [lines.index(line) for line in before + after]
    assert described == sorted(described) and len(described) == 4  # the kinematic start is told with its advection
    integrator = lines.index("integrator symplectic_euler, then walls (restitution, friction)")
    assert lines.index(before[-1]) < integrator < lines.index(after[0])


def test_scenes_with_work_between_steps_or_parallel_loops_step_the_long_way():
    assert not Simulation(load_scene(SCENES / "fireworks.toml")).plan.fuses  # emitters act between steps
    from sandbox.research.bench import INTERACTIVE_BLOCK

    # 10,000 particles, springs, heat, and a power source (its per-step mass sum is not shared out in a team)
    power = [*INTERACTIVE_BLOCK, 'heat.sources.0.mode="power"', "heat.sources.0.power=500.0"]
    big = Simulation(load_scene(SCENES / "melting_block.toml", power))
    assert (
        not big.model.loops.serial_pairs and not big.plan.fuses and big.plan.team is None
    )  # each pass on both threads
    big.step(2)
    assert big.plan.fused_batches == 0 and big.step_count == 2
    implicit = lj_box()
    implicit.set_integrator("implicit_euler")  # conjugate-gradient iterations between evaluation and update
    implicit.step(3)
    assert implicit.plan.fused_batches == 0 and implicit.step_count == 3


@pytest.mark.skipif(
    not hasattr(os, "sched_getaffinity")
    or len(os.sched_getaffinity(0)) < 2
    or os.environ.get("SANDBOX_PIN_THREADS") == "0",
    reason="pinning needs Linux and two cores",
)
def test_taichi_worker_threads_are_pinned_one_per_core():
    """Linux often woke both CPU workers on one core (a parallel loop then ran at serial speed): each is pinned."""
    import taichi as ti

    from sandbox.core import runtime, threads

    runtime.reset()  # a Taichi start of its own (the pinning runs at each start), kernels compiled by now
    sim = lj_box()
    workers = int(ti.cfg.cpu_max_num_threads)
    assert sim.arch == "cpu" and workers >= 2
    if workers < len(os.sched_getaffinity(0)):
        pytest.skip("fewer workers than cores (a CPU quota or SANDBOX_CPU_THREADS): left to the scheduler")
    assert len(threads.pinned) == workers
    cores = [core for _tid, core in threads.pinned]
    assert len(set(cores)) == min(workers, len(os.sched_getaffinity(0)))
    for tid, core in threads.pinned:
        assert tid != os.getpid() and os.path.isdir(f"/proc/self/task/{tid}")
        assert os.sched_getaffinity(tid) == {core}


def test_workers_fewer_than_the_cores_are_left_to_the_scheduler(monkeypatch):
    """Pinned round robin from the first core, every process with fewer workers than its cores (2 threads each of
    several renders on 16 cores) would crowd cores 0 and 1 while the rest stayed idle: such pools are not pinned."""
    from sandbox.core import runtime, threads

    runtime.init("cpu", "f32")  # a running pool: before, its workers were found and pinned
    monkeypatch.setattr(threads.os, "sched_getaffinity", lambda pid: set(range(16)), raising=False)
    monkeypatch.setattr(threads.os, "sched_setaffinity", lambda pid, cores: pytest.fail("pinned"), raising=False)
    assert threads.pin_workers(2) == [] and threads.pinned == []


TEAM_SIDE = 65.0  # about 3,400 particles in 5,046 slots: a size that steps as a team of threads (loops.TEAM_FROM)


def team_box(**kwargs) -> Simulation:
    sim = lj_box(TEAM_SIDE, **kwargs)
    if sim.plan.team is None:
        pytest.skip("team stepping needs two or more CPU threads")
    return sim


@pytest.mark.parametrize("reorder", [0, 20], ids=["unsorted", "sorted_every_20"])
def test_a_team_of_threads_gives_the_trajectory_of_the_parallel_long_way(reorder):
    """Every thread runs every step of a batch over its share of the particles, meeting the others at barriers:
    bit for bit the states, clock and list builds of launching each pass of each step in parallel from the host."""
    team, long_way = team_box(reorder=reorder), team_box(reorder=reorder)
    long_way.plan.fuses = False
    for n in (1, 30, 100):
        team.step(n)
        long_way.step(n)
    assert team.plan.team is not None and team.plan.fused_batches >= 3 and long_way.plan.fused_batches == 0
    assert_same_states(_state(long_way), _state(team))
    assert (team.time, team.step_count) == (long_way.time, long_way.step_count)
    assert team.hood.lists.builds == long_way.hood.lists.builds > 2
    assert team.hood.lists.host_builds == 0  # every build ran inside the team's launches


def _hot_melting_block(**world) -> Simulation:
    over = ["world.precision=f64", "heat.sources.0.temperature=400.0"] + [f"world.{k}={v}" for k, v in world.items()]
    return Simulation(load_scene(SCENES / "melting_block.toml", over))


def _refreezing_wax(**world) -> Simulation:
    data = _wax_refreezing_data()
    data["world"].update(world)
    return Simulation(make_scene(data))


@pytest.mark.parametrize(
    "make, refreezes", [(_hot_melting_block, False), (_refreezing_wax, True)], ids=["melting_block", "refreezing_wax"]
)
def test_a_team_steps_springs_and_heat_as_the_parallel_long_way_does(make, refreezes):
    """Springs soften, break (and refreezing makes new ones between batches) and heat flows inside the team's
    launches: bit for bit the states, springs and clock of launching each pass in parallel from the host. The room
    for spawning (world.capacity) puts the small scenes in the team's size range."""
    team, long_way = make(capacity=5100), make(capacity=5100)
    if team.plan.team is None:
        pytest.skip("team stepping needs two or more CPU threads")
    long_way.plan.fuses = False
    alive_at_start = int(team.state.springs.alive.to_numpy().sum())
    for n in (1, 60, 240):
        team.step(n)
        long_way.step(n)
    assert team.plan.fused_batches >= 3 and long_way.plan.fused_batches == 0
    assert_same_states(_state(long_way), _state(team))
    assert np.array_equal(team.state.springs.factor.to_numpy(), long_way.state.springs.factor.to_numpy())
    assert (team.time, team.step_count) == (long_way.time, long_way.step_count)
    assert team.hood.lists.host_builds == 0
    if refreezes:
        assert (
            int(team.state.springs.created[None]) > team.state.springs.built_count + 10
        )  # springs made between batches
    else:
        assert 0 < int(team.state.springs.alive.to_numpy().sum()) < alive_at_start  # springs broke inside the launches


def test_a_team_that_cannot_start_changes_nothing_and_the_scene_steps_the_long_way():
    """More workers than the thread pool has threads: the started ones give up at the first barrier, before any
    work; the launch reports it (-1), nothing has moved, and the simulation steps the long way from then on."""
    from sandbox.step.team import Team

    sim, long_way = team_box(), team_box()
    long_way.plan.fuses = False
    sim.plan.use_team(Team(sim.rates, 2 * sim.plan.team.workers))
    before = _state(sim)
    assert sim.plan.team.run(5, 1, 0, sim.integrator, sim.hood.ids(True), sim.dt, sim.plan.fused.stopped_stage) == -1
    assert_same_states(before, _state(sim))
    sim.step(30)
    long_way.step(30)
    assert sim.plan.team is None and not sim.plan.fuses and sim.step_count == 30
    assert_same_states(_state(long_way), _state(sim))


def test_kernel_errors_still_name_the_file_and_line_and_mark_the_expression():
    """runtime.py formats Taichi's per-statement error excerpts itself (a start-up cost): a compile error still says
    where, quotes the line and marks the expression."""
    import taichi as ti

    from sandbox.core import runtime

    runtime.init("cpu")
    x = ti.field(float, shape=4)

    @ti.kernel
    def broken():
        for i in x:
            x[i] = not_defined_anywhere + 1.0  # noqa: F821

    with pytest.raises(Exception) as err:
        broken()
    text = str(err.value)
    quoted = next(line for line in text.splitlines() if "not_defined_anywhere + 1.0" in line)
    marks = text.splitlines()[text.splitlines().index(quoted) + 1]
    assert f'File "{__file__}"' in text and "in broken" in text
    assert marks.strip() == "^" * len("not_defined_anywhere")  # the name that is not defined
    assert marks.index("^") == quoted.index("not_defined_anywhere")


def test_whole_step_launches_compile_without_the_cfg_pass_and_the_setting_comes_back():
    """The team's and the fused steps' kernels compile without Taichi's CFG pass (a cold-start cost); every other
    kernel (the renderer's, which run slower without it) keeps it, also after an error inside."""
    import taichi as ti

    from sandbox.core import runtime

    sim = lj_box()
    cfg = ti.cfg
    seen = []

    class Spy:  # stands in for the team: records the setting during the launch, then declines (-1: step the long way)
        def run(self, *args) -> int:
            seen.append(cfg.cfg_optimization)
            return -1

    assert cfg.cfg_optimization
    sim.plan.use_team(Spy())
    sim.step(1)
    assert seen == [False] and cfg.cfg_optimization
    assert sim.plan.team is None and sim.step_count == 1
    with pytest.raises(RuntimeError), runtime.without_cfg_pass():
        raise RuntimeError("inside")
    assert cfg.cfg_optimization


def test_copies_measurements_and_refreezing_compile_without_the_cfg_pass_and_the_rest_with_it(monkeypatch):
    """Kernels that run at most once a frame compile without the CFG pass (faster to compile, transfer.py); the
    passes of a step and the renderer's kernels keep it."""
    import taichi as ti
    from taichi.lang import kernel_impl

    from sandbox.render.raster import Renderer

    with_pass: dict[str, bool] = {}
    materialize = kernel_impl.Kernel.materialize

    def materialize_and_note(self, key=None, args=None, arg_features=None):
        if key not in self.compiled_kernels:
            with_pass.setdefault(self.func.__name__, ti.cfg.cfg_optimization)
        return materialize(self, key, args, arg_features)

    monkeypatch.setattr(kernel_impl.Kernel, "materialize", materialize_and_note)
    sim = Simulation(make_scene(_wax_refreezing_data()))
    sim.plan.fuses = False  # the long way: one launch per pass
    sim.step(3)
    sim.terms.refreeze.run()
    sim.stats()
    sim.restore(sim.snapshot())
    Renderer(sim.model, sim.state, 64, 48, sim.scene.render).render()
    assert not any(with_pass[name] for name in ("_copy", "_measure", "_prepare", "_bond")), with_pass
    assert all(with_pass[name] for name in ("_rates_update", "_sort_and_count", "_splat_pass_2d")), with_pass


@pytest.mark.parametrize(
    "make",
    [
        lambda: lj_box(),
        lambda: Simulation(load_scene(SCENES / "melting_block.toml", [*SMALL_BLOCK, "world.precision=f64"])),
    ],
    ids=["lj_box", "melting_block_900"],
)
def test_widening_the_lists_recompiles_nothing_and_keeps_the_trajectory(make, request):
    """Lists that grow (an emitter or the spawn tool packing particles closer) are a new, wider array that every
    compiled kernel takes as it is: no kernel is compiled again (it was a stall of about a second each time), and
    the trajectory is the one the narrower lists give."""
    wide, narrow = make(), make()
    wide.step(30)
    narrow.step(30)
    compiled = request.getfixturevalue("compiled_kernels")  # from here on
    width = wide.hood.lists.width
    wide.hood.lists._allocate(2 * width)  # what grow() does, here without an overflow first
    for sim in (wide, narrow):
        sim.hood.lists.invalidate()  # both rebuild now (a rebuild at another step sums the forces in another order)
    wide.step(60)
    narrow.step(60)
    assert wide.hood.lists.width == 2 * width and narrow.hood.lists.width == width
    assert compiled == []
    assert_same_states(_state(wide), _state(narrow))


@pytest.mark.parametrize(
    "make, integrator",
    [
        (lambda: lj_box(), "velocity_verlet"),
        (
            lambda: Simulation(load_scene(SCENES / "melting_block.toml", [*SMALL_BLOCK, "world.precision=f64"])),
            "velocity_verlet",
        ),
        (lambda: team_box(), "velocity_verlet"),
        (lambda: lj_box(), "verlet"),
        (lambda: lj_box(), "midpoint"),
        (lambda: team_box(), "midpoint"),
        (
            lambda: Simulation(load_scene(SCENES / "melting_block.toml", [*SMALL_BLOCK, "world.precision=f64"])),
            "rk4",
        ),
        (lambda: team_box(), "rk4"),
    ],
    ids=[
        "lj_box",
        "melting_block_900",
        "team",
        "lj_box_position_verlet",
        "lj_box_midpoint",
        "team_midpoint",
        "melting_block_900_rk4",
        "team_rk4",
    ],
)
def test_staged_integrators_fused_or_teamed_step_as_the_long_way_does(make, integrator):
    """The Verlet methods as leapfrog update each particle once per step, midpoint and RK4 once per stage, so they
    run many steps to a launch (and as a team) like symplectic Euler: over 1,000 steps in calls of several sizes,
    bit for bit the long way's states."""
    fast, long_way = make(), make()
    long_way.plan.fuses = False
    for sim in (fast, long_way):
        sim.set_integrator(integrator)
        for n in (1, 7, 64, 928):
            sim.step(n)
    assert fast.plan.fused_batches >= 4 and long_way.plan.fused_batches == 0
    assert_same_states(_state(long_way), _state(fast))
    assert (fast.time, fast.step_count) == (long_way.time, long_way.step_count) == (long_way.time, 1000)


@pytest.mark.parametrize("make", [lambda: lj_box(), lambda: team_box()], ids=["one_thread", "team"])
def test_a_list_that_overflows_between_the_stages_of_a_step_is_widened_and_the_step_goes_on(make, monkeypatch):
    """RK4 with lists exactly as wide as the widest count: a later rebuild overflows, mostly at a stage after the
    first (its positions are the trial ones). The launch stops before that stage's forces, the host widens the lists
    and the next launch goes on from that stage: bit for bit the long way, which widens them inside the stage."""
    fast, long_way = make(), make()
    long_way.plan.fuses = False
    stopped_at = []
    run_fused = fast.plan._run_fused

    def run_and_note(batch, *alone):
        done = run_fused(batch, *alone)
        stopped_at.append(fast.plan.pending_stage)
        return done

    monkeypatch.setattr(fast.plan, "_run_fused", run_and_note)
    for sim in (fast, long_way):
        sim.set_integrator("rk4")
        sim.step(1)
        nb, n = sim.hood.lists, int(sim.particles.n[None])
        nb.invalidate()
        nb.ensure_fresh()  # a build at the current positions
        nb._allocate(int(nb.count.to_numpy()[:n].max()))  # no room for one more neighbour
        nb._sort_and_fill(nb.flat)  # the same build again, into the narrow lists
        assert int(nb.overflow[None]) == 0
        sim.step(300)
    assert fast.hood.lists.grown == long_way.hood.lists.grown == 1
    assert any(stage > 0 for stage in stopped_at), stopped_at  # the overflow came between stages
    assert fast.plan.pending_stage == 0 and fast.step_count == long_way.step_count == 301
    assert_same_states(_state(long_way), _state(fast))


def test_load_watch_gives_the_team_up_once_another_task_wants_one_of_its_cores(tmp_path):
    """A team of 2 spinning workers on 2 cores needs both: one other runnable task (beside one other CPU-bound
    program the team ran at 10 M particle-steps/s against one thread's 25) makes the machine busy, after a few reads;
    a brief one does not. Reads move the estimate by SMOOTHING; the reader itself is not another task."""
    from sandbox.core.threads import LoadWatch

    loadavg = tmp_path / "loadavg"
    watch = LoadWatch(2, str(loadavg), cores=2, own=lambda: 1, machine=2)
    seen = []
    for running in (1, 2, 1, 1, 2, 2, 2, 2, 1, 1, 1, 1):
        loadavg.write_text(f"0.5 0.5 0.5 {running}/80 1234\n")
        watch.last = -1.0  # read now
        seen.append(watch.busy())
    assert seen == [False, False, False, False, False, True, True, True, True, False, False, False], seen
    # on 4 cores two others leave the team's 2 threads a core each
    roomy = LoadWatch(2, str(loadavg), cores=4, own=lambda: 1, machine=4)
    loadavg.write_text("0.5 0.5 0.5 3/80 1234\n")
    for _ in range(10):
        roomy.last = -1.0
        assert not roomy.busy()
    # pinned to 2 of 16 cores: 14 others fill the cores it may not use first; the 15th lands on one of its own
    pinned = LoadWatch(2, str(loadavg), cores=2, own=lambda: 1, machine=16)
    for running, busy_after in ((15, False), (16, True)):
        loadavg.write_text(f"0.5 0.5 0.5 {running}/80 1234\n")
        for _ in range(10):
            pinned.last = -1.0
            busy = pinned.busy()
        assert busy == busy_after, running
    assert not LoadWatch(1, str(loadavg)).busy() and not LoadWatch(2, str(tmp_path / "none")).busy()


def test_crowded_ways_keep_the_faster_and_try_the_other_again():
    """While crowded the plan times the long way and one thread in stints and keeps the faster; a way's first stint
    (which compiles) is not timed; the slower is tried again every RETRY seconds."""
    from sandbox.step.crowd import ALONE, LONG, RETRY, STINT, CrowdedWays

    now = [0.0]
    ways = CrowdedWays(clock=lambda: now[0])
    cost = {ALONE: 1e-3, LONG: 2e-3}  # seconds a step
    chosen = []
    for _ in range(8):
        way = ways.choose()
        chosen.append(way)
        now[0] += 0.1
        ways.record(way, 5.0 if ways.stints[way] == 0 else cost[way] * STINT, STINT)  # 5 s: the compile
    assert chosen[:4] == [ALONE, ALONE, LONG, LONG] and set(chosen[4:]) == {ALONE}
    assert ways.per_step == pytest.approx({ALONE: 1e-3, LONG: 2e-3})
    now[0] += RETRY
    assert ways.choose() == LONG
    ways.record(LONG, 0.6e-3 * STINT, STINT)  # the other program has stopped sharing the same core
    assert ways.choose() == ALONE  # recent seconds over recent steps: (20 + 12) / 30 ms = 1.07 ms, still the slower
    ways.record(LONG, 0.6e-3 * STINT, STINT)  # (16 + 12) / 35 ms = 0.8 ms: now the faster
    assert ways.choose() == ALONE  # not run for RETRY seconds: tried again first
    ways.record(ALONE, 1e-3 * STINT, STINT)
    assert [ways.choose() for _ in range(3)] == [LONG] * 3


def test_a_short_stint_without_a_list_build_does_not_make_the_slower_way_look_faster():
    """A stint is cut short where a call asks for fewer steps (a frame's substeps, a call's remainder); one of a few
    steps that holds no list build reads faster than its way is. A way is timed by its recent seconds over its recent
    steps, so such a stint counts for its few steps: averaged by stint, the long way looked a third faster than it was
    beside 3 hogs (W1-3D) and was chosen while slower."""
    from sandbox.step.crowd import ALONE, LONG, STINT, CrowdedWays

    now = [0.0]
    ways = CrowdedWays(clock=lambda: now[0])
    for way in (ALONE, LONG):  # the first stints compile and are not timed
        ways.record(way, 5.0, STINT)
    ways.record(ALONE, 15e-3 * STINT, STINT)  # one thread: 15 ms a step, list builds included
    ways.record(LONG, 20e-3 * STINT, STINT)  # the long way: 20 ms a step
    for _ in range(2):
        ways.record(LONG, 3 * 8e-3, 3)  # 3 steps between list builds: 8 ms each
    assert ways.per_step[LONG] > ways.per_step[ALONE]
    assert ways.choose() == ALONE
    fade = 0.5 ** (3 / STINT)  # recent seconds and steps halve every STINT steps
    recent = (fade * fade * 400 + fade * 24 + 24, fade * fade * 20 + fade * 3 + 3)  # ms, steps
    assert ways.per_step[LONG] == pytest.approx(recent[0] / recent[1] * 1e-3)  # 16.9 ms


def test_the_slower_way_is_tried_less_often_each_time_it_proves_slower():
    """A try of the slower way every RETRY seconds spends 9% of a long crowded run on it: each try that finds it
    slower still doubles the wait before the next (up to MAX_RETRY); once it leads, both are tried at the first pace."""
    from sandbox.step.crowd import ALONE, LONG, MAX_RETRY, RETRY, STINT, CrowdedWays

    now = [0.0]
    ways = CrowdedWays(clock=lambda: now[0])
    cost = {ALONE: 1e-3, LONG: 1.5e-3}
    tries_of_long = []
    for _ in range(3000):  # 0.1 s a stint: 300 s of crowded stepping
        way = ways.choose()
        if way == LONG and ways.stints[LONG] >= 2:
            tries_of_long.append(now[0])
        now[0] += 0.1
        ways.record(way, cost[way] * STINT, STINT)
    gaps = [b - a for a, b in zip(tries_of_long, tries_of_long[1:])]  # a wait, and the stint (0.1 s) it follows
    expected = [2 * RETRY, 4 * RETRY, 8 * RETRY] + [MAX_RETRY] * (len(gaps) - 3)
    assert len(gaps) >= 8 and all(0 <= gap - wait < 0.25 for gap, wait in zip(gaps, expected)), gaps
    assert ways.wait[LONG] == MAX_RETRY
    cost[ALONE] = 2e-3  # the scheduler now favours the long way: one thread's stints slow down, the long way leads
    for _ in range(10):
        way = ways.choose()
        now[0] += 0.1
        ways.record(way, cost[way] * STINT, STINT)
    assert ways.choose() == LONG and ways.wait == {LONG: RETRY, ALONE: RETRY}


def test_one_thread_on_a_crowded_machine_steps_springs_and_heat_as_the_team_does(tmp_path):
    """The crowded machine's one-thread way runs the team's own kernel on one worker: a kernel of its own (the fused
    one-thread launch) is compiled with Taichi's fast math, which let the compiler sum the melting block's forces in
    another order (an ulp apart at the second step, 4 broken springs fewer by the end of its demo)."""
    from sandbox.core.threads import LoadWatch
    from sandbox.step.crowd import ALONE

    team, alone = (Simulation(load_scene(SCENES / "melting_block.toml")) for _ in range(2))
    if team.plan.team is None:
        pytest.skip("team stepping needs two or more CPU threads")
    loadavg = tmp_path / "loadavg"
    loadavg.write_text("0.5 0.5 0.5 9/80 1234\n")
    alone.plan.load = LoadWatch(2, str(loadavg), cores=2, machine=2)
    alone.plan.load.others, alone.plan.load.last = 9.0, -1.0
    alone.plan.crowd.choose = lambda: ALONE
    for sim in (team, alone):
        for _ in range(12):
            sim.step(5)
    assert alone.plan.crowded_steps == 60 and team.plan.crowded_steps == 0
    assert np.array_equal(team.positions(), alone.positions())
    assert np.array_equal(team.state.particles.v.to_numpy(), alone.state.particles.v.to_numpy())


def test_a_crowded_machine_frees_the_pinned_workers_and_pins_them_again_once_it_clears(tmp_path):
    """While crowded one worker works at a time, and pinned it cannot move to the core less crowded now (beside 3
    CPU-bound programs on 2 cores the one-thread way ran 13% slower pinned in 3D): the workers may run on every usable
    core until the machine clears, then each is pinned to its own core again for the team."""
    from sandbox.core import threads
    from sandbox.core.threads import LoadWatch

    sim = team_box()
    if sim.plan.team is None or not threads.pinned:
        pytest.skip("needs a team and workers pinned one per core (two or more cores)")
    everywhere = os.sched_getaffinity(0)
    loadavg = tmp_path / "loadavg"
    watch = sim.plan.load = LoadWatch(2, str(loadavg), cores=2, machine=2)
    loadavg.write_text("0.5 0.5 0.5 9/80 1234\n")
    watch.others, watch.last = 9.0, -1.0
    sim.step(20)
    assert sim.plan.crowded_steps == 20
    assert all(os.sched_getaffinity(tid) == everywhere for tid, _core in threads.pinned)
    loadavg.write_text("0.5 0.5 0.5 1/80 1234\n")
    watch.others, watch.last = 0.0, -1.0
    sim.step(20)
    assert sim.plan.crowded_steps == 20
    assert all(os.sched_getaffinity(tid) == {core} for tid, core in threads.pinned)


def test_a_crowded_machine_steps_other_ways_with_the_teams_trajectory(tmp_path):
    """While other work shares the cores the plan steps the long way or on one thread (each timed, the faster kept),
    and the team again once the machine clears: bit for bit the trajectory of a run that kept the team throughout."""
    from sandbox.core.threads import LoadWatch
    from sandbox.step.crowd import ALONE, LONG

    loadavg = tmp_path / "loadavg"
    watch = LoadWatch(2, str(loadavg), cores=2, machine=2)
    kept, crowded = team_box(), team_box()
    crowded.plan.load = watch
    loadavg.write_text("0.5 0.5 0.5 9/80 1234\n")
    watch.others, watch.last = 9.0, -1.0
    crowded.step(100)  # crowded throughout: stints of 20 steps, each way warmed and timed
    assert crowded.plan.crowded_steps == 100
    assert crowded.plan.crowd.stints[ALONE] >= 2 and crowded.plan.crowd.stints[LONG] >= 2
    alone_batches = crowded.plan.fused_batches
    assert alone_batches >= 2  # the one-thread stints ran fused launches
    loadavg.write_text("0.5 0.5 0.5 1/80 1234\n")
    watch.others, watch.last = 0.0, -1.0
    crowded.step(60)  # clear again: the team
    kept.step(100)
    kept.step(60)
    assert crowded.plan.fused_batches > alone_batches and crowded.plan.crowded_steps == 100
    assert_same_states(_state(kept), _state(crowded))
    assert (kept.time, kept.step_count) == (crowded.time, crowded.step_count)

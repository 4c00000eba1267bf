"""Force laws: the Voigt spring-damper, the generalized pair force (and its 12-6 Lennard-Jones case), momentum."""

import numpy as np
import pytest
import taichi as ti

from sandbox.physics.neighbours import list_width
from sandbox.physics.pair import equilibrium_distance, pair_energy, radial_force
from sandbox.simulation import Simulation

from .conftest import make_scene, scene_dict

LJ_WORLD = {"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.001}


def two_particles(pair=None, springs=True, material="jelly", **world):
    """Two particles 1 apart at (10.5, 10.5) and (11.5, 10.5), optionally joined by one spring."""
    w = {"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.001}
    w.update(world)
    data = scene_dict(
        world=w,
        bodies=[
            {
                "material": material,
                "shape": "box",
                "lo": [10, 10],
                "hi": [12, 11],
                "springs": springs,
                "spring_radius": 1.0,
            }
        ],
    )
    if pair is not None:
        data["pair"] = pair
    return Simulation(make_scene(data))


def place(sim, x, v=None):
    x = np.asarray(x, dtype=np.float32)
    full = sim.particles.x.to_numpy()
    full[: len(x)] = x
    sim.particles.x.from_numpy(full)
    vel = sim.particles.v.to_numpy()
    vel[: len(x)] = 0 if v is None else np.asarray(v, dtype=np.float32)
    sim.particles.v.from_numpy(vel)
    sim.rates.evaluate()
    return sim.forces()


def test_spring_force_law_and_equal_opposite():
    sim = two_particles()
    assert sim.state.springs.count == 1
    k, c = sim.scene.materials["jelly"].stiffness, sim.scene.materials["jelly"].damping
    d = np.array([1.3, 0.4])
    f = place(sim, [[10.0, 10.0], [10.0 + d[0], 10.0 + d[1]]])
    r = np.linalg.norm(d)
    expected = k * (r - 1.0) * d / r  # stretched: pulls i towards j
    assert np.allclose(f[0], expected, rtol=1e-5)
    assert np.array_equal(f[1], -f[0])  # exactly, not just approximately
    # Damper: j moving away along d at speed u adds c u d_hat on i, opposing the stretching rate
    u = 0.7
    f = place(sim, [[10.0, 10.0], [10.0 + d[0], 10.0 + d[1]]], v=[[0, 0], list(u * d / r)])
    assert np.allclose(f[0], expected + c * u * d / r, rtol=1e-5)
    assert np.array_equal(f[1], -f[0])


def test_compressed_spring_pushes_apart():
    sim = two_particles()
    f = place(sim, [[10.0, 10.0], [10.6, 10.0]])
    assert f[0][0] < 0 < f[1][0]


def test_lennard_jones_is_the_generalized_form_with_a8_b14():
    # 12-6 LJ with eps = sigma = 1: F(r) = 24 (2 r^-13 - r^-7) (repulsive positive); energy 4 (r^-12 - r^-6)
    for r in (0.95, 1.0, 2 ** (1 / 6), 1.3, 1.8, 2.4):
        f_lj = 24 * (2 * r**-13 - r**-7)
        g = radial_force(r, 24.0, 48.0, 0.0, 8, 14)  # F_i = g d, d from i to j: repulsion is g < 0
        assert -g * r == pytest.approx(f_lj, rel=1e-12)
        u_lj = 4 * (r**-12 - r**-6) - 4 * (2.5**-12 - 2.5**-6)
        assert pair_energy(r, 24.0, 48.0, 0.0, 8, 14, 2.5) == pytest.approx(u_lj, rel=1e-12, abs=1e-12)
    assert equilibrium_distance(24.0, 48.0, 0.0, 8, 14) == pytest.approx(2 ** (1 / 6), rel=1e-9)


def test_lj_in_taichi_matches_analytic_and_vanishes_at_equilibrium():
    sim = two_particles(pair={"a": 8.0, "b": 14.0, "cutoff": 2.5}, springs=False, material="lj")
    for r in (0.95, 1.1, 1.5, 2.2):
        f = place(sim, [[10.0, 10.0], [10.0 + r, 10.0]])
        f_lj = 24 * (2 * r**-13 - r**-7)  # repulsive positive: pushes i to -x
        assert f[0][0] == pytest.approx(-f_lj, rel=1e-4, abs=1e-5)  # f32 positions
        assert f[1][0] == -f[0][0]
        e = sim.stats().pair_energy
        assert e == pytest.approx(4 * (r**-12 - r**-6) - 4 * (2.5**-12 - 2.5**-6), rel=1e-4, abs=1e-5)
    f = place(sim, [[10.0, 10.0], [10.0 + 2 ** (1 / 6), 10.0]])
    assert abs(f[0][0]) < 1e-4  # force scale here is ~24
    f = place(sim, [[10.0, 10.0], [12.6, 10.0]])
    assert np.all(f == 0)  # beyond the cutoff


def test_default_form_a2_b4_zero_at_equilibrium_and_energy_is_its_integral():
    alpha, beta, eps = 3.0, 2.0, 0.1
    r_eq = equilibrium_distance(alpha, beta, eps, 2, 4)
    assert radial_force(r_eq, alpha, beta, eps, 2, 4) == pytest.approx(0, abs=1e-9)
    for r in (0.9, 1.2, 1.7):
        h = 1e-6
        du = (pair_energy(r + h, alpha, beta, eps, 2, 4, 3.0) - pair_energy(r - h, alpha, beta, eps, 2, 4, 3.0)) / (
            2 * h
        )
        assert du == pytest.approx(r * radial_force(r, alpha, beta, eps, 2, 4), rel=1e-6)


def test_coincident_particles_get_finite_opposite_push():
    sim = two_particles(pair={"a": 8.0, "b": 14.0, "cutoff": 2.5}, springs=False, material="lj")
    for gap in (0.0, 1e-7, 0.3):
        f = place(sim, [[10.0, 10.0], [10.0 + gap, 10.0]])
        assert np.all(np.isfinite(f))
        assert f[0][0] < 0 < f[1][0]
        assert np.allclose(f[0], -f[1])
    # the cap: below core * r_eq the force keeps its value at the core
    core_r = 0.6 * 2 ** (1 / 6)
    f_core = 24 * (2 * core_r**-13 - core_r**-7)
    assert abs(f[0][0]) == pytest.approx(f_core, rel=1e-4)


def test_total_force_vanishes_without_gravity():
    data = scene_dict(
        world=LJ_WORLD,
        pair={"a": 8.0, "b": 14.0, "cutoff": 2.5},
        bodies=[
            {
                "material": "wax",
                "shape": "box",
                "lo": [5, 5],
                "hi": [15, 13],
                "jitter": 0.3,
                "seed": 3,
                "random_velocity": 0.5,
            },
            {"material": "lj", "shape": "box", "lo": [15, 5], "hi": [22, 12], "springs": False, "jitter": 0.2},
        ],
    )
    data["heat"] = {"ambient": 20.0}
    sim = Simulation(make_scene(data))
    sim.rates.evaluate()
    f = sim.forces().astype(np.float64)
    scale = np.abs(f).sum()
    assert scale > 0
    assert np.abs(f.sum(axis=0)).max() < 1e-5 * scale


def small_lj_box(**world):
    w = {"dim": 2, "lo": [0, 0], "hi": [22.36, 22.36], "dt": 0.005, "periodic": True}
    w.update(world)
    data = scene_dict(
        world=w,
        pair={"a": 8.0, "b": 14.0, "cutoff": 2.5},
        bodies=[
            {
                "material": "lj",
                "shape": "box",
                "lo": [0, 0],
                "hi": [22.36, 22.36],
                "spacing": 1.118,
                "springs": False,
                "random_velocity": 1.0,
                "seed": 5,
            }
        ],
    )
    return Simulation(make_scene(data))


def test_neighbour_lists_give_the_same_forces_as_a_cell_scan():
    sim = small_lj_box()
    assert sim.hood.lists is not None
    sim.step(200)  # particles cross the periodic boundary and the lists are rebuilt several times
    assert sim.hood.lists.builds > 2
    sim.rates.evaluate()
    with_lists = sim.forces().copy()
    sim.hood.grid.rebuild()
    sim.rates._rates(False, sim.rates.no_lists)
    assert np.allclose(with_lists, sim.forces(), rtol=1e-4, atol=1e-4)
    plain = small_lj_box(neighbor_list=False)
    assert plain.hood.lists is None
    plain.step(200)
    # same trajectory either way (up to float summation order over a chaotic 200 steps: compare energies)
    assert plain.stats().total_energy == pytest.approx(sim.stats().total_energy, rel=1e-3)


@pytest.mark.parametrize("periodic", [False, True])
def test_the_blocked_prefix_sum_of_a_gpu_sorts_the_grid_as_the_serial_one(periodic):
    """A GPU sums the cells' counts in blocks (CellGrid.prefix_sum); forced on the CPU, both sums give every cell
    the start that the particles in the cells before it make, and the sort puts each particle in its own cell."""
    from sandbox.core import runtime
    from sandbox.core.loops import LoopPolicy
    from sandbox.physics.grid import SCAN_BLOCK, CellGrid

    runtime.init("cpu")
    rng = np.random.default_rng(5)
    n, side = 3000, 60.0
    x = ti.Vector.field(2, ti.f32, shape=n)
    count = ti.field(ti.i32, shape=())
    points = rng.uniform(0.0, side, (n, 2)).astype(np.float32)
    points[: n // 3] = rng.uniform(10.0, 12.0, (n // 3, 2))  # a crowd: some cells hold many, most none
    x.from_numpy(points)
    count[None] = n
    starts = []
    for blocked in (False, True):
        loops = LoopPolicy("cpu", n)
        loops.gpu = blocked
        grid = CellGrid(x, count, [0.0, 0.0], [side, side], 0.5, periodic, n, loops)
        assert grid.n_cells > 2 * SCAN_BLOCK  # more than one block, the last one partial
        grid.rebuild()
        cells = grid.particle_cell.to_numpy()
        expected = np.concatenate([[0], np.cumsum(np.bincount(cells, minlength=grid.n_cells))[:-1]])
        start = grid.cell_start.to_numpy()
        np.testing.assert_array_equal(start, expected)
        order = grid.sorted_ids.to_numpy()
        np.testing.assert_array_equal(np.sort(order), np.arange(n))
        np.testing.assert_array_equal(np.diff(cells[order]) >= 0, True)  # in cell order
        starts.append(start)
    np.testing.assert_array_equal(starts[0], starts[1])


@pytest.mark.long
@pytest.mark.parametrize("dim", [2, 3])
def test_a_gpus_list_build_gives_the_cpus_lists_and_trajectory_to_the_bit(dim, monkeypatch):
    """The GPU's shapes of the grid's sort (the blocked prefix sum) and of the list build (storing only the kept
    neighbours), forced on the CPU, list the same neighbours in the same order: a run steps to the same bits."""
    from sandbox.core import loops
    from sandbox.research.bench import lj_box_3d_sim

    def run(gpu: bool):
        made = loops.LoopPolicy.__init__

        def policy(self, *args, **kwargs):
            made(self, *args, **kwargs)
            self.gpu = gpu

        with monkeypatch.context() as patch:
            patch.setattr(loops.LoopPolicy, "__init__", policy)
            sim = small_lj_box() if dim == 2 else lj_box_3d_sim(8, "cpu")
        assert sim.model.loops.gpu is gpu
        sim.step(150)
        lists = sim.hood.lists
        rows = lists.ids.to_numpy()
        listed = [tuple(rows[i, : lists.count[i]]) for i in range(sim.model.built.count)]
        return sim.positions().copy(), lists.builds, listed

    cpu_x, cpu_builds, cpu_lists = run(False)
    gpu_x, gpu_builds, gpu_lists = run(True)
    assert cpu_builds == gpu_builds > 5
    assert cpu_lists == gpu_lists
    np.testing.assert_array_equal(cpu_x, gpu_x)


def test_list_rows_are_never_a_multiple_of_32_entries_apart():
    """Rows 128 bytes apart or a multiple of it start on a fraction of the cache's sets (W1-3D's step 20% slower at
    width 128 than at 129): the width keeps 1.5x the widest row plus 8 and steps off multiples of 32."""
    widths = {w: list_width(w) for w in range(0, 400)}
    assert all(width % 32 != 0 and width >= max(16, 1.5 * w + 8) for w, width in widths.items())
    assert list_width(80) == 132 and list_width(64) == 104 and list_width(5) == 16


def test_half_lists_are_sized_from_their_own_rows_and_keep_room_as_the_packing_slides():
    """Half lists are 1.5 times as wide as their widest row at the start, plus 8: narrower than rows sized from the
    full neighbour count (twice the memory; W1-3D's step 6% slower at width 129 than at 112). Sliding the
    lattice across the cells changes which particle lists which pair (one at the back of its cell lists its
    cell-mates), and every half row still fits: the lists never grow."""
    sim = small_lj_box()
    nb = sim.hood.lists
    assert nb.half
    x = sim.positions()
    box = 22.36
    d = x[:, None, :] - x[None, :, :]
    d -= box * np.round(d / box)
    r2 = (d**2).sum(-1)
    full = ((r2 < (nb.reach + nb.skin) ** 2).sum(1) - 1).max()
    assert nb.width == list_width(int(nb.widest[None])) >= 1.5 * int(nb.widest[None]) + 8
    assert nb.width < 1.5 * full  # sized from full rows, it was 1.5 full + 8
    for shift in np.linspace(0.0, 3.0, 7):  # the lattice slid by fractions of a cell: every half row fits
        place(sim, (x + shift) % box)
        sim.step(1)
    assert nb.grown == 0 and nb.usable


def crowd(sim):
    n = sim.model.built.count
    rng = np.random.default_rng(0)
    return np.full((n, 2), 11.0) + rng.uniform(-0.5, 0.5, (n, 2))  # every particle within one cell


def test_crowding_widens_the_neighbour_lists():
    sim = small_lj_box(periodic=False)
    width = sim.hood.lists.width
    place(sim, crowd(sim))
    assert sim.hood.lists.grown == 1 and sim.hood.lists.width >= sim.model.built.count - 1 > width
    reference = sim.forces().copy()
    sim.hood.grid.rebuild()
    sim.rates._rates(False, sim.rates.no_lists)
    # the crowd's forces nearly cancel on some particles: compare against the largest (f32, other summation order)
    assert np.allclose(reference, sim.forces(), rtol=0, atol=1e-5 * np.abs(reference).max())


def test_a_crowd_past_the_list_memory_cap_falls_back_to_the_grid_and_stays_finite(monkeypatch):
    import sandbox.physics.neighbours as nb

    monkeypatch.setattr(nb, "MAX_BYTES", 1)
    sim = small_lj_box(periodic=False)
    with pytest.warns(UserWarning, match="neighbour list overflow"):
        place(sim, crowd(sim))
    assert np.all(np.isfinite(sim.forces()))
    sim.step(20)
    s = sim.stats()
    assert np.isfinite(s.total_energy) and np.all(np.isfinite(sim.positions()))


def test_live_pair_scaling_moves_the_equilibrium_and_the_curve_shows_it():
    sim = two_particles(pair={"a": 8.0, "b": 14.0, "cutoff": 2.5}, springs=False, material="lj", precision="f64")
    sim.terms.pair.set_scale(2.0, 2.0)  # both doubled: the same law, twice as strong
    r = 1.3
    f = place(sim, [[10.0, 10.0], [10.0 + r, 10.0]])
    assert f[0][0] == pytest.approx(-2 * 24 * (2 * r**-13 - r**-7), rel=1e-5)  # (place() rounds to f32)
    sim.terms.pair.set_scale(2.0, 1.0)  # attraction doubled: r_eq = (beta / alpha)^(1/6) shrinks by 2^(-1/6)
    r_eq = 2 ** (1 / 6) * 2 ** (-1 / 6)
    assert sim.terms.pair.r_eq_np[0, 0] == pytest.approx(r_eq, rel=1e-9)
    assert abs(place(sim, [[10.0, 10.0], [10.0 + r_eq, 10.0]])[0][0]) < 1e-4
    r_curve, force = sim.terms.pair.curve()
    crossing = r_curve[np.argmax(force > 0)]  # repulsive (negative) inside, attractive outside
    assert abs(crossing - r_eq) < (r_curve[1] - r_curve[0]) * 1.01
    assert np.all(np.diff(force[r_curve < sim.terms.pair.r_core_np[0, 0]]) == 0)  # held below the core


def test_light_stats_reuse_the_last_pair_energy_and_measure_the_rest():
    sim = two_particles(pair={"a": 8.0, "b": 14.0, "cutoff": 2.5}, springs=False, material="lj", gravity=[0, -1])
    place(sim, [[10.0, 10.0], [11.2, 10.0]], v=[[0.5, 0.0], [0.0, 0.0]])
    full = sim.stats()
    place(sim, [[10.0, 10.5], [11.6, 10.5]], v=[[1.0, 0.0], [0.0, 0.0]])
    light = sim.stats(pair_energy=False)
    assert light.pair_energy == full.pair_energy  # not rescanned ...
    assert light.kinetic_energy == pytest.approx(0.5) and light.gravity_energy != full.gravity_energy  # ... the rest is
    assert sim.stats().pair_energy != full.pair_energy  # a full call measures it again


def _harmonic_trap(centre):
    """A new term in one class (tests/test_forces.py alone): a harmonic trap F = -m w^2 (x - c) on every particle,
    its strength a field of its own that the state carries."""
    import taichi as ti

    from sandbox.core.oriented import data_oriented
    from sandbox.physics.term import Term

    @data_oriented
    class Trap(Term):
        key = "trap"
        stage = "forces"  # summed after gravity and field drag (registered after them)
        particle_force = True

        @staticmethod
        def wanted(parts) -> bool:
            return True

        def __init__(self, parts):
            self.particles = parts.state.particles
            self.w2 = ti.field(float, shape=())  # w^2 (1 / time^2)
            self.w2[None] = 4.0
            self.centre = ti.Vector(list(centre))

        def words(self, where: str) -> list[str]:
            return ["harmonic trap"] if where == "rates" else []

        def declare(self, state) -> None:
            state.declare("trap", self, ("w2",))

        @ti.func
        def force(self, i):
            p = self.particles
            return -p.mass[i] * self.w2[None] * (p.x[i] - self.centre)

    return Trap


@pytest.fixture
def trap_registered():
    """The trap in the term registry for one test (registering is all a new term's module does)."""
    from sandbox.physics.term import TERMS, register

    centre = np.array([11.0, 10.0])
    trap = register(_harmonic_trap(centre))
    yield centre
    TERMS.remove(trap)


def test_a_term_added_in_one_class_acts_in_every_way_of_stepping(trap_registered, tmp_path):
    """A new term is one class, registered: a harmonic trap moves free particles on x(t) = c + (x0 - c) cos(w t),
    the same bits stepped the long way (a launch per pass), many steps to a launch on one thread, and by a team of
    threads; pipeline() names it in the rates line, and its field is state (saved with it)."""
    from sandbox.files import persist

    from .test_fast_paths import team_box

    centre = trap_registered
    world = {"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.001, "precision": "f64"}
    world["integrator"] = "velocity_verlet"
    body = {"material": "jelly", "shape": "box", "lo": [10, 10], "hi": [12, 11], "springs": False}
    one_by_one, fused = (Simulation(make_scene(scene_dict(world=world, bodies=[body]))) for _ in range(2))
    one_by_one.plan.fuses = False
    assert fused.plan.fuses and any(
        line.startswith("fused rates kernel") and line.endswith("harmonic trap") for line in fused.pipeline()
    )
    x0 = fused.positions().copy()
    assert len(x0) == 2 and not np.allclose(x0, centre)
    for sim in (one_by_one, fused):
        sim.step(1000)  # t = 1
    x = fused.positions()
    assert np.array_equal(x, one_by_one.positions()) and fused.plan.fused_batches > 0 == one_by_one.plan.fused_batches
    expected = centre + (x0 - centre) * np.cos(2.0 * 1.0)
    assert np.abs(x - expected).max() < 1e-5 < np.abs(x0 - expected).min()
    assert "trap.w2" in {e.name for e in fused.state.entries()}
    fused.terms.trap.w2[None] = 9.0
    fused.save(tmp_path / "trapped")
    one_by_one.terms.trap.w2[None] = 1.0
    persist.load_into(one_by_one, tmp_path / "trapped.npz")
    assert one_by_one.terms.trap.w2[None] == 9.0  # put back with the state
    team, long_way = team_box(), team_box()  # an LJ liquid in the trap, 2,900 particles
    long_way.plan.fuses = False
    for sim in (team, long_way):
        sim.step(40)
    assert team.plan.team is not None and team.plan.fused_batches > 0 == long_way.plan.fused_batches
    assert np.array_equal(team.positions(), long_way.positions())
    assert team.terms.trap is not None


MORSE = {"law": "morse", "depth": 1.5, "width": 2.0, "distance": 1.1, "cutoff": 3.0}


def _morse(r: float) -> tuple[float, float]:
    """The Morse well of MORSE by hand: (U(r), dU/dr)."""
    e = np.exp(-2.0 * (r - 1.1))
    return 1.5 * (1.0 - e) ** 2 - 1.5, 2.0 * 1.5 * 2.0 * e * (1.0 - e)


def test_a_new_pair_law_is_one_class_and_its_force_is_minus_the_derivative_of_its_energy():
    """The Morse law is one class (physics/pair_laws.py; the cutoff, shifts and core are the term's, issue 73): in
    NumPy its force is the central difference of its own energy and both equal the formula by hand; in the Taichi step
    two particles feel m_i m_j dU/dr along their separation and measure U shifted to zero at the cutoff."""
    from sandbox.physics.pair_laws import NUMPY, MorseLaw

    law, c = MorseLaw(None), (1.5, 2.0, 1.1)
    for r in (0.8, 1.1, 1.6, 2.5):
        h = 1e-6
        du = (law.u(r + h, c, NUMPY) - law.u(r - h, c, NUMPY)) / (2 * h)
        assert r * law.g(r * r, c, NUMPY) == pytest.approx(du, rel=1e-6, abs=1e-9)
        assert (law.u(r, c, NUMPY), r * law.g(r * r, c, NUMPY)) == pytest.approx(_morse(r), rel=1e-12, abs=1e-12)
    assert law.equilibrium(c) == 1.1
    sim = two_particles(pair=MORSE, springs=False, material="lj")
    m = float(np.prod(sim.particles.mass.to_numpy()[:2]))
    for r in (0.9, 1.1, 1.5, 2.4):
        f = place(sim, [[10.0, 10.0], [10.0 + r, 10.0]])
        u, du = _morse(r)
        assert f[0][0] == pytest.approx(m * du, rel=1e-4, abs=1e-5)  # attracting (du > 0) pulls i to +x
        assert f[1][0] == -f[0][0]
        assert sim.stats().pair_energy == pytest.approx(m * (u - _morse(3.0)[0]), rel=1e-4, abs=1e-5)


def test_a_morse_cluster_keeps_its_energy_under_velocity_verlet():
    """NVE with the new law: a 5 x 5 cluster of Morse atoms, jostled, over 2,000 velocity-Verlet steps in f64."""
    world = {"dim": 2, "lo": [0, 0], "hi": [30, 30], "dt": 0.002, "substeps": 50, "integrator": "velocity_verlet"}
    world["precision"] = "f64"
    data = scene_dict(
        world=world,
        pair=MORSE,
        bodies=[{"material": "lj", "shape": "box", "lo": [10, 10], "hi": [15, 15], "springs": False}],
    )
    sim = Simulation(make_scene(data))
    rng = np.random.default_rng(3)
    n = int(sim.particles.n[None])
    v = sim.particles.v.to_numpy()
    v[:n] += rng.normal(scale=0.3, size=(n, 2))
    sim.particles.v.from_numpy(v)
    e0 = sim.stats().total_energy
    energies = []
    for _ in range(40):
        sim.advance_frame()
        energies.append(sim.stats().total_energy)
    assert sim.step_count == 2000 and sim.stats().pair_energy < -1.0  # bound: the well holds them
    assert np.max(np.abs(np.array(energies) - e0)) < 2e-4 * abs(e0)
